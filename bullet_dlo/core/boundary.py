"""Boundary conditions: how each cable end is held, and prescribed motion of held ends.

An end is ``free``, ``pinned`` (position held), ``fork`` (position and the section's roll about the
holder's axis held, the direction free: see :class:`~bullet_dlo.core.enums.EndMode`) or ``clamped`` (position,
tangent and roll held, like a gripper). A held end follows a pose trajectory: its start pose plus the superposition
of motion items, all relative to that start pose (displacements [m], rotation vectors [rad]
about world axes, turning the clamp direction about the held node):

* :class:`Move`: a straight-line displacement and/or rotation, minimum-jerk, rest to rest;
* :class:`Waypoints`: a smooth path through displacements and rotations at given times
  (C2 piecewise quintic: the knot velocities and accelerations of a C2 cubic spline, at rest
  at the first and last waypoint; rotations interpolated as rotation vectors, exact at the
  waypoints, so keep steps between waypoints below ~90 degrees); at most one per end;
* :class:`Sine`: amplitude * sin(2 pi f (t - start) + phase) in position and/or rotation, for
  ``duration`` seconds (default: forever), with optional minimum-jerk ramps in and out.

Rotations turn the clamp direction in this order: moves (in the order given), the path, the sines.
In a scene file's ``motion:`` list each entry has ``type: move`` (the default), ``waypoints`` or ``sine``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from bullet_dlo.core.kernels.holders import (
    MOVE_COLUMNS,
    PATH_COLUMNS,
    SINE_COLUMNS,
    HolderPlan,
    empty_samples,
    min_jerk,  # noqa: F401 (min_jerk: robots.dual_arm)
    sample_holders,
)
from bullet_dlo.core.enums import EndMode
from bullet_dlo.core.validate import ParameterError, check_nonnegative, check_positive, check_vector3

END_MODES = EndMode.names()  # free | pinned | fork | clamped (bullet_dlo.core.enums.EndMode)
END_NAMES = ("first", "last")


def check_end_mode(name: str, what: str = "end") -> str:
    """``free``/``pinned``/``fork``/``clamped`` in lower case, raising ParameterError for anything else."""
    key = str(name).lower()
    if key not in END_MODES:
        raise ParameterError(f"{what} must be one of {', '.join(END_MODES)}, got {name!r}")
    return key


@dataclass(frozen=True)
class Move:
    """A smooth move of one held end.

    Attributes:
        end: ``"first"`` or ``"last"``.
        displacement: translation of the end over the move [m], shape (3,).
        start: start time [s], >= 0.
        duration: duration [s], > 0.
        rotation: rotation vector (axis * angle) [rad] applied to the held direction about
            the held node over the move, shape (3,).
    """

    end: str
    displacement: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start: float = 0.0
    duration: float = 1.0
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        _check_end(self.end)
        object.__setattr__(self, "displacement", tuple(check_vector3("motion displacement", self.displacement)))
        object.__setattr__(self, "rotation", tuple(check_vector3("motion rotation", self.rotation)))
        object.__setattr__(self, "start", check_nonnegative("motion start", self.start))
        object.__setattr__(self, "duration", check_positive("motion duration", self.duration))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Move":
        return cls(**_motion_keys(data, {"end", "displacement", "start", "duration", "rotation"}, "move"))

    def as_row(self) -> np.ndarray:
        """[start, duration, dx, dy, dz, rx, ry, rz] (SI) for the Numba evaluator, shape (8,)."""
        return np.array([self.start, self.duration, *self.displacement, *self.rotation], dtype=float)


def _motion_keys(data: Mapping[str, Any], allowed: set[str], kind: str) -> dict[str, Any]:
    """The keys of a motion entry of type ``kind`` (without ``type``), unknown keys and a missing ``end`` refused."""
    data = {k: v for k, v in dict(data).items() if k != "type"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ParameterError(f"unknown {kind} motion key(s) {', '.join(unknown)}; allowed: type, "
                             f"{', '.join(sorted(allowed))}")
    if "end" not in data:
        raise ParameterError(f"{kind} motion entry needs 'end' (first or last)")
    return data


def _check_end(end: str) -> None:
    if end not in END_NAMES:
        raise ParameterError(f"motion end must be 'first' or 'last', got {end!r}")


@dataclass(frozen=True)
class Waypoints:
    """A smooth path of one held end through waypoints (relative to its start pose).

    Attributes:
        end: ``"first"`` or ``"last"``.
        times: waypoint times [s], strictly increasing, >= 0, shape (k,), k >= 2.
        displacements: displacement from the start position at each waypoint [m], shape (k, 3);
            the first must be zero (the path starts from the start pose).
        rotations: rotation vector of the clamp direction at each waypoint [rad], shape (k, 3)
            (default: none); the first must be zero.
        rest: start and end at rest (default). False (for poses sampled from a motion that
            does not start or end at rest, e.g. a recording): the spline's own end velocities
            and accelerations (not-a-knot), and the end stops dead after the last waypoint.

    Between waypoints: quintic segments matching position, velocity and acceleration of a C2
    cubic spline (zero end velocities) at every waypoint, with zero velocity and
    acceleration at the first and last (so the whole path is C2, at rest at both ends).
    """

    end: str
    times: tuple[float, ...]
    displacements: tuple[tuple[float, float, float], ...]
    rotations: tuple[tuple[float, float, float], ...] | None = None
    rest: bool = True

    def __post_init__(self) -> None:
        _check_end(self.end)
        t = np.asarray(self.times, dtype=float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.isfinite(t)):
            raise ParameterError("waypoints times must be a list of at least 2 finite times [s]")
        if t[0] < 0 or np.any(np.diff(t) <= 0):
            raise ParameterError("waypoints times must be >= 0 and strictly increasing")
        arrays = {}
        for name in ("displacements", "rotations"):
            value = getattr(self, name)
            a = np.zeros((len(t), 3)) if value is None else np.asarray(value, dtype=float)
            if a.shape != (len(t), 3) or not np.all(np.isfinite(a)):
                raise ParameterError(f"waypoints {name} must be {len(t)} finite [x, y, z] rows (one per time)")
            if np.any(a[0] != 0.0):
                raise ParameterError(f"waypoints {name}: the first waypoint must be [0, 0, 0] (the start pose)")
            arrays[name] = tuple(tuple(float(v) for v in row) for row in a)
        object.__setattr__(self, "times", tuple(float(v) for v in t))
        object.__setattr__(self, "displacements", arrays["displacements"])
        object.__setattr__(self, "rotations", arrays["rotations"])

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Waypoints":
        return cls(**_motion_keys(data, {"end", "times", "displacements", "rotations", "rest"}, "waypoints"))

    @property
    def start(self) -> float:
        return self.times[0]

    @property
    def duration(self) -> float:
        return self.times[-1] - self.times[0]

    def segments(self) -> np.ndarray:
        """The path as kernel rows (see :class:`~bullet_dlo.core.kernels.holders.HolderPlan`), shape (k - 1, 38)."""
        t = np.asarray(self.times)
        rows = np.zeros((len(t) - 1, PATH_COLUMNS))
        rows[:, 0], rows[:, 1] = t[:-1], t[1:]
        for col, values in ((2, self.displacements), (20, self.rotations)):
            rows[:, col:col + 18] = quintic_segments(t, np.asarray(values), bool(self.rest))
        return rows


def quintic_segments(t: np.ndarray, p: np.ndarray, rest: bool = True) -> np.ndarray:
    """Coefficients c_0..c_5 of C2 quintic segments through values ``p`` (k, 3) at times ``t`` (k,) [s],
    in u = (t - t_i)/(t_{i+1} - t_i): rows of (c_0 (3), ..., c_5 (3)), shape (k - 1, 18).

    Knot velocities and accelerations are those of the C2 cubic spline; ``rest``: with zero end
    velocities and the accelerations at the first and last knot set to zero, else not-a-knot.
    """
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(t, p, axis=0, bc_type="clamped" if rest else "not-a-knot")
    v, a = spline(t, 1), spline(t, 2)
    if rest:
        v[[0, -1]] = 0.0
        a[[0, -1]] = 0.0
    T = np.diff(t)[:, None]
    p0, p1, v0, v1, a0, a1 = p[:-1], p[1:], v[:-1] * T, v[1:] * T, a[:-1] * T**2, a[1:] * T**2
    dp = p1 - p0
    c = [p0, v0, 0.5 * a0,
         10 * dp - 6 * v0 - 4 * v1 - 0.5 * (3 * a0 - a1),
         -15 * dp + 8 * v0 + 7 * v1 + 0.5 * (3 * a0 - 2 * a1),
         6 * dp - 3 * v0 - 3 * v1 - 0.5 * (a0 - a1)]
    return np.concatenate(c, axis=1)


@dataclass(frozen=True)
class Sine:
    """A periodic motion of one held end about its (otherwise prescribed) pose.

    displacement(t) = amplitude * e(t) * sin(2 pi frequency (t - start) + phase) [m], and the
    clamp direction turned by rotation * e(t) * sin(...) [rad]; e rises from 0 to 1 over
    ``ramp`` seconds after ``start`` and falls back over ``ramp`` before ``start + duration``
    (minimum jerk; ramp 0: the sine starts and stops abruptly).

    Attributes:
        end: ``"first"`` or ``"last"``.
        amplitude: [m], shape (3,).
        frequency: [Hz], > 0.
        phase: [rad].
        rotation: rotation amplitude (rotation vector) [rad], shape (3,).
        start: [s], >= 0.
        duration: [s], > 0 (default, or None: forever).
        ramp: [s], >= 0, at most half the duration.
    """

    end: str
    amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frequency: float = 1.0
    phase: float = 0.0
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start: float = 0.0
    duration: float = math.inf
    ramp: float = 0.0

    def __post_init__(self) -> None:
        _check_end(self.end)
        object.__setattr__(self, "amplitude", tuple(check_vector3("sine amplitude", self.amplitude)))
        object.__setattr__(self, "rotation", tuple(check_vector3("sine rotation", self.rotation)))
        object.__setattr__(self, "frequency", check_positive("sine frequency", self.frequency))
        if not math.isfinite(float(self.phase)):
            raise ParameterError(f"sine phase must be finite [rad], got {self.phase!r}")
        object.__setattr__(self, "phase", float(self.phase))
        object.__setattr__(self, "start", check_nonnegative("sine start", self.start))
        forever = self.duration is None or self.duration == math.inf
        object.__setattr__(self, "duration", math.inf if forever else check_positive("sine duration", self.duration))
        object.__setattr__(self, "ramp", check_nonnegative("sine ramp", self.ramp))
        if 2 * self.ramp > self.duration:
            raise ParameterError(f"sine ramp must be at most half the duration ({self.duration / 2} s), got {self.ramp}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Sine":
        allowed = {"end", "amplitude", "frequency", "phase", "rotation", "start", "duration", "ramp"}
        return cls(**_motion_keys(data, allowed, "sine"))

    def as_row(self) -> np.ndarray:
        """Kernel row (see :class:`~bullet_dlo.core.kernels.holders.HolderPlan`), shape (11,)."""
        return np.array([self.start, self.duration, self.ramp, self.frequency, self.phase, *self.amplitude,
                         *self.rotation], dtype=float)


MOTION_TYPES = {"move": Move, "waypoints": Waypoints, "sine": Sine}
Motion = Move | Waypoints | Sine


@dataclass(frozen=True)
class EndHolder:
    """How one end is held and where it goes.

    Attributes:
        mode: ``free`` | ``pinned`` | ``fork`` | ``clamped``.
        position: start position of the held node [m], shape (3,).
        direction: start tangent held by a clamp (a fork's axis, about which it holds the roll), pointing
            along the cable from first to last node (unit vector), shape (3,).
        moves: prescribed motion items of this end (Move, Waypoints, Sine).
        normal: start orientation of the section held by a clamp or a fork: its first axis d1 (unit, normal to
            ``direction``), shape (3,); None: :func:`default_normal` of the direction. Only a cable with a
            material frame (``CableSpec.twist_enabled``) feels it; the motion's rotations turn it with the clamp.
    """

    mode: str
    position: np.ndarray
    direction: np.ndarray
    moves: tuple[Motion, ...] = field(default_factory=tuple)
    normal: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "mode", check_end_mode(self.mode))
        if self.moves and self.mode == "free":
            raise ParameterError("a free end cannot follow prescribed motion; make it pinned, fork or clamped")
        d = np.asarray(self.direction, dtype=float)
        if self.normal is None:
            object.__setattr__(self, "normal", default_normal(d))
        else:
            nrm = check_vector3("end normal", self.normal, unit=True)
            if abs(float(nrm @ d)) > 1e-9 * max(float(np.linalg.norm(d)), 1.0):
                raise ParameterError("end normal (the section axis d1) must be normal to the end's direction")
            object.__setattr__(self, "normal", nrm)

    @property
    def held(self) -> bool:
        """Whether the end node is kinematic (pinned, fork or clamped)."""
        return self.mode != "free"

    def move_table(self) -> np.ndarray:
        """Moves as rows of shape (k, 8); shape (0, 8) without moves."""
        rows = [m.as_row() for m in self.moves if isinstance(m, Move)]
        return np.stack(rows) if rows else np.zeros((0, MOVE_COLUMNS))

    def path_table(self) -> np.ndarray:
        """The waypoint path as segment rows, shape (k, 38); (0, 38) without one."""
        paths = [m for m in self.moves if isinstance(m, Waypoints)]
        if len(paths) > 1:
            raise ParameterError("at most one waypoints trajectory per end (put all its waypoints in one entry)")
        return paths[0].segments() if paths else np.zeros((0, PATH_COLUMNS))

    def sine_table(self) -> np.ndarray:
        """Sines as rows of shape (k, 11); (0, 11) without sines."""
        rows = [m.as_row() for m in self.moves if isinstance(m, Sine)]
        return np.stack(rows) if rows else np.zeros((0, SINE_COLUMNS))


def default_normal(direction: np.ndarray) -> np.ndarray:
    """The section axis d1 a clamp holds unless told: horizontal, z x direction normalised (so a strip laid
    along x has its width along y and its thickness vertical), or x projected normal to a vertical direction."""
    d = np.asarray(direction, dtype=float)
    d = d / max(float(np.linalg.norm(d)), 1e-300)
    n = np.cross((0.0, 0.0, 1.0), d)
    if np.linalg.norm(n) < 1e-6:
        n = np.array([1.0, 0.0, 0.0]) - d[0] * d
    return n / np.linalg.norm(n)


def holder_plan(first: EndHolder, last: EndHolder, normal: np.ndarray | None = None) -> HolderPlan:
    """Start poses and motion tables of both ends, as the kernels take them.

    normal: the buffer (3, 2, 3) the samplers write the clamps' section axis into (a twisting model's
    ``CableControl.normal``); None: the roll is not tracked.
    """
    return HolderPlan(
        start_pos=np.stack([first.position, last.position]).astype(float),
        start_dir=np.stack([first.direction, last.direction]).astype(float),
        moves_first=first.move_table(), moves_last=last.move_table(),
        path_first=first.path_table(), path_last=last.path_table(),
        sines_first=first.sine_table(), sines_last=last.sine_table(),
        start_normal=np.stack([first.normal, last.normal]).astype(float),
        normal=np.zeros((0, 2, 3)) if normal is None else normal,
    )


class MotionOffset:
    """What the motion ``items`` of end ``end`` do to a pose held by that end, evaluated by the kernels
    (the plans are built once, so that calling it every step is cheap).

    ``offset(t)`` at time t [s] gives the displacement [m], velocity [m/s], acceleration [m/s^2],
    each (3,), and the rotation matrix that turns the start orientation, (3, 3) (columns: the
    images of the world axes). A gripper holding that end follows ``position0 + displacement``
    with orientation ``R @ R0``.
    """

    def __init__(self, items: Sequence[Motion], end: str):
        mine = tuple(m for m in items if m.end == end)
        holders = [EndHolder("clamped", np.zeros(3), axis, mine) for axis in np.eye(3)]
        self.plans = [holder_plan(h, h) for h in holders]
        self.samples = empty_samples()

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        s = self.samples
        turn = np.empty((3, 3))
        for axis, plan in enumerate(self.plans):
            sample_holders(plan, float(t), 0.0, s)
            turn[:, axis] = s.dir[0, 0]
        return s.pos[0, 0].copy(), s.vel[0, 0].copy(), s.acc[0, 0].copy(), turn


def motion_offset(items: Sequence[Motion], end: str, times: np.ndarray | Sequence[float]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:class:`MotionOffset` at several ``times`` [s], shape (k,): displacement, velocity, acceleration,
    each (k, 3), and rotation matrices, (k, 3, 3)."""
    offset = MotionOffset(items, end)
    rows = [offset(t) for t in np.atleast_1d(np.asarray(times, dtype=float))]
    return tuple(np.array([r[i] for r in rows]) for i in range(4))  # type: ignore[return-value]


def parse_motion(items: Sequence[Mapping[str, Any]] | None) -> tuple[Motion, ...]:
    """Parse the scene file's ``motion`` list (entries with ``type: move`` (default), ``waypoints`` or ``sine``)."""
    if items is None:
        return ()
    if not isinstance(items, (list, tuple)):
        raise ParameterError("motion must be a list of moves")
    out = []
    for k, item in enumerate(items):
        if isinstance(item, (Move, Waypoints, Sine)):
            out.append(item)
            continue
        if not isinstance(item, Mapping):
            raise ParameterError(f"motion[{k}] must be a mapping with 'type' (move, waypoints, sine) and 'end'")
        kind = str(item.get("type", "move")).lower()
        if kind not in MOTION_TYPES:
            raise ParameterError(f"motion[{k}].type must be one of {', '.join(MOTION_TYPES)}, got {kind!r}")
        out.append(MOTION_TYPES[kind].from_dict(item))
    for end in END_NAMES:
        if sum(isinstance(m, Waypoints) and m.end == end for m in out) > 1:
            raise ParameterError(f"motion: at most one waypoints entry per end ('{end}' has more)")
    return tuple(out)


ROLL_TOL = 1e-3
"""A clamp's roll about the cable axis [rad] above which the scene twists the cable (0.057 deg). Smaller rolls
are side effects of tilts about an axis a hair off the perpendicular (2e-6 rad in the wrist tilt tests); the
torsion they would give, G J / L x 1e-3 rad, is 0.01 N m for a 5 mm steel rod of 0.5 m, far less for cables."""
ROLL_SAMPLES = 2001
"""Instants over the scene's duration at which the clamps' roll is read."""


def end_roll(holder: EndHolder, times: np.ndarray) -> np.ndarray:
    """The roll [rad] of a held end about the cable's axis at ``times`` [s]: the angle by which its motion
    turns the held section axis d1 beyond the minimal rotation that carries the start tangent d0 to the
    current one R d0 (the twist part of R's swing-twist decomposition about d0). Zeros without motion."""
    times = np.asarray(times, dtype=float)
    if not any(map(turns, holder.moves)):
        return np.zeros(times.shape)  # translations only: the held section never turns (and sampling costs ~0.1 s)
    end = holder.moves[0].end
    offset = MotionOffset(holder.moves, end)
    d0 = np.asarray(holder.direction, dtype=float) / np.linalg.norm(holder.direction)
    n0 = np.asarray(holder.normal, dtype=float)
    out = np.empty(times.shape)
    for k, t in enumerate(times):
        rot = offset(float(t))[3]
        d1, n1 = rot @ d0, rot @ n0
        c = float(d0 @ d1)
        if c < -1.0 + 1e-9:  # the tangent turned right round: the swing is ambiguous, count it as a roll
            out[k] = np.pi
            continue
        moved = n0 - float(n0 @ d1) / (1.0 + c) * (d0 + d1)  # n0 carried by the minimal rotation d0 -> d1
        out[k] = np.arctan2(float(np.cross(moved, n1) @ d1), float(moved @ n1))
    return out


def turns(item: Motion) -> bool:
    """Whether a motion item rotates its end at all (a nonzero rotation vector anywhere in it)."""
    rows = item.rotations if isinstance(item, Waypoints) else (item.rotation,)
    return any(v != 0.0 for row in rows for v in row)
