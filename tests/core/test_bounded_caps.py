"""The friction limits a contact solve's second attempt starts from (``core/kernels/contact.py``, ``bounded_caps``).

A contact Newton solve freezes each row's friction limit and moves it to mu f_n at the solution as an outer fixed
point, started from the predictor (the step's map at the start velocities): the penalty force at the predictor's
depth (``elastic_caps``), k_n h v for a node arriving at speed v. With a stiff penalty that is k_n h^2 / m times the
force that stops the node within the step (1e4 on the soft cable below at 1 kHz). It is the start that converges on a
cable coming to rest on a table (a stick-first start; from below, a 60 Hz cable slid below the capstan threshold), and
the one a cable swinging into a table's side face at 1 kHz did not converge from (``tests/bullet/test_edge_slide.py``):
a solve without free bodies that ends wildly far from convergence is taken again from the limits here, where the
depth a row's own motion adds over the step is taken with the stiffness the step's inertia gives it,
min(k_n, m_row / (cx hf)).
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.kernels.contact import SLIDE, STICK, bounded_caps, elastic_caps, make_contacts

R = 0.002  # [m] cable radius
KN = 4.74e6  # [N/m] the penalty stiffness of the soft cable's contacts in Bullet worlds
MU_S, MU_D = 0.3, 0.2
M = 4.7e-4  # [kg] a node's mass (9 g over 19 segments)


def _plane_row(n: int, nodes: tuple[int, int], weights: tuple[float, float], kn: float = KN, state: int = STICK):
    """A contact set with one penalty row of the ground plane z = 0 (normal +z) on ``nodes`` with ``weights``."""
    c = make_contacts(n, 1, R)
    c.count[0] = 1
    c.node[0] = nodes
    c.weight[0] = weights
    c.normal[0] = (0.0, 0.0, 1.0)
    c.k_n[0] = c.k_t[0] = kn
    c.static_friction[0], c.dynamic_friction[0] = MU_S, MU_D
    c.state[0] = state
    return c


def _caps(c, x, X, mass, held, cx, hf):
    """(bounded_caps, elastic_caps) of the contact set's one row, the step from x to the predictor X."""
    out, old = np.zeros(1), np.zeros(1)
    bounded_caps(c, x, X, mass, held, cx, hf, out)
    elastic_caps(c, X, old)
    return out[0], old[0]


@pytest.mark.parametrize("h, state", [(1e-3, STICK), (1 / 240, STICK), (1 / 60, SLIDE)])
def test_an_arriving_node_starts_with_the_force_that_stops_it(h, state):
    """A node touching the plane and arriving at v: the limit is mu m v / h (implicit Euler: cx = hf = h), not the
    predictor's mu k_n h v; mu_s while stuck, mu_d while sliding."""
    v = 0.8
    x = np.array([[0.0, 0.0, R], [0.03, 0.0, R]])
    X = x + h * np.array([[0.0, 0.0, -v], [0.0, 0.0, 0.0]])
    mass, held = np.full(2, M), np.zeros(2, np.bool_)
    cap, old = _caps(_plane_row(2, (0, 0), (1.0, 0.0), state=state), x, X, mass, held, h, h)
    mu = MU_S if state == STICK else MU_D
    assert cap == pytest.approx(mu * M * v / h, rel=1e-12)
    assert old == pytest.approx(mu * KN * h * v, rel=1e-12)
    assert old / cap == pytest.approx(KN * h * h / M, rel=1e-12)  # 1e4 at 1 kHz


def test_a_resting_depth_keeps_the_penalty_force():
    """A node already d into the plane at the step's start and not moving: the penalty's mu k_n d, as the predictor's;
    a node arriving while already inside: the resting depth with k_n, the added depth with the inertia's stiffness;
    a node leaving: the predictor's (smaller) depth with k_n."""
    d, h, v = 1e-6, 1e-3, 0.5
    x = np.array([[0.0, 0.0, R - d], [0.03, 0.0, R]])
    mass, held = np.full(2, M), np.zeros(2, np.bool_)
    c = _plane_row(2, (0, 0), (1.0, 0.0))
    cap, old = _caps(c, x, x.copy(), mass, held, h, h)
    assert cap == old == pytest.approx(MU_S * KN * d, rel=1e-9)
    X = x.copy()
    X[0, 2] -= h * v
    cap, _ = _caps(c, x, X, mass, held, h, h)
    assert cap == pytest.approx(MU_S * (KN * d + M * v / h), rel=1e-9)
    X[0, 2] = R - 0.5 * d
    cap, old = _caps(c, x, X, mass, held, h, h)
    assert cap == old == pytest.approx(MU_S * KN * 0.5 * d, rel=1e-9)


def test_a_soft_penalty_or_a_held_node_keeps_the_penalty_force():
    """Where the penalty is softer than the step's inertia (k_n < m / h^2) the predictor's penalty force is the
    smaller and stays; a held node has no inertia to bound it."""
    h, v = 1e-3, 0.8
    x = np.array([[0.0, 0.0, R], [0.03, 0.0, R]])
    X = x + h * np.array([[0.0, 0.0, -v], [0.0, 0.0, 0.0]])
    mass = np.full(2, M)
    soft = 0.5 * M / h ** 2
    cap, old = _caps(_plane_row(2, (0, 0), (1.0, 0.0), kn=soft), x, X, mass, np.zeros(2, np.bool_), h, h)
    assert cap == old == pytest.approx(MU_S * soft * h * v, rel=1e-12)
    cap, old = _caps(_plane_row(2, (0, 0), (1.0, 0.0)), x, X, mass, np.array([True, False]), h, h)
    assert cap == old == pytest.approx(MU_S * KN * h * v, rel=1e-12)


def test_a_segment_row_takes_the_effective_mass_of_its_point():
    """A row at the point w0 x_a + w1 x_b of a segment whose nodes arrive at v: m_row = 1 / (w0^2 / m_a + w1^2 / m_b)
    (the mass a force at the point moves); BDF2's map (cx = hf = 2 h / 3): the limit mu m_row (depth added) / (cx hf)."""
    h = 1e-3
    cx = hf = 2.0 * h / 3.0
    w0, w1, ma, mb, v = 0.3, 0.7, M, 2.0 * M, 0.6
    x = np.array([[0.0, 0.0, R], [0.03, 0.0, R], [0.06, 0.0, R]])
    X = x.copy()
    X[1:, 2] -= cx * v
    mass, held = np.array([M, ma, mb]), np.zeros(3, np.bool_)
    cap, _ = _caps(_plane_row(3, (1, 2), (w0, w1)), x, X, mass, held, cx, hf)
    m_row = 1.0 / (w0 * w0 / ma + w1 * w1 / mb)
    assert cap == pytest.approx(MU_S * m_row * v / hf, rel=1e-12)
