"""Two arms facing each other across a table, holding the two ends of a cable.

The left arm holds the cable's first mass, the right arm its last. A grasp clamps the
cable end to the gripper's grasp frame (position and tangent): every step the held mass
follows the measured grasp frame, and the force and clamp torque the cable exerts on its
holder are applied to the gripper link, so they flow through the arm into its wrist F/T
sensor. Grippers move along Cartesian straight lines with minimum-jerk profiles, tracked by
inverse kinematics and joint position control.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import min_jerk
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_positive, check_vector3
from bullet_dlo.robots.arm import Robot, load_robot_spec, quat_from_axes
from bullet_dlo.robots.sensors import WristSensor

ARMS = ("left", "right")


@dataclass(frozen=True)
class DualArmConfig:
    """Dual-arm scene settings (SI units).

    robot: robot name in ``robots/``; cable: the cable; dt: Bullet step [s]; integrator;
    hold_height: height of the held cable ends above the floor [m]; base_distance: distance of
    each arm base from the cable's midpoint along x [m]; table_height: top of the table [m]
    (0: no table); sensor_rate [Hz] (None: every step); noise_std, bias: sensor noise and bias
    (fx fy fz mx my mz); seed: for the sensor noise.
    """

    robot: str = "kuka"
    cable: CableSpec = field(default_factory=lambda: CableSpec.lv2017(n_masses=10, damping=0.02))
    dt: float = 1.0 / 240.0
    integrator: str = "implicit_euler"
    hold_height: float = 0.35
    base_distance: float = 0.6
    table_height: float = 0.2
    sensor_rate: float | None = None
    noise_std: tuple[float, ...] = (0.0,) * 6
    bias: tuple[float, ...] = (0.0,) * 6
    seed: int = 0
    renderer: str | None = None
    substeps: int = 1


@dataclass
class CartesianMove:
    """A straight-line move of one gripper by ``displacement`` [m] from ``start`` [s] over ``duration`` [s]."""

    arm: int
    displacement: np.ndarray
    start: float
    duration: float
    origin: np.ndarray | None = None  # grasp position when the move starts (set then)


@dataclass
class DualArmRecord:
    """Per-step data: t [s], sensor wrenches in world (2, 6) (left, right), the model's end
    forces (2, 3) and clamp torques (2, 3), grasp-frame and cable-end positions (2, 3) [m]."""

    t: list = field(default_factory=list)
    wrench_world: list = field(default_factory=list)
    end_forces: list = field(default_factory=list)
    end_moments: list = field(default_factory=list)
    grasp_pos: list = field(default_factory=list)
    cable_end_pos: list = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(v) for k, v in self.__dict__.items()}


class DualArmScene:
    """Build the scene: table, two arms at their grasp poses, a straight cable between them."""

    def __init__(self, config: DualArmConfig = DualArmConfig()):
        self.config = config
        check_positive("dt", config.dt)
        spec_robot = load_robot_spec(config.robot)
        cable = config.cable
        half = 0.5 * cable.length
        h = check_positive("hold_height", config.hold_height)
        if config.table_height and h - config.table_height < 0.05:
            raise ParameterError(f"hold_height {h} m must be at least 5 cm above the table top {config.table_height} m")
        self.world = BulletWorld(dt=config.dt, renderer=config.renderer)
        w = self.world
        if config.table_height > 0:
            th = config.table_height
            w.add_box((max(half - 0.05, 0.05), 0.3, th / 2), (0.0, 0.0, th / 2), name="table")
        self.robots: list[Robot] = []
        self.grasp_targets: list[tuple[np.ndarray, np.ndarray]] = []
        for side, sign in ((0, -1.0), (1, 1.0)):
            base = (sign * config.base_distance, 0.0, 0.0)
            robot = Robot.load(spec_robot, w.client, base, 0.0 if side == 0 else np.pi)
            # grasp frame: z down (top grasp), x along the cable pointing into it
            quat = quat_from_axes((-sign, 0.0, 0.0), (0.0, 0.0, -1.0))
            target = np.array([sign * half, 0.0, h])
            q = robot.solve_ik(target, quat, seed=np.array(spec_robot.home))
            robot.reset_joints(q)
            self.robots.append(robot)
            self.grasp_targets.append((target, quat))
        w.step_bare(20)  # let the position controllers settle the arms
        self.sensors = [WristSensor(r, config.sensor_rate, config.noise_std, config.bias,
                                    rng=np.random.default_rng(config.seed + k)) for k, r in enumerate(self.robots)]
        w.step_bare(2)  # a sensor reads zero until a step has run with it enabled
        for s in self.sensors:
            s.tare()  # zero in the grasp pose, before the cable is attached (as users zero an ATI)
        start, _ = self.robots[0].grasp_pose()
        model = CableModel.straight(cable, start, (1.0, 0.0, 0.0), ("free", "free"), (), w.gravity)
        self.cable = w.add_cable(model, integrator=config.integrator, record_every=10**9,
                                 overlap_ok=[r.body for r in self.robots], substeps=config.substeps)
        self._no_self_contact_at_grasps()
        self.moves: list[CartesianMove] = []
        self.grasped = [False, False]
        self._v_prev = [np.zeros(3), np.zeros(3)]
        self.record = DualArmRecord()
        w.before_step.append(self._before_step)
        w.after_physics.append(self._after_physics)
        w.after_step.append(self._record)
        self._read_grippers(first=True)

    # ----- set-up helpers --------------------------------------------------------------------
    def _no_self_contact_at_grasps(self) -> None:
        """The gripper holds the end mass: no contacts between grippers and the end masses."""
        cid = self.world.client
        ids = self.cable.body_ids
        for robot, ends in ((self.robots[0], ids[:3]), (self.robots[1], ids[-3:])):
            for sphere in ends:
                for link in range(-1, pb.getNumJoints(robot.body, physicsClientId=cid)):
                    pb.setCollisionFilterPair(robot.body, sphere, link, -1, 0, physicsClientId=cid)

    @staticmethod
    def cable_direction(arm: int, quat: Sequence[float]) -> np.ndarray:
        """Clamp tangent (first -> last mass) from a grasp frame: its x axis points into the cable."""
        x_axis = np.array(pb.getMatrixFromQuaternion(list(quat))).reshape(3, 3)[:, 0]
        return x_axis if arm == 0 else -x_axis

    # ----- grasp / release / move ------------------------------------------------------------
    def grasp(self, arm: int | str | None = None) -> None:
        """Clamp the cable end(s) to the gripper(s) (both when ``arm`` is None)."""
        arms = (0, 1) if arm is None else (ARMS.index(arm) if isinstance(arm, str) else int(arm),)
        for a in arms:
            self.cable.hold_externally(a, "clamped")
            self.grasped[a] = True
        self._read_grippers()

    def release(self, arm: int | str | None = None) -> None:
        """Open the gripper(s): the cable end falls free."""
        arms = (0, 1) if arm is None else (ARMS.index(arm) if isinstance(arm, str) else int(arm),)
        for a in arms:
            self.cable.release(a)
            self.grasped[a] = False

    def move(self, arm: int | str, displacement: Sequence[float], duration: float, start: float | None = None) -> None:
        """Schedule a straight-line gripper move [m] over ``duration`` [s] from ``start`` [s] (default: now).

        The target is checked for reachability with IK now (ParameterError if unreachable).
        """
        a = ARMS.index(arm) if isinstance(arm, str) else int(arm)
        d = check_vector3("displacement", displacement)
        t0 = self.world.time if start is None else float(start)
        end_pos = self.grasp_targets[a][0] + d + sum((m.displacement for m in self.moves if m.arm == a), np.zeros(3))
        self.robots[a].solve_ik(end_pos, self.grasp_targets[a][1], seed=self.robots[a].joint_positions())
        self.moves.append(CartesianMove(a, d, t0, check_positive("move duration", duration)))

    def _target(self, arm: int, t: float) -> np.ndarray:
        pos = self.grasp_targets[arm][0].copy()
        for m in self.moves:
            if m.arm == arm:
                pos += m.displacement * min_jerk((t - m.start) / m.duration)[0]
        return pos

    # ----- per-step hooks ---------------------------------------------------------------------
    def _before_step(self) -> None:
        t_next = self.world.time + self.world.dt
        if any(self.grasped):  # what the cable exerts on both holders, computed once per step
            forces, torques = self.cable.end_forces(), self.cable.end_moments()
        for a, robot in enumerate(self.robots):
            if any(m.arm == a and m.start <= t_next <= m.start + m.duration + self.world.dt for m in self.moves):
                robot.set_targets(self._ik_track(robot, self._target(a, t_next), self.grasp_targets[a][1]))
            if self.grasped[a]:
                force, torque = forces[a], torques[a]
                pos = self.cable.x[0 if a == 0 else -1].tolist()
                cid = self.world.client
                pb.applyExternalForce(robot.body, robot.grasp_link, force.tolist(), pos, pb.WORLD_FRAME, cid)
                pb.applyExternalTorque(robot.body, robot.grasp_link, torque.tolist(), pb.WORLD_FRAME, cid)

    @staticmethod
    def _ik_track(robot: Robot, pos: np.ndarray, quat: np.ndarray) -> np.ndarray:
        """One damped-least-squares IK solve seeded at the current joints (targets were checked)."""
        q = robot.joint_positions()
        for j, val in zip(robot.arm_joints, q):
            pb.resetJointState(robot.kin_body, j, float(val), physicsClientId=robot.kin_client)
        sol = np.array(pb.calculateInverseKinematics(robot.kin_body, robot.grasp_link, pos.tolist(), list(quat),
                                                     maxNumIterations=50, residualThreshold=1e-8,
                                                     physicsClientId=robot.kin_client))
        idx = [robot.movable.index(j) for j in robot.arm_joints]
        return np.clip(sol[idx], robot.lower[idx], robot.upper[idx])

    def _read_grippers(self, first: bool = False) -> None:
        for a, robot in enumerate(self.robots):
            pos, quat, vel, omega = robot.grasp_state()
            acc = np.zeros(3) if first else (vel - self._v_prev[a]) / self.world.dt
            self._v_prev[a] = vel
            self.cable.set_external_pose(a, pos, vel, acc, omega, self.cable_direction(a, quat))

    def _after_physics(self) -> None:
        self._read_grippers()
        for s in self.sensors:
            s.update(self.world.time, self.world.dt)

    def _record(self) -> None:
        r = self.record
        r.t.append(self.world.time)
        r.wrench_world.append([s.last.world() for s in self.sensors])
        r.end_forces.append(self.cable.end_forces())
        r.end_moments.append(self.cable.end_moments())
        r.grasp_pos.append(self.cable.holder_positions())
        r.cable_end_pos.append([self.cable.x[0].copy(), self.cable.x[-1].copy()])

    # ----- running ------------------------------------------------------------------------------
    def run(self, duration: float) -> float:
        """Step for ``duration`` [s]; returns the wall time [s]."""
        n = max(1, int(round(check_positive("duration", duration) / self.world.dt)))
        return self.world.run_while_stable(n, self.cable)

    def window_mean(self, seconds: float = 0.5) -> dict[str, np.ndarray]:
        """Averages over the last ``seconds`` [s]: sensor wrench (2, 6) and model end forces (2, 3)."""
        rec = self.record.arrays()
        sel = rec["t"] >= rec["t"][-1] - seconds + 1e-12
        return {"wrench_world": rec["wrench_world"][sel].mean(axis=0),
                "end_forces": rec["end_forces"][sel].mean(axis=0)}

    def close(self) -> None:
        for r in self.robots:
            r.close()
        self.world.close()

    def __enter__(self) -> "DualArmScene":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
