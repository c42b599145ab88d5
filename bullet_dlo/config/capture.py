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
from bullet_dlo.config.schema import one_of, only_keys, section
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.validate import ParameterError, check_in_range, check_int, check_positive

DISTS = ("uniform", "log_uniform", "normal", "choice", "fixed")
POLICIES = ("reject", "implicit", "substeps")
SPEC_KEYS = ("seed", "episode", "policy", "max_resamples", "camera", "sample", "resolve_tol", "quality")
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
    "friction": ("float", {"dist": "fixed", "value": 0.2}, (0.0, 2.0)),
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
}


@dataclass(frozen=True)
class Distribution:
    """One parameter's distribution: uniform(low, high), log_uniform(low, high),
    normal(mean, std, clipped to the parameter's range), choice(values) or fixed(value)."""

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
        return str(out)


def _number(key: str, field_name: str, value: Any, bounds: tuple = ()) -> float:
    wanted = f"a number in [{bounds[0]}, {bounds[1]}]" if bounds else "a finite number"
    try:
        if isinstance(value, bool):
            raise TypeError
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"sample.{key}.{field_name} must be {wanted}, got {value!r}") from None
    if not math.isfinite(v):
        raise ParameterError(f"sample.{key}.{field_name} must be {wanted}, got {value!r}")
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
    dist = one_of(f"sample.{key}.dist", data.pop("dist", None), DISTS)
    allowed = {"uniform": {"low", "high"}, "log_uniform": {"low", "high"}, "normal": {"mean", "std"},
               "choice": {"values"}, "fixed": {"value"}}[dist]
    if set(data) != allowed:
        raise ParameterError(f"sample.{key} ({dist}) needs exactly {', '.join(sorted(allowed))}; got "
                             f"{', '.join(sorted(data)) or 'nothing'}")

    def in_range(name: str, v: Any) -> None:
        if kind in ("float", "int") and bounds:
            num = _number(key, name, v, bounds)
            if not bounds[0] <= num <= bounds[1]:
                raise ParameterError(f"sample.{key}.{name} = {v} is outside the allowed range "
                                     f"[{bounds[0]}, {bounds[1]}]")

    if dist in ("uniform", "log_uniform"):
        low, high = _number(key, "low", data["low"]), _number(key, "high", data["high"])
        if low > high:
            raise ParameterError(f"sample.{key}: low ({low}) > high ({high})")
        if dist == "log_uniform" and low <= 0:
            raise ParameterError(f"sample.{key}: log_uniform needs low > 0, got {low}")
        in_range("low", low)
        in_range("high", high)
        return Distribution(dist, low=low, high=high)
    if dist == "normal":
        std = _number(key, "std", data["std"])
        if std < 0:
            raise ParameterError(f"sample.{key}.std must be >= 0, got {std}")
        mean = _number(key, "mean", data["mean"])
        in_range("mean", mean)
        return Distribution(dist, mean=mean, std=std)
    if dist == "choice":
        values = data["values"]
        if not isinstance(values, (list, tuple)) or not values:
            raise ParameterError(f"sample.{key}.values must be a non-empty list")
        for v in values:
            in_range("values", v)
            if kind == "int":  # a whole number: 8.4 is refused, never rounded
                check_int(f"sample.{key}.values", v, *bounds)
        return Distribution(dist, values=tuple(values))
    in_range("value", data["value"])
    if kind == "int":
        check_int(f"sample.{key}.value", data["value"], *bounds)
    return Distribution(dist, value=data["value"])


@dataclass(frozen=True)
class CaptureSpec:
    """A validated randomisation spec (see module doc)."""

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
        sample = {k: parse_distribution(k, v) for k, v in section(data.get("sample"), "sample").items()}
        for key in ("integrator", "robot"):
            if key in sample:
                _check_names(key, sample[key])
        return cls(seed=check_int("seed", data.get("seed", 0), 0),
                   duration=check_in_range("episode.duration", episode.get("duration", 2.0), 1e-3, 3600.0),
                   record_rate=check_in_range("episode.record_rate", episode.get("record_rate", 120.0), 0.01, 1e5),
                   policy=one_of("policy", str(data.get("policy", "substeps")), POLICIES),
                   max_resamples=check_int("max_resamples", data.get("max_resamples", 20), 1, 10_000),
                   camera_fps=check_in_range("camera.fps", camera.get("fps", 0.0), 0.0, 1000.0),
                   camera_width=check_int("camera.width", camera.get("width", 160), 1, 8192),
                   camera_height=check_int("camera.height", camera.get("height", 120), 1, 8192),
                   resolve_tol=check_positive("resolve_tol", data.get("resolve_tol", 0.02)), sample=sample,
                   max_sensor_model_rms=None if rms_limit is None else check_in_range(
                       "quality.max_sensor_model_rms [cable weights]", rms_limit, 1e-6, 1e6),
                   max_hf_energy=None if hf_limit is None else check_in_range(
                       "quality.max_hf_energy [share of the variance]", hf_limit, 0.0, 1.0))

    @classmethod
    def from_yaml(cls, path: str | Path) -> "CaptureSpec":
        """Load and validate a YAML capture spec."""
        return cls.from_dict(load_mapping(path, "capture spec"))

    def to_dict(self) -> dict:
        """The spec in its YAML form (``from_dict(to_dict())`` round-trips)."""
        sample = {}
        for k, v in self.sample.items():
            entry = {kk: (list(vv) if isinstance(vv, tuple) else vv) for kk, vv in asdict(v).items() if vv is not None}
            sample[k] = entry
        out = {"seed": self.seed, "episode": {"duration": self.duration, "record_rate": self.record_rate},
               "policy": self.policy, "max_resamples": self.max_resamples,
               "camera": {"fps": self.camera_fps, "width": self.camera_width, "height": self.camera_height},
               "resolve_tol": self.resolve_tol, "sample": sample}
        quality = {"max_sensor_model_rms": self.max_sensor_model_rms, "max_hf_energy": self.max_hf_energy}
        if quality != QUALITY_DEFAULTS:  # written only when set, so the digests of older specs stay the same
            out["quality"] = quality
        return out

    def digest(self) -> str:
        """Hash of the spec: a capture directory holds episodes of one spec only."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True, default=str).encode()).hexdigest()[:16]

    def draw(self, index: int, attempt: int = 0) -> dict[str, Any]:
        """Parameters of episode ``index`` (attempt > 0: a resample), from the generator [seed, index, attempt]."""
        rng = np.random.default_rng([self.seed, index, attempt])
        out = {}
        for key, (kind, default, bounds) in PARAMETERS.items():
            dist = self.sample.get(key) or parse_distribution(key, default)
            out[key] = dist.sample(rng, kind, bounds)
        out["noise_seed"] = int(rng.integers(2**31 - 1))
        return out


def _check_names(key: str, dist: Distribution) -> None:
    """A choice or fixed value of ``integrator`` or ``robot`` naming only known ones."""
    known = list(INTEGRATORS) if key == "integrator" else robot_names()
    values = list(dist.values or ()) + ([dist.value] if dist.value is not None else [])
    if dist.dist not in ("choice", "fixed"):
        raise ParameterError(f"sample.{key} must be a choice or fixed, got {dist.dist}")
    for v in values:
        if v not in known:
            raise ParameterError(f"sample.{key}: unknown {key} {v!r}; known: {', '.join(known)}")
