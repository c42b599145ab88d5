"""Detection's row writers compile to straight code: no reference counting in the loops that call them.

Every row :func:`~bullet_dlo.bullet.contact.detect` finds goes through ``_add`` (a contact on a primitive or a hull),
``_add_row`` (a probed link's row) or ``_fill`` (self-contact, another cable). Each takes the Contacts, Store and
Shapes tuples (30, 9 and 15 arrays); a tuple whose last use sits inside a branch, or behind an early return, costs an
atomic increment and decrement of every one of its arrays per row. ``_add``'s early return for full arrays did that:
122 counts, 1.46 us a row against 32 ns without (2026-12-03, 11 rows). Results are unchanged either way, so only the
compiled code shows it (tests/llvm_loops.py, as tests/core/test_kernel_refcounts.py for the contact step's helpers).
"""
from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from bullet_dlo.bullet import contact as C
from bullet_dlo.core.kernels.contact import make_contacts
from llvm_loops import loop_increfs

N = 8  # nodes
SHAPES = 2


def _shapes() -> C.Shapes:
    """Two static boxes, the second in a collision Bullet's last step made (its rows take the unplanned sink)."""
    z = np.zeros
    return C.Shapes(kind=z(SHAPES, np.int64), pos=z((SHAPES, 3)), rot=np.tile(np.eye(3), (SHAPES, 1, 1)),
                    size=np.full((SHAPES, 3), 0.1), com=z((SHAPES, 3)), lin_vel=np.full((SHAPES, 3), 0.01),
                    ang_vel=np.full((SHAPES, 3), 0.1), static_friction=np.full(SHAPES, 0.5),
                    dynamic_friction=np.full(SHAPES, 0.4), inv_mass=z(SHAPES), inv_inertia=z(SHAPES),
                    owner=np.arange(SHAPES), slot=np.full(SHAPES, -1), inertia=z((SHAPES, 3, 3)),
                    impact=np.array([False, True]))


def _store(keys: int, rows: int) -> C.Store:
    """Every other key active (a kept anchor), the rest new; some penetration let out (sink)."""
    z = np.zeros
    return C.Store(anchor=z((keys, 4)), state=z(keys, np.int64), active=np.arange(keys) % 2 == 0,
                   keys=z(rows, np.int64), body=z(rows, np.int64), wrap=z(keys, np.bool_), drift=z((keys, 3)),
                   sink=np.full(keys, 1e-5), depth=z(keys), load=z(keys),
                   stiffness=z(keys))


@njit
def _add_rows(c, st, sh, mass, x, cl, nl):
    c.count[0] = 0
    for i in range(x.shape[0] - 1):
        C._add(c, st, i, i % 2, i, i + 1, 0.5, 0.5, cl, nl, sh, 1e3, 0.5, mass, x)
    return c.count[0]


@njit
def _add_row_rows(c, st, sh, mass, x):
    c.count[0] = 0
    for i in range(x.shape[0] - 1):
        C._add_row(c, st, i, i % 2, i, i + 1, 0.5, 0.5, sh, 1e3, 0.5, mass, x)
    return c.count[0]


@njit
def _fill_rows(c, st, x):
    c.count[0] = 0
    for i in range(x.shape[0] - 1):
        C._fill(c, st, i, -1, i, i + 1, 0.5, 0.5, 0.5, 0.4, 1e3, 0.5, 0.01, x)
    return c.count[0]


@pytest.mark.parametrize("rows", [N - 1, 3])  # room for every row; full arrays (_add drops the rest)
def test_detection_row_writers_compile_without_reference_counting(rows):
    x = np.zeros((N, 3))
    x[:, 0] = np.linspace(0.0, 0.1, N)
    mass = np.full(N, 0.01)
    cl, nl = np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 1.0])
    runs = {"_add": (_add_rows, lambda c, st: _add_rows(c, st, _shapes(), mass, x, cl, nl)),
            "_add_row": (_add_row_rows, lambda c, st: _add_row_rows(c, st, _shapes(), mass, x)),
            "_fill": (_fill_rows, lambda c, st: _fill_rows(c, st, x))}
    for name, (wrapper, run) in runs.items():
        if rows < N - 1 and name != "_add":
            continue  # (only _add checks for room: its callers check for the others)
        c = make_contacts(N, rows, 0.005)
        assert run(c, _store(2 * N, rows)) == rows  # the rows written, the rest dropped
        assert np.allclose(c.k_n[:rows], 1e3 * 0.01 if name != "_fill" else 1e3)  # k_per_mass times the mass
        count = loop_increfs(wrapper)
        assert count == 0, (f"{name}: {count} reference-count increments in its compiled loop: a tuple whose last "
                            "use sits inside a branch or behind an early return (see tests/llvm_loops.py)")
