"""Domain-randomisation specs: distributions over every parameter of a dual-arm episode.

A spec (YAML or :class:`CaptureSpec`) gives, for each parameter, a distribution::

    seed: 7
    episode: {duration: 2.0, record_rate: 120}
    policy: substeps                  # reject | implicit | substeps (unstable samples)
    sample:
      youngs_modulus: {dist: log_uniform, low: 1.0e7, high: 5.0e9}
      n_masses: {dist: choice, values: [8, 10, 12]}
      diameter: {dist: uniform, low: 0.003, high: 0.006}
      ...
      dt: {dist: choice, values: [0.004166666666666667, 0.001]}
      integrator: {dist: choice, values: [implicit_euler, symplectic_euler]}
      robot: {dist: choice, values: [kuka, panda]}
      displacement_x: {dist: uniform, low: -0.1, high: 0.0}
      speed: {dist: uniform, low: 0.05, high: 0.2}
      noise_std: {dist: fixed, value: 0.0}
    camera: {fps: 0}                  # > 0 stores compressed frames at that rate

Episode i's parameters depend only on (seed, i): its generator is seeded with [seed, i].
``n_masses: auto`` lets each episode pick its number of masses by a convergence test on its
own scene (:func:`bullet_dlo.analysis.resolve.resolve_masses`, tolerance ``resolve_tol`` on end
forces); the sampled damping is then the k_d of a 10-mass cable, rescaled to keep its rate.
``damping_rate`` [1/s] and ``internal_damping`` [s] (see :class:`~bullet_dlo.core.spec.CableSpec`)
mean the same at any n and need no rescaling; ``damping`` (k_d, default 0.02) adds to them.

**Gripper motion.** Without a ``motion:`` section the right gripper makes one straight
minimum-jerk move (``displacement_x/y/z`` [m] at ``speed`` [m/s] from ``move_start`` [s]). A
``motion:`` section replaces it: a list of entries exactly as in a scene file's ``motion:``
(:func:`~bullet_dlo.core.boundary.parse_motion`: ``type: move | waypoints | sine``, end ``first`` =
left gripper, ``last`` = right gripper, times on the episode clock) in which any number (a time,
duration, frequency, phase, ramp, one component of a displacement, rotation or amplitude, one
waypoint coordinate) may be a distribution of the ``sample:`` grammar::

    motion:
      - {type: sine, end: last, amplitude: [0, 0, {dist: uniform, low: 0.01, high: 0.03}],
         frequency: {dist: uniform, low: 1.0, high: 3.0}, start: 0.2, duration: 1.2, ramp: 0.2}
      - {type: move, end: first, rotation: [0, 0, {dist: uniform, low: -0.3, high: 0.3}],
         start: 0.3, duration: 0.8}

Every number, given or drawn, lies in its key's range (:data:`MOTION_NUMBERS`: times [0, 3600] s,
durations [1e-3, 3600] s, frequency [1e-3, 1e3] Hz, phase and rotations [-6.2832, 6.2832] rad,
displacements and amplitudes [-1, 1] m; a normal is clipped to it). The spec is refused at load
unless every draw builds a valid core item: waypoint time ranges may not overlap, the first
waypoint is exactly [0, 0, 0], 2 x ramp <= duration for every draw, and each entry is built
with its distributions at their lowest, highest and typical values; errors name the key
(``motion[1].frequency``). With ``motion:``, the default move's parameters (:data:`MOVE_KEYS`) are
refused in ``sample:`` (they would do nothing) and left out of the drawn parameters, which hold
the drawn entries as ``motion`` instead. The motion's draws come from a generator of their own,
[seed, index, attempt, MOTION_STREAM], so they never change ``sample:``'s draws.

**Grip.** ``grip`` (choice or fixed of ``clamp`` | ``friction``), ``grip_force`` [N] per finger,
``grip_static_friction``, ``grip_dynamic_friction`` [-] and ``grip_reach`` [m] are passed to
:class:`~bullet_dlo.config.robot.DualArmSpec` (a friction grip holds up to 2 grip_static_friction
grip_force along the gripper, then slips at 2 grip_dynamic_friction grip_force and lets go after
slipping ``grip_reach``). Defaults: a clamp (force 5 N, friction 0.5 / 0.4, reach 0.02 m). Coulomb
friction needs dynamic <= static in every draw, so a spec whose ``grip_dynamic_friction`` range
reaches above the lowest ``grip_static_friction`` is refused at load (no clipping: every draw is what
the spec says; a normal spans the whole [0, 2] range, so use uniform or choice). They are drawn after
every older parameter and after ``noise_seed``: specs written before them keep their draws and digests.

**Renamed keys** (:data:`RENAMED`, one vocabulary with scene files and the API): ``friction`` is
``dynamic_friction``, ``grip_mu_static`` / ``grip_mu_dynamic`` are ``grip_static_friction`` /
``grip_dynamic_friction``. The old names are accepted for one release with a DeprecationWarning; a
spec's digest is computed under the old names, so a directory captured before the rename still
takes episodes of the renamed spec, and draws are unchanged (same order, same generator).

**Section and twist** (issue 22; see :class:`~bullet_dlo.core.spec.CableSpec`): ``poisson_ratio``,
``section`` (choice or fixed of ``round`` | ``tube`` | ``rectangle``), ``inner_diameter`` [m] (a tube's),
``width`` and ``thickness`` [m] (a rectangle's) and ``twist`` (choice or fixed of true | false: a material
frame, so the grippers' roll twists the cable and the wrists feel the torsion). Each dimension is used only
by its own section, so a spec may choose among sections; a spec whose tube bore can be drawn at 0 or reach
the lowest diameter, or whose rectangle can be drawn 0 m wide or thick, is refused at load. Drawn after the grips,
and in an episode's parameters only when ``sample:`` gives them (older specs keep their draws and their
episodes' parameters).

**Cable friction.** ``dynamic_friction`` and ``static_friction`` [-] (default 0.2 / 0.3): as the grip's, a spec
whose ``dynamic_friction`` range reaches above the lowest ``static_friction`` is refused at load.
``static_friction`` is drawn last, and is in an episode's parameters only when ``sample:`` gives it.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bullet_dlo.config.loader import load_mapping
from bullet_dlo.config.robot import robot_names
from bullet_dlo.config.schema import keyed, one_of, only_keys, section
from bullet_dlo.core.boundary import MOTION_TYPES, parse_motion
from bullet_dlo.core.enums import Dist, GripKind, IntegratorName, NamedSet, Section, UnstablePolicy
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.validate import ParameterError, check_in_range, check_int, check_positive, renamed_keys

DISTS = Dist.names()
POLICIES = UnstablePolicy.names()
RENAMED: dict[str, str] = {"friction": "dynamic_friction", "grip_mu_static": "grip_static_friction",
                           "grip_mu_dynamic": "grip_dynamic_friction"}
"""Deprecated ``sample:`` keys (and drawn parameter names) -> their names now (one release)."""
NAMED: dict[str, type[NamedSet]] = {"integrator": IntegratorName, "grip": GripKind, "section": Section}
"""``sample:`` keys whose values are a closed set (``robot`` is the open set of ``robots/``)."""
MAX_SEED = 2**62
"""Largest ``seed``: the seed (and the episode's ``seed + index`` of a rollout) is stored as a 64-bit integer."""
SPEC_KEYS = ("seed", "episode", "policy", "max_resamples", "camera", "sample", "resolve_tol", "quality", "motion")
QUALITY_DEFAULTS = {"max_sensor_model_rms": 1.0, "max_hf_energy": None}  # [cable weights], [share]

# parameter -> (kind, default distribution, allowed range) ; kind: float | int | str
PARAMETERS: dict[str, tuple[str, dict, tuple]] = {
    "length": ("float", {"dist": "fixed", "value": 0.3}, (0.05, 2.0)),
    "diameter": ("float", {"dist": "fixed", "value": 0.004}, (5e-4, 0.05)),
    "mass": ("float", {"dist": "fixed", "value": 0.03}, (1e-4, 5.0)),
    "youngs_modulus": ("float", {"dist": "fixed", "value": 126e6}, (1e4, 1e12)),
    "n_masses": ("int", {"dist": "fixed", "value": 10}, (3, 200)),
    "damping": ("float", {"dist": "fixed", "value": 0.02}, (0.0, 10.0)),
    "damping_rate": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 1e3)),
    "internal_damping": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 0.1)),
    "dynamic_friction": ("float", {"dist": "fixed", "value": 0.2}, (0.0, 2.0)),
    "dt": ("float", {"dist": "fixed", "value": 1.0 / 240.0}, (1e-5, 0.05)),
    "integrator": ("str", {"dist": "fixed", "value": "implicit_euler"}, ()),
    "robot": ("str", {"dist": "fixed", "value": "kuka"}, ()),
    "hold_height": ("float", {"dist": "fixed", "value": 0.35}, (0.27, 0.6)),
    "displacement_x": ("float", {"dist": "fixed", "value": 0.0}, (-0.15, 0.1)),
    "displacement_y": ("float", {"dist": "fixed", "value": 0.0}, (-0.15, 0.15)),
    "displacement_z": ("float", {"dist": "fixed", "value": 0.005}, (-0.1, 0.2)),
    "speed": ("float", {"dist": "fixed", "value": 0.05}, (1e-3, 1.0)),
    "move_start": ("float", {"dist": "fixed", "value": 0.5}, (0.0, 100.0)),
    "noise_std": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 10.0)),
    "sensor_rate": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 1e5)),
    # drawn after everything above (and after noise_seed): older specs keep their draws
    "grip": ("str", {"dist": "fixed", "value": "clamp"}, ()),
    "grip_force": ("float", {"dist": "fixed", "value": 5.0}, (1e-3, 1e3)),
    "grip_static_friction": ("float", {"dist": "fixed", "value": 0.5}, (0.0, 2.0)),
    "grip_dynamic_friction": ("float", {"dist": "fixed", "value": 0.4}, (0.0, 2.0)),
    "grip_reach": ("float", {"dist": "fixed", "value": 0.02}, (1e-4, 0.5)),
    # the section and the material frame (issue 22), drawn after the grips; in an episode's parameters only
    # when the spec samples them (older specs keep their draws and their episodes' parameters)
    "poisson_ratio": ("float", {"dist": "fixed", "value": 0.3}, (0.0, 0.49)),
    "section": ("str", {"dist": "fixed", "value": "round"}, ()),
    "inner_diameter": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 0.05)),
    "width": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 0.05)),
    "thickness": ("float", {"dist": "fixed", "value": 0.0}, (0.0, 0.05)),
    "twist": ("bool", {"dist": "fixed", "value": False}, ()),
    # the cable's static friction, drawn after the sections, only when sampled (older specs keep their draws)
    "static_friction": ("float", {"dist": "fixed", "value": 0.3}, (0.0, 2.0)),
}
SECTION_KEYS = ("poisson_ratio", "section", "inner_diameter", "width", "thickness", "twist")
OPTIONAL_KEYS = SECTION_KEYS + ("static_friction",)  # in an episode's parameters only when the spec samples them
DRAWN_LAST = ("grip", "grip_force", "grip_static_friction", "grip_dynamic_friction", "grip_reach") + OPTIONAL_KEYS


@dataclass(frozen=True)
class Distribution:
    """One parameter's distribution: uniform(low, high), log_uniform(low, high),
    normal(mean, std, clipped to the parameter's range), choice(values) or fixed(value).

    Every number is in the parameter's own unit [as in :data:`PARAMETERS`: m, kg, Pa, s, N, -], and a
    field the distribution does not use is None.

    dist: :class:`~bullet_dlo.core.enums.Dist`.
    low: lower end of a uniform or log-uniform range [the parameter's unit].
    high: upper end of a uniform or log-uniform range [the parameter's unit].
    mean: of a normal [the parameter's unit].
    std: standard deviation of a normal [the parameter's unit].
    values: the choices of a choice.
    value: the value of a fixed.
    """

    dist: str
    low: float | None = None
    high: float | None = None
    mean: float | None = None
    std: float | None = None
    values: tuple | None = None
    value: Any = None

    def sample(self, rng: np.random.Generator, kind: str, bounds: tuple) -> Any:
        if self.dist == "fixed":
            out = self.value
        elif self.dist == "choice":
            out = self.values[int(rng.integers(len(self.values)))]
        elif self.dist == "uniform":
            out = rng.uniform(self.low, self.high)
        elif self.dist == "log_uniform":
            out = math.exp(rng.uniform(math.log(self.low), math.log(self.high)))
        else:
            out = rng.normal(self.mean, self.std)
            if bounds:
                out = min(max(out, bounds[0]), bounds[1])
        if kind == "int":
            return out if out == "auto" else int(round(out))
        if kind == "float":
            return float(out)
        if kind == "bool":
            return bool(out)
        return str(out)


def _number(name: str, field_name: str, value: Any, bounds: tuple = ()) -> float:
    """``value`` as a finite float; the error names ``<name>.<field_name>`` (e.g. ``sample.length.low``)."""
    wanted = f"a number in [{bounds[0]}, {bounds[1]}]" if bounds else "a finite number"
    try:
        if isinstance(value, bool):
            raise TypeError
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}.{field_name} must be {wanted}, got {value!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"{name}.{field_name} must be {wanted}, got {value!r}")
    return v


def parse_distribution(key: str, data: Mapping[str, Any]) -> Distribution:
    """Validate one parameter's distribution; errors name ``sample.<key>``."""
    if key not in PARAMETERS:
        raise ParameterError(f"unknown parameter sample.{key}; known: {', '.join(PARAMETERS)}")
    if not isinstance(data, Mapping):
        data = {"dist": "fixed", "value": data}
    data = dict(data)
    if key == "n_masses" and data == {"dist": "fixed", "value": "auto"}:
        return Distribution("fixed", value="auto")  # chosen per episode by resolve_masses
    kind, _, bounds = PARAMETERS[key]
    return _distribution(f"sample.{key}", data, kind, bounds)


def _distribution(name: str, data: Mapping[str, Any], kind: str, bounds: tuple) -> Distribution:
    """Validate a distribution mapping of the value called ``name`` (``sample.length``, ``motion[0].frequency``)
    of ``kind`` (float | int | str) whose every value must lie in ``bounds`` (() for names)."""
    data = dict(data)
    dist = one_of(f"{name}.dist", data.pop("dist", None), Dist)
    if kind == "bool" and dist not in ("choice", "fixed"):
        raise ParameterError(f"{name} must be a choice or fixed (of true, false), got {dist}")
    allowed = {"uniform": {"low", "high"}, "log_uniform": {"low", "high"}, "normal": {"mean", "std"},
               "choice": {"values"}, "fixed": {"value"}}[dist]
    if set(data) != allowed:
        raise ParameterError(f"{name} ({dist}) needs exactly {', '.join(sorted(allowed))}; got "
                             f"{', '.join(sorted(data)) or 'nothing'}")

    def in_range(field_name: str, v: Any) -> None:
        if kind == "bool" and not isinstance(v, bool):
            raise ParameterError(f"{name}.{field_name} must be true or false, got {v!r}")
        if kind in ("float", "int") and bounds:
            num = _number(name, field_name, v, bounds)
            if not bounds[0] <= num <= bounds[1]:
                raise ParameterError(f"{name}.{field_name} = {v} is outside the allowed range "
                                     f"[{bounds[0]}, {bounds[1]}]")

    if dist in ("uniform", "log_uniform"):
        low, high = _number(name, "low", data["low"]), _number(name, "high", data["high"])
        if low > high:
            raise ParameterError(f"{name}: low ({low}) > high ({high})")
        if dist == "log_uniform" and low <= 0:
            raise ParameterError(f"{name}: log_uniform needs low > 0, got {low}")
        in_range("low", low)
        in_range("high", high)
        return Distribution(dist, low=low, high=high)
    if dist == "normal":
        std = _number(name, "std", data["std"])
        if std < 0:
            raise ParameterError(f"{name}.std must be >= 0, got {std}")
        mean = _number(name, "mean", data["mean"])
        in_range("mean", mean)
        return Distribution(dist, mean=mean, std=std)
    if dist == "choice":
        values = data["values"]
        if not isinstance(values, (list, tuple)) or not values:
            raise ParameterError(f"{name}.values must be a non-empty list")
        for v in values:
            in_range("values", v)
            if kind == "int":  # a whole number: 8.4 is refused, never rounded
                check_int(f"{name}.values", v, *bounds)
        return Distribution(dist, values=tuple(values))
    in_range("value", data["value"])
    if kind == "int":
        check_int(f"{name}.value", data["value"], *bounds)
    return Distribution(dist, value=data["value"])


def support(dist: Distribution, bounds: tuple) -> tuple[float, float]:
    """Smallest and largest value ``dist`` can draw (a normal is clipped to ``bounds``, so it spans them)."""
    if dist.dist == "fixed":
        return float(dist.value), float(dist.value)
    if dist.dist == "choice":
        return float(min(dist.values)), float(max(dist.values))
    if dist.dist == "normal":
        return float(bounds[0]), float(bounds[1])
    return float(dist.low), float(dist.high)


def _distribution_dict(dist: Distribution) -> dict:
    """A distribution in its YAML form."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(dist).items() if v is not None}


# ----- the motion: section ------------------------------------------------------------------------
# every number of a motion entry, given or drawn, lies in its key's range: (low, high, unit)
MOTION_NUMBERS: dict[str, tuple[float, float, str]] = {
    "start": (0.0, 3600.0, "s"), "duration": (1e-3, 3600.0, "s"), "ramp": (0.0, 1800.0, "s"),
    "frequency": (1e-3, 1e3, "Hz"), "phase": (-6.2832, 6.2832, "rad"), "times": (0.0, 3600.0, "s"),
    "displacement": (-1.0, 1.0, "m"), "amplitude": (-1.0, 1.0, "m"), "displacements": (-1.0, 1.0, "m"),
    "rotation": (-6.2832, 6.2832, "rad"), "rotations": (-6.2832, 6.2832, "rad"),
}
MOTION_VECTORS = ("displacement", "amplitude", "rotation")  # [x, y, z]
MOTION_ROWS = ("displacements", "rotations")  # one [x, y, z] per waypoint
MOTION_STREAM = 0x6D6F74  # tags the motion's generator [seed, index, attempt, tag], apart from sample:'s
MOVE_KEYS = ("displacement_x", "displacement_y", "displacement_z", "speed", "move_start")  # the default move's


def parse_motion_section(items: Any) -> tuple[dict, ...]:
    """Validate a capture spec's ``motion:`` list: scene-file motion entries whose numbers may be
    distributions. Returns the entries with every number a float or a :class:`Distribution`.

    Refused (one ParameterError naming ``motion[k].<key>``): a number or distribution outside its
    key's range (:data:`MOTION_NUMBERS`), waypoint times whose ranges overlap, a sine ramp that can
    exceed half its duration, and anything the core item refuses at the lowest, highest or typical values.
    """
    if items is None:
        return ()
    if not isinstance(items, (list, tuple)) or not items:
        raise ParameterError(f"motion must be a non-empty list of motion entries (type: {' | '.join(MOTION_TYPES)}),"
                             f" got {'[]' if isinstance(items, (list, tuple)) else type(items).__name__}; leave it out for the default straight move (no move: "
                             "sample.displacement_z: 0)")
    entries = []
    for k, item in enumerate(items):
        where = f"motion[{k}]"
        data = section(item, where)
        kind = one_of(f"{where}.type", str(data.get("type", "move")).lower(), MOTION_TYPES)
        entry = {"type": kind, **{key: _motion_value(f"{where}.{key}", key, v) for key, v in data.items()
                                  if key != "type"}}
        _check_overlaps(where, entry)
        entries.append(entry)
    for pick in ("low", "high", "typical"):  # the core's own checks, at the ends of every range
        built = [_pick(e, pick) for e in entries]
        for k, entry in enumerate(built):
            keyed(f"motion[{k}]", parse_motion, [entry])
        parse_motion(built)  # rules across entries (one waypoints entry per end); its message names motion
    return tuple(entries)


def _motion_value(name: str, key: str, value: Any) -> Any:
    """One key of a motion entry: numbers (or lists of them) checked against the key's range, others kept."""
    if key not in MOTION_NUMBERS or (value is None and key in ("duration", "rotations")):  # the core's defaults
        return value
    lo, hi, unit = MOTION_NUMBERS[key]
    if key in MOTION_VECTORS:
        return [_motion_number(f"{name}[{i}]", v, key) for i, v in enumerate(_list(name, value, 3, unit, lo, hi))]
    if key == "times":
        return [_motion_number(f"{name}[{i}]", v, key) for i, v in enumerate(_list(name, value, 0, unit, lo, hi))]
    if key in MOTION_ROWS:
        rows = _list(name, value, 0, unit, lo, hi)
        return [[_motion_number(f"{name}[{i}][{j}]", v, key) for j, v in enumerate(_list(f"{name}[{i}]", row, 3,
                                                                                            unit, lo, hi))]
                for i, row in enumerate(rows)]
    return _motion_number(name, value, key)


def _list(name: str, value: Any, n: int, unit: str, lo: float, hi: float) -> list:
    """``value`` as a list (of ``n`` items when n > 0), else a ParameterError naming ``name``."""
    if not isinstance(value, (list, tuple)) or (n and len(value) != n) or not value:
        what = "[x, y, z]" if n == 3 else "a non-empty list"
        raise ParameterError(f"{name} must be {what} of numbers in [{lo}, {hi}] {unit} (or distributions), "
                             f"got {value!r}")
    return list(value)


def _motion_number(name: str, value: Any, key: str) -> float | Distribution:
    """A number of a motion entry: a float in the key's range, or a distribution whose every draw is."""
    lo, hi, unit = MOTION_NUMBERS[key]
    if isinstance(value, Mapping):
        return _distribution(name, value, "float", (lo, hi))
    return check_in_range(f"{name} [{unit}]", value, lo, hi)


def _span(value: Any, key: str) -> tuple[float, float]:
    """Smallest and largest value of a motion number (a float or a distribution)."""
    if isinstance(value, Distribution):
        return support(value, MOTION_NUMBERS[key][:2])
    return float(value), float(value)


def _check_overlaps(where: str, entry: dict) -> None:
    """Every draw keeps waypoint times increasing, the first waypoint at the start pose and a sine's
    ramps within its duration."""
    for key in MOTION_ROWS:
        rows = entry.get(key)
        if entry["type"] == "waypoints" and rows and any(_span(v, key) != (0.0, 0.0) for v in rows[0]):
            raise ParameterError(f"{where}.{key}[0] must be [0, 0, 0] (the start pose; nothing drawn), "
                                 f"got {_motion_yaml({key: rows[0]})[key]!r}")
    times = entry.get("times")
    if entry["type"] == "waypoints" and isinstance(times, list):
        for i in range(1, len(times)):
            (_, before), (after, _) = _span(times[i - 1], "times"), _span(times[i], "times")
            if after <= before:
                raise ParameterError(f"{where}.times[{i}] can be drawn at or before times[{i - 1}] "
                                     f"(from {after} s, while times[{i - 1}] reaches {before} s): each time's "
                                     "range must lie above the previous one's")
    if entry["type"] == "sine" and "ramp" in entry and entry.get("duration") is not None:
        ramp, duration = _span(entry["ramp"], "ramp")[1], _span(entry["duration"], "duration")[0]
        if 2 * ramp > duration:
            raise ParameterError(f"{where}.ramp can be drawn above half the duration (ramp up to {ramp} s, "
                                 f"duration from {duration} s): keep 2 x ramp <= duration")


def _pick(entry: dict, pick: str) -> dict:
    """The entry with each distribution replaced by its lowest, highest or typical (mean, first, middle) value."""
    def one(value: Any, key: str) -> Any:
        if isinstance(value, list):
            return [one(v, key) for v in value]
        if not isinstance(value, Distribution):
            return value
        lo, hi = _span(value, key)
        if pick != "typical":
            return lo if pick == "low" else hi
        return {"fixed": value.value, "choice": (value.values or (0,))[0], "normal": value.mean}.get(
            value.dist, 0.5 * (lo + hi))

    return {key: one(v, key) for key, v in entry.items()}


def draw_motion_entries(entries: tuple[dict, ...], rng: np.random.Generator) -> list[dict]:
    """The motion entries with every distribution drawn from ``rng`` (keys in sorted order, so the draws do
    not depend on how the spec was written), JSON-able: what :func:`~bullet_dlo.core.boundary.parse_motion` takes."""
    def one(value: Any, key: str) -> Any:
        if isinstance(value, list):
            return [one(v, key) for v in value]
        if isinstance(value, Distribution):
            return value.sample(rng, "float", MOTION_NUMBERS[key][:2])
        return value

    return [{key: one(entry[key], key) for key in sorted(entry)} for entry in entries]


def _motion_yaml(entry: dict) -> dict:
    """A motion entry in its YAML form (distributions as mappings)."""
    def one(value: Any) -> Any:
        if isinstance(value, list):
            return [one(v) for v in value]
        return _distribution_dict(value) if isinstance(value, Distribution) else value

    return {key: one(v) for key, v in entry.items()}


@dataclass(frozen=True)
class CaptureSpec:
    """A validated randomisation spec (see module doc; :meth:`from_dict` is its boundary).

    seed: of every episode's generator [-]; duration: of an episode [s] (``episode.duration``);
    record_rate: samples stored per second [Hz] (``episode.record_rate``); policy: what an unstable draw
    gets, :class:`~bullet_dlo.core.enums.UnstablePolicy`; max_resamples: draws tried per episode [-];
    camera_fps: stored frames per second [Hz] (0: none); camera_width, camera_height: frame size [px];
    resolve_tol: relative tolerance [-] of ``n_masses: auto``; sample: the distribution of each parameter
    (:data:`PARAMETERS`); max_sensor_model_rms: RMS |sensor - model| above which an episode is flagged
    [cable weights] (None: never); max_hf_energy: share of the F/T variance above 10 Hz that flags an
    episode [-] (None: never); motion: the ``motion:`` entries, numbers as floats or Distributions.
    """

    seed: int = 0
    duration: float = 2.0
    record_rate: float = 120.0
    policy: str = "substeps"
    max_resamples: int = 20
    camera_fps: float = 0.0
    camera_width: int = 160
    camera_height: int = 120
    resolve_tol: float = 0.02
    sample: dict[str, Distribution] = field(default_factory=dict)
    max_sensor_model_rms: float | None = 1.0  # [cable weights] RMS |sensor - model| above it flags an episode
    max_hf_energy: float | None = None  # share of the F/T variance above 10 Hz that flags an episode
    motion: tuple[dict, ...] = ()  # motion entries, numbers as floats or Distributions (parse_motion_section)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "CaptureSpec":
        """Validate a parsed spec; errors name the offending key (``sample.<parameter>``, ``episode.duration``)."""
        data = section(data, "capture spec")
        only_keys(data, SPEC_KEYS, "capture spec")
        episode = section(data.get("episode"), "episode")
        only_keys(episode, ("duration", "record_rate"), "episode")
        camera = section(data.get("camera"), "camera")
        only_keys(camera, ("fps", "width", "height"), "camera")
        quality = {**QUALITY_DEFAULTS, **section(data.get("quality"), "quality")}
        only_keys(quality, tuple(QUALITY_DEFAULTS), "quality")
        rms_limit, hf_limit = quality["max_sensor_model_rms"], quality["max_hf_energy"]
        raw = renamed_keys(section(data.get("sample"), "sample"), RENAMED, "sample.", stacklevel=3)
        sample = {k: parse_distribution(k, v) for k, v in raw.items()}
        for key in ("integrator", "robot", "grip", "section"):
            if key in sample:
                _check_names(key, sample[key])
        _check_friction_order(sample)
        _check_grip_integrator(sample)
        _check_sections(sample)
        motion = parse_motion_section(data.get("motion"))
        for key in MOVE_KEYS:
            if motion and key in sample:
                raise ParameterError(f"sample.{key} sets the default straight move of the right gripper, which "
                                     f"the motion: section replaces; with motion:, leave out {', '.join(MOVE_KEYS)}")
        return cls(seed=check_int("seed", data.get("seed", 0), 0, MAX_SEED),
                   duration=check_in_range("episode.duration", episode.get("duration", 2.0), 1e-3, 3600.0),
                   record_rate=check_in_range("episode.record_rate", episode.get("record_rate", 120.0), 0.01, 1e5),
                   policy=one_of("policy", data.get("policy", "substeps"), UnstablePolicy),
                   max_resamples=check_int("max_resamples", data.get("max_resamples", 20), 1, 10_000),
                   camera_fps=check_in_range("camera.fps", camera.get("fps", 0.0), 0.0, 1000.0),
                   camera_width=check_int("camera.width", camera.get("width", 160), 1, 8192),
                   camera_height=check_int("camera.height", camera.get("height", 120), 1, 8192),
                   resolve_tol=check_positive("resolve_tol", data.get("resolve_tol", 0.02)), sample=sample,
                   max_sensor_model_rms=None if rms_limit is None else check_in_range(
                       "quality.max_sensor_model_rms [cable weights]", rms_limit, 1e-6, 1e6),
                   max_hf_energy=None if hf_limit is None else check_in_range(
                       "quality.max_hf_energy [share of the variance]", hf_limit, 0.0, 1.0), motion=motion)

    @classmethod
    def from_yaml(cls, path: str | Path) -> "CaptureSpec":
        """Load and validate a YAML capture spec."""
        return cls.from_dict(load_mapping(path, "capture spec"))

    def to_dict(self) -> dict:
        """The spec in its YAML form (``from_dict(to_dict())`` round-trips)."""
        sample = {k: _distribution_dict(v) for k, v in self.sample.items()}
        out = {"seed": self.seed, "episode": {"duration": self.duration, "record_rate": self.record_rate},
               "policy": self.policy, "max_resamples": self.max_resamples,
               "camera": {"fps": self.camera_fps, "width": self.camera_width, "height": self.camera_height},
               "resolve_tol": self.resolve_tol, "sample": sample}
        quality = {"max_sensor_model_rms": self.max_sensor_model_rms, "max_hf_energy": self.max_hf_energy}
        if quality != QUALITY_DEFAULTS:  # written only when set, so the digests of older specs stay the same
            out["quality"] = quality
        if self.motion:  # likewise
            out["motion"] = [_motion_yaml(e) for e in self.motion]
        return out

    def digest(self) -> str:
        """Hash of the spec: a capture directory holds episodes of one spec only. Computed with the sample
        keys under their names before :data:`RENAMED`, so a spec's digest did not change with the rename."""
        out = self.to_dict()
        old = {new: old for old, new in RENAMED.items()}
        out["sample"] = {old.get(k, k): v for k, v in out["sample"].items()}
        return hashlib.sha256(json.dumps(out, sort_keys=True, default=str).encode()).hexdigest()[:16]

    def draw(self, index: int, attempt: int = 0) -> dict[str, Any]:
        """Parameters of episode ``index`` (attempt > 0: a resample), from the generator [seed, index, attempt];
        with a ``motion:`` section, ``motion`` holds the drawn entries (:meth:`draw_motion`) in place of the
        default move's parameters (:data:`MOVE_KEYS`)."""
        rng = np.random.default_rng([self.seed, index, attempt])
        out = {}
        for key in [k for k in PARAMETERS if k not in DRAWN_LAST]:
            out[key] = self._sample(key, rng)
        out["noise_seed"] = int(rng.integers(2**31 - 1))
        for key in DRAWN_LAST:
            if key in OPTIONAL_KEYS and key not in self.sample:
                continue  # its default (the plain round cable), drawn without a number from rng
            out[key] = self._sample(key, rng)
        if self.motion:
            for key in MOVE_KEYS:
                del out[key]
            out["motion"] = self.draw_motion(index, attempt)
        return out

    def draw_motion(self, index: int, attempt: int = 0) -> list[dict]:
        """The ``motion:`` entries of episode ``index`` with their distributions drawn (JSON-able, what
        :func:`~bullet_dlo.core.boundary.parse_motion` takes), from a generator of their own,
        [seed, index, attempt, MOTION_STREAM], so ``sample:``'s draws do not depend on them."""
        return draw_motion_entries(self.motion, np.random.default_rng([self.seed, index, attempt, MOTION_STREAM]))

    def _sample(self, key: str, rng: np.random.Generator) -> Any:
        kind, default, bounds = PARAMETERS[key]
        return (self.sample.get(key) or parse_distribution(key, default)).sample(rng, kind, bounds)


def _check_names(key: str, dist: Distribution) -> None:
    """A choice or fixed value of ``integrator``, ``robot``, ``grip`` or ``section`` naming only known ones."""
    known = list(NAMED[key].names()) if key in NAMED else robot_names()
    values = list(dist.values or ()) + ([dist.value] if dist.value is not None else [])
    if dist.dist not in ("choice", "fixed"):
        raise ParameterError(f"sample.{key} must be a choice or fixed, got {dist.dist}")
    for v in values:
        if v not in known:
            raise ParameterError(f"sample.{key}: unknown {key} {v!r}; known: {', '.join(known)}")


def _values(sample: dict[str, Distribution], key: str) -> tuple:
    """Every value a choice or fixed parameter ``key`` can be drawn as (its default where not sampled)."""
    dist = sample.get(key) or parse_distribution(key, PARAMETERS[key][1])
    return tuple(dist.values) if dist.dist == "choice" else (dist.value,)


def _check_grip_integrator(sample: dict[str, Distribution]) -> None:
    """Refuse a spec that can draw a friction grip with an explicit integrator: every such episode would
    fail after building (the grip is part of an implicit step)."""
    explicit = [v for v in _values(sample, "integrator") if v in INTEGRATORS and INTEGRATORS[v].explicit]
    if "friction" in _values(sample, "grip") and explicit:
        raise ParameterError(f"sample.grip can be drawn as friction with sample.integrator {', '.join(explicit)}: "
                             f"a friction grip needs an implicit integrator; draw only implicit ones or no friction grip")


def _check_friction_order(sample: dict[str, Distribution]) -> None:
    """Refuse friction ranges (the cable's, the grip's) that allow a draw with dynamic > static friction (Coulomb
    friction needs dynamic <= static; refusing at load rather than clipping keeps every draw what the spec says)."""
    for static, dynamic in (("static_friction", "dynamic_friction"), ("grip_static_friction", "grip_dynamic_friction")):
        dists = {k: sample.get(k) or parse_distribution(k, PARAMETERS[k][1]) for k in (static, dynamic)}
        lowest_static = support(dists[static], PARAMETERS[static][2])[0]
        highest_dynamic = support(dists[dynamic], PARAMETERS[dynamic][2])[1]
        if highest_dynamic > lowest_static:
            raise ParameterError(f"sample.{dynamic} can be drawn above sample.{static} (up to {highest_dynamic} > "
                                 f"{lowest_static}); every draw needs 0 <= dynamic <= static friction: make the whole "
                                 f"{dynamic} range lie at or below the {static} range")


def _check_sections(sample: dict[str, Distribution]) -> None:
    """Refuse section dimensions that some draw could make invalid: a tube's inner diameter must stay above 0 and
    below the lowest drawn diameter, a rectangle's width and thickness above 0. Each dimension is used only by its own
    section (an episode that draws another section ignores it), so one spec may choose among sections."""
    def span(key: str) -> tuple[float, float]:
        return support(sample.get(key) or parse_distribution(key, PARAMETERS[key][1]), PARAMETERS[key][2])

    dist = sample.get("section") or parse_distribution("section", PARAMETERS["section"][1])
    sections = set(dist.values or ()) | ({dist.value} if dist.value is not None else set())
    if "tube" in sections and span("inner_diameter")[0] <= 0.0:
        raise ParameterError(f"sample.inner_diameter can be drawn at 0 m (from {span('inner_diameter')[0]}): a tube "
                             "needs a bore > 0 in every draw (a solid section is round)")
    if "tube" in sections and span("inner_diameter")[1] >= span("diameter")[0]:
        raise ParameterError(f"sample.inner_diameter can be drawn at or above sample.diameter (up to "
                             f"{span('inner_diameter')[1]} m, diameter from {span('diameter')[0]} m): a tube's bore "
                             "must be smaller than its diameter in every draw")
    if "rectangle" in sections:
        for key in ("width", "thickness"):
            if span(key)[0] <= 0.0:
                raise ParameterError(f"sample.{key} can be drawn at 0 m (from {span(key)[0]}): a rectangle needs "
                                     f"width and thickness > 0 in every draw")
