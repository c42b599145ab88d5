"""Robot arms as data (``robots/*.yaml``) and as PyBullet bodies with IK and position control.

A description names the arm URDF (from ``pybullet_data``), optionally a gripper from the
project's ``urdf/`` mounted through a fixed sensor joint (composed with ``yourdfpy``), the
joint that carries the wrist F/T sensor, the grasp link and the home configuration. Joint
limits are read from the URDF with ``yourdfpy``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.config.robot import RobotSpec, load_robot_spec, robot_names  # noqa: F401
from bullet_dlo.core.validate import ParameterError, check_vector3
from bullet_dlo.robots.compose import robot_urdf
from bullet_dlo.robots.transforms import quat_from_axes, quat_from_matrix, rotation  # noqa: F401


@dataclass
class Robot:
    """An arm in a Bullet world, with a kinematic twin (own DIRECT client) for IK and FK."""

    spec: RobotSpec
    client: int
    body: int
    kin_client: int
    kin_body: int
    arm_joints: list[int]
    movable: list[int]
    lower: np.ndarray
    upper: np.ndarray
    max_force: np.ndarray
    link_index: dict[str, int]
    joint_index: dict[str, int]
    finger_joints: list[int] = field(default_factory=list)
    q_target: np.ndarray | None = None

    @classmethod
    def load(cls, spec: RobotSpec, client: int, base_position: Sequence[float], base_yaw: float = 0.0) -> "Robot":
        """Load the arm at ``base_position`` [m] rotated by ``base_yaw`` [rad] about z, at home."""
        path = str(robot_urdf(spec))
        pos = check_vector3("base_position", base_position).tolist()
        quat = pb.getQuaternionFromEuler([0.0, 0.0, float(base_yaw)])
        flags = pb.URDF_USE_INERTIA_FROM_FILE
        body = pb.loadURDF(path, pos, quat, useFixedBase=True, flags=flags, physicsClientId=client)
        kin_client = pb.connect(pb.DIRECT)
        kin_body = pb.loadURDF(path, pos, quat, useFixedBase=True, flags=flags, physicsClientId=kin_client)
        joint_index, link_index, movable = {}, {}, []
        lower, upper, force = [], [], []
        for j in range(pb.getNumJoints(body, physicsClientId=client)):
            info = pb.getJointInfo(body, j, physicsClientId=client)
            joint_index[info[1].decode()] = j
            link_index[info[12].decode()] = j
            if info[2] != pb.JOINT_FIXED:
                movable.append(j)
                lower.append(info[8])
                upper.append(info[9])
                force.append(info[10] * spec.max_force_scale)
        for name in (spec.sensor_joint, *spec.finger_joints):
            if name not in joint_index:
                raise ParameterError(f"robot {spec.name!r} has no joint {name!r}; joints: {', '.join(joint_index)}")
        if spec.grasp_link not in link_index:
            raise ParameterError(f"robot {spec.name!r} has no link {spec.grasp_link!r}")
        fingers = [joint_index[n] for n in spec.finger_joints]
        arm = [j for j in movable if j not in fingers]
        if len(spec.home) != len(arm):
            raise ParameterError(f"robot {spec.name!r}: home has {len(spec.home)} angles, the arm has {len(arm)} joints")
        robot = cls(spec, client, body, kin_client, kin_body, arm, movable, np.array(lower), np.array(upper),
                    np.array(force), link_index, joint_index, fingers)
        robot.reset_joints(np.array(spec.home))
        return robot

    # ----- kinematics ---------------------------------------------------------------------
    @property
    def grasp_link(self) -> int:
        return self.link_index[self.spec.grasp_link]

    def joint_positions(self) -> np.ndarray:
        """Current arm joint angles [rad]."""
        return np.array([s[0] for s in pb.getJointStates(self.body, self.arm_joints, physicsClientId=self.client)])

    def reset_joints(self, q: np.ndarray) -> None:
        """Teleport the arm (and its twin) to joint angles q [rad]; fingers to closed; hold there."""
        for j, val in zip(self.arm_joints, q):
            pb.resetJointState(self.body, j, float(val), physicsClientId=self.client)
            pb.resetJointState(self.kin_body, j, float(val), physicsClientId=self.kin_client)
        for j in self.finger_joints:
            pb.resetJointState(self.body, j, self.spec.finger_closed, physicsClientId=self.client)
        self.set_targets(q)

    def grasp_pose(self, kinematic: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """World position [m] and quaternion of the grasp frame (of the twin with ``kinematic``)."""
        c, b = (self.kin_client, self.kin_body) if kinematic else (self.client, self.body)
        st = pb.getLinkState(b, self.grasp_link, computeForwardKinematics=True, physicsClientId=c)
        return np.array(st[4]), np.array(st[5])

    def grasp_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Grasp frame position [m], quaternion, linear velocity [m/s] and angular velocity [rad/s]."""
        st = pb.getLinkState(self.body, self.grasp_link, computeLinkVelocity=True, computeForwardKinematics=True,
                             physicsClientId=self.client)
        com, frame, v_com, omega = np.array(st[0]), np.array(st[4]), np.array(st[6]), np.array(st[7])
        return frame, np.array(st[5]), v_com + np.cross(omega, frame - com), omega

    def solve_ik(self, position: Sequence[float], quat: Sequence[float], seed: np.ndarray | None = None,
                 tol: float = 1e-4, iterations: int = 20) -> np.ndarray:
        """Arm joint angles [rad] that put the grasp frame at ``position`` [m], ``quat``.

        PyBullet's damped least-squares IK with joint limits, iterated on the kinematic twin
        and checked with forward kinematics; ParameterError if the pose is not reached within
        ``tol`` (position [m] and orientation [rad]).
        """
        pos = check_vector3("target position", position)
        q = self.joint_positions() if seed is None else np.asarray(seed, float)
        rest = np.array(self.spec.home)
        err_p = err_r = np.inf
        for _ in range(iterations):
            for j, val in zip(self.arm_joints, q):
                pb.resetJointState(self.kin_body, j, float(val), physicsClientId=self.kin_client)
            p_now, q_now = self.grasp_pose(kinematic=True)
            err_p = float(np.linalg.norm(p_now - pos))
            err_r = _angle_between(q_now, quat)
            if err_p < tol and err_r < 10 * tol:
                return q
            kwargs = {}
            if _ < iterations // 2:  # null-space IK (limits, rest pose) first, plain DLS to polish
                kwargs = dict(lowerLimits=self.lower.tolist(), upperLimits=self.upper.tolist(),
                              jointRanges=(self.upper - self.lower).tolist(), restPoses=_full(self, rest).tolist())
            sol = pb.calculateInverseKinematics(self.kin_body, self.grasp_link, pos.tolist(), list(quat),
                                                maxNumIterations=100, residualThreshold=1e-7,
                                                physicsClientId=self.kin_client, **kwargs)
            full = np.array(sol)
            idx = [self.movable.index(j) for j in self.arm_joints]
            q = np.clip(full[idx], self.lower[idx], self.upper[idx])
        raise ParameterError(f"pose unreachable for robot {self.spec.name!r}: target {np.round(pos, 4).tolist()} "
                             f"missed by {err_p * 1000:.1f} mm / {np.degrees(err_r):.1f} deg after IK")

    # ----- control ------------------------------------------------------------------------
    def set_targets(self, q: np.ndarray) -> None:
        """Joint position targets [rad] for the arm (strong position control), fingers closed."""
        self.q_target = np.asarray(q, float).copy()
        arm_force = [float(self.max_force[self.movable.index(j)]) for j in self.arm_joints]
        pb.setJointMotorControlArray(self.body, self.arm_joints, pb.POSITION_CONTROL, targetPositions=self.q_target,
                                     forces=arm_force, physicsClientId=self.client)
        if self.finger_joints:
            pb.setJointMotorControlArray(self.body, self.finger_joints, pb.POSITION_CONTROL,
                                         targetPositions=[self.spec.finger_closed] * len(self.finger_joints),
                                         forces=[20.0] * len(self.finger_joints), physicsClientId=self.client)

    def subtree_links(self, joint: int) -> list[int]:
        """Links carried by ``joint`` (its child and everything below it)."""
        parents = {j: pb.getJointInfo(self.body, j, physicsClientId=self.client)[16]
                   for j in range(pb.getNumJoints(self.body, physicsClientId=self.client))}
        out = [joint]
        for j in sorted(parents):
            if parents[j] in out and j not in out:
                out.append(j)
        return out

    def close(self) -> None:
        if pb.isConnected(self.kin_client):
            pb.disconnect(self.kin_client)


def _full(robot: Robot, arm_values: np.ndarray) -> np.ndarray:
    """Values for every movable joint (IK rest poses): arm values, fingers closed."""
    out = []
    for j in robot.movable:
        out.append(arm_values[robot.arm_joints.index(j)] if j in robot.arm_joints else robot.spec.finger_closed)
    return np.array(out)


def _angle_between(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Rotation angle [rad] between two quaternions."""
    d = abs(float(np.dot(np.asarray(q1) / np.linalg.norm(q1), np.asarray(q2) / np.linalg.norm(q2))))
    return 2.0 * float(np.arccos(min(1.0, d)))
