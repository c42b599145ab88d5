"""The friction caps' outer fixed point, cap = mu f_n(x(cap)) (``contact.relax_caps``): each contact solve freezes
the rows' friction limits, solves, and takes the limits again at the solution. Three maps with a known fixed point
stand in for the solve: one whose limit overshoots and decays slowly (a row pressed harder when its friction is
smaller), one whose limit jumps between zero and a value (a large limit lifts the row out of the ground, a small one
lets it back in: a plain fixed point cycles for ever), and one that converges monotonically (left as it is)."""
from __future__ import annotations

import numpy as np

from bullet_dlo.core.kernels.contact import make_contacts, relax_caps

A, LAM = 0.019, 0.9  # overshooting: g(c) = A - LAM c, fixed point A / (1 + LAM) = 0.01 N
B, S = 0.02, 2.0  # jumping: g(c) = max(0, B - S c), fixed point B / (1 + S)
M0, SLOPE = 0.005, 0.5  # monotone: g(c) = M0 + SLOPE c, fixed point M0 / (1 - SLOPE) = 0.01 N
FIXED = np.array([A / (1.0 + LAM), B / (1.0 + S), M0 / (1.0 - SLOPE)])


def _limits(cap: np.ndarray) -> np.ndarray:
    """The three rows' limits [N] at the solution with the limits ``cap`` [N] in use."""
    return np.array([A - LAM * cap[0], max(0.0, B - S * cap[1]), M0 + SLOPE * cap[2]])


def _passes(relaxed: bool, count: int) -> np.ndarray:
    """The limits in use after ``count`` passes from zero, with relax_caps or the plain update cap <- g(cap)."""
    c = make_contacts(3, 3, 0.001)
    c.count[0] = 3
    history = np.zeros((3, 2))
    for p in range(1, count + 1):
        new = _limits(c.cap)
        if relaxed:
            relax_caps(c, new, history, p)
        else:
            c.cap[:] = new
    return c.cap.copy()


def test_relaxed_caps_reach_the_fixed_point_where_plain_passes_cycle_or_crawl():
    """After 8 passes the relaxed limits of the two overshooting rows are within 1e-6 of their fixed points; the
    plain update is still 40 % off on the first (0.9^8) and cycles between 0 and B on the second."""
    relaxed, plain = _passes(True, 8), _passes(False, 8)
    assert np.all(np.abs(relaxed[:2] - FIXED[:2]) <= 1e-6 * FIXED[:2]), relaxed
    assert abs(plain[0] - FIXED[0]) > 0.3 * FIXED[0] and plain[1] in (0.0, B), plain


def test_a_monotone_row_takes_the_whole_step():
    """A row converging monotonically (slope 1/2) is not slowed: its limits are the plain update's, pass by pass."""
    for count in range(1, 7):
        assert _passes(True, count)[2] == _passes(False, count)[2]


def test_the_overshooting_linear_row_is_solved_by_its_secant():
    """On a linear map the secant is exact: the second relaxed pass lands on the fixed point (to round-off), where
    the plain update is 0.9^2 of the way back."""
    assert abs(_passes(True, 2)[0] - FIXED[0]) <= 1e-12
