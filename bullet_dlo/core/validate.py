"""Input validation shared by every layer: one error type and the checks that raise it.

Every check returns the value converted (float, int or array) or raises
:class:`ParameterError` with one line naming the parameter and the allowed range.
"""
from __future__ import annotations

import math
import warnings
from typing import Any, Mapping

import numpy as np


class ParameterError(ValueError):
    """A parameter is outside its allowed range; the message names it and the range."""


MAX_STEPS = 1e10  # time steps of one run at most, whether dt and duration come from files or flags


def _float(name: str, value: Any, wanted: str) -> float:
    """``value`` as a float; booleans, None and non-numbers raise ParameterError (``wanted``: the range)."""
    if isinstance(value, bool) or value is None:
        raise ParameterError(f"{name} must be {wanted}, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{name} must be {wanted}, got {value!r}") from None


def check_positive(name: str, value: Any) -> float:
    """Return ``value`` as a finite float > 0 or raise ParameterError naming ``name``."""
    v = _float(name, value, "a number > 0")
    if not math.isfinite(v) or v <= 0.0:
        raise ParameterError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def check_nonnegative(name: str, value: Any) -> float:
    """Return ``value`` as a finite float >= 0 or raise ParameterError naming ``name``."""
    v = _float(name, value, "a number >= 0")
    if not math.isfinite(v) or v < 0.0:
        raise ParameterError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def check_in_range(name: str, value: Any, lo: float, hi: float, *, open_hi: bool = False) -> float:
    """Return ``value`` as a float in [lo, hi] (or [lo, hi)) or raise ParameterError."""
    v = _float(name, value, f"a number in [{lo}, {hi}]")
    bad = not math.isfinite(v) or v < lo or (v >= hi if open_hi else v > hi)
    if bad:
        bracket = ")" if open_hi else "]"
        raise ParameterError(f"{name} must be in [{lo}, {hi}{bracket}, got {value!r}")
    return v


def check_friction_order(dynamic: float, static: float, where: str = "", hint: str = "") -> None:
    """Coulomb friction slips at or below the force it holds: refuse ``dynamic > static`` [-], naming
    ``{where}dynamic_friction`` and ``{where}static_friction`` (``where``: e.g. "cable.", "arms.grip_";
    ``hint``: appended to the static value). The one statement of the rule for the cable's and the grips'."""
    if dynamic > static:
        raise ParameterError(f"{where}dynamic_friction ({dynamic}) must be at most {where}static_friction "
                             f"({static}){hint}: Coulomb friction slips at or below the force it holds")


def check_int(name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """Return ``value`` as an int in [lo, hi] or raise ParameterError (a float must be a whole
    number: 10.0 is 10, 8.4 is refused, never rounded)."""
    rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, (float, np.floating)) and float(value).is_integer():
            value = int(value)
        else:
            raise ParameterError(f"{name} must be an integer {rng}, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        raise ParameterError(f"{name} must be an integer {rng}, got {value!r}")
    return v


def check_bool(name: str, value: Any) -> bool:
    """Return ``value`` if it is true or false (YAML true/false); anything else raises ParameterError."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise ParameterError(f"{name} must be true or false, got {value!r}")


def check_finite(name: str, value: Any) -> float:
    """Return ``value`` as a finite float or raise ParameterError naming ``name``."""
    v = _float(name, value, "a finite number")
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    return v


def check_steps(dt: float, duration: float, substeps: int = 1, dt_name: str = "dt",
                duration_name: str = "duration") -> int:
    """Number of steps of a run of ``duration`` [s] at ``dt`` [s] (x ``substeps``), after checking that
    dt is at most the duration and that the run has at most :data:`MAX_STEPS` steps."""
    if dt > duration:
        raise ParameterError(f"{dt_name} = {dt:g} s must be at most {duration_name} = {duration:g} s")
    steps = duration / dt * substeps
    if steps > MAX_STEPS:
        raise ParameterError(f"{duration_name} / {dt_name} = {steps:.3g} steps; at most {MAX_STEPS:.0e} steps "
                             "per run (raise dt or shorten the duration)")
    return max(1, int(round(duration / dt)))


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


def renamed_keys(data: Mapping[str, Any], renames: Mapping[str, str], where: str = "",
                 stacklevel: int = 3) -> dict[str, Any]:
    """``data`` with each deprecated key of ``renames`` (old name -> new name) replaced by its new name.

    Each old key found gives one DeprecationWarning naming the new key (``where``: a prefix such as
    ``cable.`` or ``sample.``); both names at once raise ParameterError. Old names are accepted for one
    release after their rename.
    """
    out = dict(data)
    for old, new in renames.items():
        if old not in out:
            continue
        if new in out:
            raise ParameterError(f"{where}{old} and {where}{new} are the same parameter ({old} is its old name); "
                                 f"give only {where}{new}")
        warnings.warn(f"{where}{old} is deprecated; use {where}{new} (the old name goes in the next release)",
                      DeprecationWarning, stacklevel=stacklevel)
        out[new] = out.pop(old)
    return out
