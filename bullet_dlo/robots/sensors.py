"""Wrist force/torque sensors that behave like real ones (tare, rate, noise, bias).

PyBullet reports, for a joint with ``enableJointForceTorqueSensor``, the wrench the parent
link applies to the child through the joint, in the child link's centre-of-mass frame
(moments about that centre of mass). A :class:`WristSensor` turns that into what a user of
an ATI-style sensor sees: the load on the tool side, zeroed by a tare taken in a reference
pose, sampled at the sensor's own rate, with optional Gaussian noise and bias, in the
sensor frame and in the world frame. Sampling follows :class:`~bullet_dlo.core.timing.RateGate`,
the rule video and dataset frames follow too: samples on the grid start + k / rate, the
reading held in between.

Sign convention of the forces in a :class:`Wrench`: the load applied to the tool side, e.g. the force
the held cable pulls on the gripper (a hanging cable gives a negative z force in world).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.kernels import bind
from bullet_dlo.bullet.native import StateReader
from bullet_dlo.core.timing import RateGate
from bullet_dlo.core.validate import ParameterError, check_nonnegative
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.kernels import momentum, sensor_reading


@dataclass(frozen=True)
class Wrench:
    """One F/T reading.

    t: time [s]; force [N] and torque [N m] (about the sensor frame origin) of the load on the
    tool side, in the sensor frame (``*_sensor``) and in the world frame (``*_world``).
    """

    t: float
    force_sensor: np.ndarray
    torque_sensor: np.ndarray
    force_world: np.ndarray
    torque_world: np.ndarray

    def world(self) -> np.ndarray:
        """[fx, fy, fz, mx, my, mz] in world frame."""
        return np.concatenate([self.force_world, self.torque_world])

    def sensor(self) -> np.ndarray:
        """[fx, fy, fz, mx, my, mz] in the sensor frame."""
        return np.concatenate([self.force_sensor, self.torque_sensor])


def payload(robot: Robot) -> tuple[list[int], np.ndarray]:
    """The tool side of ``robot``'s sensor joint: its links (the sensor's own first) and their masses [kg]."""
    links = robot.subtree_links(robot.joint_index[robot.spec.sensor_joint])
    return links, np.array([pb.getDynamicsInfo(robot.body, j, physicsClientId=robot.client)[0] for j in links])


def sensor_links(robot: Robot) -> list[int]:
    """Links a wrist sensor reads every step: its own (the sensor frame) and the payload links with mass."""
    links, mass = payload(robot)
    return [j for k, j in enumerate(links) if k == 0 or mass[k] > 0]


class WristSensor:
    """F/T sensor on ``robot``'s sensor joint (whose reaction reporting :meth:`Robot.load` switched on).

    Args:
        robot: the arm.
        rate: sampling rate [Hz] (None: every physics step); readings are held between samples.
        noise_std: standard deviation of Gaussian noise per component [N, N, N, N m, N m, N m].
        bias: constant offset added to every reading (same units).
        compensate_inertia: subtract the payload's inertial force m a (from link velocities),
            as a calibrated sensor with a known tool would; the tare removes its weight.
        rng: random generator for the noise (seeded for reproducible data).
        reader: a :class:`~bullet_dlo.bullet.native.StateReader` that its owner reads every step
            (e.g. the dual-arm coupling, which reads both arms in one call), whose row ``row`` holds
            the robot with :func:`sensor_links` last; None: the sensor reads for itself.
    """

    def __init__(self, robot: Robot, rate: float | None = None, noise_std=(0.0,) * 6, bias=(0.0,) * 6,
                 compensate_inertia: bool = True, rng: np.random.Generator | None = None,
                 reader: StateReader | None = None, row: int = 0):
        name = robot.spec.sensor_joint
        if name not in robot.joint_index:
            raise ParameterError(f"robot {robot.spec.name!r} has no joint {name!r} for the F/T sensor")
        self.robot = robot
        self.joint = robot.joint_index[name]
        self.gate = RateGate(rate)
        self.noise_std = np.array([check_nonnegative("noise_std", v) for v in noise_std], dtype=float)
        self.bias = np.array(bias, dtype=float)
        if self.noise_std.shape != (6,) or self.bias.shape != (6,):
            raise ParameterError("noise_std and bias must have 6 components (fx fy fz mx my mz)")
        self.compensate_inertia = bool(compensate_inertia)
        self.rng = rng or np.random.default_rng(0)
        self.payload, self.payload_mass = payload(robot)
        links = sensor_links(robot)
        self._mass = np.array([self.payload_mass[self.payload.index(j)] for j in links])
        # link states of the queried links and the joint's state: a shared reader (read by its owner
        # every step, e.g. the dual-arm coupling, these links last in its row) or one of our own
        self._own_reader = reader is None
        self.reader = reader or StateReader(robot.client, 0, [robot.body], [links], [self.joint])
        if self.reader.bodies[row] != robot.body or list(self.reader.links[row, -len(links):]) != links:
            raise ParameterError("the shared state reader must hold the sensor's links last in the arm's row")
        self._rows = self.reader.link_rows[row, -len(links):]
        self._reaction = self.reader.joint_rows[row, 2:8]
        self._noisy = bool(np.any(self.noise_std > 0))  # no noise: no draws (the generator is used only here)
        self._tare = np.zeros(6)
        self._prev = np.zeros(4)  # payload momentum [kg m/s] one step ago, and whether it is valid
        self._scratch = np.zeros(12)
        self._last: Wrench | None = None
        self._reading = bind(sensor_reading, self._rows, self._mass, self._reaction, 1.0, True, True, self._tare,
                             self.bias, self._prev, self._scratch)  # no per-call type dispatch

    # ----- raw physics ------------------------------------------------------------------------
    def raw(self) -> np.ndarray:
        """Wrench the arm applies to the tool side, sensor frame, as PyBullet reports it, shape (6,)."""
        return np.array(pb.getJointState(self.robot.body, self.joint, physicsClientId=self.robot.client)[2])

    def payload_momentum(self) -> np.ndarray:
        """Sum of m v over the payload (the tool side's links) [kg m/s], world frame, now, (3,)."""
        self.reader.read()
        out = np.zeros(3)
        momentum(self._rows, self._mass, out)
        return out

    def tare(self) -> None:
        """Zero the sensor in the current (reference) pose: later readings are relative to it."""
        self._tare[:] = self.raw()
        self._prev[:] = 0.0

    # ----- readings ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> Wrench:
        """Sample (if due at the sensor's rate) and return the current reading at time t [s].

        dt: physics step [s] (for the payload acceleration of the inertia compensation,
        tracked at every step, sampled or not). The arithmetic is one compiled call
        (:func:`~bullet_dlo.robots.kernels.sensor_reading`); a shared reader is read by its owner
        before this runs.
        """
        if self._own_reader:
            self.reader.read()
        due = self.gate.due(t)
        offset = self.bias
        if due and self._noisy:
            offset = self.bias + self.rng.normal(size=6) * self.noise_std
        out = self._scratch
        if not self._reading(self._rows, self._mass, self._reaction, float(dt), self.compensate_inertia, due,
                             self._tare, offset, self._prev, out):
            return self._last  # held between samples
        values = out.copy()  # one array, four views
        self._last = Wrench(t, values[0:3], values[3:6], values[6:9], values[9:12])
        return self._last

    @property
    def rate(self) -> float | None:
        """Sampling rate [Hz] (None: every physics step)."""
        return self.gate.rate

    @property
    def last(self) -> Wrench | None:
        """The latest reading (None before the first :meth:`update`)."""
        return self._last
