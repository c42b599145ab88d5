"""Sampling at a rate of its own inside a fixed-step loop (sensors, video frames, dataset frames)."""
from __future__ import annotations

import math

from bullet_dlo.core.validate import ParameterError


class RateGate:
    """Says at which times of a fixed-step loop a sampler running at ``rate`` [Hz] fires.

    The first call fires; later calls fire once the next due time is reached. Due times are
    start + k / rate, so the average rate is exact whatever the physics step (no drift),
    and a sampler slower than the loop holds its value between firings. ``rate=None``
    fires at every call.
    """

    def __init__(self, rate: float | None):
        if rate is not None and not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
            raise ParameterError(f"rate must be a finite number > 0 [Hz] or None, got {rate!r}")
        self.rate = None if rate is None else float(rate)
        self._next: float | None = None

    def due(self, t: float) -> bool:
        """True if the sampler fires at time ``t`` [s] (and then schedules the next firing)."""
        if self.rate is None:
            return True
        if self._next is not None and t < self._next - 1e-9 / self.rate:
            return False
        period = 1.0 / self.rate
        # next due time strictly after t, on the grid start + k period
        self._next = (t if self._next is None else self._next) + period
        if self._next <= t:
            self._next += period * math.floor((t - self._next) / period + 1.0)
        return True

    def reset(self) -> None:
        """Forget the schedule: the next call fires."""
        self._next = None
