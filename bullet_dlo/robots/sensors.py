"""Wrist force/torque sensors that behave like real ones (tare, rate, noise, bias).

A real F/T sensor measures the wrench the arm transmits to the tool side through the sensor
joint; users remove the payload (hand, fingers) below it as a world-frame weight plus its
inertial load, and tare the sensor's own offset. A :class:`WristSensor` does the same, in this
order: the transmitted wrench (:func:`~bullet_dlo.robots.kernels.tool_reaction`), the payload's
weight and inertia removed (from the robot description, or a calibration,
:func:`identify_payload`), the tare, sampled at the sensor's own rate with optional Gaussian
noise and bias, in the sensor frame and in the world frame. Sampling follows
:class:`~bullet_dlo.core.timing.RateGate`, the rule video and dataset frames follow too: samples on
the grid start + k / rate, the reading held in between.

The transmitted wrench is computed by Newton-Euler of the tool side (its links' rates of momentum,
minus their weights, minus every other load on them: the held cable's, Bullet's contacts), not
taken from Bullet's joint reaction (:meth:`WristSensor.raw`). Bullet computes that reaction in
two articulated-body passes per step, and its second (constraint) pass adds the links'
velocity-product terms (Coriolis, gyroscopic) a second time (``btMultiBody::
computeAccelerationsArticulatedBodyAlgorithmMultiDof`` with ``isConstraintPass``): right at rest,
wrong by a load growing as the square of the turn rate and independent of the step (a Panda hand
turned 90 degrees in 0.7 s read 1.7 N off, six times a 30 g cable's weight). The cost: loads applied
to the tool side outside this library (your own ``applyExternalForce`` on a hand link, a constraint
you attach to it) are not seen; contacts are.

Sign convention of the forces in a :class:`Wrench`: the load applied to the tool side, e.g. the force
the held cable pulls on the gripper (a hanging cable gives a negative z force in world).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.kernels import bind
from bullet_dlo.bullet.native import StateReader
from bullet_dlo.config.robot import PAYLOADS
from bullet_dlo.core.timing import RateGate
from bullet_dlo.core.validate import ParameterError, check_nonnegative
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.kernels import Payload, SensorMemory, momentum, sensor_reading, tool_reaction


@dataclass(frozen=True)
class Wrench:
    """One F/T reading.

    t: time [s]; force_sensor [N], torque_sensor [N m]: the load on the tool side, torque about the
    sensor frame origin, in the sensor frame; force_world [N], torque_world [N m]: the same in the world
    frame; each (3,).
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


def sensor_links(robot: Robot) -> list[int]:
    """Links a wrist sensor reads every step, of the tool side of ``robot``'s sensor joint (the links it
    carries): its own (the sensor frame) and the links with mass or
    rotational inertia (a massless link with inertia, as the Panda's grasp target with 0.1 kg m^2, still
    takes a torque to turn)."""
    links = robot.subtree_links(robot.joint_index[robot.spec.sensor_joint])
    infos = [pb.getDynamicsInfo(robot.body, j, physicsClientId=robot.client) for j in links]
    return [j for k, (j, info) in enumerate(zip(links, infos)) if k == 0 or info[0] > 0 or sum(info[2]) > 0]


COMPENSATIONS = PAYLOADS
"""How a wrist sensor knows its payload (the scene's ``arms.payload``): ``urdf``: every tool-side link's mass, centre of mass and
inertia from the robot description; ``calibrated``: mass and centre of mass identified from unloaded
readings at several orientations (:func:`identify_payload`), then the rotational inertia from swings of
the wrist (:func:`identify_inertia`), as users of real F/T sensors do."""


def urdf_payload(robot: Robot, gravity: Sequence[float]) -> Payload:
    """The tool side below ``robot``'s sensor as the robot description gives it: per link of
    :func:`sensor_links`, mass [kg] and principal inertia [kg m^2] (Bullet's CoM frame); gravity [m/s^2]."""
    infos = [pb.getDynamicsInfo(robot.body, j, physicsClientId=robot.client) for j in sensor_links(robot)]
    return Payload(np.array([i[0] for i in infos], dtype=float), np.zeros((len(infos), 3)),
                   np.array([i[2] for i in infos], dtype=float), np.array(gravity, dtype=float))


@dataclass(frozen=True)
class PayloadFit:
    """A payload identified from unloaded sensor readings (:func:`identify_payload` at rest, then
    :func:`identify_inertia` while the wrist swings).

    mass [kg]; com [m]: its centre of mass in the sensor frame; force_offset [N], moment_offset
    [N m]: the sensor's own offset (sensor frame); rms_force [N], rms_moment [N m]: residuals of the
    static fit; orientations: how many readings it used; inertia [kg m^2]: its principal moments of
    inertia about its centre of mass along the sensor frame's axes (zero: not identified).
    """

    mass: float
    com: tuple[float, float, float]
    force_offset: tuple[float, float, float]
    moment_offset: tuple[float, float, float]
    rms_force: float
    rms_moment: float
    orientations: int
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def payload(self, gravity: Sequence[float]) -> Payload:
        """As the sensor kernel takes it: one body on the sensor's own row (its rotational inertia along the
        sensor frame's axes)."""
        return Payload(np.array([self.mass]), np.array([self.com]), np.array([self.inertia], dtype=float),
                       np.array(gravity, dtype=float))


def identify_payload(rotations: np.ndarray, reactions: np.ndarray, gravity: Sequence[float]) -> PayloadFit:
    """Mass and centre of mass of a sensor's payload, and the sensor's offset, by least squares.

    rotations (m, 3, 3): the sensor frame's orientation (sensor -> world) at m rest poses without
    load; reactions (m, 6): the sensor joint's reaction then (what the arm applies, sensor frame,
    moments about the sensor frame's origin); gravity [m/s^2] (3,). At rest the arm carries the
    payload's weight: -f = M R^T g + f0 and -m = (M c) x (R^T g) + m0, linear in M, f0 and M c, m0.
    At least three orientations not about one axis are needed (ParameterError otherwise).
    """
    rot = np.asarray(rotations, dtype=float)
    react = np.asarray(reactions, dtype=float)
    g_sensor = np.einsum("kji,j->ki", rot, np.asarray(gravity, dtype=float))  # R^T g per pose
    m = len(rot)
    eye = np.tile(np.eye(3), (m, 1))
    a_force = np.hstack([g_sensor.reshape(-1, 1), eye])
    mass, *f0 = np.linalg.lstsq(a_force, -react[:, :3].reshape(-1), rcond=None)[0]
    a_moment = np.hstack([np.concatenate([-skew(v) for v in g_sensor]), eye])  # (Mc) x g = -g x (Mc)
    sol_m = np.linalg.lstsq(a_moment, -react[:, 3:].reshape(-1), rcond=None)[0]
    if m < 3 or np.linalg.matrix_rank(a_moment[:, :3], tol=1e-3 * np.linalg.norm(gravity)) < 3 or mass <= 0:
        raise ParameterError(f"identify_payload: {m} orientations do not determine the payload (need >= 3, "
                             f"not all about one axis)")
    com = sol_m[:3] / mass
    res_f = a_force @ np.r_[mass, f0] + react[:, :3].reshape(-1)
    res_m = a_moment @ sol_m + react[:, 3:].reshape(-1)
    return PayloadFit(float(mass), tuple(float(v) for v in com), tuple(float(v) for v in f0),
                      tuple(float(v) for v in sol_m[3:]), float(np.sqrt(np.mean(res_f ** 2))),
                      float(np.sqrt(np.mean(res_m ** 2))), m)


def identify_inertia(fit: PayloadFit, rotations: np.ndarray, accelerations: np.ndarray,
                     angular_accelerations: np.ndarray, moments: np.ndarray, gravity: Sequence[float]) -> PayloadFit:
    """``fit`` with the payload's rotational inertia identified, by least squares, from readings while the
    wrist swings, taken where it turns back (angular velocity near zero, angular acceleration large).

    rotations (m, 3, 3): the sensor frame's orientation (sensor -> world); accelerations (m, 3) [m/s^2],
    angular_accelerations (m, 3) [rad/s^2]: the sensor frame origin's, world frame; moments (m, 3) [N m]: the
    sensor joint's reaction moment then (sensor frame, about its origin); gravity [m/s^2] (3,). With no
    angular velocity the arm applies m = J alpha + M c x (a + alpha x c - g) - m0 (sensor frame, ``fit``'s
    M, c and m0), linear in the principal moments of J along the sensor frame's axes, each fitted on its own.
    Bullet's joint reaction is right here, as at rest: its error while the links turn is of their velocities
    (see the module doc). Moments the swings did not excite stay zero; a negative fit (noise) is clipped to zero.
    """
    rot = np.asarray(rotations, dtype=float)
    to_sensor = lambda v: np.einsum("kji,kj->ki", rot, np.asarray(v, dtype=float))  # noqa: E731  R^T v per row
    alpha, acc = to_sensor(angular_accelerations), to_sensor(accelerations)
    g = np.einsum("kji,j->ki", rot, np.asarray(gravity, dtype=float))
    c = np.asarray(fit.com, dtype=float)
    lever = fit.mass * np.cross(c, acc + np.cross(alpha, c) - g)
    rest = np.asarray(moments, dtype=float) - lever + np.asarray(fit.moment_offset, dtype=float)  # = J alpha
    den = np.einsum("ki,ki->i", alpha, alpha)
    excited = den > 1e-6 * max(float(den.max()), 1e-300)
    inertia = np.where(excited, np.einsum("ki,ki->i", alpha, rest) / np.where(excited, den, 1.0), 0.0)
    return replace(fit, inertia=tuple(float(max(v, 0.0)) for v in inertia))


def skew(v: Sequence[float]) -> np.ndarray:
    """The matrix of the cross product v x ., (3, 3)."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


class WristSensor:
    """F/T sensor on ``robot``'s sensor joint (whose reaction reporting :meth:`Robot.load` switched on).

    The reading is the load on the tool side: what the arm applies to it, minus the payload's own
    weight (world-frame gravity, so at any orientation) and inertia, minus the sensor's own offset
    taken by :meth:`tare`. The payload is the tool side below the sensor (hand, fingers, grasp frame).

    Args:
        robot: the arm.
        gravity: the world's gravity [m/s^2] (3,).
        rate: sampling rate [Hz] (None: every physics step); readings are held between samples.
        noise_std: standard deviation of Gaussian noise per component [N, N, N, N m, N m, N m].
        bias: constant offset added to every reading (same units).
        compensate_inertia: also remove the payload's inertial load (rates of its momenta, from link
            velocities), as a calibrated sensor with a known tool would.
        payload: the payload's model (:class:`PayloadFit` from a calibration); None: from the robot
            description (:func:`urdf_payload`).
        rng: random generator for the noise (seeded for reproducible data).
        contacts: returns the contact points of the step just taken as an unfiltered
            ``pybullet.getContactPoints()`` gives them (e.g. :meth:`~bullet_dlo.bullet.world.BulletWorld.contacts`,
            one query per step for the world); None: the sensor makes that query itself.
        reader: a :class:`~bullet_dlo.bullet.native.StateReader` that its owner reads every step
            (e.g. the dual-arm coupling, which reads both arms in one call), whose row ``row`` holds
            the robot with :func:`sensor_links` last; None: the sensor reads for itself.
        noise_block: samples' noise drawn from ``rng`` at once (the same numbers in the same order as one draw
            per sample; for a generator nobody else draws from, e.g. the dual-arm sensors' own): 1 draws per sample.
    """

    TRANSMITTED = "newton_euler"
    """How the transmitted wrench is computed (recorded with episodes and rollouts as ``sensor_transmitted``;
    files without it took Bullet's joint reaction, off while a hand turned: see the module doc)."""

    TARE_WARNING = 0.01
    """A tare that removes more than this share of the payload's weight means the payload model does
    not fit the sensed tool (a wrong mass, centre of mass or gravity): warned."""

    def __init__(self, robot: Robot, gravity: Sequence[float], rate: float | None = None, noise_std=(0.0,) * 6,
                 bias=(0.0,) * 6, compensate_inertia: bool = True, payload: PayloadFit | None = None,
                 rng: np.random.Generator | None = None, contacts: Callable[[], Sequence] | None = None,
                 reader: StateReader | None = None, row: int = 0, noise_block: int = 1):
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
        self.compensation = "urdf" if payload is None else "calibrated"
        self.payload = urdf_payload(robot, gravity) if payload is None else payload.payload(gravity)
        links = sensor_links(robot)
        # link states of the queried links and the joint's state: a shared reader (read by its owner
        # every step, e.g. the dual-arm coupling, these links last in its row) or one of our own
        self._own_reader = reader is None
        self.reader = reader or StateReader(robot.client, 0, [robot.body], [links], [self.joint])
        if self.reader.bodies[row] != robot.body or list(self.reader.links[row, -len(links):]) != links:
            raise ParameterError("the shared state reader must hold the sensor's links last in the arm's row")
        self._rows = self.reader.link_rows[row, -len(links):]
        # the transmitted wrench, by Newton-Euler of the tool side as the robot description gives it
        self._tool = urdf_payload(robot, gravity)
        self._tool_memory = SensorMemory(np.zeros((len(links), 6)), np.zeros(1))
        self._tool_links = frozenset(robot.subtree_links(self.joint))  # contacts on these load the tool
        # unfiltered: a query filtered by body swaps A and B where Bullet's pair has the body second, and
        # then turns the normal but not the friction directions (PyBullet's processRequestContactpoint)
        self._contacts = contacts or (lambda: pb.getContactPoints(physicsClientId=robot.client))
        self._applied = np.zeros(6)  # loads on the tool side in the last step, world frame [N, N m about 0]
        self._reaction = np.zeros(6)  # what the arm applied to the tool side, sensor frame
        self._transmit = bind(tool_reaction, self._rows, self._tool, 1.0, self._tool_memory, self._applied,
                              self._reaction)
        self._noisy = bool(np.any(self.noise_std > 0))  # no noise: no draws (the generator is used only here)
        self.noise_block = max(1, int(noise_block))
        self._noise_rows: np.ndarray | None = None  # bias plus noise of the coming samples (noise_block > 1)
        self._noise_next = 0
        self._tare = np.zeros(6)
        self._memory = SensorMemory(np.zeros((len(self.payload.mass), 6)), np.zeros(1))
        self._scratch = np.zeros(12)
        self.offset = np.zeros(6)  # bias plus noise of the latest sample [N, N m], sensor frame
        self.values = np.zeros(12)  # the latest sample: [f, m] sensor frame, [f, m] world frame
        self._last: Wrench | None = None
        self._last_t: float | None = None  # time [s] of the latest sample (None before the first)
        self._reading = bind(sensor_reading, self._rows, self.payload, self._reaction, 1.0, True, True, self._tare,
                             self.bias, self._memory, self._scratch)  # no per-call type dispatch

    # ----- raw physics ------------------------------------------------------------------------
    def raw(self) -> np.ndarray:
        """Wrench the arm applies to the tool side, sensor frame, as Bullet's joint reaction reports it
        (right at rest; off while the tool turns, see the module doc), shape (6,)."""
        return np.array(pb.getJointState(self.robot.body, self.joint, physicsClientId=self.robot.client)[2])

    def payload_momentum(self) -> np.ndarray:
        """Sum of m v over the payload (the tool side's links) [kg m/s], world frame, now, (3,)."""
        self.reader.read()
        out = np.zeros(3)
        momentum(self._rows, self.payload.mass, out)
        return out

    @property
    def payload_mass(self) -> float:
        """Mass of the payload below the sensor [kg], as the sensor compensates it."""
        return float(self.payload.mass.sum())

    def tare(self) -> np.ndarray:
        """Zero the sensor's own offset in the current pose, unloaded and at rest: later readings have
        what it reads now (payload weight removed) subtracted. Returns that offset [N, N m] (6,), sensor frame;
        warns when it exceeds :attr:`TARE_WARNING` of the payload's weight."""
        if self._own_reader:
            self.reader.read()
        self._tare[:] = 0.0
        self._memory.valid[0] = 0.0
        self._tool_memory.valid[0] = 0.0
        self._applied[:] = 0.0
        self._add_contacts()
        self._transmit(self._rows, self._tool, 1.0, self._tool_memory, self._applied, self._reaction)
        self._tool_memory.valid[0] = 0.0  # the first step's rates start from it, as the payload's do
        out = np.zeros(12)
        self._reading(self._rows, self.payload, self._reaction, 1.0, False, True, self._tare, np.zeros(6),
                      self._memory, out)
        self._tare[:] = out[:6]
        weight = self.payload_mass * float(np.linalg.norm(self.payload.gravity))
        if np.linalg.norm(self._tare[:3]) > self.TARE_WARNING * weight:
            warnings.warn(f"wrist sensor of {self.robot.spec.name!r}: the tare removes "
                          f"{np.linalg.norm(self._tare[:3]):.3g} N, more than {100 * self.TARE_WARNING:g} % of the "
                          f"{self.compensation} payload's weight ({weight:.3g} N): the payload model does not fit "
                          f"the tool (mass, centre of mass or gravity), or the arm was loaded or moving", stacklevel=2)
        return self._tare.copy()

    # ----- readings ---------------------------------------------------------------------------
    def update(self, t: float, dt: float, applied: np.ndarray | None = None) -> Wrench:
        """Sample (if due at the sensor's rate) and return the current reading at time t [s].

        dt: physics step [s] (for the accelerations of the tool side, tracked at every step, sampled
        or not); applied (6,): the loads this library applied to the tool side in the step just taken
        (the held cable's), force [N] and moment about the world origin [N m], world frame (None:
        none); Bullet's contacts on the tool side's links are added here. The arithmetic is two
        compiled calls (:func:`~bullet_dlo.robots.kernels.tool_reaction`,
        :func:`~bullet_dlo.robots.kernels.sensor_reading`); a shared reader is read by its owner
        before this runs.
        """
        if self._own_reader:
            self.reader.read()
        if applied is None:
            self._applied[:] = 0.0
        else:
            self._applied[:] = applied
        due, offset = self._prepare(t)
        self._transmit(self._rows, self._tool, float(dt), self._tool_memory, self._applied, self._reaction)
        if self._reading(self._rows, self.payload, self._reaction, float(dt), self.compensate_inertia, due,
                         self._tare, offset, self._memory, self._scratch):
            self._sampled(t, offset)
        return self.last  # held between samples

    def _prepare(self, t: float, contacts: bool = True) -> tuple[bool, np.ndarray]:
        """Before the kernels of a step at time t [s], with ``_applied`` set to the library's loads: whether
        a sample is due, then (if so) Bullet's contacts added to ``_applied`` (unless the caller knows the step
        had none: ``contacts=False``) and this sample's bias plus noise drawn. Returns (due, offset (6,))."""
        due = self.gate.due(t)
        if due and contacts:  # between samples only the momenta are tracked, and they need no loads
            self._add_contacts()
        offset = self.bias
        if due and self._noisy:
            offset = self._noise()
        return due, offset

    def _noise(self) -> np.ndarray:
        """Bias plus this sample's noise (6,): ``bias + rng.normal(size=6) * noise_std``, drawn ``noise_block``
        samples at a time (Generator.normal draws a block's numbers in the order of one draw per sample, and the
        products and sums are the same per element: the same bits)."""
        if self.noise_block == 1:
            return self.bias + self.rng.normal(size=6) * self.noise_std
        rows, i = self._noise_rows, self._noise_next
        if rows is None or i == len(rows):
            rows = self._noise_rows = self.bias + self.rng.normal(size=(self.noise_block, 6)) * self.noise_std
            i = 0
        self._noise_next = i + 1
        return rows[i]

    def _sampled(self, t: float, offset: np.ndarray) -> None:
        """After the reading kernel sampled at time t [s] into ``_scratch``: keep it (the Wrench is built
        when :attr:`last` is read: most steps nobody reads it)."""
        self.offset = offset
        self.values = self._scratch.copy()  # one array, four views
        self._last_t = t
        self._last = None

    def _add_contacts(self) -> None:
        """Add the contact forces Bullet applied to the tool side's links in the last step to the applied
        loads (force [N], moment about the world origin [N m], world frame)."""
        body, tool = self.robot.body, self._tool_links
        for c in self._contacts():
            if c[1] == body and c[3] in tool:
                sign, point = 1.0, c[5]
            elif c[2] == body and c[4] in tool:
                sign, point = -1.0, c[6]  # the tool is body B: the opposite force, at its own point
            else:
                continue
            # on body A: the normal force along the normal on B (pointing from B to A), the friction along its directions
            force = sign * (c[9] * np.asarray(c[7]) + c[10] * np.asarray(c[11]) + c[12] * np.asarray(c[13]))
            self._applied[:3] += force
            self._applied[3:] += np.cross(point, force)

    @property
    def rows(self) -> np.ndarray:
        """The link states the sensor reads (row 0: its own link, whose CoM frame is the sensor frame)."""
        return self._rows

    @property
    def rate(self) -> float | None:
        """Sampling rate [Hz] (None: every physics step)."""
        return self.gate.rate

    @property
    def last(self) -> Wrench | None:
        """The latest reading (None before the first :meth:`update`)."""
        if self._last is None and self._last_t is not None:
            values = self.values
            self._last = Wrench(self._last_t, values[0:3], values[3:6], values[6:9], values[9:12])
        return self._last
