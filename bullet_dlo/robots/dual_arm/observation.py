"""What is measured in the dual-arm scene: the two wrist F/T sensors and the per-step record.

The sensors are updated after every Bullet step (by the physics' read phase) (each samples at its own rate, see
:class:`~bullet_dlo.robots.sensors.WristSensor`); the record then stores, per step, the
sensor readings beside the model's ground truth (the cable's end forces and clamp torques,
grasp-frame and cable-end positions), the pairs the tests and the study compare.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bullet_dlo.core.validate import ParameterError, check_positive
from bullet_dlo.robots.dual_arm.physics import ARMS, END_NODE, DualArmPhysics
from bullet_dlo.bullet.kernels import bind
from bullet_dlo.robots.kernels import load_mismatch, wrist_pair
from bullet_dlo.robots.sensors import WristSensor
from bullet_dlo.robots.transforms import cross3


@dataclass
class DualArmRecord:
    """Per-step data, arms in the order (left, right): t [s] (n,); wrench_world: sensor wrenches in world
    [fx fy fz mx my mz] [N, N m] (n, 2, 6); end_forces, end_moments: the model's end forces [N] and clamp
    torques [N m] (n, 2, 3); grasp_pos, cable_end_pos: grasp-frame and cable-end positions [m] (n, 2, 3)."""

    t: list = field(default_factory=list)
    wrench_world: list = field(default_factory=list)
    end_forces: list = field(default_factory=list)
    end_moments: list = field(default_factory=list)
    grasp_pos: list = field(default_factory=list)
    cable_end_pos: list = field(default_factory=list)

    def arrays(self) -> dict[str, np.ndarray]:
        """The columns as arrays, shapes as in the class docstring."""
        return {k: np.array(v) for k, v in self.__dict__.items()}


SENSOR_CHECK = (0.1, 0.005)
"""A wrist sample may differ from the load the cable applied in the same step by this share of the
cable's weight plus this many newtons [N] (force) or newton metres [N m] (moment about the sensor
origin) before :class:`SensorCheck` fails it. It catches gross errors: loads on the hand the model does
not hold (a gripper pressed into the table: hundreds of newtons), a payload model that does not fit
the tool (a calibration gone wrong), inertia compensation switched off, a payload tared in the wrong
frame (the bug of issue 27: up to 34 cable weights). With the robot description's payload the
transmitted wrench and its compensation use the same momenta (:mod:`bullet_dlo.robots.sensors`), so
an unloaded hand reads zero in any motion and the mismatch is rounding (below 1e-12 N); it was 54 mN
for a Panda turning 90 degrees in 4 s and 1.7 N in 0.7 s with Bullet's joint reaction."""


class SensorCheck:
    """Every wrist sample compared with the load the cable applied to that gripper in the same step.

    The sensor's reading without its bias and noise must equal that load (force, and moment about
    the sensor origin): what the payload compensation and Bullet's wrist reaction get wrong shows up
    here. ``worst`` [N or N m] and ``worst_t`` [s] per arm and kind (force, moment), ``samples``, :attr:`rms`;
    :meth:`failures` says which exceed ``limit`` = share of the cable weight + absolute (:data:`SENSOR_CHECK`).

    This is the sensor-model comparison of record: recorded rows hold ``cable.end_forces()`` after the
    cable's step, the load of the *next* step (the coupling is explicit), so rows compared with each
    other differ by a step's change of the load, which a fast motion makes newtons.
    """

    def __init__(self, weight: float, limit: tuple[float, float] = SENSOR_CHECK):
        self.weight = float(weight)
        self.limit = limit
        self.worst = np.zeros((2, 2))
        self.worst_t = np.zeros((2, 2))
        self.samples = 0
        self._sumsq = np.zeros((2, 2))  # per arm: squared mismatch lengths summed, force [N^2], moment [N^2 m^2]
        self._kernel = None  # load_mismatch's machine code, bound on first use

    def check(self, arm: int, t: float, sensor: WristSensor, force, torque, point, held: bool) -> None:
        """Compare arm ``arm``'s sample at ``t`` [s] with the force [N] at ``point`` [m] and torque [N m] the
        cable applied to that gripper if it ``held`` it (else with no load)."""
        args = (sensor.rows, sensor.values, sensor.offset, force, torque, point, bool(held), float(t),
                self.worst[arm], self.worst_t[arm], self._sumsq[arm])
        if self._kernel is None:
            self._kernel = bind(load_mismatch, *args)
        self._kernel(*args)
        self.samples += arm == 0

    @property
    def rms(self) -> np.ndarray:
        """RMS length of the mismatch over both arms' samples, force [N] and moment [N m], (2,) (NaN before any)."""
        if not self.samples:
            return np.full(2, np.nan)
        return np.sqrt(self._sumsq.sum(axis=0) / (2 * self.samples))

    @property
    def allowed(self) -> float:
        """The largest mismatch allowed per component [N or N m]."""
        return self.limit[0] * self.weight + self.limit[1]

    def failures(self) -> list[str]:
        """Why the wrist readings should not be trusted, as short reasons (empty: they agree with the model)."""
        out = []
        for arm in (0, 1):
            for kind, (name, unit) in enumerate((("force", "N"), ("moment", "N m"))):
                if self.worst[arm, kind] > self.allowed:
                    out.append(f"{ARMS[arm]} wrist {name} differs from the cable's load by "
                               f"{self.worst[arm, kind]:.3g} {unit} at t = {self.worst_t[arm, kind]:.3f} s "
                               f"(allowed {self.allowed:.3g})")
        return out

    def summary(self) -> dict:
        """JSON-ready: worst force [N] and moment [N m] mismatch per arm, the allowed value, the failures."""
        return {"worst_force": self.worst[:, 0].tolist(), "worst_moment": self.worst[:, 1].tolist(),
                "allowed": self.allowed, "samples": self.samples, "failures": self.failures()}


NOISE_BLOCK = 240
"""Samples' noise each wrist sensor draws at once (one second at 240 Hz; the same numbers as a draw per sample)."""


class DualArmObservation:
    """Wrist sensors on both arms (settings from ``physics.spec``) and, optionally, the per-step record.

    Build it right after the physics, before the first step: the sensors tare on the arms'
    last settle step, taken before the cable was attached (as users zero an ATI sensor in the
    grasp pose before grasping). A dataset capture or an environment with its own recording
    passes ``record=False`` and reads ``sensors[i].last`` (a :class:`~bullet_dlo.robots.sensors.Wrench`)
    from its own ``world.after_step`` hook. One observation per physics.
    """

    def __init__(self, physics: DualArmPhysics, record: bool = True):
        if physics.world.steps:
            raise ParameterError("build the observation before the first step: its sensors tare on the unloaded arms")
        spec = physics.spec
        self.physics = physics
        fits = physics.payload_fits or (None, None)
        self.sensors = [WristSensor(robot, physics.world.gravity, spec.sensor_rate, spec.noise_std, spec.bias,
                                    payload=fits[k], rng=np.random.default_rng(spec.seed + k),
                                    contacts=physics.world.contacts, reader=physics.reader, row=k,
                                    noise_block=NOISE_BLOCK)  # their generators are their own
                        for k, robot in enumerate(physics.robots)]
        for s in self.sensors:
            s.tare()
        self._sampled = np.zeros(2, dtype=np.bool_)  # which sensor sampled in the last step
        self._arm_bodies = frozenset(s.robot.body for s in self.sensors)
        self._pair = None  # wrist_pair's machine code, bound on first use
        self.check = SensorCheck(spec.cable.mass * float(np.linalg.norm(physics.world.gravity)))
        self.record = DualArmRecord()
        physics.observation = self  # the physics samples the sensors in its read phase
        if record:
            physics.world.after_step.append(self._record_step)

    def read_sensors(self) -> None:
        """Sample the wrist sensors after the Bullet step (phase 4 of the dual-arm step, see
        :mod:`~bullet_dlo.robots.dual_arm.physics`) and check them against the loads the cable applied."""
        world, physics = self.physics.world, self.physics
        t = world.time
        # what the cable applied in the Bullet step just taken: its step (after these hooks) replaces them
        forces, torques = physics.cable.planned_end_loads()
        points, held = physics.load_points, physics.held
        s0, s1 = self.sensors
        # without contacts in the step the kernel writes the cable's loads itself; with some, they are written
        # here and _prepare adds Bullet's contacts on the tool (the same order of additions either way)
        model = self._model_tool_loads()  # the cable contact model's reactions on the tool links (None: none)
        fill = model is None and not world.contacts()
        if fill:  # the common step: nothing touched the tools, nothing to add before the kernel
            due0, off0 = s0._prepare(t, False)
            due1, off1 = s1._prepare(t, False)
            held_c = (bool(held[0]), bool(held[1]))
        else:
            forces, torques, points, held_c, (due0, off0), (due1, off1) = self._tool_loads(
                t, forces, torques, points, held, model)
        # both sensors' kernels (transmitted wrench, reading, check against the cable's load) in one call; the
        # sensors' own arrays (filled in place) paired once
        check, sampled = self.check, self._sampled
        if self._pair is None:
            self._arrays = ((s0._rows, s1._rows), (s0._tool, s1._tool), (s0._tool_memory, s1._tool_memory),
                            (s0._applied, s1._applied), (s0._reaction, s1._reaction))
            self._arrays2 = ((s0._tare, s1._tare),)
            self._arrays3 = ((s0._memory, s1._memory), (s0._scratch, s1._scratch))
        args = (*self._arrays, (s0.payload, s1.payload), float(world.dt), (s0.compensate_inertia, s1.compensate_inertia),
                (due0, due1), *self._arrays2, (off0, off1), *self._arrays3, forces, torques, points, held_c,
                (fill, fill), float(t), check.worst, check.worst_t, check._sumsq, sampled)
        if self._pair is None:
            self._pair = bind(wrist_pair, *args)
        self._pair(*args)
        if sampled[0]:
            s0._sampled(t, off0)
            check.samples += 1
        if sampled[1]:
            s1._sampled(t, off1)

    def _tool_loads(self, t: float, forces, torques, points, held, model):
        """A step with Bullet's contacts or the contact model's reactions on a tool: each sensor's applied loads
        (the held end's, the model's push, then in _prepare Bullet's contacts) written before the kernel, and the
        check's expected load (held end plus the model's push, moments about 0). Returns the kernel's forces,
        torques, points, held flags and both sensors' (due, offset)."""
        prepared = []
        for arm, s in enumerate(self.sensors):
            applied = s._applied  # the library's loads on the tool side
            if held[arm]:  # the cable's force at its end mass and its clamp torque, as a moment about 0
                applied[:3] = forces[arm]
                applied[3:] = torques[arm] + cross3(points[arm], forces[arm])  # np.cross's bits, 1/10 its cost
            else:
                applied[:] = 0.0
            if model is not None:
                applied += model[arm]
            prepared.append(s._prepare(t))
        held_c = (bool(held[0]), bool(held[1]))
        if model is not None:
            force_c, torque_c, points_c = np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3))
            for arm in range(2):
                if held[arm]:
                    force_c[arm] = forces[arm]
                    torque_c[arm] = torques[arm] + cross3(points[arm], forces[arm])
                force_c[arm] += model[arm, :3]
                torque_c[arm] += model[arm, 3:]
            forces, torques, points, held_c = force_c, torque_c, points_c, (True, True)
        return forces, torques, points, held_c, prepared[0], prepared[1]

    def _model_tool_loads(self) -> np.ndarray | None:
        """The reactions the cable's contact model applied to each arm's tool-side links (below the sensor joint)
        in the Bullet step just taken, (2, 6): force [N] and moment about the world origin [N m], world frame; None
        when it touched no tool link. They reach the links by applyExternalForce, which the sensor's Newton-Euler
        does not see otherwise (a hand pushed by the cable read 0 N: tests/robots/test_arm_contact.py)."""
        cable = self.physics.cable
        cs = cable._contact_set
        if cs is None:
            return None
        count = int(cs.contacts.count[0])
        if count == 0:
            return None
        # contacts on the obstacles only (a cable on a peg): no arm touched, nothing to sum (per_contact costs 15 us)
        ids, arms = cs.body_ids, self._arm_bodies  # contact k's body: body_ids[shape k] for shapes >= 0
        if not len(ids) or not any(s >= 0 and int(ids[s]) in arms for s in cs.store.body[:count].tolist()):
            return None
        pc = cable.contact_forces()  # still the contacts whose reactions were applied in that step
        out, hit = np.zeros((2, 6)), False
        for arm, s in enumerate(self.sensors):
            sel = (pc["body"] == s.robot.body) & np.isin(pc["link"], list(s._tool_links))
            if sel.any():
                f = -pc["force"][sel]  # on the links, at the contact points
                out[arm, :3] = f.sum(axis=0)
                out[arm, 3:] = np.cross(pc["point"][sel], f).sum(axis=0)
                hit = True
        return out if hit else None

    def _record_step(self) -> None:
        r, cable = self.record, self.physics.cable
        r.t.append(self.physics.world.time)
        r.wrench_world.append([s.last.world() for s in self.sensors])
        r.end_forces.append(cable.end_forces())
        r.end_moments.append(cable.end_moments())
        r.grasp_pos.append(cable.holder_positions())
        r.cable_end_pos.append([cable.x[node].copy() for node in END_NODE])

    def window_mean(self, seconds: float = 0.5) -> dict[str, np.ndarray]:
        """Averages over the last ``seconds`` [s] of the record: sensor wrench in world (2, 6), end forces (2, 3)."""
        rec = self.record.arrays()
        if not len(rec["t"]):
            raise ParameterError("window_mean: nothing recorded yet (run the scene first)")
        sel = rec["t"] >= rec["t"][-1] - check_positive("window", seconds) + 1e-12
        return {"wrench_world": rec["wrench_world"][sel].mean(axis=0),
                "end_forces": rec["end_forces"][sel].mean(axis=0)}
