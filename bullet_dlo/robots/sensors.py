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

from bullet_dlo.core.timing import RateGate
from bullet_dlo.core.validate import ParameterError, check_nonnegative
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.transforms import rotation


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
    """

    def __init__(self, robot: Robot, rate: float | None = None, noise_std=(0.0,) * 6, bias=(0.0,) * 6,
                 compensate_inertia: bool = True, rng: np.random.Generator | None = None):
        name = robot.spec.sensor_joint
        if name not in robot.joint_index:
            raise ParameterError(f"robot {robot.spec.name!r} has no joint {name!r} for the F/T sensor")
        self.robot = robot
        self.joint = robot.joint_index[name]
        self.gate = RateGate(rate)
        self.noise_std = np.array([check_nonnegative("noise_std", v) for v in noise_std], dtype=float)
        self.bias = np.asarray(bias, dtype=float)
        if self.noise_std.shape != (6,) or self.bias.shape != (6,):
            raise ParameterError("noise_std and bias must have 6 components (fx fy fz mx my mz)")
        self.compensate_inertia = compensate_inertia
        self.rng = rng or np.random.default_rng(0)
        c = robot.client
        self.payload = robot.subtree_links(self.joint)  # the tool side: links the sensor carries
        self.payload_mass = np.array([pb.getDynamicsInfo(robot.body, j, physicsClientId=c)[0] for j in self.payload])
        self._tare = np.zeros(6)
        self._momentum_prev: np.ndarray | None = None  # payload momentum [kg m/s] one step ago
        self._last: Wrench | None = None

    # ----- raw physics ------------------------------------------------------------------------
    def raw(self) -> np.ndarray:
        """Wrench the arm applies to the tool side, sensor frame, as PyBullet reports it, shape (6,)."""
        return np.array(pb.getJointState(self.robot.body, self.joint, physicsClientId=self.robot.client)[2])

    def _rotation(self) -> np.ndarray:
        """Sensor frame (the child link's centre-of-mass frame) to world, (3, 3)."""
        st = pb.getLinkState(self.robot.body, self.joint, computeForwardKinematics=True,
                             physicsClientId=self.robot.client)
        return rotation(st[1])

    def _inertial_force(self, dt: float) -> np.ndarray:
        """Payload's sum of m a [N] in world, from the change of its momentum over the last step dt [s]."""
        states = pb.getLinkStates(self.robot.body, self.payload, computeLinkVelocity=True,
                                  physicsClientId=self.robot.client)
        momentum = self.payload_mass @ np.array([s[6] for s in states])  # sum of m v over the payload links
        prev, self._momentum_prev = self._momentum_prev, momentum
        return np.zeros(3) if prev is None else (momentum - prev) / dt

    def tare(self) -> None:
        """Zero the sensor in the current (reference) pose: later readings are relative to it."""
        self._tare = self.raw()
        self._momentum_prev = None

    # ----- readings ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> Wrench:
        """Sample (if due at the sensor's rate) and return the current reading at time t [s].

        dt: physics step [s] (for the payload acceleration of the inertia compensation,
        tracked at every step, sampled or not).
        """
        inertial = self._inertial_force(dt) if self.compensate_inertia else np.zeros(3)
        if not self.gate.due(t):
            return self._last  # held between samples
        rot = self._rotation()
        tared = self.raw() - self._tare
        # the load on the tool side is minus what the arm must apply (statics of the tool)
        f_sensor = -tared[:3] + rot.T @ inertial
        m_sensor = -tared[3:]
        noisy = np.concatenate([f_sensor, m_sensor]) + self.bias + self.rng.normal(size=6) * self.noise_std
        self._last = Wrench(t, noisy[:3], noisy[3:], rot @ noisy[:3], rot @ noisy[3:])
        return self._last

    @property
    def rate(self) -> float | None:
        """Sampling rate [Hz] (None: every physics step)."""
        return self.gate.rate

    @property
    def last(self) -> Wrench | None:
        """The latest reading (None before the first :meth:`update`)."""
        return self._last
