"""A flat section's contact (issue 22; docs/concepts/contact.md, "Flat sections"): the penalty rows of a rectangle
press at the section's support point, s = (b/2)|d1 . n| + (h/2)|d2 . n| from the centre line, and the twist feels
the moment that lays a tilted strip flat. Before it, the contact saw a round section (the ``diameter``): a strip
released tilted stayed tilted on the ground with its edge through it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.kernels.contact import make_contacts, set_support
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
    E[1:4, 1] = 1.0, 0.0, 0.0  # edge 0 along x, its reference director along y: theta 0 lies flat
    E[4:7, 1] = 0.0, 1.0, 0.0
    W = np.array([2.0, 0.0])

    def support(theta):
        E[7, 1] = theta
        getattr(set_support, "py_func", set_support)(c, E, W)  # (the compiled one would compile for it)
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
