"""An arm in a PyBullet world: loading from a description, kinematics (FK, IK) and position control.

The description (:class:`~bullet_dlo.config.robot.RobotSpec`, from ``robots/<name>.yaml``)
names the arm URDF, the optional gripper (composed on by :mod:`bullet_dlo.robots.compose`),
the joint that carries the wrist F/T sensor, the grasp link and the home pose. Joint limits
and motor forces are read from the loaded body.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.config.robot import RobotSpec
from bullet_dlo.core.validate import ParameterError, check_vector3
from bullet_dlo.robots.compose import robot_urdf
from bullet_dlo.robots.ik import ChainIK, chain_of
from bullet_dlo.robots.transforms import angle_between

_SOLVED: dict = {}
""":meth:`Robot.solve_ik`'s answers by (robot spec, the twin's base pose, target, seed, tolerance, iterations):
PyBullet's IK on a twin set to the seed is a function of those."""
SOLVED_SIZE = 1024  # answers kept (the dict is emptied when full)

_TWINS: dict = {}
"""Kinematic twins closed robots gave back, by (URDF path, base position, base quaternion): lists of (client, body).
An environment's reset closed its arms' twins and connected and loaded new ones (5 ms an arm). A twin's joints are set
before every use (a new robot sets them to its home pose; the compiled IK's chain is read at zero angles), so a given
back twin answers as a new one."""
TWINS_KEPT = 8  # twins kept in all (the others are disconnected)


def _free_twin(key: tuple, flags: int) -> tuple[int, int]:
    """A kinematic twin (DIRECT client, body) of the URDF at the base pose of ``key`` (:data:`_TWINS`): one given back
    if still connected, else a new one loaded with ``flags``."""
    free = _TWINS.get(key, [])
    while free:
        client, body = free.pop()
        if pb.isConnected(client):
            return client, body
    client = pb.connect(pb.DIRECT)
    path, pos, quat = key
    return client, pb.loadURDF(path, list(pos), list(quat), useFixedBase=True, flags=flags, physicsClientId=client)


@dataclass
class Robot:
    """An arm in a Bullet world, with a kinematic twin (own DIRECT client) for IK and FK.

    arm_joints: indices of the arm's revolute joints (n_arm); movable: every non-fixed joint, the
    order of PyBullet's IK solution; lower, upper [rad] and max_force [N m]: per movable joint. The
    fingers are rigid, closed (:func:`~bullet_dlo.robots.compose.rigid_fingers`).
    """

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
    ik_solver: str = "compiled"
    """How :meth:`track` solves: ``"compiled"`` (:mod:`bullet_dlo.robots.ik`, damped least squares on the URDF
    chain, about 6 us) or ``"bullet"`` (PyBullet's IK on the kinematic twin, about 125 us; the solver up to 0.4)."""

    IK_SOLVERS = ("compiled", "bullet")

    def __post_init__(self) -> None:
        # where the arm joints sit among the movable ones, worked out once (IK and control run every step)
        self._arm_columns = np.array([self.movable.index(j) for j in self.arm_joints])
        self._arm_force = self.max_force[self._arm_columns].tolist()
        home = dict(zip(self.arm_joints, self.spec.home))
        self._rest_poses = np.array([home[j] for j in self.movable])
        self._zero_velocities = [[0.0] for _ in self.arm_joints]
        if self.ik_solver not in self.IK_SOLVERS:
            raise ParameterError(f"ik_solver must be one of {', '.join(self.IK_SOLVERS)}, got {self.ik_solver!r}")
        cols = self._arm_columns
        # the chain read once from the twin (at zero angles, then put back): the compiled IK needs no body
        self.chain_ik = ChainIK(chain_of(self.kin_client, self.kin_body, self.arm_joints, self.grasp_link,
                                         self.lower[cols], self.upper[cols]))

    @classmethod
    def load(cls, spec: RobotSpec, client: int, base_position: Sequence[float], base_yaw: float = 0.0,
             visuals: bool = True) -> "Robot":
        """Load the arm at ``base_position`` [m] rotated by ``base_yaw`` [rad] about z, at home, its F/T joint on.

        ``visuals=False`` skips the visual meshes (a world that is never rendered): the Panda then
        loads in 10 ms instead of 58; dynamics and collisions are the same.
        """
        path = str(robot_urdf(spec))
        pos = check_vector3("base_position", base_position).tolist()
        quat = pb.getQuaternionFromEuler([0.0, 0.0, float(base_yaw)])
        flags = pb.URDF_USE_INERTIA_FROM_FILE
        arm_flags = flags if visuals else flags | pb.URDF_IGNORE_VISUAL_SHAPES
        body = pb.loadURDF(path, pos, quat, useFixedBase=True, flags=arm_flags, physicsClientId=client)
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
        arm = movable
        if len(spec.home) != len(arm):
            raise ParameterError(f"robot {spec.name!r}: home has {len(spec.home)} angles, "
                                 f"the arm has {len(arm)} joints")
        # the wrist joint reports its reaction wrench (for a WristSensor) from the next step on
        pb.enableJointForceTorqueSensor(body, joint_index[spec.sensor_joint], True, physicsClientId=client)
        # the twin, once the description is known to fit: kinematics only (without meshes the twin loads in 2 ms
        # instead of 58 for the Panda), one a closed robot of the same description and base gave back if there is
        twin_key = (path, tuple(pos), tuple(quat))
        twin_flags = flags | pb.URDF_IGNORE_VISUAL_SHAPES | pb.URDF_IGNORE_COLLISION_SHAPES
        kin_client, kin_body = _free_twin(twin_key, twin_flags)
        robot = cls(spec, client, body, kin_client, kin_body, arm, movable, np.array(lower), np.array(upper),
                    np.array(force), link_index, joint_index)
        robot._twin_key = twin_key
        robot.reset_joints(np.array(spec.home))
        return robot

    # ----- kinematics ---------------------------------------------------------------------
    @property
    def grasp_link(self) -> int:
        """Link index of the grasp frame."""
        return self.link_index[self.spec.grasp_link]

    def joint_positions(self) -> np.ndarray:
        """Current arm joint angles [rad]."""
        return np.array([s[0] for s in pb.getJointStates(self.body, self.arm_joints, physicsClientId=self.client)])

    def reset_joints(self, q: np.ndarray) -> None:
        """Teleport the arm (and its twin) to joint angles q [rad]; hold there."""
        for j, val in zip(self.arm_joints, q):
            pb.resetJointState(self.body, j, float(val), physicsClientId=self.client)
        self._set_twin(q)
        self.set_targets(q)

    def grasp_pose(self, kinematic: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """World position [m] and quaternion of the grasp frame (of the twin with ``kinematic``)."""
        c, b = (self.kin_client, self.kin_body) if kinematic else (self.client, self.body)
        st = pb.getLinkState(b, self.grasp_link, computeForwardKinematics=True, physicsClientId=c)
        return np.array(st[4]), np.array(st[5])

    def grasp_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Grasp frame position [m], quaternion, linear velocity [m/s] and angular velocity [rad/s]."""
        return tuple(np.array(v) for v in self.grasp_state_tuples())

    def grasp_state_tuples(self) -> tuple[tuple, tuple, tuple, tuple]:
        """:meth:`grasp_state` as plain tuples of floats (the per-step coupling reads it twice per step,
        where building four small arrays costs more than Bullet's query)."""
        st = pb.getLinkState(self.body, self.grasp_link, computeLinkVelocity=True, computeForwardKinematics=True,
                             physicsClientId=self.client)
        # v_frame = v_com + omega x (frame - com)
        (cx, cy, cz), (fx, fy, fz), (vx, vy, vz), omega = st[0], st[4], st[6], st[7]
        wx, wy, wz = omega
        dx, dy, dz = fx - cx, fy - cy, fz - cz
        v_frame = (vx + (wy * dz - wz * dy), vy + (wz * dx - wx * dz), vz + (wx * dy - wy * dx))
        return st[4], st[5], v_frame, omega

    def solve_ik(self, position: Sequence[float], quat: Sequence[float], seed: np.ndarray | None = None,
                 tol: float = 1e-4, iterations: int = 20) -> np.ndarray:
        """Arm joint angles [rad], shape (n_arm,), that put the grasp frame at ``position`` [m], ``quat``.

        PyBullet's damped least-squares IK (:meth:`_ik`) iterated on the kinematic twin from
        ``seed`` (default: the current joints) and checked with forward kinematics: with joint
        limits and the home pose as rest pose (null space) for the first half of the iterations,
        plain to polish. ParameterError if the pose is not reached within ``tol`` [m] in position
        and ``10 tol`` [rad] in orientation. Use it to check targets; :meth:`track` follows them.
        """
        pos = check_vector3("target position", position)
        q = self.joint_positions() if seed is None else np.asarray(seed, float)
        # the same problem on the same twin has the same answer: kept (an environment's reset solves its grasp poses
        # again, 15 ms), and the twin left where the solve leaves it
        key = (self.spec, pb.getBasePositionAndOrientation(self.kin_body, physicsClientId=self.kin_client),
               pos.tobytes(), np.asarray(quat, float).tobytes(), q.tobytes(), float(tol), int(iterations))
        try:
            solved = _SOLVED.get(key)
        except TypeError:  # (a spec holding lists: not hashable, solved every time)
            solved = key = None
        if solved is not None:
            self._set_twin(solved)
            return solved.copy()
        err_p = err_r = np.inf
        for k in range(iterations):
            err_p, err_r = self._twin_miss(q, pos, quat)
            if err_p < tol and err_r < 10 * tol:
                if key is not None:
                    if len(_SOLVED) >= SOLVED_SIZE:
                        _SOLVED.clear()
                    _SOLVED[key] = q.copy()
                return q
            q = self._ik(pos, quat, null_space=k < iterations // 2, iterations=100, residual=1e-7)
        raise ParameterError(f"pose unreachable for robot {self.spec.name!r}: target {np.round(pos, 4).tolist()} "
                             f"missed by {err_p * 1000:.1f} mm / {np.degrees(err_r):.1f} deg after IK")

    def track(self, position: np.ndarray, quat: Sequence[float]) -> np.ndarray:
        """Arm joint angles [rad] for a grasp-frame target near the current pose: one IK solve seeded at the
        measured joints, for targets :meth:`solve_ik` found reachable (per-step tracking, no FK check),
        within the joint limits. :attr:`ik_solver` says how: compiled damped least squares on the URDF chain
        (:class:`~bullet_dlo.robots.ik.ChainIK`, to 1e-9 m and 1e-8 rad in its own double-precision
        kinematics, at most 50 iterations) or PyBullet's IK on the twin (50 iterations, residual 1e-8).
        The two land on the target alike (``tests/robots/test_ik.py``) but not on the same bits."""
        return self._track_from(position, quat, self.joint_positions())

    def _track_from(self, position: np.ndarray, quat: Sequence[float], q: np.ndarray) -> np.ndarray:
        """:meth:`track`'s solve from joint angles ``q`` [rad]."""
        if self.ik_solver == "compiled":
            return self.chain_ik.solve(position, quat, q)
        self._set_twin(q)
        return self._ik(position, quat, null_space=False, iterations=50, residual=1e-8)

    def track_within(self, position: np.ndarray, quat: Sequence[float], tol: float = 1e-3) -> np.ndarray | None:
        """:meth:`track`, or None when its answer leaves the grasp frame more than ``tol`` [m] from ``position``: the
        target is beyond the arm's reach from where it is (out of its workspace, or a joint at its limit on the
        way). The compiled IK's own residual decides (no extra work; 1e-9 m on a reachable target); PyBullet's IK,
        up to ~1.5 mm off a reachable target 2.5 cm away in one solve, by forward kinematics on the twin after
        up to three solves, each from the last one's angles."""
        q = self.track(position, quat)
        if self.ik_solver == "compiled":
            return q if self.chain_ik.error <= tol else None
        for _ in range(3):
            if self._twin_miss(q, position, quat)[0] <= tol:
                return q
            q = self._track_from(position, quat, q)
        return None

    def path_miss(self, poses: Sequence[tuple[np.ndarray, np.ndarray]],
                  tol: float = 1e-4) -> tuple[int, float, float] | None:
        """Whether the grasp frame can follow ``poses`` (position [m], quaternion [x, y, z, w]) in order from the
        current joints as :meth:`track` follows targets: each pose solved from the angles found for the one
        before and checked by forward kinematics within ``tol`` [m] and ``10 tol`` [rad]. None if it can, else
        (index of the first pose missed, its position error [m], its orientation error [rad]). A pose that
        :meth:`solve_ik` reaches from other angles can still be beyond the path's reach (a roll that takes a
        wrist joint to its limit on the way)."""
        q = self.joint_positions()
        for k, (pos, quat) in enumerate(poses):
            q = self._track_from(pos, quat, q)
            err_p, err_r = self._twin_miss(q, pos, quat)
            if err_p > tol or err_r > 10 * tol:
                return k, err_p, err_r
        return None

    def _twin_miss(self, q: np.ndarray, position: np.ndarray, quat: Sequence[float]) -> tuple[float, float]:
        """The kinematic twin put at joint angles ``q`` [rad]: its grasp frame's distance [m] and angle [rad] from
        the target ``position``, ``quat`` (forward kinematics)."""
        self._set_twin(q)
        p_now, q_now = self.grasp_pose(kinematic=True)
        return float(np.linalg.norm(p_now - position)), angle_between(q_now, quat)

    def _ik(self, position: Sequence[float], quat: Sequence[float], null_space: bool, iterations: int,
            residual: float) -> np.ndarray:
        """The IK inner loop, once: PyBullet's IK on the twin from its current joints; arm angles clipped to limits.

        null_space: respect joint limits and pull towards the home pose (the rest pose).
        """
        extra = {}
        if null_space:
            extra = dict(lowerLimits=self.lower.tolist(), upperLimits=self.upper.tolist(),
                         jointRanges=(self.upper - self.lower).tolist(), restPoses=self._rest_poses.tolist())
        sol = pb.calculateInverseKinematics(self.kin_body, self.grasp_link, list(position), list(quat),
                                            maxNumIterations=iterations, residualThreshold=residual,
                                            physicsClientId=self.kin_client, **extra)
        cols = self._arm_columns
        return np.clip(np.array(sol)[cols], self.lower[cols], self.upper[cols])

    def _set_twin(self, q: np.ndarray) -> None:
        """Put the kinematic twin's arm at joint angles q [rad] (velocities zero), in one call to Bullet
        (seven ``resetJointState`` calls cost about 3x as much: 11 vs 3.3 us; the same state)."""
        pb.resetJointStatesMultiDof(self.kin_body, self.arm_joints, [[float(v)] for v in q],
                                    targetVelocities=self._zero_velocities, physicsClientId=self.kin_client)

    # ----- control ------------------------------------------------------------------------
    def set_targets(self, q: np.ndarray) -> None:
        """Joint position targets [rad] for the arm (strong position control)."""
        pb.setJointMotorControlArray(self.body, self.arm_joints, pb.POSITION_CONTROL, targetPositions=list(q),
                                     forces=self._arm_force, physicsClientId=self.client)

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
        """Give the kinematic twin back for the next robot of the same description and base (:func:`_free_twin`;
        one built otherwise is disconnected): the arm goes with its world."""
        if not pb.isConnected(self.kin_client):
            return
        key = getattr(self, "_twin_key", None)
        if key is not None and sum(map(len, _TWINS.values())) < TWINS_KEPT:
            _TWINS.setdefault(key, []).append((self.kin_client, self.kin_body))
            self.kin_client = -1  # (this robot's IK is over; the twin is another's from now on)
        else:
            pb.disconnect(self.kin_client)
