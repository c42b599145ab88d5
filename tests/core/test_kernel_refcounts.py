"""The contact rows' per-row helpers compile to straight arithmetic: no reference counting in their loops.

A kernel reads a field of a NamedTuple of arrays (``c.support``) as a new reference to the array. Numba removes
the count's increment and decrement again when they sit in one block; when the read sits in one arm of a branch
whose value is merged after it (``s if s > 0.0 else c.radius[0]``), they stay, as two atomic operations and a
call per read. One such read in ``_gap`` made the contact kernels 8-40x slower (2026-12-03: ``contact_forces`` on
a cable lying on a table 1.2 -> 10.2 us at n = 20, 2.5 -> 37.8 us at n = 80; the coupled step's contact scenes
2.4x -> 3.9-4.8x their contact-free twin) with every result unchanged, so only this reading of the compiled code
catches it. Each helper is called over all rows from a small uncached wrapper, whose LLVM code must hold no
``NRT_incref``; the wrappers compile in a few seconds.
"""
from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from bullet_dlo.core.kernels import contact as K
from llvm_loops import loop_increfs

N = 6  # nodes
ROWS = 5


@njit
def _gap_rows(c, x):
    s = 0.0
    for k in range(c.count[0]):
        s += K._gap(c, k, x)
    return s


@njit
def _slip_rows(c, x, u):
    s = 0.0
    for k in range(c.count[0]):
        s += K._slip(c, k, x, u)
    return s


@njit
def _approach_rows(c, v):
    s = 0.0
    for k in range(c.count[0]):
        s += K._approach(c, k, v)
    return s


@njit
def _sticks_rows(c, x, u):
    s = 0
    for k in range(c.count[0]):
        s += K._sticks(c, k, K._slip(c, k, x, u))
    return s


@njit
def _row_blocks_rows(c, x, u, blk):
    s = 0.0
    for k in range(c.count[0]):
        K._row_blocks(c, k, x, 1.0, 0.1, u, blk)
        s += blk[0, 0, 0] + blk[1, 0, 0]
    return s


@njit
def _grip_rows(g, x, w):
    s = 0.0
    for e in range(2):
        s += K._grip_cap(g, e) + K._grip_offset(g, e, x, w)
    return s


def _contacts(section: tuple[float, float]) -> K.Contacts:
    """Rows on consecutive segments of an N-node cable, half of them penetrating, some with friction."""
    c = K.make_contacts(N, ROWS, 0.005, section=section)
    c.count[0] = ROWS
    for k in range(ROWS):
        c.node[k] = k, k + 1
        c.weight[k] = 0.5, 0.5
        c.normal[k] = 0.0, 0.0, 1.0
        c.point[k] = 0.0, 0.0, 0.004 if k % 2 else -0.004
        c.k_n[k], c.k_t[k], c.cap[k] = 1e4, 1e3, 0.1 * (k % 3)
    return c


# (the scratch arrays come as arguments: an array the wrapper allocated is counted where it is passed on)
CASES = {"_gap": lambda c, x: _gap_rows(c, x), "_slip": lambda c, x: _slip_rows(c, x, np.empty(3)),
         "_approach": lambda c, x: _approach_rows(c, x), "_sticks": lambda c, x: _sticks_rows(c, x, np.empty(3)),
         "_row_blocks": lambda c, x: _row_blocks_rows(c, x, np.empty(3), np.empty((2, 3, 3))),
         "_grip_cap, _grip_offset": lambda c, x: _grip_rows(c.grip, x, np.empty(3))}
WRAPPERS = {"_gap": _gap_rows, "_slip": _slip_rows, "_approach": _approach_rows, "_sticks": _sticks_rows,
            "_row_blocks": _row_blocks_rows, "_grip_cap, _grip_offset": _grip_rows}


@pytest.mark.parametrize("helper", list(CASES))
def test_a_contact_rows_helper_compiles_without_reference_counting(helper):
    x = np.zeros((N, 3))
    x[:, 0] = np.linspace(0.0, 0.1, N)
    for section in ((0.0, 0.0), (0.02, 0.002)):  # round, flat: one compilation (the same types)
        value = CASES[helper](_contacts(section), x)
        assert np.isfinite(value)
    count = loop_increfs(WRAPPERS[helper])
    assert count == 0, (f"{helper}: {count} reference-count increments in its compiled loop: an array or tuple whose "
                        "last use sits inside a branch (read it before the branch)")

