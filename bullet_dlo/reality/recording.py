"""A marker recording: positions of markers along a cable over time, two held marker pairs.

Units: t [s], positions [m] (world frame, z up), arc lengths [m]. A recording says where the
cable's two held ends are (each held by a gripper that also carries two markers, the *held
pair*) and where the markers between them are; what a model predicts is the free markers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bullet_dlo.core.validate import ParameterError


@dataclass(frozen=True)
class MarkerRecording:
    """Marker positions along a cable, held at both ends by pairs of markers.

    Attributes:
        name: where it came from (e.g. the file stem).
        t: sample times [s], (k,), strictly increasing, starting at 0.
        markers: marker positions [m], (k, m, 3), markers ordered along the cable.
        s: arc length of each marker from marker 0 [m], (m,), strictly increasing.
        first_pair, last_pair: indices of the two markers held rigidly at each end, ordered
            along the cable (outer, inner) for the first end and (inner, outer) for the last.
    """

    name: str
    t: np.ndarray
    markers: np.ndarray
    s: np.ndarray
    first_pair: tuple[int, int] = (0, 1)
    last_pair: tuple[int, int] = (-2, -1)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        x = np.asarray(self.markers, dtype=float)
        s = np.asarray(self.s, dtype=float)
        if t.ndim != 1 or len(t) < 3 or np.any(np.diff(t) <= 0):
            raise ParameterError(f"recording {self.name}: t must hold at least 3 strictly increasing times [s]")
        if x.ndim != 3 or x.shape[0] != len(t) or x.shape[2] != 3 or x.shape[1] < 5:
            raise ParameterError(f"recording {self.name}: markers must have shape ({len(t)}, m >= 5, 3) [m], "
                                 f"got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ParameterError(f"recording {self.name}: markers must be finite")
        if s.shape != (x.shape[1],) or np.any(np.diff(s) <= 0):
            raise ParameterError(f"recording {self.name}: s must be {x.shape[1]} strictly increasing arc lengths [m]")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "markers", x)
        object.__setattr__(self, "s", s)

    @property
    def n_markers(self) -> int:
        return self.markers.shape[1]

    @property
    def held(self) -> np.ndarray:
        """Indices of the held markers (both pairs), (4,)."""
        m = self.n_markers
        return np.array(sorted({i % m for i in (*self.first_pair, *self.last_pair)}))

    @property
    def free(self) -> np.ndarray:
        """Indices of the markers between the held pairs (what a model predicts)."""
        return np.setdiff1d(np.arange(self.n_markers), self.held)

    def clamp(self, end: str) -> tuple[np.ndarray, np.ndarray]:
        """Where the gripper at ``end`` (first | last) holds the cable over time: the inner held marker's
        position [m], (k, 3), and the pair's direction along the cable (first to last marker), unit, (k, 3).

        A pair of markers fixes a direction only: the gripper's roll about the cable axis is unknown.
        """
        pair = self.first_pair if end == "first" else self.last_pair
        a, b = self.markers[:, pair[0]], self.markers[:, pair[1]]
        d = b - a
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return (b if end == "first" else a).copy(), d
