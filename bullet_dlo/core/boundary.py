"""Boundary conditions: how each cable end is held, and prescribed motion of held ends.

An end is ``free``, ``pinned`` (position held) or ``clamped`` (position and tangent held,
like a gripper). A held end follows a pose trajectory: its start pose plus a sum of
:class:`Move` s, each a straight-line displacement and/or a rotation about the held node
with a smooth (minimum-jerk, quintic) start and stop.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from bullet_dlo.core.kernels.holders import MOVE_COLUMNS, min_jerk  # noqa: F401 (min_jerk: robots.dual_arm)
from bullet_dlo.core.validate import ParameterError, check_nonnegative, check_positive, check_vector3

END_MODES = ("free", "pinned", "clamped")
END_NAMES = ("first", "last")


def check_end_mode(name: str, what: str = "end") -> str:
    """``free``/``pinned``/``clamped`` in lower case, raising ParameterError for anything else."""
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
        """[start, duration, dx, dy, dz, rx, ry, rz] (SI) for the Numba evaluator, shape (8,)."""
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
        object.__setattr__(self, "mode", check_end_mode(self.mode))
        if self.moves and self.mode == "free":
            raise ParameterError("a free end cannot follow prescribed motion; make it pinned or clamped")

    @property
    def held(self) -> bool:
        """Whether the end node is kinematic (pinned or clamped)."""
        return self.mode != "free"

    def move_table(self) -> np.ndarray:
        """Moves as rows of shape (k, 8); shape (0, 8) without moves."""
        if not self.moves:
            return np.zeros((0, MOVE_COLUMNS))
        return np.stack([m.as_row() for m in self.moves])


def parse_motion(items: Sequence[Mapping[str, Any]] | None) -> tuple[Move, ...]:
    """Parse the scene file's ``motion`` list into Moves."""
    if items is None:
        return ()
    if not isinstance(items, (list, tuple)):
        raise ParameterError("motion must be a list of moves")
    return tuple(m if isinstance(m, Move) else Move.from_dict(m) for m in items)
