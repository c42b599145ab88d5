"""One Bullet step's model kernel called with two arguments instead of eleven: :class:`StepArgs`.

:func:`~bullet_dlo.bullet.kernels.sync_and_advance` takes ten arguments that are the same objects every step (the
stepper, the model's arrays, the held ends' plan and measurements, the coupling, the scratch, the detector, the
contacts, the free bodies, the stall guard: about 150 arrays in NamedTuples) and one that changes (the
:class:`~bullet_dlo.bullet.kernels.StepInput`). Numba unboxes every array of every argument on each call (7.6 us a
step at n = 10, more than a bare Bullet step of the cable's spheres); :func:`make_step_args` packs the ten into one
StructRef once (the arrays are shared, not copied) and :func:`step_with` unpacks them inside compiled code (0.3 us).
:class:`~bullet_dlo.bullet.solver.CableSolver` builds a new one whenever one of the ten objects is replaced (a
rebuilt contact set, a restarted detector), so the kernel always sees the objects a plain call would pass: the same
kernel on the same data, the same bits.
"""
from __future__ import annotations

from numba.experimental import structref

from bullet_dlo.bullet.contact_call import FixedFields
from bullet_dlo.bullet.kernels import sync_and_advance
from bullet_dlo.core.kernels.jit import njit

FIELDS = ("stepper", "arrays", "plan", "holders", "coupling", "workspace", "detector", "contacts", "bodies", "guard")


@structref.register
class StepArgsType(FixedFields):
    """Numba type of :class:`StepArgs` (fields: :data:`FIELDS`, typed as the objects packed)."""


class StepArgs(structref.StructRefProxy):
    """The ten per-cable arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` (:data:`FIELDS`), packed."""


structref.define_proxy(StepArgs, StepArgsType, list(FIELDS))


@njit(cache=True)
def make_step_args(stepper, arrays, plan, holders, coupling, workspace, detector, contacts, bodies, guard):
    """Pack the per-cable arguments (compiled and cached: the proxy's own constructor is compiled in every process)."""
    return StepArgs(stepper, arrays, plan, holders, coupling, workspace, detector, contacts, bodies, guard)


@njit(cache=True, error_model="numpy")
def step_with(args, inp):
    """:func:`~bullet_dlo.bullet.kernels.sync_and_advance` on the packed arguments and the step's input."""
    return sync_and_advance(args.stepper, args.arrays, args.plan, args.holders, args.coupling, args.workspace,
                            args.detector, inp, args.contacts, args.bodies, args.guard)
