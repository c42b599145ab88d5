"""A held end that follows a measured holder (a gripper) is second order in the Bullet step.

Bullet moves a body by h v_new (semi-implicit Euler), so the velocity it reports after a step is half a step
behind the pose. Extrapolated at constant velocity from it, a held end lagged an accelerating gripper by a dt^2
in position and about a dt in velocity: a first-order error in the cable's forces (through the Panda scene, E
fitted from the end forces came out 0.04-0.09 % high at 0.5 ms, 0.01 % at 0.125 ms). Checked here: the grasp
frames' velocities and accelerations from the last three poses (exact for a constant acceleration), and a
Bullet cable whose end follows a sine through measured poses against the same sine as a move table.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.kernels.holders import ExternalHolders
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.kernels import ANG_VEL, COM, FRAME, FRAME_QUAT, LIN_VEL, grasp_frames


def test_grasp_frames_give_the_velocities_at_the_pose_time_of_a_constant_acceleration():
    """Poses on a parabola turning about a fixed axis at constant angular acceleration: from the third pose on,
    the holders' velocities and accelerations are the motion's own at the pose's time (whatever velocity
    Bullet reports: here the step's mean, half a step behind)."""
    h = 1e-3
    x0, v0, a = np.array([0.1, -0.2, 0.3]), np.array([0.5, 0.2, -0.1]), np.array([3.0, -2.0, 1.0])
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    w0, alpha = 1.5, -40.0  # [rad/s], [rad/s^2] about axis
    rows = np.zeros((2, 1, 27))
    history = np.zeros((2, 3, 7))
    zeros = np.zeros((2, 3))
    ext = ExternalHolders(np.ones(2, dtype=np.bool_), *(zeros.copy() for _ in range(5)), np.tile([1.0, 0, 0], (2, 1)),
                          zeros.copy())
    for k in range(4):
        t = k * h
        quat = Rotation.from_rotvec(axis * (w0 * t + 0.5 * alpha * t * t)).as_quat()
        for arm in range(2):
            rows[arm, 0, FRAME:FRAME + 3] = rows[arm, 0, COM:COM + 3] = x0 + v0 * t + 0.5 * a * t * t
            rows[arm, 0, FRAME_QUAT:FRAME_QUAT + 4] = quat
            rows[arm, 0, LIN_VEL:LIN_VEL + 3] = v0 + a * (t - 0.5 * h)  # Bullet's: (x(t) - x(t - h)) / h
            rows[arm, 0, ANG_VEL:ANG_VEL + 3] = axis * (w0 + alpha * (t - 0.5 * h))
        grasp_frames(rows, history, 0.0 if k == 0 else 1.0 / h, zeros, ext)
    for arm in range(2):
        assert np.allclose(ext.vel[arm], v0 + a * t, rtol=0, atol=1e-11)
        assert np.allclose(ext.acc[arm], a, rtol=0, atol=1e-7)
        assert np.allclose(ext.omega[arm], axis * (w0 + alpha * t), rtol=0, atol=1e-9)
        assert np.allclose(ext.alpha[arm], axis * alpha, rtol=0, atol=1e-5)


SPEC = CableSpec.lv2017(n_masses=8, damping_rate=1.0, internal_damping=3e-3)
AMP, FREQ, TURN = np.array([0.0, 0.004, 0.0012]), 6.0, np.array([0.0, 0.0, 0.05])  # [m], [Hz], [rad]


def _end_forces(dt: float, measured: bool, duration: float = 0.25) -> np.ndarray:
    """End forces [N] (steps, 2, 3) of a cable whose last end follows a 6 Hz sine, BDF2 at ``dt``: as a move
    table (exact poses at every sample time of a step) or, ``measured``, through a holder's pose measured after
    each Bullet step with its velocity, acceleration, angular velocity and acceleration at that time (what the
    grasp coupling gives a gripper's)."""
    om = 2 * np.pi * FREQ
    with BulletWorld(dt=dt) as world:
        motion = () if measured else (Sine("last", tuple(AMP), FREQ, rotation=tuple(TURN)),)
        cable = world.add_cable(SPEC, start=(0.0, 0.0, 0.3), ends=("clamped", "clamped"), motion=motion,
                                integrator="bdf2")
        if measured:
            start = cable.x[-1].copy()

            def follow() -> None:
                t = world.time
                s, c = np.sin(om * t), np.cos(om * t)
                direction = Rotation.from_rotvec(TURN * s).apply([1.0, 0.0, 0.0])
                cable.set_external_pose(1, start + AMP * s, AMP * om * c, -AMP * om * om * s, TURN * om * c,
                                        direction, angular_acceleration=-TURN * om * om * s)

            follow()
            cable.hold_externally(1)
            world.after_physics.append(follow)  # measured after Bullet's step, as the grasp coupling reads the arms
        forces = []
        for _ in range(int(round(duration / dt))):
            world.step()
            forces.append(cable.end_forces())
        assert cable.stable
        return np.array(forces)


def test_a_held_end_following_measured_poses_matches_its_move_table_to_second_order():
    gaps = []
    for dt in (2e-3, 1e-3, 5e-4):
        gaps.append(np.abs(_end_forces(dt, True) - _end_forces(dt, False)).max())
    orders = np.log2(np.array(gaps[:-1]) / np.array(gaps[1:]))
    # extrapolated at constant velocity: first order
    assert np.all(orders > 1.7), (gaps, orders)
