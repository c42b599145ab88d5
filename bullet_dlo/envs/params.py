"""The one validation layer of the environments' keyword arguments and of ``reset``'s inputs.

Every keyword argument of every registered environment (:data:`bullet_dlo._gym_registration.ENV_IDS`)
is checked here, before anything is built (no Bullet world, no robot spec), through the checks of
:mod:`bullet_dlo.core.validate`: a bad value raises :class:`~bullet_dlo.core.validate.ParameterError`
with one line naming the keyword and its allowed range or type. The ranges are SI and physical
(a gripper speed a real arm reaches, a force a real cell stops at, images a 24 GB machine renders);
:data:`NUMBERS` is the table the constructors' docstrings quote.

Numbers must be real numbers (int, float or NumPy scalars; not strings, bools or None), finite
and inside the range; flags real bools (``'false'`` is refused, not taken as true); sizes pairs
of whole numbers of pixels; choices one of the listed values.
"""
from __future__ import annotations

from collections.abc import Mapping
from numbers import Real
from typing import Any

import numpy as np

from bullet_dlo.core.validate import ParameterError, check_bool, check_finite, check_int

NUMBERS: dict[str, tuple[float, float, str, bool]] = {
    # kwarg: (low, high, unit, low excluded)
    "control_dt": (0.0, 1.0, "s", True),  # and a whole multiple of the physics step (randomisation.check_control_period)
    "max_speed": (0.0, 2.0, "m/s", True),  # a Panda's end effector reaches 1.7 m/s
    "workspace": (0.0, 2.0, "m", True),  # beyond any arm's reach (Panda 0.855 m)
    "settle_time": (0.0, 10.0, "s", False),
    # TensionTracking-v0
    "tension_range": (0.0, 100.0, "N", False),  # each of (low, high), low <= high
    "max_amplitude": (0.0, 1.0, "(fraction of the mean tension)", False),  # the target never goes negative
    "target_offset": (0.0, 0.5, "m", False),
    "overload": (0.0, 1000.0, "N", True),  # TensionTracking-v0 and Routing-v0
    # Shaping-v0
    "inward": (0.0, 0.5, "m", False),
    "lateral": (0.0, 0.5, "m", False),
    "vertical": (0.0, 0.5, "m", False),
    "success_error": (0.0, 0.5, "m", True),
    # Routing-v0
    "max_yaw_rate": (0.0, 10.0, "rad/s", True),
    "force_soft": (0.0, 1000.0, "N", True),
}
"""Numeric keyword arguments: (low, high, unit, low excluded); high is always included."""

SHAPE_POINTS = (2, 1000)  # points along the cable in the ``cable`` observation and shape targets
IMAGE_SIDE = (16, 4096)  # [px] each side of ``image_size`` and ``render_size`` (4096^2 RGB-D: 112 MB a frame)
CAMERAS = (None, "rgb", "depth", "rgbd")
RENDER_MODES = (None, "rgb_array", "human")
MAX_SUBSTEPS = 10_000  # physics steps per control step (control_dt / dt) at most
MAX_SETTLE_STEPS = 100_000  # physics steps of the settling (settle_time / dt) at most


def short(value: Any, limit: int = 60) -> str:
    """``repr(value)`` on one line, cut to ``limit`` characters (messages stay one line)."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def range_text(name: str) -> str:
    """The allowed range of numeric kwarg ``name``, e.g. ``(0, 1] s``."""
    lo, hi, unit, lo_open = NUMBERS[name]
    return f"{'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}"


def number(name: str, value: Any, *, label: str | None = None) -> float:
    """``value`` as a float inside ``NUMBERS[name]`` or ParameterError (``label``: the name in the message)."""
    lo, hi, _, lo_open = NUMBERS[name]
    label = label or name
    wanted = f"{label} must be a number in {range_text(name)}, got {short(value)}"
    if isinstance(value, (str, bytes, bool, np.bool_)) or not isinstance(value, (Real, np.number)):
        raise ParameterError(wanted)
    try:
        v = check_finite(label, value)
    except ParameterError:
        raise ParameterError(wanted) from None
    if v < lo or (lo_open and v == lo) or v > hi:
        raise ParameterError(wanted)
    return v


def number_pair(name: str, value: Any) -> tuple[float, float]:
    """A (low, high) pair of numbers inside ``NUMBERS[name]`` with low <= high, or ParameterError."""
    wanted = f"{name} must be a pair (low, high) of numbers in {range_text(name)} with low <= high, got {short(value)}"
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__") or len(value) != 2:
        raise ParameterError(wanted)
    try:
        low, high = (number(name, v) for v in value)
    except ParameterError:
        raise ParameterError(wanted) from None
    if low > high:
        raise ParameterError(wanted)
    return low, high


def size(name: str, value: Any) -> tuple[int, int]:
    """A (width, height) pair of whole numbers of pixels, each in :data:`IMAGE_SIDE`, or ParameterError."""
    lo, hi = IMAGE_SIDE
    wanted = f"{name} must be a pair (width, height) of integers in [{lo}, {hi}] px, got {short(value)}"
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__") or len(value) != 2:
        raise ParameterError(wanted)
    try:
        return tuple(check_int(name, v, lo, hi) for v in value)
    except ParameterError:
        raise ParameterError(wanted) from None


def choice(name: str, value: Any, allowed: tuple) -> Any:
    """``value`` if it is one of ``allowed`` (None or strings), else ParameterError."""
    if (value is None or isinstance(value, str)) and value in allowed:
        return value
    listed = ", ".join("None" if a is None else repr(a) for a in allowed)
    raise ParameterError(f"{name} must be one of {listed}, got {short(value)}")


def flag(name: str, value: Any) -> bool:
    """A real bool (True or False; ``'false'``, 0 or None are refused) or ParameterError."""
    try:
        return check_bool(name, value)
    except ParameterError:
        raise ParameterError(f"{name} must be a bool (True or False), got {short(value)}") from None


def shape_points(value: Any) -> int:
    """Points along the cable: an integer in :data:`SHAPE_POINTS`, or ParameterError."""
    lo, hi = SHAPE_POINTS
    try:
        return check_int("shape_points", value, lo, hi)
    except ParameterError:
        raise ParameterError(f"shape_points must be an integer in [{lo}, {hi}], got {short(value)}") from None


def check_work(control_dt: float, settle_time: float, dt: float) -> tuple[int, int]:
    """(physics steps per control step, settling steps) at physics step ``dt`` [s], each capped
    (:data:`MAX_SUBSTEPS`, :data:`MAX_SETTLE_STEPS`) so that no step or reset runs for hours."""
    substeps = control_dt / dt
    if substeps > MAX_SUBSTEPS * (1.0 + 1e-9):  # a whole multiple at the cap passes despite rounding
        raise ParameterError(f"control_dt = {control_dt:g} s is {substeps:.4g} physics steps of dt = {dt:g} s; at most "
                             f"{MAX_SUBSTEPS} per control step (lower control_dt or raise dt in the randomisation)")
    settle = max(1, int(round(settle_time / dt)))  # noqa: RUF046 - as before: the same step count
    if settle > MAX_SETTLE_STEPS:
        raise ParameterError(f"settle_time = {settle_time:g} s is {settle} physics steps of dt = {dt:g} s; at most "
                             f"{MAX_SETTLE_STEPS} (lower settle_time or raise dt in the randomisation)")
    return int(round(substeps)), settle  # noqa: RUF046 - dt may be a NumPy float


def check_reset(seed: Any, options: Any) -> int | None:
    """``reset``'s inputs: ``seed`` None or an integer >= 0 (returned as an int); ``options`` None or
    an empty mapping (these environments take no reset options; a vector env's ``reset_mask`` is
    removed by the vector env before it reaches them). ParameterError otherwise."""
    if options is not None:
        if not isinstance(options, Mapping):
            raise ParameterError(f"options must be None or an empty dict (no reset options), got {short(options)}")
        if options:
            raise ParameterError(f"options: unknown key(s) {short(list(options))}; these environments take no reset "
                                 "options (None or {})")
    if seed is None:
        return None
    try:
        return check_int("seed", seed, 0)
    except ParameterError:
        raise ParameterError(f"seed must be None or an integer >= 0, got {short(seed)}") from None
