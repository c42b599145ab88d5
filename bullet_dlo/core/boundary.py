"""Boundary conditions: how each cable end is held, and prescribed motion of held ends.

An end is ``free``, ``pinned`` (position held) or ``clamped`` (position and tangent held,
like a gripper). A held end follows a pose trajectory: its start pose plus a sum of
:class:`Move` s, each a straight-line displacement and/or a rotation about the held node
with a smooth (minimum-jerk, quintic) start and stop.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from numba import njit

from bullet_dlo.core.validate import ParameterError, check_nonnegative, check_positive, check_vector3

END_MODES = ("free", "pinned", "clamped")
END_NAMES = ("first", "last")
FREE, PINNED, CLAMPED = 0, 1, 2


def end_mode_code(name: str, what: str = "end") -> int:
    """Map ``free``/``pinned``/``clamped`` to 0/1/2, raising ParameterError otherwise."""
    key = str(name).lower()
    if key not in END_MODES:
        raise ParameterError(f"{what} must be one of {', '.join(END_MODES)}, got {name!r}")
    return END_MODES.index(key)


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
        if self.end not in END_NAMES:
            raise ParameterError(f"motion end must be 'first' or 'last', got {self.end!r}")
        object.__setattr__(self, "displacement", tuple(check_vector3("motion displacement", self.displacement)))
        object.__setattr__(self, "rotation", tuple(check_vector3("motion rotation", self.rotation)))
        object.__setattr__(self, "start", check_nonnegative("motion start", self.start))
        object.__setattr__(self, "duration", check_positive("motion duration", self.duration))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Move":
        allowed = {"end", "displacement", "start", "duration", "rotation"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ParameterError(f"unknown motion key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(allowed))}")
        if "end" not in data:
            raise ParameterError("motion entry needs 'end' (first or last)")
        return cls(**dict(data))

    def as_row(self) -> np.ndarray:
        """[start, duration, dx, dy, dz, rx, ry, rz] for the Numba evaluator."""
        return np.array([self.start, self.duration, *self.displacement, *self.rotation], dtype=float)


@dataclass(frozen=True)
class EndHolder:
    """How one end is held and where it goes.

    Attributes:
        mode: ``free`` | ``pinned`` | ``clamped``.
        position: start position of the held node [m], shape (3,).
        direction: start tangent held by a clamp, pointing along the cable from first to last
            node (unit vector), shape (3,).
        moves: prescribed moves of this end.
    """

    mode: str
    position: np.ndarray
    direction: np.ndarray
    moves: tuple[Move, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        end_mode_code(self.mode)
        if self.moves and self.mode == "free":
            raise ParameterError("a free end cannot follow prescribed motion; make it pinned or clamped")

    @property
    def code(self) -> int:
        return end_mode_code(self.mode)

    def move_table(self) -> np.ndarray:
        """Moves as rows of shape (k, 8); shape (0, 8) without moves."""
        if not self.moves:
            return np.zeros((0, 8))
        return np.stack([m.as_row() for m in self.moves])


@njit(cache=True, error_model="numpy")
def min_jerk(tau):
    """Quintic minimum-jerk profile s(tau) and its first two derivatives for tau in [0, 1]."""
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    t2 = tau * tau
    t3 = t2 * tau
    s = t3 * (10.0 - 15.0 * tau + 6.0 * t2)
    ds = 30.0 * t2 * (1.0 - 2.0 * tau + t2)
    dds = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2)
    return s, ds, dds


@njit(cache=True, error_model="numpy")
def _rotate(vec, rx, ry, rz):
    """Rotate the 3-vector ``vec`` in place by the rotation vector (rx, ry, rz) (Rodrigues)."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    if angle < 1e-15:
        return
    kx, ky, kz = rx / angle, ry / angle, rz / angle
    ca, sa = math.cos(angle), math.sin(angle)
    v0, v1, v2 = vec[0], vec[1], vec[2]
    dot = kx * v0 + ky * v1 + kz * v2
    cx = ky * v2 - kz * v1
    cy = kz * v0 - kx * v2
    cz = kx * v1 - ky * v0
    vec[0] = v0 * ca + cx * sa + kx * dot * (1.0 - ca)
    vec[1] = v1 * ca + cy * sa + ky * dot * (1.0 - ca)
    vec[2] = v2 * ca + cz * sa + kz * dot * (1.0 - ca)


@njit(cache=True, error_model="numpy")
def held_pose(t, p0, d0, moves, pos, vel, acc, direction):
    """Pose of a held end at time t [s] from its start pose and move table (k, 8).

    Writes position [m], velocity [m/s], acceleration [m/s^2] and unit direction (all (3,)).
    Moves superpose: translations add, rotations compose in table order.
    """
    pos[:] = p0
    vel[:] = 0.0
    acc[:] = 0.0
    direction[:] = d0
    for k in range(moves.shape[0]):
        start, dur = moves[k, 0], moves[k, 1]
        s, ds, dds = min_jerk((t - start) / dur)
        for j in range(3):
            pos[j] += moves[k, 2 + j] * s
            vel[j] += moves[k, 2 + j] * ds / dur
            acc[j] += moves[k, 2 + j] * dds / (dur * dur)
        if s > 0.0:
            _rotate(direction, moves[k, 5] * s, moves[k, 6] * s, moves[k, 7] * s)


@njit(cache=True, error_model="numpy")
def sample_holders(t, h, p0s, d0s, moves_first, moves_last, hold_pos, hold_vel, hold_acc, hold_dir):
    """Held-end poses at t, t + h/2 and t + h for both ends.

    Outputs have shape (3, 2, 3): [time sample, end (first, last), xyz].
    """
    for k in range(3):
        tk = t + 0.5 * h * k
        held_pose(tk, p0s[0], d0s[0], moves_first, hold_pos[k, 0], hold_vel[k, 0], hold_acc[k, 0], hold_dir[k, 0])
        held_pose(tk, p0s[1], d0s[1], moves_last, hold_pos[k, 1], hold_vel[k, 1], hold_acc[k, 1], hold_dir[k, 1])


def parse_motion(items: Sequence[Mapping[str, Any]] | None) -> tuple[Move, ...]:
    """Parse the scene file's ``motion`` list into Moves."""
    if items is None:
        return ()
    if not isinstance(items, (list, tuple)):
        raise ParameterError("motion must be a list of moves")
    return tuple(m if isinstance(m, Move) else Move.from_dict(m) for m in items)
