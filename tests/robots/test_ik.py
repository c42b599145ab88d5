"""The compiled kinematics (bullet_dlo.robots.ik) against PyBullet's: forward kinematics on the body, and
the pose the IK reaches measured by PyBullet's forward kinematics, beside PyBullet's own IK."""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.config.robot import load_robot_spec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.ik import chain_of, rotation_error
from bullet_dlo.robots.transforms import angle_between

ROBOTS = ["kuka", "panda"]
BULLET_ROUNDING = 2e-6
"""[m] and [-]: PyBullet's link states agree with double-precision kinematics of the same chain to about
4e-7 (Bullet's own rounding of the stored joint frames); well below any tolerance an arm is driven to."""


@pytest.fixture(params=ROBOTS)
def arm(request):
    client = pb.connect(pb.DIRECT)
    # off the origin and turned, as the dual-arm scene places its right arm: the base transform must count
    robot = Robot.load(load_robot_spec(request.param), client, (0.4, -0.1, 0.05), base_yaw=2.5, visuals=False)
    yield robot
    robot.close()
    pb.disconnect(client)


def _twin_pose(arm: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grasp frame by PyBullet's forward kinematics (the twin at q): position [m], quaternion."""
    arm._set_twin(q)
    return arm.grasp_pose(kinematic=True)


def test_forward_kinematics_is_bullets(arm):
    rng = np.random.default_rng(1)
    cols = arm._arm_columns
    for _ in range(25):
        q = rng.uniform(arm.lower[cols], arm.upper[cols])
        pos, quat = _twin_pose(arm, q)
        p, r = arm.chain_ik.pose(q)
        assert np.abs(p - pos).max() < BULLET_ROUNDING
        assert np.abs(r - Rotation.from_quat(quat).as_matrix()).max() < BULLET_ROUNDING


def test_jacobian_is_the_derivative_of_the_pose(arm):
    """Each column against central differences of the compiled forward kinematics (position and rotation)."""
    from bullet_dlo.robots.ik import forward

    c = arm.chain_ik.chain
    q = np.array(arm.spec.home, dtype=float)
    k = len(q)
    pos, rot, jac = np.empty(3), np.empty((3, 3)), np.empty((6, k))
    forward(c.origin_pos, c.origin_rot, c.axis, c.tail_pos, c.tail_rot, q, pos, rot, jac)
    h = 1e-6
    for i in range(k):
        dq = np.zeros(k)
        dq[i] = h
        (pp, rp), (pm, rm) = arm.chain_ik.pose(q + dq), arm.chain_ik.pose(q - dq)
        rv = np.empty(3)
        rotation_error(rp, rm, rv)
        assert np.allclose((pp - pm) / (2 * h), jac[:3, i], atol=1e-8)
        assert np.allclose(rv / (2 * h), jac[3:, i], atol=1e-8)


def test_tracking_reaches_nearby_targets_as_well_as_pybullet(arm):
    """Targets as an env step asks for (up to 2 cm and 0.05 rad from the pose now): the compiled IK's joints,
    measured by PyBullet's forward kinematics, land on the target within Bullet's rounding, at least as
    close as PyBullet's IK (50 iterations, residual 1e-8) on the twin, and inside the joint limits."""
    rng = np.random.default_rng(2)
    cols = arm._arm_columns
    pos0, quat0 = arm.grasp_pose()
    worst_compiled = worst_bullet = 0.0
    for _ in range(20):
        target = pos0 + rng.uniform(-0.02, 0.02, 3)
        quat = (Rotation.from_rotvec(rng.uniform(-0.05, 0.05, 3)) * Rotation.from_quat(quat0)).as_quat()
        arm.ik_solver = "compiled"
        q_c = arm.track(target, quat)
        arm.ik_solver = "bullet"
        q_b = arm.track(target, quat)
        for q in (q_c, q_b):
            assert np.all(q >= arm.lower[cols]) and np.all(q <= arm.upper[cols])
        p_c, r_c = _twin_pose(arm, q_c)
        p_b, r_b = _twin_pose(arm, q_b)
        err_c = np.linalg.norm(p_c - target)
        worst_compiled = max(worst_compiled, err_c)
        worst_bullet = max(worst_bullet, np.linalg.norm(p_b - target))
        assert err_c < 5 * BULLET_ROUNDING and angle_between(r_c, quat) < 5 * BULLET_ROUNDING
        assert np.abs(q_c - q_b).max() < 1e-2  # the same solution branch: no jump to another arm posture
    assert worst_compiled <= worst_bullet + BULLET_ROUNDING


def test_a_target_past_a_joint_limit_stops_at_the_limit(arm):
    """A pose reached only by turning the first joint past its upper limit: the joints stay within limits."""
    cols = arm._arm_columns
    q = np.array(arm.spec.home, dtype=float)
    q[0] = arm.upper[cols][0] - 0.05
    arm.reset_joints(q)
    beyond = q.copy()
    beyond[0] = arm.upper[cols][0] + 0.3  # the base joint's turn carries the grasp frame around
    target, quat = _twin_pose(arm, beyond)  # (this sets the twin past its limit: Bullet allows a reset there)
    out = arm.chain_ik.solve(target, quat, q)
    assert np.all(out >= arm.lower[cols]) and np.all(out <= arm.upper[cols])
    assert out[0] == arm.upper[cols][0]  # pushed against the limit, not past it


def test_a_bad_ik_solver_is_refused(arm):
    with pytest.raises(ParameterError, match="ik_solver must be one of compiled, bullet"):
        Robot(arm.spec, arm.client, arm.body, arm.kin_client, arm.kin_body, arm.arm_joints, arm.movable, arm.lower,
              arm.upper, arm.max_force, arm.link_index, arm.joint_index, ik_solver="newton")


def test_joints_off_the_chain_are_refused(arm):
    """Two joints that are not ancestor and descendant (the fingers, or the tip before the first joint)."""
    j = arm.arm_joints
    with pytest.raises(ParameterError, match="not one serial chain"):
        chain_of(arm.kin_client, arm.kin_body, [j[1], j[0]], arm.grasp_link, [-1, -1], [1, 1])
