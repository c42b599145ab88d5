"""A contact set's per-step kernels called on packed arguments: :class:`SetArgs` and :class:`BroadArgs`.

As :mod:`bullet_dlo.bullet.solver_call` does for the model's step: :func:`~bullet_dlo.bullet.contact.quiet`,
:func:`~bullet_dlo.bullet.contact.detect` and :func:`~bullet_dlo.bullet.contact._probe_broad` take a contact set's
arrays (about 80, most inside NamedTuples) beside the step's few inputs, and Numba unboxes every array on each call:
2-3 us of a 3 us ``quiet`` at n = 10, more than its work. Those arrays are the same objects for the set's life
(:class:`~bullet_dlo.bullet.contact.ContactSet` makes them when it is built and only writes into them), so the set
packs them once here (shared, not copied) and calls the kernels through ``quiet_with``, ``detect_with`` and
``probe_broad_with`` (:mod:`bullet_dlo.bullet.contact`), which unpack them inside compiled code. A rebuilt set
(new bodies, other cables) packs its own. The kernels see the arrays a plain call would pass: the same bits.
"""
from __future__ import annotations

from numba import types
from numba.experimental import structref

from bullet_dlo.core.kernels.jit import njit

SET_FIELDS = ("shapes", "hulls", "contacts", "bodies", "store", "others", "probes", "seg_k", "seg_l", "seg_b",
              "seg_held", "probe_out", "self_mu", "zeta")
"""What :func:`~bullet_dlo.bullet.contact.detect` and :func:`~bullet_dlo.bullet.contact.quiet` read of the set."""
BROAD_FIELDS = ("api", "cable_box", "row_of", "row_body", "row_link", "out", "segments", "nodes", "segs", "mid",
                "quat", "data", "pairs", "hit", "boxes", "todo")
""":func:`~bullet_dlo.bullet.contact._probe_broad`'s arguments but the step's positions and reach."""


class FixedFields(types.StructRef):
    """A pack of arrays that no kernel replaces (a new pack replaces the whole): the compiler borrows its fields
    (:mod:`bullet_dlo.core.kernels.jit`); fields typed as the objects packed. Base of every packed-arguments type."""

    fields_fixed = True

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


@structref.register
class SetArgsType(FixedFields):
    """Numba type of :class:`SetArgs` (fields: :data:`SET_FIELDS`)."""


@structref.register
class BroadArgsType(FixedFields):
    """Numba type of :class:`BroadArgs` (fields: :data:`BROAD_FIELDS`)."""


class SetArgs(structref.StructRefProxy):
    """A contact set's arrays for detection (:data:`SET_FIELDS`), packed."""


class BroadArgs(structref.StructRefProxy):
    """A contact set's arrays for the probed links' broad phase (:data:`BROAD_FIELDS`), packed."""


structref.define_proxy(SetArgs, SetArgsType, list(SET_FIELDS))
structref.define_proxy(BroadArgs, BroadArgsType, list(BROAD_FIELDS))


@njit(cache=True)
def make_set_args(shapes, hulls, contacts, bodies, store, others, probes, seg_k, seg_l, seg_b, seg_held, probe_out,
                  self_mu, zeta):
    """Pack a set's detection arrays (compiled and cached: the proxy's own constructor compiles in every process)."""
    return SetArgs(shapes, hulls, contacts, bodies, store, others, probes, seg_k, seg_l, seg_b, seg_held, probe_out,
                   self_mu, zeta)


@njit(cache=True)
def make_broad_args(api, cable_box, row_of, row_body, row_link, out, segments, nodes, segs, mid, quat, data, pairs,
                    hit, boxes, todo):
    """Pack a set's broad-phase arrays (compiled and cached)."""
    return BroadArgs(api, cable_box, row_of, row_body, row_link, out, segments, nodes, segs, mid, quat, data, pairs,
                     hit, boxes, todo)
