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
        self.payload = robot.subtree_links(self.joint)  # the tool side: links the sensor carries, its own first
        self.payload_mass = np.array([pb.getDynamicsInfo(robot.body, j, physicsClientId=c)[0] for j in self.payload])
        # links queried every step: the sensor's own (its orientation) and those with mass (the momentum)
        self._queried = [j for k, j in enumerate(self.payload) if k == 0 or self.payload_mass[k] > 0]
        self._payload_mass = [float(self.payload_mass[self.payload.index(j)]) for j in self._queried]
        self._bias_list = self.bias.tolist()
        self._noisy = bool(np.any(self.noise_std > 0))  # no noise: no draws (the generator is used only here)
        self._tare = np.zeros(6)
        self._tare_list = [0.0] * 6
        self._momentum_prev: tuple[float, float, float] | None = None  # payload momentum [kg m/s] one step ago
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

    def _payload_states(self) -> tuple:
        """PyBullet's link states, with velocities, of the sensor's own link and the payload links with mass."""
        return pb.getLinkStates(self.robot.body, self._queried, computeLinkVelocity=True,
                                computeForwardKinematics=True, physicsClientId=self.robot.client)

    def _inertial_force(self, states: tuple, dt: float) -> tuple[float, float, float]:
        """Payload's sum of m a [N] in world, from the change of its momentum over the last step dt [s].

        states: :meth:`_payload_states` now. Plain floats: the payload has a handful of links and
        this runs every physics step, where numpy's per-call cost (a few microseconds) would
        exceed the arithmetic many times over.
        """
        px, py, pz = self._momentum(states)
        prev, self._momentum_prev = self._momentum_prev, (px, py, pz)
        if prev is None:
            return 0.0, 0.0, 0.0
        return (px - prev[0]) / dt, (py - prev[1]) / dt, (pz - prev[2]) / dt

    def payload_momentum(self) -> np.ndarray:
        """Sum of m v over the payload (the tool side's links) [kg m/s], world frame, now, (3,)."""
        return np.array(self._momentum(self._payload_states()))

    def _momentum(self, states: tuple) -> tuple[float, float, float]:
        """Sum of m v [kg m/s] over the payload links, from their :meth:`_payload_states`."""
        px = py = pz = 0.0
        for m, s in zip(self._payload_mass, states):
            v = s[6]
            px += m * v[0]
            py += m * v[1]
            pz += m * v[2]
        return px, py, pz

    def tare(self) -> None:
        """Zero the sensor in the current (reference) pose: later readings are relative to it."""
        self._tare = self.raw()
        self._tare_list = self._tare.tolist()
        self._momentum_prev = None

    # ----- readings ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> Wrench:
        """Sample (if due at the sensor's rate) and return the current reading at time t [s].

        dt: physics step [s] (for the payload acceleration of the inertia compensation,
        tracked at every step, sampled or not). Per-step code: scalar arithmetic on the
        tuples PyBullet returns, one numpy array per reading (the Wrench fields are views of it).
        """
        if self.compensate_inertia:
            states = self._payload_states()  # one call: velocities for the inertia, the sensor link's orientation
            inertial = self._inertial_force(states, dt)
            if not self.gate.due(t):
                return self._last  # held between samples
            quat = states[0][1]
        else:
            if not self.gate.due(t):
                return self._last
            inertial = (0.0, 0.0, 0.0)
            quat = pb.getLinkState(self.robot.body, self.joint, computeForwardKinematics=True,
                                   physicsClientId=self.robot.client)[1]
        robot = self.robot
        raw = pb.getJointState(robot.body, self.joint, physicsClientId=robot.client)[2]
        r = pb.getMatrixFromQuaternion(quat)  # row-major 3x3, sensor frame -> world
        ax, ay, az = inertial
        tare = self._tare_list
        # the load on the tool side is minus what the arm must apply (statics of the tool); inertia in sensor frame
        w = [tare[0] - raw[0] + (r[0] * ax + r[3] * ay + r[6] * az),
             tare[1] - raw[1] + (r[1] * ax + r[4] * ay + r[7] * az),
             tare[2] - raw[2] + (r[2] * ax + r[5] * ay + r[8] * az),
             tare[3] - raw[3], tare[4] - raw[4], tare[5] - raw[5]]
        bias = self._bias_list
        w = [w[k] + bias[k] for k in range(6)]
        if self._noisy:
            w = (np.array(w) + self.rng.normal(size=6) * self.noise_std).tolist()
        fx, fy, fz, mx, my, mz = w
        f_world = [r[0] * fx + r[1] * fy + r[2] * fz, r[3] * fx + r[4] * fy + r[5] * fz,
                   r[6] * fx + r[7] * fy + r[8] * fz]
        m_world = [r[0] * mx + r[1] * my + r[2] * mz, r[3] * mx + r[4] * my + r[5] * mz,
                   r[6] * mx + r[7] * my + r[8] * mz]
        values = np.array(w + f_world + m_world)  # one array, four views: this runs twice per step
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
