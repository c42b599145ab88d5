"""The holders of a free body in the cable's step (core/kernels/contact.py, ``Bodies.hold_*``; bullet/held_bodies.py):
each of Bullet's contact points on the body in the last step keeps its measured normal load, which lets go as the
step moves the body's point off the holder, -hold_c v_n, down to nothing. Checked here: the residual is the
potential's gradient (the line search's merit and Newton's direction agree), the Schur block is the residual's
derivative, and the load's bounds (none added when the body presses into the holder, all of it gone once the body
leaves faster than load / hold_c)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.kernels.contact import (_add_holder_block, _add_holders, _holder_change, body_potential,
                                             make_bodies)

H = 1 / 60  # [s]


def _held_body(rng):
    """One active 50 g body with three holder points of different loads, arms and normals, on a moving holder."""
    bd = make_bodies(4, 8, 1)
    bd.active[0] = True
    bd.mass[0] = 0.05
    bd.inertia[0] = np.diag([2e-5, 3e-5, 4e-5])
    bd.gravity[:] = (0.0, 0.0, -9.81)
    bd.hold_count[0] = 3
    normals = rng.normal(size=(3, 3)) + (0.0, 0.0, 3.0)
    bd.hold_normal[0, :3] = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    bd.hold_arm[0, :3] = rng.normal(scale=0.02, size=(3, 3))
    bd.hold_load[0, :3] = (0.2, 0.05, 0.0)  # [N] (the last: a point Bullet found within its margin, unloaded)
    bd.hold_vel[0, :3] = (0.0, 0.01, -0.02)  # [m/s]
    bd.hold_c[0] = 100.0 * bd.mass[0] / H
    return bd


def _holder_part(bd, vel):
    out = np.zeros((1, 6))
    _add_holders(bd, H, vel, out)
    return out[0]


def test_the_holders_residual_is_their_potentials_gradient_and_the_block_its_derivative():
    rng = np.random.default_rng(3)
    bd = _held_body(rng)
    for _ in range(20):
        vel = rng.normal(scale=0.02, size=(1, 6))
        res = _holder_part(bd, vel)
        grad, jac = np.zeros(6), np.zeros((6, 6))
        for j in range(6):
            e = np.zeros((1, 6))
            e[0, j] = 1e-7
            grad[j] = (body_potential(bd, H, vel + e) - body_potential(bd, H, vel - e)) / 2e-7
            jac[:, j] = (_holder_part(bd, vel + e) - _holder_part(bd, vel - e)) / 2e-7
        inertia = np.r_[bd.mass[0] * (vel[0, :3] - bd.vel[0, :3]) - H * bd.mass[0] * bd.gravity,
                        bd.inertia[0] @ (vel[0, 3:] - bd.vel[0, 3:])]
        assert grad - inertia == pytest.approx(-res, abs=1e-9)
        bd.vel_new[:] = vel
        block = np.zeros((6, 6))
        _add_holder_block(bd, H, block)
        assert block == pytest.approx(-jac, abs=1e-6 * bd.hold_c[0] * H)


def test_a_holder_adds_nothing_under_a_pressing_body_and_lets_all_go_under_a_leaving_one():
    rng = np.random.default_rng(5)
    bd = _held_body(rng)
    n, a = bd.hold_normal[0, 0], bd.hold_arm[0, 0]
    vel = np.zeros((1, 6))
    for speed, change in [(-0.05, 0.0), (1e-4, -bd.hold_c[0] * 1e-4), (0.05, -0.2)]:
        vel[0, :3] = (speed + bd.hold_vel[0, 0]) * n  # the body's point at hold_arm moves at v_n = speed off it
        dl, between = _holder_change(bd, 0, 0, vel)
        assert dl == pytest.approx(change, rel=1e-9)
        assert between == (change not in (0.0, -0.2))
    # the body turning: its point's velocity Omega x arm counts
    vel[0, :3] = bd.hold_vel[0, 0] * n
    vel[0, 3:] = np.cross(a, n) / np.dot(np.cross(a, n), np.cross(a, n)) * 1e-4  # Omega x a . n = 1e-4 m/s
    assert _holder_change(bd, 0, 0, vel)[0] == pytest.approx(-bd.hold_c[0] * 1e-4, rel=1e-6)
