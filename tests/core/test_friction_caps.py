"""The friction caps' outer fixed point, cap = mu f_n(x(cap)) (``contact.relax_caps``): each contact solve freezes
the rows' friction limits, solves, and takes the limits again at the solution. Three maps with a known fixed point
stand in for the solve: one whose limit overshoots and decays slowly (a row pressed harder when its friction is
smaller), one whose limit jumps between zero and a value (a large limit lifts the row out of the ground, a small one
lets it back in: a plain fixed point cycles for ever), and one that converges monotonically (left as it is)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.kernels.contact import elastic_caps, make_contacts, predicted_caps, relax_caps

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


K_N, MU_F, R = 2.4e6, 0.3, 0.002  # [N/m], [-], [m]: the soft cable's penalty, friction and radius


def _row_on_a_plane(weights: tuple[float, float], depth: float, speed: float) -> tuple:
    """Contacts of a 3-node cable with one row on the plane z = 0 (normal +z) at nodes 0 and 1 with ``weights``,
    the row's point ``depth`` [m] into the plane at the predictor, approaching it at ``speed`` [m/s]; node masses 1,
    2, 3 g. Returns (contacts, x, v, mass)."""
    c = make_contacts(3, 2, R)
    c.count[0] = 1
    c.node[0] = 0, 1
    c.weight[0] = weights
    c.normal[0] = 0.0, 0.0, 1.0
    c.k_n[0] = c.k_t[0] = K_N
    c.static_friction[0] = c.dynamic_friction[0] = MU_F
    x = np.zeros((3, 3))
    x[:, 2] = R - depth
    v = np.zeros((3, 3))
    v[:, 2] = -speed
    return c, x, v, np.array([1e-3, 2e-3, 3e-3])


def test_an_arriving_node_starts_with_the_force_that_stops_it_not_the_predictors_penetration():
    """A point arriving at q = 0.7 m/s, 1 kHz (cx = hf = h): the predictor puts it h q = 0.7 mm deep, whose penalty
    force (1.7 kN) is k_n h^2 / m_eff times the force m_eff q / h that stops it in the step (m_eff = 1 / (w_a^2 /
    m_a + w_b^2 / m_b), the point's mass); the first pass's cap is mu times the latter. A row already 0.1 mm deep
    before the approach keeps that penalty force on top."""
    h, q = 1e-3, 0.7
    for weights in ((1.0, 0.0), (0.25, 0.75)):
        inv = weights[0] ** 2 / 1e-3 + weights[1] ** 2 / 2e-3
        for before in (0.0, 1e-4):
            c, x, v, mass = _row_on_a_plane(weights, before + h * q, q)
            elastic, out = np.zeros(1), np.zeros(1)
            elastic_caps(c, x, elastic)
            predicted_caps(c, x, v, mass, np.zeros(3, np.bool_), h, h, out)
            assert elastic[0] == pytest.approx(MU_F * K_N * (before + h * q))
            assert out[0] == pytest.approx(MU_F * (K_N * before + q / (inv * h)), rel=1e-9)
            assert out[0] < 0.01 * elastic[0] if before == 0.0 else out[0] < 0.25 * elastic[0]


@pytest.mark.parametrize("case", ["held", "resting", "leaving"])
def test_the_bound_leaves_held_resting_and_leaving_rows_at_their_penetration(case):
    """A row on a held node (its motion is imposed: no mass stops it), one at rest and one moving away keep the
    predictor's penalty force."""
    held = np.array([case == "held", False, False])
    speed = {"held": 0.7, "resting": 0.0, "leaving": -0.7}[case]
    c, x, v, mass = _row_on_a_plane((1.0, 0.0), 3e-4, speed)
    elastic, out = np.zeros(1), np.zeros(1)
    elastic_caps(c, x, elastic)
    predicted_caps(c, x, v, mass, held, 1e-3, 1e-3, out)
    assert out[0] == elastic[0] == pytest.approx(MU_F * K_N * 3e-4)
