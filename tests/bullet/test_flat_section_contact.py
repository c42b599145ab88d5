"""A flat section's contact (issue 22; docs/concepts/contact.md, "Flat sections"): the penalty rows of a rectangle
press at the section's support point, s = (b/2)|d1 . n| + (h/2)|d2 . n| from the centre line, and the twist feels
the moment that lays a tilted strip flat. Before it, the contact saw a round section (the ``diameter``): a strip
released tilted stayed tilted on the ground with its edge through it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.kernels.contact import contact_forces, contact_potential, make_contacts, row_edges, set_support
from bullet_dlo.core.kernels.twist import edge_frame
from bullet_dlo.core.kernels.banded import HALF
from bullet_dlo.core.kernels.twist_coupled import HALF_T, _add_contact_band, _add_section_couples, _add_section_moments
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

WIDTH, THICKNESS = 0.02, 0.0003  # [m]


def _ribbon(n: int, friction: float) -> CableSpec:
    """A PET ribbon 0.2 m x 20 mm x 0.3 mm (E 2 GPa), whose contact envelope is its thickness."""
    return CableSpec(length=0.2, diameter=THICKNESS, mass=0.2 * WIDTH * THICKNESS * 1400, youngs_modulus=2e9,
                     section="rectangle", width=WIDTH, thickness=THICKNESS, n_masses=n, damping_rate=5.0,
                     static_friction=friction, dynamic_friction=friction)


def _material_axes(x: np.ndarray, twist) -> tuple[np.ndarray, np.ndarray]:
    """Each segment's material axes d1 (the width's), d2 (the thickness'), (n-1, 3) each, from positions x and the
    twist state: the reference director carried from its tangent onto the segment's by the minimal rotation, turned
    by theta about the tangent (the kernels' convention, d2 = t x d1)."""
    e = np.diff(x, axis=0)
    t = e / np.linalg.norm(e, axis=1)[:, None]
    d1, d2 = np.empty_like(t), np.empty_like(t)
    for k in range(len(t)):
        a, r = twist.tan[k], twist.ref[k]
        axis, c = np.cross(a, t[k]), float(a @ t[k])
        r = c * r + np.cross(axis, r) + axis * (axis @ r) / (1.0 + c)  # Rodrigues' formula for the turn a -> t
        r -= (r @ t[k]) * t[k]
        r /= np.linalg.norm(r)
        b = np.cross(t[k], r)
        d1[k] = math.cos(twist.theta[k]) * r + math.sin(twist.theta[k]) * b
        d2[k] = np.cross(t[k], d1[k])
    return d1, d2


def _drop(tilt: float, friction: float, n: int = 11, rate: float = 1000.0, duration: float = 0.3):
    """A free ribbon laid straight along x with its section turned by ``tilt`` [rad] about its axis, its lowest edge
    1 mm above the ground, released; returns the cable's twist angles at the end, its centre line's lowest height
    [m] over the last 0.1 s, and its section's lowest point (the edges, from the material axes) over the run [m]."""
    lift = 0.5 * WIDTH * abs(math.sin(tilt)) + 0.5 * THICKNESS * abs(math.cos(tilt)) + 1e-3
    model = CableModel.straight(_ribbon(n, friction), start=(0.0, 0.0, lift), ends=("free", "free"))
    deepest, centre = np.inf, np.inf
    steps = int(round(duration * rate))
    with BulletWorld(dt=1.0 / rate) as world:
        cable = world.add_cable(model, integrator="bdf2")
        world.step()  # (builds the material frame)
        cable.twist.theta[:] += tilt
        cable.twist.prev[0] += tilt  # (BDF2's history turned with it: no twist rate from the turn)
        for k in range(steps):
            world.step()
            assert cable.stable, cable.reason
            x = cable.x
            d1, d2 = _material_axes(x, cable.twist)
            mid = 0.5 * (x[1:, 2] + x[:-1, 2])
            reach = 0.5 * WIDTH * np.abs(d1[:, 2]) + 0.5 * THICKNESS * np.abs(d2[:, 2])
            deepest = min(deepest, float((mid - reach).min()))
            if k >= steps - int(0.1 * rate):
                centre = min(centre, float(x[:, 2].min()))
        return cable.twist.theta.copy(), centre, deepest


@pytest.mark.parametrize("tilt, friction", [(0.3, 0.0), (1.2, 0.3)])
def test_a_tilted_strip_falls_flat_onto_the_ground(tilt, friction):
    """Released with its section tilted 0.3 rad (frictionless) or 1.2 rad (friction 0.3), the strip ends flat: its
    section within 0.02 rad of the ground's plane (theta a multiple of pi), its centre line at h/2 above the ground
    (within 5 %, the penalty's sag aside), and no edge ever deeper in the ground than h/2 (the support function's
    corners are rounded over a tilt of h/4b, which lets a sharp edge in a little; with the round envelope the tilted
    strip stayed tilted, its edge 3-9 mm through the ground)."""
    theta, centre, deepest = _drop(tilt, friction)
    off_flat = np.abs(np.angle(np.exp(2j * theta)) / 2.0)  # distance to the nearest multiple of pi [rad]
    assert off_flat.max() < 0.02, theta
    assert abs(centre - 0.5 * THICKNESS) < 0.05 * 0.5 * THICKNESS, centre
    assert deepest > -0.5 * THICKNESS, deepest


def test_support_distance_and_its_derivatives():
    """The support distance of a 20 x 0.3 mm section against a ground (normal +z): h/2 lying flat, b/2 on its edge,
    and its first and second derivatives in theta those of finite differences (central, step 1e-5 rad), over the
    turn; its rate is ds/dtheta times the twist rate; the touching point the friction holds moves s theta (n x t)
    as the section turns by theta about its axis t (the Python twin of the compiled kernel)."""
    c = make_contacts(3, 1, 0.5 * THICKNESS, section=(WIDTH, THICKNESS))
    c.count[0] = 1
    c.node[0] = 0, 1  # a segment row on edge 0
    c.weight[0] = 0.5, 0.5
    c.normal[0] = 0.0, 0.0, 1.0
    E = np.zeros((8, 4))
    E[0, 1] = 0.01  # (its length)
    E[1:4, 1] = 1.0, 0.0, 0.0  # edge 0 along x, its reference director along y: theta 0 lies flat
    E[4:7, 1] = 0.0, 1.0, 0.0
    W = np.array([2.0, 0.0])
    ref, tan = np.array([[0.0, 1.0, 0.0]] * 2), np.array([[1.0, 0.0, 0.0]] * 2)

    def support(theta):
        E[7, 1] = theta
        getattr(set_support, "py_func", set_support)(c, E, W, ref, tan)  # (the compiled one would compile for it)
        return c.support[0].copy()

    assert support(0.0)[0] == pytest.approx(0.5 * THICKNESS, rel=1e-12)
    assert support(0.5 * math.pi)[0] == pytest.approx(0.5 * WIDTH, rel=1e-12)
    d = 1e-5
    for theta in np.linspace(-3.0, 3.0, 61):
        s0, sp, sm = support(theta), support(theta + d), support(theta - d)
        first = (sp[0] - sm[0]) / (2.0 * d)
        second = (sp[3] - sm[3]) / (2.0 * d)
        assert s0[3] == pytest.approx(first, rel=1e-5, abs=1e-9)
        assert s0[5] == pytest.approx(second, rel=1e-4, abs=1e-7)
        assert s0[1] == pytest.approx(2.0 * s0[3], rel=1e-12)
        assert s0[2] == 0.0 and s0[4] == 0.0  # a segment row has its own edge only (the second slot)
        assert 0.5 * THICKNESS - 1e-12 <= s0[0] <= math.hypot(0.5 * WIDTH, 0.5 * THICKNESS)
        # the touching point's tangential move since the step's start (theta0 = 0 here), s theta (n x t), and
        # its derivative in theta against finite differences
        np.testing.assert_allclose(s0[6:9], [0.0, s0[0] * theta, 0.0], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(s0[15:18], (sp[6:9] - sm[6:9]) / (2.0 * d), rtol=1e-4, atol=1e-8)
        assert not s0[12:15].any()


def _section_rows(x, theta, ref, tan, theta0, rows, ground=0.0):
    """Contact rows against a ground at height ``ground`` [m] (normal +z) for a 20 x 0.3 mm section on positions x
    [m] (n, 3) with twist angles theta [rad] (n - 1,), reference frames (ref, tan) and step-start angles theta0;
    ``rows``: (node a, node b, friction anchor [m] (3,), friction cap [N]) each. Returns the contact set with its
    support set, and the edges' frames (the coupled step's Scratch edges)."""
    n = x.shape[0]
    c = make_contacts(n, len(rows), 0.5 * THICKNESS, section=(WIDTH, THICKNESS))
    c.count[0] = len(rows)
    for k, (a, b, anchor, cap) in enumerate(rows):
        c.node[k] = a, b
        c.weight[k] = (1.0, 0.0) if a == b else (0.5, 0.5)
        c.normal[k] = 0.0, 0.0, 1.0
        c.point[k] = 0.0, 0.0, ground
        c.k_n[k], c.k_t[k], c.cap[k] = 2e3, 1e3, cap
        c.anchor[k, :3] = anchor
        c.anchor[k, 3] = c.weight[k, 1]
        e0, e1 = row_edges(a, b, n - 1)
        c.support[k, 9] = theta0[e0] if e0 >= 0 else 0.0
        c.support[k, 10] = theta0[e1] if e1 >= 0 else 0.0
    E = np.zeros((8, n + 1))
    dirs, clamp = np.zeros((2, 3)), np.zeros((2, 3))
    for k in range(n - 1):
        E[:, k + 1] = edge_frame.py_func(x, dirs, theta, ref, tan, clamp, k)
    set_support(c, E, np.zeros(n - 1), ref, tan)
    return c, E


def _section_contact(x, theta, ref, tan, theta0, rows):
    """The contact of :func:`_section_rows` on the ground at height 0. Returns (potential [J], forces on the nodes
    [N] (n, 3), moments about the edges [N m] (n - 1,)) as the coupled step computes them."""
    n = x.shape[0]
    c, E = _section_rows(x, theta, ref, tan, theta0, rows)
    v = np.zeros_like(x)
    force = np.zeros_like(x)
    contact_forces(c, x, v, force)
    _add_section_couples(c, E, force)
    r = np.zeros(4 * n)
    _add_section_moments(c, 1.0, n - 1, r)
    return contact_potential(c, x, v, 0.0), force, r[3::4][: n - 1].copy()


def _sloped_strip(seed: int, n: int = 5, seg: float = 0.01):
    """Positions [m] of a strip sloping into the ground, its twist angles [rad], the step's start angles and
    reference frames (other tangents than the edges'): a state the coupled step meets mid-solve."""
    rng = np.random.default_rng(seed)
    x = np.zeros((n, 3))
    x[:, 0] = seg * np.arange(n)
    x[:, 2] = 0.2 * seg * np.arange(n)[::-1] - 0.004 + 2e-4 * rng.standard_normal(n)  # sloped, into the ground
    x[:, 1] = 1e-3 * rng.standard_normal(n)
    t0 = np.diff(x, axis=0)
    t0 /= np.linalg.norm(t0, axis=1)[:, None]
    tan = t0 + 0.05 * rng.standard_normal(t0.shape)  # the step started from other tangents
    tan /= np.linalg.norm(tan, axis=1)[:, None]
    ref = np.cross(tan, rng.standard_normal(tan.shape))
    ref /= np.linalg.norm(ref, axis=1)[:, None]
    theta = 0.4 + 0.1 * rng.standard_normal(n - 1)
    theta0 = theta - 0.05 * rng.standard_normal(n - 1)
    return x, theta, theta0, ref, tan


def test_section_contact_forces_are_the_gradient_of_its_potential():
    """On a sloped strip whose section is tilted and turned since the step's start, pressing the ground at two node
    rows and a segment row with friction (stuck and sliding), the contact forces on the nodes and moments about the
    edges are minus the gradient of the contact potential (central differences, within 1e-5 of the largest): the
    normal force acts at the touching point, off the centre line, so it puts a bending couple on the edges' nodes
    as the section turns with their tangents, and so does the friction through the touching point's move. Without
    those couples the force missed up to (n . t)(b/2)/l of the normal force per node (20 % here), the coupled
    Newton's potential and residual disagreed, and a tilted ribbon's frictional landing failed its solves."""
    n, seg = 5, 0.01
    x, theta, theta0, ref, tan = _sloped_strip(3, n, seg)
    rows = [(a, b, 0.5 * (x[a] + x[b]) + offset, cap) for a, b, offset, cap in
            [(1, 1, np.array([1e-4, -2e-4, 0.0]), 10.0), (2, 2, np.array([-3e-3, 1e-3, 0.0]), 0.5),
             (3, 4, np.array([2e-4, 5e-4, 0.0]), 10.0)]]
    phi, force, moment = _section_contact(x, theta, ref, tan, theta0, rows)
    assert phi > 0.0 and np.abs(force).max() > 1.0  # pressing, with friction
    d = 1e-7
    grad_x = np.zeros_like(x)
    for i in range(n):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += d
            xm[i, j] -= d
            grad_x[i, j] = (_section_contact(xp, theta, ref, tan, theta0, rows)[0]
                            - _section_contact(xm, theta, ref, tan, theta0, rows)[0]) / (2.0 * d)
    grad_t = np.zeros(n - 1)
    for e in range(n - 1):
        tp, tm = theta.copy(), theta.copy()
        tp[e] += d
        tm[e] -= d
        grad_t[e] = (_section_contact(x, tp, ref, tan, theta0, rows)[0]
                     - _section_contact(x, tm, ref, tan, theta0, rows)[0]) / (2.0 * d)
    scale = np.abs(force).max()
    np.testing.assert_allclose(force, -grad_x, rtol=0.0, atol=1e-5 * scale)
    np.testing.assert_allclose(moment, -grad_t, rtol=0.0, atol=1e-5 * scale * seg)


def test_section_friction_stiffness_in_the_newton_matrix_is_its_slip_gradients():
    """The coupled Newton matrix's friction terms of a flat section's rows (stuck and sliding, on node and segment
    rows, a held node) are T^T K T: K the friction spring, T the slip's gradient over the positions and twist
    angles, here from central differences of the slip with the support recomputed. The slip counts the section's
    touching point's move s (theta - theta0) (n x t), which moves with the edges' nodes (s and n x t turn with the
    tangent) as well as with theta: without those position terms (before) the matrix missed up to 5 % of the
    friction spring here, and a tilted ribbon resting on the ground with friction took 8-10 Newton iterations a step
    (linear convergence) and failed a fifth of its solves at 1 kHz (``demos/ribbon_landing.py``)."""
    n = 5
    x, theta, theta0, ref, tan = _sloped_strip(5, n)
    rows = [(a, b, 0.5 * (x[a] + x[b]) + offset, cap) for a, b, offset, cap in
            [(1, 1, np.array([1e-4, -2e-4, 0.0]), 10.0), (2, 2, np.array([-3e-3, 1e-3, 0.0]), 0.5),
             (3, 4, np.array([2e-4, 5e-4, 0.0]), 10.0), (4, 4, np.array([-1e-3, 2e-3, 0.0]), 0.3)]]
    ground = -0.05  # (no row presses: the friction's terms alone)
    c, E = _section_rows(x, theta, ref, tan, theta0, rows, ground)
    held = np.zeros(n, dtype=np.bool_)
    held[0] = True
    band = np.zeros((4 * n, HALF_T + 1))
    _add_contact_band(c, held, x, E, 1.0, 0.0, np.zeros((3 * n, 2 * HALF + 1)), band, np.zeros_like(band), False)
    matrix = np.zeros((4 * n, 4 * n))
    for p in range(4 * n):
        for d in range(HALF_T + 1):
            if p + d < 4 * n:
                matrix[p, p + d] = matrix[p + d, p] = band[p, d]

    def slips(xq, thq):
        """Each row's slip [m] (rows, 3): the anchored point and the touching point's move, off the anchor."""
        cq, _ = _section_rows(xq, thq, ref, tan, theta0, rows, ground)
        out = np.empty((len(rows), 3))
        for k, (a, b, anchor, _) in enumerate(rows):
            sa = cq.anchor[k, 3]
            out[k] = (1.0 - sa) * xq[a] + sa * xq[b] + cq.support[k, 6:9] - anchor
            out[k, 2] = 0.0  # (the tangential part: the ground's normal is z)
        return out

    d = 1e-7
    grad = np.zeros((len(rows), 3, 4 * n))  # dslip/dq in the coupled layout (x_i at 4 i + j, theta_e at 4 e + 3)
    for q in range(4 * n):
        if q % 4 == 3 and q // 4 >= n - 1:
            continue
        xp, xm, tp, tm = x.copy(), x.copy(), theta.copy(), theta.copy()
        if q % 4 == 3:
            tp[q // 4] += d
            tm[q // 4] -= d
        else:
            xp[q // 4, q % 4] += d
            xm[q // 4, q % 4] -= d
        grad[:, :, q] = (slips(xp, tp) - slips(xm, tm)) / (2.0 * d)
    expected = np.zeros_like(matrix)
    regimes = set()
    for k in range(len(rows)):
        u = slips(x, theta)[k]
        ul = float(np.linalg.norm(u))
        stick = c.k_t[k] * ul <= c.cap[k]
        regimes.add(stick)
        proj = np.diag([1.0, 1.0, 0.0])
        spring = c.k_t[k] * proj if stick else c.cap[k] / ul * (proj - np.outer(u, u) / ul ** 2)
        expected += grad[k].T @ spring @ grad[k]
    assert regimes == {True, False}  # both regimes met
    free = [q for q in range(4 * n) if not (q % 4 < 3 and held[q // 4]) and not (q % 4 == 3 and q // 4 >= n - 1)]
    got, want = matrix[np.ix_(free, free)], expected[np.ix_(free, free)]
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-6 * np.abs(want).max())
