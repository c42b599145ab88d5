"""The dual-arm scene's physics: world, table, two arms and the cable, coupled at the grasps.

Everything needed to step, and nothing about what an episode does (:mod:`.task`) or what is
measured (:mod:`.observation`). The left arm (index 0) holds the cable's first end, the right
arm (index 1) its last. A held end is clamped to its gripper's grasp frame (position and
tangent), or, with ``spec.grip = "friction"``, held by a friction grip that slips along the
gripper at 2 mu F_n (:meth:`~bullet_dlo.bullet.cable.BulletCable.grip_with_friction`).

The physics is a coupling of its world (:meth:`bullet_dlo.bullet.world.BulletWorld.step` lists
the phases). One step of the dual-arm scene, the wrist wrench's path in order:

1. the cable's sphere forces go to Bullet (contact with the table and obstacles);
2. :meth:`DualArmPhysics.load`: the force and clamp torque the cable's last step planned for each
   held end are applied to the gripper link, so they flow through the arm into its wrist joint;
   then the task (if any) sets the arms' joint targets;
3. Bullet steps the arms: the wrist joints carry the cable's load in their reaction;
4. :meth:`DualArmPhysics.read`: both arms are read in one go (grasp frames, the wrist sensors' links
   and joints: :class:`~bullet_dlo.bullet.native.StateReader`), each held cable end is given the
   measured grasp frame (position, velocity, acceleration, angular velocity, tangent) to follow;
   then the wrist sensors (the observation, if any) sample the joint reactions, remove the payload
   and are checked against the loads of phase 2;
5. the cable takes its own step, held by the grasp frames of phase 4, and plans the loads of the
   next phase 2;
6. recorders (``world.after_step`` hooks) store the step.

Where a C compiler is available the wrenches go to Bullet and the states come back through
Bullet's C API from compiled code (:mod:`bullet_dlo.bullet.native`), else through PyBullet's
Python API; both give the same numbers to the last bit.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation

from bullet_dlo.bullet.cable import BulletCable
from bullet_dlo.bullet.kernels import bind
from bullet_dlo.bullet.native import StateReader, apply_wrenches, kernel_api
from bullet_dlo.bullet.world import BulletWorld, add_obstacles
from bullet_dlo.config.robot import CALIBRATION_TILTS, DualArmSpec, RobotSpec, load_robot_spec
from bullet_dlo.core.boundary import default_normal
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.kernels import FRAME_QUAT, grasp_frames
from bullet_dlo.robots.sensors import PayloadFit, identify_inertia, identify_payload, sensor_links
from bullet_dlo.robots.transforms import quat_from_axes, rotation

ARMS = ("left", "right")
"""Arm names by index; arm i holds cable end i (the cable's API numbers its ends 0 = first, 1 = last)."""
END_NODE = (0, -1)
"""Cable node held by arm i."""
SETTLE_STEPS = 150
"""Bare Bullet steps before the cable is attached: the position controllers settle the arms,
and the wrist joints' reaction (a sensor's tare) is then that of the unloaded arms at rest.
Bullet's position motors (gain 0.1) remove 10 % of the arms' sag per step, so 150 steps leave
below 1e-6 of it; with 22, the tare held the payload's m a of a still-settling arm, which every
later (inertia-compensated) reading carried as a bias ~ 1/dt: +1.0 % of the vertical load and
0.5 mN sideways on the Panda at 1 kHz (``python demos/sensor_bias.py``)."""
SWING = (0.05, 3.0, 2.0)
"""A payload calibration's wrist swings (:meth:`DualArmPhysics.calibrate_payloads`): amplitude [rad], frequency
[Hz] and periods of each of the last three joints in turn; about 20 rad/s^2 at the wrist, where it turns back."""
SOLVER_RESIDUAL = 1e-9
"""Bullet's solver residual threshold in the dual-arm world (its default: 1e-7)."""
NO_CONTACT_NODES = 3
"""Cable masses at each end that do not collide with the arm holding that end (nor, in the contact model,
the segments next to them); the rest of the cable meets both arms."""


def arm_index(arm: int | str) -> int:
    """Index (0 left, 1 right) of an arm given by name or index; ParameterError otherwise."""
    if isinstance(arm, str) and arm in ARMS:
        return ARMS.index(arm)
    if not isinstance(arm, (str, bool)) and arm in (0, 1):
        return int(arm)
    raise ParameterError(f"arm must be one of {', '.join(ARMS)} (or 0, 1), got {arm!r}")


def arm_indices(arm: int | str | None) -> tuple[int, ...]:
    """Both arms for None, else the one arm's index."""
    return (0, 1) if arm is None else (arm_index(arm),)


class DualArmPhysics:
    """World, table, two arms at their grasp poses and the cable between them, ready to step.

    Built in this order: the arms are placed by IK so that their grasp frames hold the ends of
    the straight cable (z down, x along the cable pointing into it), settled for
    :data:`SETTLE_STEPS` bare steps, then the cable is added, both ends free, in its static
    shape in the grippers' hold (:meth:`settled_state`; ``spec.start = "straight"``: straight). Build the
    observation (:class:`~.observation.DualArmObservation`) right after, before the first step:
    its sensors tare on the unloaded arms. Any task then clamps ends (:meth:`clamp`) and drives
    the arms (``robots[i].set_targets``) from a ``world.before_step`` hook.

    Attributes: ``world`` (:class:`BulletWorld`), ``robots`` (left, right), ``cable``
    (:class:`~bullet_dlo.bullet.cable.BulletCable`), ``grasp_poses``: per arm, the grasp
    frame it was built at (position [m] (3,), quaternion [x, y, z, w] (4,)), ``held``: per arm,
    whether its cable end is clamped.
    """

    def __init__(self, spec: DualArmSpec = DualArmSpec()):
        self.spec = spec
        robot_spec = load_robot_spec(spec.robot)
        opts = spec.bullet
        self.world = BulletWorld(dt=spec.dt, gravity=spec.gravity, ground=opts.ground,
                                 ground_height=opts.ground_height, ground_friction=opts.ground_friction,
                                 solver_residual=SOLVER_RESIDUAL, renderer=spec.renderer)
        # Bullet's solver stops at a residual of 1e-7 by default, which left the KUKA's wrist reaction
        # 1.6 mN sideways at rest (0.5 % of a 30 g cable's weight); at 1e-9 it is 0.006 mN, same cost (lower still
        # once the cable meets a free body: BulletWorld.solve_free_bodies)
        try:
            self._add_table()
            add_obstacles(self.world, opts.obstacles)  # pegs, fixtures: the cable touches them
            self.robots: list[Robot] = []
            self.grasp_poses: list[tuple[np.ndarray, np.ndarray]] = []
            for arm, sign in zip(ARMS, (-1.0, 1.0)):
                self._add_arm(robot_spec, sign, 0.0 if arm == "left" else np.pi)
            self.world.step_bare(SETTLE_STEPS)
            self.payload_fits = self.calibrate_payloads() if spec.payload == "calibrated" else None
            self.cable = self._add_cable()
        except Exception:
            self.close()
            raise
        self.held = [False, False]
        # one read per step of both arms (grasp frame, then the wrist sensor's links), shared with the sensors
        self.reader = StateReader(self.world.client, self.world.native_handle(), [r.body for r in self.robots],
                                  [[r.grasp_link] + sensor_links(r) for r in self.robots],
                                  [r.joint_index[r.spec.sensor_joint] for r in self.robots])
        self._grasp_history = np.zeros((2, 3, 7))  # the grasp frames' last two poses, for their velocities
        self._grasp_links = np.array([r.grasp_link for r in self.robots], dtype=np.int32)
        self._held_mask = np.zeros(2, dtype=np.bool_)
        self._end_points = np.zeros((2, 3))  # [m] where the cable's end forces act: its end masses
        self._apply_wrenches = None  # native.apply_wrenches's machine code, bound on first use
        self._section = np.zeros((2, 3))  # held section axis d1 in each grasp frame (a twisting cable's roll)
        self._grasp_frames = bind(grasp_frames, self.reader.link_rows, self._grasp_history, 0.0, self._section,
                                  self.cable.ext)
        self.task = None  # set by a task (DualArmTask): it drives the arms in load()
        self.observation = None  # set by DualArmObservation: its sensors sample in read()
        self.world.couplings.append(self)
        self._follow_grippers(first=True)

    # ----- building ------------------------------------------------------------------------------
    def _add_table(self) -> None:
        th = self.spec.table_height
        if th > 0:
            half = 0.5 * self.spec.cable.length
            self.world.add_box((max(half - 0.05, 0.05), 0.3, th / 2), (0.0, 0.0, th / 2), name="table")

    def _add_arm(self, robot_spec: RobotSpec, sign: float, base_yaw: float) -> None:
        """Load an arm at x = sign * base_distance and put its grasp frame on the cable end at x = sign * L/2."""
        spec = self.spec
        robot = Robot.load(robot_spec, self.world.client, (sign * spec.base_distance, 0.0, 0.0), base_yaw,
                           visuals=spec.renderer is not None)  # no renderer: nothing will draw the meshes
        self.robots.append(robot)  # before the IK, so that close() releases its twin if the pose is unreachable
        # position-controlled at its joints' force limits (hundreds of times the cable's loads): the cable meets its
        # links as kinematic obstacles (docs/concepts/contact.md, "Driven links")
        fingers = {robot.joint_index[name] for name in robot_spec.finger_joints}
        self.world.drive_body(robot.body, [k for k in range(-1, pb.getNumJoints(robot.body, physicsClientId=robot.client))
                                           if k not in fingers])
        quat = quat_from_axes((-sign, 0.0, 0.0), (0.0, 0.0, -1.0))  # top grasp, x pointing into the cable
        position = np.array([sign * 0.5 * spec.cable.length, 0.0, spec.hold_height])
        robot.reset_joints(robot.solve_ik(position, quat, seed=np.array(robot_spec.home)))
        self.grasp_poses.append((position, quat))

    def _add_cable(self) -> BulletCable:
        """The cable from the left grasp frame along +x, both ends free, not colliding with its holders;
        settled in the grippers' hold (``spec.start``) or straight."""
        start, _ = self.robots[0].grasp_pose()
        model = CableModel.straight(self.spec.cable, start, (1.0, 0.0, 0.0), ("free", "free"), (), self.world.gravity)
        state = self.settled_state(model) if self.spec.start == "settled" else None
        spec = self.spec
        cable = self.world.add_cable(model, integrator=spec.integrator, record_every=10**9, state=state,
                                     overlap_ok=[r.body for r in self.robots], substeps=spec.substeps,
                                     self_collision=spec.bullet.self_collision, sync=spec.bullet.sync,
                                     newton=spec.newton, detector=spec.detector)
        cid = self.world.client
        ends = (cable.body_ids[:NO_CONTACT_NODES], cable.body_ids[-NO_CONTACT_NODES:])
        for robot, spheres in zip(self.robots, ends):
            for sphere in spheres:
                for link in range(-1, pb.getNumJoints(robot.body, physicsClientId=cid)):
                    pb.setCollisionFilterPair(robot.body, sphere, link, -1, 0, physicsClientId=cid)
        if cable.model_contact:  # the same ends out of the contact model's contact with their arm (the grasp)
            n = cable.model.n
            held = list(zip(self.robots, (range(NO_CONTACT_NODES), range(n - NO_CONTACT_NODES, n))))
            for k, (robot, nodes) in enumerate(held):
                cable.exclude_contact(robot.body, nodes=nodes, rebuild=k == len(held) - 1)  # (one rebuild for both)
        return cable

    def settled_state(self, model: CableModel) -> CableState:
        """Static equilibrium of ``model``'s cable under gravity with both ends clamped in the grasp
        frames as the arms hold them now (positions and tangents), at rest: (n, 3) positions [m].

        Contact is not part of the static solve: the table must stay below the hold (checked by
        DualArmSpec's clearance); a cable that would sag through it is refused.
        """
        (p0, q0), (p1, q1) = (robot.grasp_pose() for robot in self.robots)
        d0, d1 = self.cable_direction(0, q0), self.cable_direction(1, q1)
        held = CableModel.straight(model.spec, p0, d0, ("clamped", "clamped"), (), model.gravity)
        # the last clamp's section axis built for its own reached tangent d1: the first's (built for d0) is normal
        # to d1 only to the IK's precision (~1e-8 rad), not to the 1e-9 EndHolder asks
        held = replace(held, last=replace(held.last, position=np.asarray(p1, dtype=float), direction=d1,
                                          normal=default_normal(d1)))
        x_start = model.x0.copy()  # the straight layout, its last node pulled onto the right grasp
        x_start += np.outer(np.linspace(0.0, 1.0, model.n), np.asarray(p1) - x_start[-1])
        res = solve_static(held, x_start)
        if not res.converged:
            raise ParameterError(f"the cable's static shape in the grippers' hold did not converge "
                                 f"(residual {res.residual:.3g} N); use start: straight")
        top = self.spec.table_height
        if top > 0 and float(res.x[:, 2].min()) - 0.5 * model.spec.diameter < top:
            raise ParameterError(f"the settled cable sags to z = {res.x[:, 2].min():.4f} m, through the table top "
                                 f"{top} m; raise hold_height or use start: straight")
        return res.state()

    def calibrate_payloads(self, tilts: Sequence[Sequence[float]] = CALIBRATION_TILTS) -> list[PayloadFit]:
        """Identify each wrist sensor's payload (mass, centre of mass, offset) as on a real robot: turn each
        unloaded gripper about its grasp point by each rotation vector of ``tilts`` [rad] (world frame),
        settle, read the sensor joint and fit (:func:`~bullet_dlo.robots.sensors.identify_payload`);
        then back to the grasp pose and settle; then the payload's rotational inertia from swings of the wrist
        there (:meth:`_swing_wrists`, :func:`~bullet_dlo.robots.sensors.identify_inertia`). Poses the IK cannot
        reach exactly are used as reached (the fit takes the measured orientation). Call before the cable is
        attached."""
        homes = [r.joint_positions() for r in self.robots]
        links = [sensor_links(r)[0] for r in self.robots]  # the sensor frame is this link's CoM frame
        joints = [r.joint_index[r.spec.sensor_joint] for r in self.robots]
        rotations: list[list[np.ndarray]] = [[], []]
        reactions: list[list[np.ndarray]] = [[], []]
        for tilt in tilts:
            turn = Rotation.from_rotvec(np.asarray(tilt, dtype=float))
            for robot, (position, quat), q in zip(self.robots, self.grasp_poses, homes):
                target = (turn * Rotation.from_quat(quat)).as_quat()
                try:
                    robot.reset_joints(robot.solve_ik(position, target, seed=q))
                except ParameterError:  # not exactly reachable: the pose the IK gets to serves as well
                    robot.reset_joints(robot.track(position, target))
            self.world.step_bare(SETTLE_STEPS)
            for arm, (robot, link, joint) in enumerate(zip(self.robots, links, joints)):
                state = pb.getLinkState(robot.body, link, physicsClientId=self.world.client)
                rotations[arm].append(rotation(state[1]))
                reactions[arm].append(np.array(pb.getJointState(robot.body, joint, physicsClientId=self.world.client)[2]))
        for robot, q in zip(self.robots, homes):
            robot.reset_joints(q)
        self.world.step_bare(SETTLE_STEPS)
        fits = [identify_payload(np.array(rotations[a]), np.array(reactions[a]), self.world.gravity) for a in (0, 1)]
        return [identify_inertia(fit, *swing, self.world.gravity) for fit, swing in zip(fits, self._swing_wrists())]

    def _swing_wrists(self) -> list[tuple[np.ndarray, ...]]:
        """Both unloaded arms at rest swing each of their last three joints in turn by :data:`SWING` (amplitude
        [rad], frequency [Hz], periods) about the pose they hold, then settle back; per arm the readings where the
        wrist turns back (angular velocity below 5 % of its largest, angular acceleration above 30 %): the sensor
        frame's rotations (m, 3, 3), its origin's acceleration and angular acceleration (backward differences of the
        link velocities, world frame, (m, 3) each) and the sensor joint's reaction moment (m, 3) (for
        :func:`~bullet_dlo.robots.sensors.identify_inertia`)."""
        cid, dt = self.world.client, self.world.dt
        amplitude, frequency, periods = SWING
        links = [sensor_links(r)[0] for r in self.robots]
        joints = [r.joint_index[r.spec.sensor_joint] for r in self.robots]
        homes = [r.joint_positions() for r in self.robots]

        def read(arm: int) -> tuple[np.ndarray, ...]:
            robot = self.robots[arm]
            state = pb.getLinkState(robot.body, links[arm], computeLinkVelocity=1, physicsClientId=cid)
            moment = pb.getJointState(robot.body, joints[arm], physicsClientId=cid)[2][3:]
            return rotation(state[1]), np.array(state[6]), np.array(state[7]), np.array(moment)

        out: list[list[list[np.ndarray]]] = [[[], [], [], []], [[], [], [], []]]
        steps = int(round(periods / frequency / dt))
        for back in (3, 2, 1):
            runs: list[list[tuple]] = [[], []]
            prev = [read(a) for a in (0, 1)]
            for k in range(1, steps + 1):
                for robot, q in zip(self.robots, homes):
                    target = q.copy()
                    target[max(len(q) - back, 0)] += amplitude * np.sin(2.0 * np.pi * frequency * k * dt)
                    robot.set_targets(target)
                self.world.step_bare(1)
                for arm in (0, 1):
                    now = read(arm)
                    runs[arm].append((now[0], (now[1] - prev[arm][1]) / dt, (now[2] - prev[arm][2]) / dt, now[2],
                                      now[3]))
                    prev[arm] = now
            for arm in (0, 1):
                spin = np.array([np.linalg.norm(r[3]) for r in runs[arm]])
                turn = np.array([np.linalg.norm(r[2]) for r in runs[arm]])
                for r, w, a in zip(runs[arm], spin, turn):
                    if w <= 0.05 * spin.max() and a >= 0.3 * turn.max():
                        for store, value in zip(out[arm], (r[0], r[1], r[2], r[4])):
                            store.append(value)
            for robot, q in zip(self.robots, homes):
                robot.set_targets(q)
            self.world.step_bare(SETTLE_STEPS)
        return [tuple(np.array(v).reshape(-1, *((3, 3) if i == 0 else (3,))) for i, v in enumerate(out[a]))
                for a in (0, 1)]

    # ----- the grasp coupling --------------------------------------------------------------------
    def clamp(self, arm: int) -> None:
        """Clamp cable end ``arm`` to that arm's grasp frame (from the current measured pose), rigidly or
        by a friction grip (``spec.grip``)."""
        spec = self.spec
        if spec.grip == "friction":
            self.cable.grip_with_friction(arm, spec.grip_force, spec.grip_static_friction, spec.grip_dynamic_friction,
                                         reach=spec.grip_reach)
        else:
            self.cable.hold_externally(arm, "clamped")
        if self.cable.control.k_twist.shape[0]:
            # a cable with a material frame: the clamp holds the section axis it closed on, fixed in the grasp
            # frame from now on, so the gripper's roll about the cable twists the cable
            quat = self.reader.link_rows[arm, 0, FRAME_QUAT:FRAME_QUAT + 4]
            self._section[arm] = rotation(quat).T @ self.cable.ext.normal[arm]
        self.held[arm] = True
        self._follow_grippers()

    def unclamp(self, arm: int) -> None:
        """Let cable end ``arm`` go: it is free from the next step on."""
        self.cable.release(arm)
        self.held[arm] = False

    @staticmethod
    def cable_direction(arm: int, quat: Sequence[float]) -> np.ndarray:
        """Clamp tangent (first -> last mass) from arm ``arm``'s grasp frame: its x axis points into the cable
        (the per-step coupling computes the same in :func:`~bullet_dlo.robots.kernels.grasp_frames`)."""
        x, y, z, w = quat
        sign = 1.0 if arm == 0 else -1.0
        return sign * np.array([1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + z * w), 2.0 * (x * z - y * w)])

    def load(self) -> None:
        """Phase 2 of the world's step (see module doc): the cable's loads on the held grippers, then the
        task's arm targets."""
        self._apply_cable_wrench()
        if self.task is not None:
            self.task.drive()

    def read(self) -> None:
        """Phase 4 of the world's step (see module doc): both arms read, the held ends given the measured
        grasp frames, then the wrist sensors sampled."""
        self._follow_grippers()
        if self.observation is not None:
            self.observation.read_sensors()

    def _apply_cable_wrench(self) -> None:
        """Before the Bullet step: the cable's force [N] (at the end mass) and clamp torque [N m] on each holder."""
        held = self.held
        if self.spec.grip == "friction":
            for arm in (0, 1):  # a friction grip that the end slid out of holds nothing any more
                if held[arm] and not self.cable.grip.active[arm]:
                    held[arm] = False
        if not (held[0] or held[1]):
            return
        forces, torques = self.cable.planned_end_loads()  # left by the cable's own step kernel
        x = self.cable.x
        points = self._end_points
        points[0], points[1] = x[END_NODE[0]], x[END_NODE[1]]
        native = self.world.native_handle()
        if native:
            self._held_mask[0], self._held_mask[1] = held
            args = (kernel_api(native), self.reader.bodies, self._grasp_links, self._held_mask, forces, points,
                    torques)
            if self._apply_wrenches is None:
                self._apply_wrenches = bind(apply_wrenches, *args)
            self._apply_wrenches(*args)
            return
        cid = self.world.client
        for arm, robot in enumerate(self.robots):
            if held[arm]:
                pb.applyExternalForce(robot.body, robot.grasp_link, forces[arm].tolist(), points[arm].tolist(),
                                      pb.WORLD_FRAME, cid)
                pb.applyExternalTorque(robot.body, robot.grasp_link, torques[arm].tolist(), pb.WORLD_FRAME, cid)

    @property
    def load_points(self) -> np.ndarray:
        """Where the cable's forces were applied in the last step [m], (2, 3): its end masses then."""
        return self._end_points

    def _follow_grippers(self, first: bool = False) -> None:
        """After the Bullet step: read both arms (for the sensors too) and make the measured grasp frames
        the holder poses of the cable's ends (:func:`~bullet_dlo.robots.kernels.grasp_frames`)."""
        self.reader.read()
        self._grasp_frames(self.reader.link_rows, self._grasp_history, 0.0 if first else 1.0 / self.world.dt,
                           self._section, self.cable.ext)

    # ----- running -------------------------------------------------------------------------------
    def run(self, duration: float) -> float:
        """Step for ``duration`` [s] (whole steps), stopping if the cable goes unstable; returns the wall time [s]."""
        return self.world.run_while_stable(self.world.steps_in(duration), self.cable)

    def run_timed(self, duration: float) -> tuple[float, float]:
        """:meth:`run`, with the first step timed apart: (first step, the other steps) wall time [s]. The first
        step loads (or, on a cold cache, compiles) every kernel a step calls, so the second number is the
        run's cost and the first its start-up."""
        steps = self.world.steps_in(duration)
        first = self.world.run_while_stable(1, self.cable)
        rest = self.world.run_while_stable(steps - 1, self.cable) if self.cable.stable else 0.0
        return first, rest

    def close(self) -> None:
        """Disconnect the arms' kinematic twins and the world."""
        for r in getattr(self, "robots", ()):
            r.close()
        self.world.close()
