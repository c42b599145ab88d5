"""Scene files: a portable YAML description of one cable run, and running it.

Schema (extra keys are rejected with a message naming them)::

    cable: {length: 0.3, diameter: 0.004, mass: 0.03, youngs_modulus: 126.0e6,
            n_masses: 10, damping: 0.01}           # or {preset: lv2017, n_masses: 20}
    layout: {start: [0, 0, 0.5], direction: [1, 0, 0]}   # straight from mass 0
    ends: {first: clamped, last: clamped}                 # free | pinned | fork | clamped
    motion: [{end: last, displacement: [0, 0, 0.005], start: 0.5, duration: 0.1}]
    gravity: [0, 0, -9.81]
    integrator: implicit_euler
    dt: 0.001
    duration: 2.0
    # optional
    initial: straight            # or static: start from the equilibrium under gravity
    detector: {max_strain: 0.5, energy_factor: 1.0, check_every: 1, energy_every: 10}
    newton: {max_iter: 8, tol: 1.0e-9}
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bullet_dlo.config.loader import load_mapping
from bullet_dlo.config.robot import ArmsOptions
from bullet_dlo.config.schema import check_cable, keyed, one_of, only_keys, section
from bullet_dlo.config.world import BulletOptions
from bullet_dlo.core.boundary import Move, parse_motion
from bullet_dlo.core.engine import DetectorOptions, SimulationResult
from bullet_dlo.core.enums import EndMode, InitialShape, IntegratorName, ToleranceTarget, name_of
from bullet_dlo.core.integrators import NewtonOptions, get_integrator
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState
from bullet_dlo.core.spec import RENAMED as CABLE_RENAMED
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import (
    ParameterError,
    check_positive,
    check_steps,
    check_vector3,
    renamed_keys,
)

TOP_KEYS = ("cable", "layout", "ends", "motion", "gravity", "integrator", "dt", "duration",
            "initial", "detector", "newton", "name", "bullet", "tolerance", "arms")
INITIAL = InitialShape.names()
TOLERANCE_TARGETS = ToleranceTarget.names()


@dataclass(frozen=True)
class Scene:
    """A validated scene: cable, layout, end conditions, motion, integration settings (a scene file's
    keys; see docs/guides/scene-files.md). Validated once, in :meth:`from_dict`.

    Attributes:
        cable: the cable (``cable:``).
        start: position of mass 0 [m] (``layout.start``).
        direction: unit direction of the straight cable from mass 0 [-] (``layout.direction``).
        ends: (first, last) end modes, :class:`~bullet_dlo.core.enums.EndMode` (``ends:``).
        motion: prescribed end motions (``motion:``).
        gravity: [m/s^2].
        integrator: :class:`~bullet_dlo.core.enums.IntegratorName`.
        dt: time step [s].
        duration: simulated time [s].
        initial: :class:`~bullet_dlo.core.enums.InitialShape`, or None when not given (straight for
            ``simulate``, settled for the dual-arm scene).
        detector: instability detector settings (``detector:``).
        newton: Newton solver settings of the implicit integrators (``newton:``).
        name: the scene's name [-].
        bullet: the ``bullet:`` section.
        auto_n: ``n_masses: auto`` was given [-].
        auto_dt: ``dt: auto`` was given (also picks the integrator) [-].
        tolerance: relative tolerance of ``auto`` resolution [-] (``tolerance.value``).
        tolerance_target: :class:`~bullet_dlo.core.enums.ToleranceTarget` (``tolerance.target``).
        arms: the ``arms:`` section, None when the file has none (the arm defaults apply).
        given: the top-level keys the file gave (an engine refuses those it cannot honour).
        twist_reason: why the material frame is on although the file did not ask for it (a clamp rolls
            about the cable's axis; set by :func:`bullet_dlo.sim.resolved`), "" otherwise [-].
    """

    cable: CableSpec
    start: tuple[float, float, float] = (0.0, 0.0, 0.5)
    direction: tuple[float, float, float] = (1.0, 0.0, 0.0)
    ends: tuple[str, str] = ("clamped", "clamped")
    motion: tuple[Move, ...] = ()
    gravity: tuple[float, float, float] = STANDARD_GRAVITY
    integrator: str = "implicit_euler"
    dt: float = 1e-3
    duration: float = 1.0
    initial: str | None = None  # None: not given (straight for simulate, settled for the dual-arm scene)
    detector: DetectorOptions = field(default_factory=DetectorOptions)
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    name: str = "scene"
    bullet: BulletOptions = field(default_factory=BulletOptions)
    auto_n: bool = False  # n_masses: auto
    auto_dt: bool = False  # dt: auto (also picks the integrator)
    tolerance: float = 0.01
    tolerance_target: str = "both"
    arms: ArmsOptions | None = None  # None: the file has no ``arms:`` section (the arm defaults apply)
    given: frozenset[str] = frozenset()  # the top-level keys the scene file gave (an engine refuses those it cannot honour)
    twist_reason: str = ""  # why the frame was switched on by need (sim.resolved), "" when not

    # ----- parsing -------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Scene":
        """Validate a parsed scene mapping; errors name the offending key."""
        data = section(data, "scene")
        only_keys(data, TOP_KEYS, "scene")
        if "cable" not in data:
            raise ParameterError("cable: missing (give cable parameters or {preset: lv2017})")
        cable_map = renamed_keys(section(data["cable"], "cable"), CABLE_RENAMED, "cable.", stacklevel=3)
        auto_n = cable_map.get("n_masses") == "auto"
        if auto_n:
            cable_map["n_masses"] = 10  # placeholder until resolve() picks it
        check_cable(cable_map)  # the bounds capture specs share (config.schema.CABLE_BOUNDS)
        cable = keyed("cable", CableSpec.from_dict, cable_map)
        auto_dt = data.get("dt") == "auto"
        if auto_dt:
            data = {**data, "dt": 1e-3}
        tol = section(data.get("tolerance"), "tolerance")
        only_keys(tol, ("value", "target"), "tolerance")
        tol_value = keyed("tolerance.value", check_positive, "tolerance", tol.get("value", 0.01))
        tol_target = one_of("tolerance.target", tol.get("target", "both"), ToleranceTarget)
        layout = section(data.get("layout"), "layout")
        only_keys(layout, ("start", "direction"), "layout")
        start = tuple(keyed("layout.start", check_vector3, "start", layout.get("start", (0.0, 0.0, 0.5))))
        direction = tuple(keyed("layout.direction", check_vector3, "direction",
                                layout.get("direction", (1.0, 0.0, 0.0)), unit=True))
        ends_map = section(data.get("ends"), "ends")
        only_keys(ends_map, ("first", "last"), "ends")
        ends = tuple(name_of(f"ends.{key}", ends_map.get(key, "clamped"), EndMode, lower=True)
                     for key in ("first", "last"))
        motion = keyed("motion", parse_motion, data.get("motion"))
        for mv in motion:
            if ends[0 if mv.end == "first" else 1] == "free":
                raise ParameterError(f"motion: end '{mv.end}' is free; only pinned, fork or clamped ends can be moved")
        gravity = tuple(keyed("gravity", check_vector3, "gravity", data.get("gravity", STANDARD_GRAVITY)))
        integrator = one_of("integrator", data.get("integrator", "implicit_euler"), IntegratorName)
        dt = keyed("dt", check_positive, "dt", data.get("dt", 1e-3))
        duration = keyed("duration", check_positive, "duration", data.get("duration", 1.0))
        check_steps(dt, duration)
        initial = one_of("initial", data["initial"], InitialShape) if "initial" in data else None
        det = section(data.get("detector"), "detector")
        only_keys(det, ("max_strain", "energy_factor", "check_every", "energy_every"), "detector")
        nwt = section(data.get("newton"), "newton")
        only_keys(nwt, ("max_iter", "tol", "definite", "exact_from", "reuse_matrix"), "newton")
        bullet = BulletOptions.from_dict(data.get("bullet"))
        check_steps(dt, duration, bullet.substeps, duration_name="duration x bullet.substeps")
        arms = ArmsOptions.from_dict(data["arms"]) if data.get("arms") is not None else None
        return cls(cable, start, direction, ends, motion, gravity, integrator, dt, duration, initial,
                   DetectorOptions(**det), NewtonOptions(**nwt), str(data.get("name", "scene")),
                   bullet, auto_n, auto_dt, tol_value, tol_target, arms, frozenset(map(str, data)))

    @classmethod
    def from_yaml(cls, path: str | Path) -> "Scene":
        """Load and validate a YAML scene file."""
        return cls.from_dict(load_mapping(path, "scene file"))

    # ----- the model -----------------------------------------------------------------------
    def build_model(self) -> CableModel:
        """The discretised cable with its end conditions and motion."""
        return CableModel.straight(self.cable, self.start, self.direction, self.ends, self.motion, self.gravity)

    def initial_state(self, model: CableModel) -> CableState:
        """Straight at rest, or the static equilibrium under gravity (``initial: static``; ParameterError when the
        static solve does not converge, rather than a start that is no equilibrium)."""
        if self.initial == "static":
            res = solve_static(model)
            if not res.converged:
                raise ParameterError(f"initial: static did not converge (largest force {res.residual:.3g} N after "
                                     f"{res.iterations} Newton iterations); use initial: straight")
            return res.state()
        return model.initial_state()

    @property
    def arm_start(self) -> str:
        """How the dual-arm scene attaches the cable (``DualArmSpec.start``): in its static shape
        between the grippers unless the scene file says ``initial: straight``."""
        return "straight" if self.initial == "straight" else "settled"


def holds_moment(model: CableModel, mode: str) -> bool:
    """Whether an end held in ``mode`` takes a moment from ``model``'s cable: a clamp, or a fork of a cable with a
    material frame (the twist about its axis)."""
    return mode == "clamped" or (mode == "fork" and model.spec.twist_enabled)


def result_json(scene: Scene, model: CableModel, result: SimulationResult, engine: str = "core") -> dict[str, Any]:
    """The portable output of ``bullet-dlo simulate`` (see README for the keys)."""
    def vec(a: np.ndarray) -> list[float]:
        return [float(v) for v in a]

    held = model.arrays.held
    forces = result.end_forces[-1] if len(result.end_forces) else np.zeros((2, 3))
    ok = result.stable
    crit = critical_dt(model, scene.integrator)
    return {
        "stable": bool(ok),
        "time_to_instability": result.time_to_instability,
        "reason": result.reason,
        "critical_dt": crit if crit is None or math.isfinite(crit) else None,
        "final_positions": result.final_state.x.tolist(),
        "end_forces": {
            "first": vec(forces[0]) if held[0] and ok else None,
            "last": vec(forces[1]) if held[-1] and ok else None,
        },
        "end_moments": {
            "first": vec(result.end_moments[0]) if holds_moment(model, scene.ends[0]) and ok else None,
            "last": vec(result.end_moments[1]) if holds_moment(model, scene.ends[1]) and ok else None,
        },
        "steps": result.steps,
        "wall_time_s": result.wall_time_s,
        "integrator": get_integrator(scene.integrator).name,
        "dt": scene.dt,
        "duration": scene.duration,
        "n_masses": scene.cable.n_masses,
        "cable_weight": scene.cable.mass * float(np.linalg.norm(scene.gravity)),
        "newton_failures": result.newton_failures,
        "newton_failure_share": result.newton_failure_share,
        "max_strain_seen": result.max_strain_seen,
        "warnings": list(result.warnings),
        "twist": scene.cable.twist_enabled,
        "twist_reason": scene.twist_reason,
        "engine": engine,
    }
