"""Input validation shared by every layer: one error type and the checks that raise it.

Every check returns the value converted (float, int or array) or raises
:class:`ParameterError` with one line naming the parameter and the allowed range.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np


class ParameterError(ValueError):
    """A parameter is outside its allowed range; the message names it and the range."""


def check_positive(name: str, value: Any) -> float:
    """Return ``value`` as a finite float > 0 or raise ParameterError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number > 0, got {value!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise ParameterError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def check_nonnegative(name: str, value: Any) -> float:
    """Return ``value`` as a finite float >= 0 or raise ParameterError naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number >= 0, got {value!r}") from None
    if not math.isfinite(v) or v < 0.0:
        raise ParameterError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def check_in_range(name: str, value: Any, lo: float, hi: float, *, open_hi: bool = False) -> float:
    """Return ``value`` as a float in [lo, hi] (or [lo, hi)) or raise ParameterError."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number in [{lo}, {hi}], got {value!r}") from None
    bad = not math.isfinite(v) or v < lo or (v >= hi if open_hi else v > hi)
    if bad:
        bracket = ")" if open_hi else "]"
        raise ParameterError(f"{name} must be in [{lo}, {hi}{bracket}, got {value!r}")
    return v


def check_int(name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """Return ``value`` as an int in [lo, hi] or raise ParameterError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ParameterError(f"{name} must be an integer >= {lo}, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise ParameterError(f"{name} must be an integer {rng}, got {value!r}")
    return v


def check_vector3(name: str, value: Any, *, unit: bool = False) -> np.ndarray:
    """Return ``value`` as a finite float array of shape (3,); with ``unit`` normalise it."""
    try:
        v = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a list of 3 numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ParameterError(f"{name} must be a list of 3 finite numbers, got {value!r}")
    if unit:
        norm = float(np.linalg.norm(v))
        if norm < 1e-12:
            raise ParameterError(f"{name} must be a non-zero direction, got {value!r}")
        v = v / norm
    return v
