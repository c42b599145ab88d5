"""Cable parameters from recorded end loads: least squares on force, moment or any linear residual, with
intervals that mean something.

The forward model is the core engine (:func:`bullet_dlo.core.engine.simulate`, no PyBullet):
both cable ends clamped, each following its gripper's recorded grasp pose as a waypoint path
(:class:`~bullet_dlo.core.boundary.Waypoints`, C2 through the recorded poses), started from
the static equilibrium at the first pose (or straight). Its end forces and clamp moments (the
loads the cable exerts on each holder, every recorded state: ``SimulationResult.end_moment_history``)
are compared with what each recording holds (:mod:`bullet_dlo.analysis.fit_recording`: wrist
forces, moments, or a linear map of both such as joint torques), each kind divided by its noise
level, over one recording or a set at once (shared parameters, per-recording residuals);
``scipy.optimize.least_squares`` varies the parameters in log space.

Uncertainty. The Jacobian standard error sigma^2 (J^T J)^-1 (kept as ``jacobian_standard_errors``)
assumes independent residuals and is far too small when the residual is correlated (coloured
noise, model discrepancy, numerical damping the model does not have). The reported interval is
the widest of (:mod:`bullet_dlo.analysis.fit_stats`): a delete-a-window jackknife over time
windows at least 5 residual correlation times long (and over recordings; Student's t with B - 1
degrees of freedom), the Newey-West (HAC) sandwich, and the Jacobian one. The fit also reports
the residual's whiteness (autocorrelation, integrated correlation time, effective samples,
Ljung-Box), the held-out residual of each window predicted by the others' refit, the per-window
parameter spread, and a conditional parameter profile. Verdict: when the recordings hold fewer
than ``min_windows`` independent windows (residual correlated over a time comparable to them) or
the held-out residual exceeds ``max_holdout_ratio`` x the in-sample one, or the residual is more than
``max_noise_ratio`` times the recordings' noise level and not white (the model misses a systematic part of the
signal, e.g. a contact it lacks: the interval would be the spread of a biased estimate), model discrepancy
dominates: every parameter is reported ``identifiable: false`` with no interval and the reason.
A parameter is also not identifiable when its interval's relative half-width / 1.96 exceeds
``max_relative_se``, when it sits at a bound, or when J^T J is blind to it.

Numerical damping (:mod:`bullet_dlo.analysis.fit_numerics`). The fitted model runs with the
integrator, n and dt stated in the result; at the fitted parameters the integrator's numerical
damping ratio on the lowest modes must stay below ``max_numerical_damping`` x the physical one and
its stiffest mode must not ring; else a warning (``integrator="auto"``: BDF2, dt halved and the
fit repeated until it holds, at most 3 times). A recording that says how it was simulated
(``Recording.source``) gets the same check for its own integrator, and ``match_source`` fits with it.

Grasp frames follow the dual-arm convention (:class:`bullet_dlo.robots.dual_arm.DualArmPhysics`):
the left arm (index 0) holds the cable's first end and its grasp x axis points along the cable;
the right arm's x axis points into the cable, i.e. along minus the cable tangent.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from scipy import stats
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from bullet_dlo.analysis.fit_numerics import (
    NumericalDampingCheck,
    numerical_damping_check,
)
from bullet_dlo.analysis.fit_recording import (
    CLAMP_SIGN,
    KINDS,
    UNITS,
    ModelRun,
    Recording,
    markers_on,
    noise_scale,
    predicted,
)
from bullet_dlo.analysis.fit_stats import (
    WINDOW_TAUS,
    block_jackknife,
    hac_variances,
    recording_random_effects,
    t_quantile,
    whiteness,
    window_bounds,
    windows_for,
)
from bullet_dlo.core.boundary import EndHolder, Motion, Waypoints, motion_offset
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.enums import FitStart, ResidualKind, name_of
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState, build_arrays
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import (
    ParameterError,
    check_in_range,
    check_int,
    check_positive,
)

BOUNDS = {  # allowed range of each fittable parameter (SI), also its log-space box
    "youngs_modulus": (1e3, 1e13),
    "damping_rate": (1e-6, 1e4),
    "internal_damping": (1e-9, 1.0),
    "damping": (1e-9, 1e3),
    "mass": (1e-6, 1e3),
    "shear_modulus": (1e2, 1e13),
}
GUESS = {"youngs_modulus": 1e8, "damping_rate": 1.0, "internal_damping": 1e-3, "damping": 1e-3}
START = FitStart.names()  # where the model starts (bullet_dlo.core.enums.FitStart)
"""How the model starts: ``static`` (equilibrium at the first poses), ``straight`` (at rest, straight),
``recorded`` (the recording's ``initial`` shape and velocity), ``auto`` (recorded when the recording has
an initial shape, else static)."""
AUTO_INTEGRATOR = "bdf2"
AUTO_HALVINGS = 3
__all__ = [
    "BOUNDS",
    "CLAMP_SIGN",
    "KINDS",
    "START",
    "FitOptions",
    "FitResult",
    "ModelRun",
    "Recording",
    "default_parameters",
    "fit_cable",
    "held_model",
    "holder_paths",
    "log_variances",
    "model_forces",
    "model_loads",
    "model_run",
    "run_loads",
    "run_model",
    "synthetic_recording",
]


def default_parameters(fit_mass: bool) -> list[str]:
    """The CableSpec fields fitted by default: E and the damping terms the spec has (k_d otherwise), and the mass."""
    names = {f.name for f in fields(CableSpec)}
    damping = [k for k in ("internal_damping", "damping_rate") if k in names] or ["damping"]
    return ["youngs_modulus", *damping] + (["mass"] if fit_mass else [])


@dataclass(frozen=True)
class FitOptions:
    """How the forward model runs, the fit stops and its uncertainty is judged.

    integrator, dt [s]: the core engine's (``auto``: BDF2 with dt halved until its numerical damping
    passes the check); start: one of :data:`START`; knot_rate: waypoints per second taken from the recorded poses
    [Hz]; skip: time at the start of each recording left out of the residual [s]; max_evaluations:
    forward runs allowed per fit; max_relative_se: above it (equivalent standard error / value) [-] a
    parameter is called not identifiable; max_condition: above it J^T J is called near-singular [-].
    kinds: residual kinds to fit (None: every kind each recording has); sigma: noise level per kind
    [the kind's unit: N, N m, m] (None or missing: estimated from the recordings' first differences); windows:
    most time windows per recording for the jackknife; min_windows: fewer independent windows in
    all: no confident number; level: interval coverage [-]; max_holdout_ratio: held-out / in-sample
    residual RMS above which discrepancy is declared [-]; max_numerical_damping: allowed numerical /
    physical damping ratio on the lowest modes [-]; profile_points: points of each conditional profile
    (0: none); match_source: run the model with the recording's own integrator and dt (``source``);
    stiffness_grid: Young's moduli tried before the descent, log-spaced over a decade either side of
    the start (the start among them), the best one starting it (0 or 1: none). An oscillating record
    has a residual with a minimum at every frequency that puts the ringing in phase somewhere; a local
    descent from a start a factor 2 off lands in one of those (a cantilever recording fitted at
    0.16x its E, confidently, before the grid); after the descent the grid about the fitted values
    finds other minima (:func:`other_minima`); min_explained: below this share [-] of the measured signal
    explained by the fitted model (1 - |r|^2 / |y|^2, weighted: what predicting nothing would leave), the
    model does not reproduce the signal and no number is confident (a strip fit at a tenth of its E
    predicted no ringing in the band the torques were compared in, and was called confident);
    max_noise_ratio: above this residual RMS over the noise level (``sigma``) [-], with a residual that is not
    white (Ljung-Box p < 0.01), discrepancy is declared (a cable recorded in contact with a box the fit does not
    model left 21x its noise level and got E 4 % off within a +-2 % interval; a recording at n 30 fitted at
    n 10, 4x: E 11 % off within +-0.6 %; a model that matches leaves 0.8-1.2x, coloured noise included).
    """

    integrator: str = "implicit_midpoint"
    dt: float = 1e-3
    start: str = "auto"
    knot_rate: float = 1000.0
    skip: float = 0.0
    max_evaluations: int = 60
    max_relative_se: float = 0.3
    max_condition: float = 1e8
    kinds: tuple[str, ...] | None = None
    sigma: Mapping[str, float] | None = field(default=None, compare=False)
    windows: int = 8
    min_windows: int = 4
    level: float = 0.95
    max_holdout_ratio: float = 1.5
    max_numerical_damping: float = 0.1
    profile_points: int = 5
    match_source: bool = False
    stiffness_grid: int = 9
    min_explained: float = 0.5
    max_noise_ratio: float = 3.0

    def __post_init__(self) -> None:
        check_positive("dt", self.dt)
        check_positive("knot_rate", self.knot_rate)
        check_int("max_evaluations", self.max_evaluations, 2)
        if self.integrator != "auto" and self.integrator not in INTEGRATORS:
            raise ParameterError(f"integrator must be auto or one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        object.__setattr__(self, "start", name_of("start", self.start, FitStart))
        if not self.skip >= 0:
            raise ParameterError(f"skip must be >= 0 [s], got {self.skip!r}")
        if self.kinds is not None:
            object.__setattr__(self, "kinds", tuple(self.kinds))
            if not self.kinds:
                raise ParameterError(f"kinds must be a non-empty subset of {', '.join(KINDS)}, got []")
            object.__setattr__(self, "kinds", tuple(name_of("kinds", k, ResidualKind) for k in self.kinds))
        for kind, value in (self.sigma or {}).items():
            name_of("sigma key", kind, ResidualKind)
            check_positive(f"sigma[{kind}]", value)
        check_int("windows", self.windows, 2, 1000)
        check_int("min_windows", self.min_windows, 2, 1000)
        check_in_range("level", self.level, 0.5, 1.0, open_hi=True)
        check_in_range("max_holdout_ratio", self.max_holdout_ratio, 1.0, 1e6)
        check_positive("max_numerical_damping", self.max_numerical_damping)
        check_positive("max_relative_se", self.max_relative_se)
        check_int("profile_points", self.profile_points, 0, 101)
        check_int("stiffness_grid", self.stiffness_grid, 0, 101)
        check_in_range("min_explained", self.min_explained, 0.0, 1.0)
        check_in_range("max_noise_ratio", self.max_noise_ratio, 1.0, 1e6)


@dataclass
class FitResult:
    """Fitted parameters with honest intervals, the identifiability verdict and the fitted loads.

    values: by CableSpec field name [SI: each field's unit]; intervals: (low, high) at ``level``
    [each field's unit] or None where not identifiable; standard_errors: the interval's half-width /
    1.96 (an equivalent standard error [each field's unit]; inf when not identifiable by the
    Jacobian); relative_se: standard error / value [-]; jacobian_standard_errors: the
    uncorrelated-residual ones, for comparison [each field's unit]; identifiable: by name; reasons:
    why not, by name; condition: of the column-scaled J^T J [-]; sigma: weighted residual standard
    deviation [-] (1: the residual is the noise level); rms: residual RMS of the first kind of the
    first recording [its units]; evaluations: forward model runs made; success, message: the
    optimiser's own report; warnings: what the fit noticed (numerics, windows, bounds); forces /
    moments: model end loads of the first recording at its times [N] / [N m], (k, 2, 3); loads: the
    model's run per recording (:class:`~bullet_dlo.analysis.fit_recording.ModelRun`); spec: the fitted
    cable; interval_method: how the intervals were made (window jackknife, HAC or Jacobian, the widest);
    integrator, dt [s], n_masses: how the fitted model runs; level: the intervals' coverage [-];
    sigma_weighted: the residual's weighted RMS [-]; whiteness, holdout, per_recording, numerics,
    profiles, verdict: see :meth:`to_dict`.
    """

    values: dict[str, float]
    standard_errors: dict[str, float]
    relative_se: dict[str, float]
    identifiable: dict[str, bool]
    condition: float
    sigma: float
    rms: float
    evaluations: int
    success: bool
    message: str
    spec: CableSpec
    forces: np.ndarray
    warnings: list[str] = field(default_factory=list)
    intervals: dict[str, tuple[float, float] | None] = field(default_factory=dict)
    interval_method: str = ""
    jacobian_standard_errors: dict[str, float] = field(default_factory=dict)
    reasons: dict[str, str] = field(default_factory=dict)
    moments: np.ndarray | None = None
    loads: list[ModelRun] = field(default_factory=list)
    integrator: str = ""
    dt: float = 0.0
    n_masses: int = 0
    whiteness: dict[str, Any] = field(default_factory=dict)
    holdout: dict[str, Any] = field(default_factory=dict)
    per_recording: list[dict[str, Any]] = field(default_factory=list)
    numerics: dict[str, Any] = field(default_factory=dict)
    profiles: dict[str, Any] = field(default_factory=dict)
    verdict: dict[str, Any] = field(default_factory=dict)
    level: float = 0.95
    sigma_weighted: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able summary (no arrays)."""
        finite = lambda v: float(v) if v is not None and math.isfinite(v) else None
        params = {}
        for k in self.values:
            iv = self.intervals.get(k)
            params[k] = {"value": self.values[k], "interval": list(iv) if iv else None,
                         "standard_error": finite(self.standard_errors[k]),
                         "relative_standard_error": finite(self.relative_se[k]),
                         "jacobian_standard_error": finite(self.jacobian_standard_errors.get(k)),
                         "identifiable": self.identifiable[k], "reason": self.reasons.get(k)}
        return {
            "parameters": params, "interval_level": self.level, "interval_method": self.interval_method,
            "verdict": self.verdict, "condition": finite(self.condition), "sigma": self.sigma,
            "sigma_weighted": self.sigma_weighted, "rms": self.rms, "whiteness": self.whiteness, "holdout": self.holdout,
            "per_recording": self.per_recording, "model_run": {"integrator": self.integrator, "dt_s": self.dt,
                                                               "n_masses": self.n_masses},
            "numerical_damping": self.numerics, "profiles": self.profiles,
            "evaluations": self.evaluations, "success": self.success, "message": self.message,
            "warnings": self.warnings, "cable": self.spec.to_dict(),
        }


# ----- the forward model -----------------------------------------------------------------------
def holder_paths(rec: Recording, knot_rate: float) -> tuple[EndHolder, EndHolder]:
    """:func:`recorded_holders`, built once per recording and knot rate and kept on the recording (a Recording is
    not changed once made): a fit runs its model tens of times, and building the paths took a quarter of a short
    run's time (50 ms for a 1 s recording)."""
    memo = rec.__dict__.setdefault("_holder_paths", {})  # (a frozen dataclass: its fields stay as they are)
    if knot_rate not in memo:
        memo[knot_rate] = recorded_holders(rec, knot_rate)
    return memo[knot_rate]


def recorded_holders(rec: Recording, knot_rate: float) -> tuple[EndHolder, EndHolder]:
    """Both ends clamped at the first recorded poses, following the recorded poses as waypoint paths.

    Knots: the recorded samples thinned to about ``knot_rate`` [Hz] (always the first and last),
    plus one knot extrapolated linearly a knot interval past the last (so that the path's end, where
    the held end would stop, lies after the last recorded time: without it the held end's
    acceleration at the last sample put up to 0.9 N into the model's end force); times are taken
    from the recording's start (t - t[0]).
    """
    step = max(1, int(round(1.0 / (knot_rate * float(np.median(np.diff(rec.t)))))))
    idx = np.unique(np.r_[np.arange(0, len(rec.t), step), len(rec.t) - 1])
    t = rec.t[idx] - rec.t[0]
    t = np.r_[t, 2.0 * t[-1] - t[-2]]
    dirs = rec.clamp_directions()
    holders = []
    for arm, end in enumerate(("first", "last")):
        if rec.held[arm] == "free":  # nobody holds it: its recorded pose is only where it starts
            holders.append(EndHolder("free", rec.grasp_pos[0, arm].copy(), dirs[0, arm].copy()))
            continue
        pos = rec.grasp_pos[idx, arm]
        pos = np.vstack([pos, 2.0 * pos[-1] - pos[-2]])
        rot = Rotation.from_quat(rec.grasp_quat[idx, arm])
        rel = (rot * rot[0].inv()).as_rotvec()  # turn since the start, world axes [rad]
        rel = np.vstack([rel, 2.0 * rel[-1] - rel[-2]])
        path = Waypoints(end, tuple(t), tuple(map(tuple, pos - pos[0])), tuple(map(tuple, rel)), rest=False)
        normal = rot[0].as_matrix()[:, 1] if rec.section_frame else None  # the grasp frame's y is d1
        holders.append(EndHolder("clamped", rec.grasp_pos[0, arm].copy(), dirs[0, arm].copy(), (path,), normal))
    return holders[0], holders[1]


def held_model(spec: CableSpec, first: EndHolder, last: EndHolder,
               gravity: Sequence[float] = STANDARD_GRAVITY) -> CableModel:
    """A cable between two held ends, laid on the straight line between their start positions; with one
    end free, laid straight from the held end along its clamp direction over the cable's length."""
    n = spec.n_masses
    s = np.linspace(0.0, 1.0, n)
    if first.mode == "free":
        x0 = last.position - np.outer(s[::-1], spec.length * last.direction)
    elif last.mode == "free":
        x0 = first.position + np.outer(s, spec.length * first.direction)
    else:
        x0 = first.position + np.outer(s, last.position - first.position)
    g = np.asarray(gravity, dtype=float)
    return CableModel(spec, first, last, g, build_arrays(spec, first.mode, last.mode, g), x0)


def start_state(model: CableModel, start: str, rec: Recording | None = None) -> CableState | None:
    """The model's start (one of :data:`START`; ``auto`` and ``recorded`` need ``rec``); None when a static start
    does not converge (its last iterate is no equilibrium: the run would start with a jolt)."""
    if start == "auto":
        start = "recorded" if rec is not None and rec.initial is not None else "static"
    if start == "recorded":
        if rec is None or rec.initial is None:
            raise ParameterError("start recorded needs a recording with an initial shape (Recording.initial)")
        return recorded_state(model, rec)
    if start == "static":
        res = solve_static(model)
        return res.state() if res.converged else None
    return model.initial_state()


def recorded_state(model: CableModel, rec: Recording) -> CableState:
    """The recording's initial shape and velocity at the model's nodes: cubic splines in arc length through
    the recorded points, the held nodes where their holders are."""
    s, x, v = rec.initial
    s_nodes = np.linspace(0.0, model.spec.length, model.n)
    x0 = CubicSpline(s, x, axis=0)(s_nodes)
    v0 = CubicSpline(s, v, axis=0)(s_nodes)
    for i, holder in ((0, model.first), (-1, model.last)):
        if holder.held:
            x0[i] = holder.position
    return CableState(x0, v0, 0.0)


def run_model(model: CableModel, t: np.ndarray, integrator: str, dt: float, state: CableState,
              positions: bool = False) -> ModelRun | None:
    """End forces [N] and clamp moments [N m] of ``model`` at times ``t`` [s] from 0, each (k, 2, 3), and
    with ``positions`` the node positions [m], (k, n, 3), run with ``integrator`` at ``dt`` [s] from
    ``state``; None if the run went unstable."""
    res = simulate(model, integrator, dt, float(t[-1]) + dt, state=state, record_every=1, max_records=10**9)
    if not res.stable:
        return None
    x = at_times(res.t, res.x, t) if positions else None
    return ModelRun(at_times(res.t, res.end_forces, t), at_times(res.t, res.end_moment_history, t), x,
                    np.linspace(0.0, model.spec.length, model.n))


def run_loads(model: CableModel, t: np.ndarray, integrator: str, dt: float,
              start: str = "static") -> tuple[np.ndarray, np.ndarray] | None:
    """End forces [N] and clamp moments [N m] of ``model`` at times ``t`` [s] from 0, each (k, 2, 3),
    run with ``integrator`` at ``dt`` [s] from ``start``; None if the run went unstable."""
    state = start_state(model, start)
    run = None if state is None else run_model(model, t, integrator, dt, state)
    return None if run is None else (run.forces, run.moments)


def at_times(t_run: np.ndarray, series: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``series`` (len(t_run), ...) recorded at increasing times ``t_run`` [s], linearly interpolated at
    ``t`` [s] (held at the ends)."""
    j = np.clip(np.searchsorted(t_run, t, side="right") - 1, 0, len(t_run) - 2)
    w = np.clip((t - t_run[j]) / (t_run[j + 1] - t_run[j]), 0.0, 1.0)
    w = w.reshape((-1,) + (1,) * (series.ndim - 1))
    return (1.0 - w) * series[j] + w * series[j + 1]


def run_integrator(options: FitOptions) -> str:
    """The integrator name ``options`` run the model with (``auto`` is BDF2)."""
    return AUTO_INTEGRATOR if options.integrator == "auto" else options.integrator


def run_setup(rec: Recording, options: FitOptions) -> tuple[str, float]:
    """(integrator, dt [s]) the model of ``rec`` runs with: the recording's own with ``match_source``."""
    if options.match_source and rec.source and rec.source.get("integrator") and rec.source.get("dt"):
        return str(rec.source["integrator"]), float(rec.source["dt"])
    return run_integrator(options), options.dt


def model_run(spec: CableSpec, rec: Recording, options: FitOptions = FitOptions(),
              gravity: Sequence[float] = STANDARD_GRAVITY) -> ModelRun | None:
    """The core model held as the recording says (its ends following the recorded grasp poses), at the
    recorded times: end loads, and node positions when the recording has markers; None if unstable (or its
    static start did not converge). A recording that states its cable's length gets that length (same mass per
    length)."""
    spec = for_recording(spec, rec)
    model = held_model(spec, *holder_paths(rec, options.knot_rate), gravity)
    integrator, dt = run_setup(rec, options)
    state = start_state(model, options.start, rec)
    if state is None:
        return None
    return run_model(model, rec.t - rec.t[0], integrator, dt, state, positions=rec.markers is not None)


def for_recording(spec: CableSpec, rec: Recording) -> CableSpec:
    """``spec`` with the recording's cable length when it states one (mass per length kept)."""
    if rec.length is None or rec.length == spec.length:
        return spec
    return spec.with_(length=rec.length, mass=spec.mass * rec.length / spec.length)


def model_loads(spec: CableSpec, rec: Recording, options: FitOptions = FitOptions(),
                gravity: Sequence[float] = STANDARD_GRAVITY) -> tuple[np.ndarray, np.ndarray] | None:
    """End forces [N] and clamp moments [N m] of the core model following the recorded grasp poses, at the
    recorded times, each (k, 2, 3); None if the run went unstable."""
    run = model_run(spec, rec, options, gravity)
    return None if run is None else (run.forces, run.moments)


def model_forces(spec: CableSpec, rec: Recording, options: FitOptions = FitOptions(),
                 gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray | None:
    """End forces [N] of the core model following the recorded grasp poses, at the recorded times, (k, 2, 3);
    None if the run went unstable."""
    loads = model_loads(spec, rec, options, gravity)
    return None if loads is None else loads[0]


# ----- the residual ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Layout:
    """Where each residual row comes from: ``recs`` fitted, ``kinds`` per recording, ``keep`` (sample
    indices in the residual) per recording, ``sigma`` per kind [its units]; per row: recording,
    sample (index into that recording's ``keep``), channel (global id)."""

    recs: list[Recording]
    kinds: list[list[str]]
    keep: list[np.ndarray]
    sigma: dict[str, float]
    rec_of: np.ndarray
    sample_of: np.ndarray
    channel_of: np.ndarray

    def weighted(self, runs: list[ModelRun]) -> np.ndarray:
        """The residual (prediction - measurement) / sigma of every kind, recording after recording (m,)."""
        parts = []
        for rec, kinds, keep, run in zip(self.recs, self.kinds, self.keep, runs):
            for kind in kinds:
                parts.append(((predicted(rec, kind, run) - rec.observed(kind))[keep] / self.sigma[kind]).ravel())
        return np.concatenate(parts)


def make_layout(recs: list[Recording], options: FitOptions, n_params: int) -> Layout:
    """The residual layout of ``recs`` under ``options`` (kinds, skip, noise levels); ParameterError when a
    recording has none of the kinds asked for or too few samples."""
    kinds, keep = [], []
    for i, rec in enumerate(recs):
        have = [k for k in rec.kinds() if options.kinds is None or k in options.kinds]
        lacking = [k for k in options.kinds or () if k not in rec.kinds()]
        if lacking:  # a kind asked for is never dropped silently
            hint = (" (a wrist sensor's moments are about the sensor, not the grasp point: give a grasp_moment "
                    "column, or fit a simulated file's model moments: --forces end_forces)" if "moment" in lacking else "")
            raise ParameterError(f"recording {rec.name or i} has no {', '.join(lacking)} residual, asked for by "
                                 f"kinds {','.join(options.kinds or ())} (it has {', '.join(rec.kinds())}){hint}")
        if not have:
            raise ParameterError(f"recording {rec.name or i} has none of the residual kinds {list(options.kinds)} "
                                 f"(it has {', '.join(rec.kinds())})")
        idx = np.flatnonzero(((rec.t - rec.t[0]) >= options.skip) & (True if rec.use is None else rec.use))
        if len(idx) < 3:
            raise ParameterError(f"skip {options.skip} s leaves too few samples of recording {rec.name or i}")
        kinds.append(have)
        keep.append(idx)
    if sum(len(i) for i in keep) < n_params + 2:
        raise ParameterError(f"skip {options.skip} s leaves too few samples to fit {n_params} parameters")
    sigma = {}
    for kind in sorted({k for ks in kinds for k in ks}):
        given = (options.sigma or {}).get(kind)
        pooled = [rec.observed(kind)[kp] for rec, ks, kp in zip(recs, kinds, keep) if kind in ks]
        sigma[kind] = float(given) if given else float(np.median([noise_scale(y) for y in pooled]))
    rec_of, sample_of, channel_of = [], [], []
    channel = 0
    for i, (rec, ks, kp) in enumerate(zip(recs, kinds, keep)):
        for kind in ks:
            c = rec.observed(kind).shape[1]
            rec_of.append(np.full(len(kp) * c, i))
            sample_of.append(np.repeat(np.arange(len(kp)), c))
            channel_of.append(np.tile(channel + np.arange(c), len(kp)))
            channel += c
    return Layout(recs, kinds, keep, sigma, np.concatenate(rec_of), np.concatenate(sample_of),
                  np.concatenate(channel_of))


# ----- the fit ---------------------------------------------------------------------------------
def fit_cable(rec: Recording | Sequence[Recording], spec: CableSpec, parameters: Sequence[str] | None = None,
              options: FitOptions = FitOptions(), gravity: Sequence[float] = STANDARD_GRAVITY,
              guess: dict[str, float] | None = None) -> FitResult:
    """Identify ``parameters`` (CableSpec field names; default :func:`default_parameters` with the
    mass fitted) of a cable whose other fields (length, diameter, n_masses, ...) are those of ``spec``,
    from one recording or a set of them (shared parameters).

    Start values: ``guess``, else the spec's value when > 0, else :data:`GUESS`. Returns a
    :class:`FitResult`; never raises for a motion that does not determine a parameter (that is
    reported, with a warning), only for bad input (ParameterError).
    """
    recs = [rec] if isinstance(rec, Recording) else list(rec)
    if not recs or not all(isinstance(r, Recording) for r in recs):
        raise ParameterError("fit needs one Recording or a non-empty sequence of them")
    names = list(parameters) if parameters is not None else default_parameters(fit_mass=True)
    allowed = {f.name for f in fields(CableSpec)} & set(BOUNDS)
    bad = [k for k in names if k not in allowed]
    if bad or not names or len(set(names)) != len(names):
        raise ParameterError(f"fit parameters must be distinct names from {', '.join(sorted(allowed))}, got {names}")
    layout = make_layout(recs, options, len(names))
    if "mass" in names and all(k == "marker" for ks in layout.kinds for k in ks):
        raise ParameterError("mass cannot be fitted from marker positions alone (shapes under gravity see E I / "
                             "(rho A) only): give the mass and fit youngs_modulus")
    if "shear_modulus" in names and not spec.twist_enabled:
        raise ParameterError("shear_modulus needs a cable with a material frame (twist: true, or a non-round "
                             "section): without it the model has no twist for G to act on")
    start = {k: float((guess or {}).get(k) or getattr(spec, k) or start_value(spec, k)) for k in names}
    lo = np.log([BOUNDS[k][0] for k in names])
    hi = np.log([BOUNDS[k][1] for k in names])
    theta = np.clip(np.log([start[k] for k in names]), lo + 1e-9, hi - 1e-9)
    trial = lambda th: spec.with_(**{k: float(math.exp(v)) for k, v in zip(names, th)})
    runs = [0]
    halvings = 0
    while True:
        cost = residual_function(layout, trial, options, gravity, runs)
        if halvings == 0:
            grid = stiffness_grid(cost, theta, names, options.stiffness_grid, (lo, hi))
            theta = min(grid, key=lambda g: g[1])[0] if grid else theta
        descend = lambda th: least_squares(cost, th, bounds=(lo, hi), method="trf", diff_step=1e-3, x_scale=1.0,
                                           max_nfev=options.max_evaluations, xtol=1e-8, ftol=1e-10)
        sol = descend(theta)
        scan = stiffness_grid(cost, sol.x, names, options.stiffness_grid, (lo, hi))  # E about the fit, others fitted
        starts = other_minima(scan, sol.x, names, 2.0 * float(sol.cost))
        sol, others = best_of_minima(sol, [descend(th) for th in starts], names)
        fitted = trial(sol.x)
        check = numerics_for(fitted, recs[0], options, gravity)
        if options.integrator != "auto" or check.ok or halvings >= AUTO_HALVINGS:
            break
        options, theta, halvings = replace(options, dt=options.dt / 2), sol.x, halvings + 1
    return summarise(sol, names, fitted, layout, options, gravity, runs[0], cost, check, (lo, hi), others)


def start_value(spec: CableSpec, name: str) -> float:
    """A parameter's start when neither the guess nor the spec gives one: G from E and nu, else :data:`GUESS`."""
    return spec.effective_shear_modulus if name == "shear_modulus" else GUESS[name]


def stiffness_grid(cost: Callable[[np.ndarray], np.ndarray], theta: np.ndarray, names: list[str],
                   points: int, bounds: tuple[np.ndarray, np.ndarray]) -> list[tuple[np.ndarray, float]]:
    """``theta`` with log E replaced by each of ``points`` values log-spaced over a decade either side of it
    (itself among them; clipped to the bounds), with the cost |r|^2 there, in order of E; empty when E is not
    fitted or points < 2. The descent starts from the best point of the grid about the start; the local minima
    of the grid about the fitted values, other than the fit's own, are descended too (:func:`other_minima`)."""
    if "youngs_modulus" not in names or points < 2:
        return []
    j = names.index("youngs_modulus")
    grid = []
    for off in np.log(10.0) * np.linspace(-1.0, 1.0, points | 1):  # odd: the start is the middle point
        th = theta.copy()
        th[j] = float(np.clip(theta[j] + off, bounds[0][j] + 1e-9, bounds[1][j] - 1e-9))
        r = cost(th)
        grid.append((th, float(r @ r)))
    return grid


def other_minima(grid: list[tuple[np.ndarray, float]], fitted: np.ndarray, names: list[str],
                 base: float) -> list[np.ndarray]:
    """Starts of the grid's interior local minima in E (costlier neighbours on both sides) that lie more than
    one grid step from the fitted log E ``fitted`` and cost less than twice the fit's |r|^2 ``base`` already
    there (a recording that rings has a minimum wherever the ringing falls in phase, most of them far worse:
    not worth a descent each): a cable held still under gravity pulls its clamps with a tension that rises
    with E while it hangs like a string and falls once it holds itself up like a beam, so a static load is
    met by two stiffnesses; the cheapest two, at most."""
    if len(grid) < 3:
        return []
    j = names.index("youngs_modulus")
    spacing = abs(grid[1][0][j] - grid[0][0][j])
    minima = [grid[i] for i in range(1, len(grid) - 1)
              if grid[i][1] < grid[i - 1][1] and grid[i][1] < grid[i + 1][1] and grid[i][1] < 2.0 * base
              and abs(grid[i][0][j] - fitted[j]) > 1.01 * spacing]
    return [th for th, _ in sorted(minima, key=lambda g: g[1])[:2]]


def best_of_minima(sol, alternatives: list, names: list[str]) -> tuple[Any, list[tuple[float, float]]]:
    """The cheapest of the descent ``sol`` and the ``alternatives`` (least_squares results), and the others that
    ended more than 10 % away from it in E, as (E [Pa], |r|^2) pairs."""
    best = min([sol, *alternatives], key=lambda s: s.cost)
    if not alternatives:
        return best, []
    j = names.index("youngs_modulus")
    others = [(math.exp(s.x[j]), 2.0 * float(s.cost)) for s in (sol, *alternatives)
              if s is not best and abs(s.x[j] - best.x[j]) > math.log(1.1)]
    return best, others


def residual_function(layout: Layout, trial: Callable[[np.ndarray], CableSpec], options: FitOptions,
                      gravity: Sequence[float], runs: list[int]) -> Callable[[np.ndarray], np.ndarray]:
    """theta (log parameters) -> the weighted residual of every recording; an unstable run gives a large
    constant (10 x the largest weighted measurement) so the solver keeps away."""
    scale = max(float(np.max(np.abs(rec.observed(k)[kp]))) / layout.sigma[k]
                for rec, ks, kp in zip(layout.recs, layout.kinds, layout.keep) for k in ks) + 1.0
    size = len(layout.rec_of)

    def residual(theta: np.ndarray) -> np.ndarray:
        runs[0] += 1
        runs_ = [model_run(trial(theta), rec, options, gravity) for rec in layout.recs]
        if any(x is None for x in runs_):
            return np.full(size, 10.0 * scale)
        return layout.weighted(runs_)

    return residual


def numerics_for(spec: CableSpec, rec: Recording, options: FitOptions, gravity: Sequence[float],
                 integrator: str | None = None, dt: float | None = None) -> NumericalDampingCheck:
    """The numerical-damping check of ``spec`` held as in ``rec`` at its first poses, for the model's
    integrator and dt (or the ones given), about its static shape (the straight one where that does not
    converge)."""
    model = held_model(for_recording(spec, rec), *holder_paths(rec, options.knot_rate), gravity)
    run_int, run_dt = run_setup(rec, options)
    state = start_state(model, "static") or model.initial_state()
    return numerical_damping_check(model, state, integrator or run_int, dt or run_dt, options.max_numerical_damping)


# ----- what the fit means ----------------------------------------------------------------------
def summarise(sol, names: list[str], fitted: CableSpec, layout: Layout, options: FitOptions,
              gravity: Sequence[float], evaluations: int, cost: Callable[[np.ndarray], np.ndarray],
              check: NumericalDampingCheck, bounds: tuple[np.ndarray, np.ndarray],
              others: Sequence[tuple[float, float]] = ()) -> FitResult:
    """Intervals, whiteness, held-out residuals, profiles, the numerical check and the verdict of ``sol``
    (a least_squares result in log parameters); ``others``: other local minima of the cost in E, as
    (E [Pa], |r|^2): one whose cost rises less than the 95 % threshold above the fit's makes E not
    identifiable."""
    r, jac = np.asarray(sol.fun), np.asarray(sol.jac)
    m, p = len(r), len(names)
    sigma2 = float(r @ r) / max(m - p, 1)
    var_log, condition = log_variances(jac, sigma2)
    values = {k: float(getattr(fitted, k)) for k in names}
    jac_sd = np.sqrt(var_log)
    at_bound = {k: bool(abs(x - lo) < 1e-6 or abs(x - hi) < 1e-6)
                for k, x, lo, hi in zip(names, sol.x, *bounds)}
    sample_dt = float(np.median([np.median(np.diff(rec.t)) for rec in layout.recs]))
    wh = whiteness([r[layout.channel_of == c] for c in np.unique(layout.channel_of)], sample_dt)
    block, per_rec_windows, window_s = assign_windows(layout, wh.window_tau_s, sample_dt, options.windows)
    blocks = int(block.max()) + 1
    active = [j for j in range(p) if math.isfinite(var_log[j]) and not at_bound[names[j]] and jac_sd[j] < 10.0]
    half, source = interval_half_widths(r, jac, active, block, layout, wh.tau_samples, jac_sd, options.level)
    loads = [model_run(fitted, rec, options, gravity) for rec in layout.recs]
    loads = [x if x is not None else nan_run(rec, fitted) for x, rec in zip(loads, layout.recs)]
    discretisation = discretisation_check(fitted, layout, loads, jac, active, names, options, gravity)
    half = half + np.array([discretisation["dt_shift"].get(k, 0.0) for k in names])
    jk = block_jackknife(r, jac[:, active], block) if active and blocks >= 2 else None
    ratio = jk.held_out_rms / jk.in_sample_rms if jk is not None and jk.in_sample_rms > 0 else math.inf
    explained = explained_share(r, layout)
    global_reasons = discrepancy_reasons(blocks, ratio, wh, math.sqrt(sigma2), options)
    if global_reasons:
        close = close_match_kinds(layout, loads, options)
        if close:
            flags = ", ".join(f"--sigma-{k}" if k != "marker" else "FitOptions.sigma['marker']" for k in close)
            global_reasons.append(f"the model follows the {', '.join(close)} signal to within {100 * CLOSE_MATCH:g} % "
                                  f"of its largest value, and the noise level it is held to was taken from the "
                                  f"samples' differences: a recording with little or no measurement noise (a "
                                  f"simulation without --noise?) makes any model discrepancy dominate; give the "
                                  f"noise level the data are to be fitted to ({flags})")
    if explained < options.min_explained:
        global_reasons.append(f"the fitted model explains {100 * max(explained, 0.0):.3g} % of the measured signal "
                              f"(limit {100 * options.min_explained:g} %): it does not reproduce the signal")
    kind_reasons, kind_estimates = kind_disagreement(r, jac, active, block, layout, names, values, options.level)
    warnings: list[str] = []
    if not check.ok:
        warnings.append(f"numerical damping check failed: {check.message}")
    sources = source_checks(fitted, layout, options, gravity, warnings)
    z = float(stats.norm.ppf(0.5 + options.level / 2))
    se, rel, ident, reasons, intervals = {}, {}, {}, {}, {}
    for j, k in enumerate(names):
        rel[k] = float(half[j] / z)
        se[k] = values[k] * rel[k]
        why = parameter_reason(k, j, at_bound[k], var_log[j], rel[k], global_reasons, check, options)
        why = why or kind_reasons.get(k) or source_reason(k, sources, options)
        if k == "youngs_modulus":
            why = why or second_minimum_reason(others, float(r @ r), sigma2 * wh.tau_samples)
        ident[k] = why is None
        if why:
            reasons[k] = why
            warnings.append(f"{k} is not identifiable from this motion ({why}; J^T J condition {condition:.3g})")
        intervals[k] = (values[k] * math.exp(-half[j]), values[k] * math.exp(half[j])) if ident[k] else None
    for k, b in discretisation["n_shift"].items():
        if ident.get(k) and b > half[names.index(k)]:
            warnings.append(f"{k}: refining the model to {2 * fitted.n_masses - 1} masses moves it by about "
                            f"{100 * math.expm1(b):.2g} %, more than its interval's half-width "
                            f"({100 * math.expm1(half[names.index(k)]):.2g} %): the value is that of the "
                            f"{fitted.n_masses}-mass model; fit with more masses for the cable's own")
    if condition > options.max_condition:
        warnings.append(f"J^T J is near-singular (condition {condition:.3g}): parameters trade off against each other")
    first_kind = layout.kinds[0][0]
    integrator, dt = run_setup(layout.recs[0], options)
    res = FitResult(values, se, rel, ident, condition, math.sqrt(sigma2) * layout.sigma[first_kind],
                    rms_of(layout, loads, 0, first_kind), evaluations, bool(sol.success), str(sol.message), fitted,
                    loads[0].forces, warnings, intervals, interval_method(blocks, source, names, options.level),
                    {k: values[k] * float(jac_sd[j]) for j, k in enumerate(names)}, reasons, loads[0].moments, loads,
                    integrator, dt, fitted.n_masses, level=options.level)
    res.whiteness = wh.to_dict()
    res.holdout = holdout_summary(jk, ratio, options, blocks, per_rec_windows, window_s, names, active)
    res.per_recording = per_recording_summary(layout, loads, jk, block)
    res.numerics = {"model": check.to_dict(), "recordings": sources, "discretisation": discretisation["report"],
                    "rule": f"numerical damping ratio of the {len(check.modes)} lowest modes <= "
                            f"{options.max_numerical_damping:g} x the physical one, no ringing of the stiffest mode; "
                            "else the damping parameters are reported not identifiable"
                            + (" (integrator auto: BDF2 with dt halved until it holds)" if options.integrator == "auto"
                               else "")}
    res.profiles = profiles(cost, sol.x, r, names, half, sigma2 * wh.tau_samples, options.profile_points, bounds)
    res.holdout["per_kind_estimates"] = kind_estimates
    res.verdict = {"discrepancy_dominates": bool(global_reasons), "reasons": global_reasons,
                   "confident": [k for k in names if ident[k]], "not_identifiable": reasons,
                   "windows": blocks, "windows_per_recording": per_rec_windows}
    res.sigma_weighted = math.sqrt(sigma2)
    res.verdict["explained_share"] = explained
    res.verdict["other_minima"] = [{"youngs_modulus": e, "cost_rise": (c - float(r @ r)) / (sigma2 * wh.tau_samples)}
                                   for e, c in others]
    return res


CLOSE_MATCH = 0.01
"""[-] A residual RMS below this share of a kind's largest measured magnitude: the model follows the signal
closely, so a discrepancy verdict there rests on the noise level more than on the model."""


def close_match_kinds(layout: Layout, loads: list[ModelRun], options: FitOptions) -> list[str]:
    """The residual kinds whose noise level was estimated from the samples (not given) and whose residual RMS is
    below :data:`CLOSE_MATCH` of the largest measured magnitude of that kind, in every recording holding it."""
    out = []
    for kind in layout.sigma:
        if (options.sigma or {}).get(kind):
            continue
        held = [i for i, rec in enumerate(layout.recs) if kind in layout.kinds[i]]
        if held and all(rms_of(layout, loads, i, kind)
                        < CLOSE_MATCH * float(np.max(np.abs(layout.recs[i].observed(kind)))) for i in held):
            out.append(kind)
    return out


def second_minimum_reason(others: Sequence[tuple[float, float]], base: float, scale: float) -> str | None:
    """Why E gets no confident number when another local minimum (E [Pa], |r|^2) costs less than the 95 %
    threshold (3.84, in units of ``scale``, sigma^2 times the residual's correlation length) above ``base``
    (the fit's |r|^2), or None."""
    near = [(e, (c - base) / scale) for e, c in others if scale > 0 and (c - base) / scale < 3.84]
    if not near:
        return None
    e, rise = min(near, key=lambda x: x[1])
    return (f"another stiffness explains the data as well: E {e:.3g} Pa (cost rise {rise:.2g}, 95 % threshold "
            f"3.84)")


def explained_share(r: np.ndarray, layout: Layout) -> float:
    """Share of the measured signal the fitted model explains: 1 - |r|^2 / |y|^2, both weighted (divided by
    each kind's noise level); 0 when the model does no better than predicting zero. About zero, not about
    the mean: a static hold's information is its mean level (the weight)."""
    y = np.concatenate([(rec.observed(kind)[keep] / layout.sigma[kind]).ravel()
                        for rec, kinds, keep in zip(layout.recs, layout.kinds, layout.keep) for kind in kinds])
    total = float(y @ y)
    return 1.0 - float(r @ r) / total if total > 0 else 0.0


def assign_windows(layout: Layout, tau_s: float, sample_dt: float, most: int) -> tuple[np.ndarray, list[int], list[float]]:
    """Window (block) index of every residual row: each recording cut into windows at least
    5 correlation times ``tau_s`` [s] long (at most ``most``; at least one per recording); the
    windows per recording and their lengths [s]."""
    block = np.zeros(len(layout.rec_of), dtype=int)
    counts, lengths, offset = [], [], 0
    for i, (rec, kp) in enumerate(zip(layout.recs, layout.keep)):
        duration = float(rec.t[kp[-1]] - rec.t[kp[0]]) + sample_dt
        w = max(1, windows_for(duration, tau_s, most))
        edges = np.array([a for a, _ in window_bounds(len(kp), w)] + [len(kp)])
        rows = layout.rec_of == i
        block[rows] = offset + np.searchsorted(edges, layout.sample_of[rows], side="right") - 1
        offset += len(edges) - 1
        counts.append(len(edges) - 1)
        lengths.append(duration / (len(edges) - 1))
    return block, counts, lengths


def interval_half_widths(r: np.ndarray, jac: np.ndarray, active: list[int], block: np.ndarray, layout: Layout,
                         tau_samples: float, jac_sd: np.ndarray, level: float) -> tuple[np.ndarray, list[str]]:
    """Half-width of each parameter's interval in log space (inf where J is blind) and where it came from:
    the widest of the window jackknife (Student's t, B - 1 dof), the HAC sandwich, the Jacobian one and, with
    several recordings, the random-effects one over them
    (:func:`~bullet_dlo.analysis.fit_stats.recording_random_effects`)."""
    p = jac.shape[1]
    z = float(stats.norm.ppf(0.5 + level / 2))
    half = np.full(p, math.inf)
    source = ["none"] * p
    blocks = int(block.max()) + 1
    if not active:
        return half, source
    sub = jac[:, active]
    jk = block_jackknife(r, sub, block).var_log if blocks >= 2 else np.full(len(active), math.inf)
    hac = hac_variances(r, sub, layout.rec_of, layout.sample_of, int(math.ceil(WINDOW_TAUS * tau_samples)))
    random_effects, _ = recording_random_effects(r, sub, layout.rec_of, tau_samples, level)
    tq = t_quantile(blocks, level)
    for a, j in enumerate(active):
        options = {"window jackknife": tq * math.sqrt(jk[a]), "HAC": z * math.sqrt(max(hac[a], 0.0)),
                   "Jacobian": z * float(jac_sd[j])}
        if math.isfinite(random_effects[a]):
            options["recordings"] = float(random_effects[a])
        source[j] = max(options, key=options.get)
        half[j] = options[source[j]]
    return half, source


def interval_method(blocks: int, source: list[str], names: list[str], level: float) -> str:
    """One sentence on how the intervals were made."""
    used = ", ".join(f"{k}: {s}" for k, s in zip(names, source))
    return (f"{100 * level:g} % interval in log space, the widest of: delete-a-window jackknife over {blocks} time "
            f"windows (each >= 5 residual correlation times; recordings are windows of their own), linearised "
            f"refit, Student's t with {max(blocks - 1, 1)} dof; Newey-West (HAC) sandwich; Jacobian; with several "
            f"recordings, a random-effects one over them (each recording's own estimate and variance, "
            f"DerSimonian-Laird between-recording variance, Student's t with recordings - 1 dof). Widest per "
            f"parameter: {used}")


def kind_rows(layout: Layout) -> dict[str, np.ndarray]:
    """Boolean row mask of each residual kind present."""
    kinds = np.empty(len(layout.rec_of), dtype=object)
    row = 0
    for rec, ks, kp in zip(layout.recs, layout.kinds, layout.keep):
        for kind in ks:
            size = len(kp) * rec.observed(kind).shape[1]
            kinds[row: row + size] = kind
            row += size
    return {k: kinds == k for k in sorted(set(kinds))}


def kind_disagreement(r: np.ndarray, jac: np.ndarray, active: list[int], block: np.ndarray, layout: Layout,
                      names: list[str], values: dict[str, float], level: float) -> tuple[dict[str, str], dict]:
    """Do the residual kinds (force, moment, linear) agree on each parameter? Each kind's own linearised
    estimate theta - (J_k^T J_k)^-1 J_k^T r_k with its window-jackknife variance; two kinds whose estimates
    differ by more than the t quantile x the combined standard error disagree: the model explains them
    with different parameters (discrepancy), so that parameter gets no confident number. Returns the
    reasons by parameter and the per-kind estimates (SI) for the report."""
    masks = kind_rows(layout)
    if len(masks) < 2 or not active or int(block.max()) < 1:
        return {}, {}
    est = {}
    for kind, rows in masks.items():
        sub = jac[rows][:, active]
        step = np.linalg.lstsq(sub, r[rows], rcond=1e-10)
        if step[2] < len(active):
            continue
        blocks_k = np.unique(block[rows], return_inverse=True)[1]
        var = block_jackknife(r[rows], sub, blocks_k).var_log if blocks_k.max() >= 1 else np.full(len(active), np.inf)
        est[kind] = (-step[0], var, int(blocks_k.max()) + 1)
    reasons, report = {}, {}
    for a, j in enumerate(active):
        k = names[j]
        report[k] = {kind: {"value": values[k] * math.exp(e[0][a]), "log_se": float(math.sqrt(e[1][a]))}
                     for kind, e in est.items() if math.isfinite(e[1][a])}
        kinds = list(est)
        for x in range(len(kinds)):
            for y in range(x + 1, len(kinds)):
                ea, eb = est[kinds[x]], est[kinds[y]]
                se = math.sqrt(ea[1][a] + eb[1][a])
                gap = abs(ea[0][a] - eb[0][a])
                tq = t_quantile(min(ea[2], eb[2]), level)
                if math.isfinite(se) and gap > tq * se:
                    reasons[k] = (f"the {kinds[x]} and {kinds[y]} residuals disagree on it ("
                                  f"{values[k] * math.exp(ea[0][a]):.5g} vs {values[k] * math.exp(eb[0][a]):.5g}, "
                                  f"{gap / se:.3g} combined standard errors): model discrepancy")
    return reasons, report


def discrepancy_reasons(blocks: int, ratio: float, wh, noise_ratio: float, options: FitOptions) -> list[str]:
    """Why model discrepancy dominates (none: it does not); ``noise_ratio``: the residual's RMS over the noise
    level [-]."""
    out = []
    if noise_ratio > options.max_noise_ratio and not wh.white:
        out.append(f"the residual is {noise_ratio:.3g}x the recordings' noise level (limit "
                   f"{options.max_noise_ratio:g}) and not white (Ljung-Box p {wh.p_value:.2g}): the model misses a "
                   "systematic part of the signal, and the parameters absorb it")
    if blocks < options.min_windows:
        out.append(f"the residual is correlated over {wh.window_tau_s:.3g} s (integrated autocorrelation time "
                   f"{wh.tau_s:.3g} s, envelope {wh.envelope_samples:.4g} samples; effective samples "
                   f"{wh.effective_samples:.3g} of {wh.samples}): "
                   f"the recordings hold only {blocks} windows of >= 5 correlation times, fewer than "
                   f"{options.min_windows}; what the model lacks dominates the residual")
    if ratio > options.max_holdout_ratio:
        out.append(f"windows predicted by a fit to the other windows leave {ratio:.3g}x the in-sample residual "
                   f"(limit {options.max_holdout_ratio:g}): the fitted model does not carry over")
    return out


def discretisation_check(fitted: CableSpec, layout: Layout, loads: list[ModelRun], jac: np.ndarray,
                         active: list[int], names: list[str], options: FitOptions,
                         gravity: Sequence[float]) -> dict[str, Any]:
    """How far the fitted parameters lean on the model's discretisation: the model at the fitted parameters is
    run again with dt halved and with n refined to 2 n - 1, and each change of its prediction is carried to the
    parameters by the fit's Jacobian (the Gauss-Newton step the refined model's residual would take), times
    2^p / (2^p - 1) (p: the integrator's order in dt, 2 in n: the distance to the converged model). The time
    step's share is numerical error and is added to the intervals' half-widths (``dt_shift``, log units). The
    share of n is the model's resolution (the fit is of the n-mass model, as stated): it is reported, with a
    warning where it exceeds a parameter's interval (``n_shift``, log units). ``report``: both shifts (relative)
    and the refined runs' change of the residual (RMS over the noise level; above a few, the linear step is
    rough)."""
    r0 = layout.weighted(loads)
    report: dict[str, Any] = {"rule": "parameter shift when dt is halved (added to each interval's half-width) and "
                                      "when n -> 2 n - 1 (reported), extrapolated to the converged model"}
    shifts: dict[str, dict[str, float]] = {}
    if not active or not np.all(np.isfinite(r0)):
        report["skipped"] = "no parameter with a finite interval, or the fitted model's run is not finite"
        return {"dt_shift": {}, "n_shift": {}, "report": report}
    order = INTEGRATORS[run_setup(layout.recs[0], options)[0]].order
    for label, factor in (("dt", 2.0 ** order / (2.0 ** order - 1.0)), ("n", 4.0 / 3.0)):
        runs = refined_runs(fitted, layout, options, gravity, label)
        if runs is None:
            report[label] = {"skipped": f"the model refined in {label} went unstable or cannot be built"}
            continue
        change = layout.weighted(runs) - r0
        shift = np.linalg.lstsq(jac[:, active], change, rcond=None)[0]
        shifts[label] = {names[j]: factor * abs(float(v)) for j, v in zip(active, shift)}
        report[label] = {"residual_change_over_noise": float(np.sqrt(np.mean(change ** 2))), "factor": factor,
                         "relative_bias": {k: math.expm1(b) for k, b in shifts[label].items()}}
    return {"dt_shift": shifts.get("dt", {}), "n_shift": shifts.get("n", {}), "report": report}


def refined_runs(fitted: CableSpec, layout: Layout, options: FitOptions, gravity: Sequence[float],
                 how: str) -> list[ModelRun] | None:
    """The model at ``fitted`` on every recording with dt halved (``how`` "dt") or n -> 2 n - 1 ("n"), each with
    the integrator and dt it was fitted with otherwise; None when a run goes unstable or cannot be built."""
    runs = []
    for rec in layout.recs:
        integrator, dt = run_setup(rec, options)
        opts = replace(options, integrator=integrator, dt=dt / 2.0 if how == "dt" else dt, match_source=False)
        try:
            spec = fitted if how == "dt" else fitted.with_(n_masses=2 * fitted.n_masses - 1)
            run = model_run(spec, rec, opts, gravity)
        except ParameterError:
            return None
        if run is None:
            return None
        runs.append(run)
    return runs


def parameter_reason(name: str, j: int, at_bound: bool, var_log: float, rel: float, global_reasons: list[str],
                     check: NumericalDampingCheck, options: FitOptions) -> str | None:
    """Why parameter ``name`` (column j) gets no confident number, or None."""
    if global_reasons:
        return "model discrepancy dominates: " + "; ".join(global_reasons)
    if at_bound:
        return "at its bound"
    if not math.isfinite(var_log):
        return "J^T J is blind to it"
    if name in ("damping_rate", "internal_damping", "damping") and not check.ok:
        return f"the model's integrator damps or rings as much: {check.message}"
    if rel > options.max_relative_se:
        return f"relative standard error {rel:.3g} (limit {options.max_relative_se:g})"
    return None


def source_checks(fitted: CableSpec, layout: Layout, options: FitOptions, gravity: Sequence[float],
                  warnings: list[str]) -> list[dict[str, Any]]:
    """The numerical-damping check of each simulated recording's own integrator at the fitted parameters
    (a warning when it put more damping into the data than allowed and the fit did not reproduce it)."""
    out = []
    for i, rec in enumerate(layout.recs):
        src = rec.source or {}
        if not (src.get("integrator") in INTEGRATORS and src.get("dt")):
            continue
        chk = numerics_for(fitted, rec, options, gravity, str(src["integrator"]), float(src["dt"]))
        out.append({"recording": rec.name or str(i), **chk.to_dict()})
        if not chk.ok and not options.match_source:
            warnings.append(f"recording {rec.name or i} was simulated with {chk.integrator} at dt {chk.dt:.3g} s: "
                            f"{chk.message}; the fitted damping includes the recording's numerical damping "
                            "(match_source / --match-source fits with the recording's integrator)")
    return out


def source_reason(name: str, sources: list[dict[str, Any]], options: FitOptions) -> str | None:
    """A damping parameter gets no number when a recording's own integrator put more numerical damping into
    the data than allowed and the fit did not reproduce it (``match_source``)."""
    if name not in ("damping_rate", "internal_damping", "damping") or options.match_source:
        return None
    bad = [f"{s['recording']} ({s['message']})" for s in sources if not s["ok"]]
    return f"the recording's integrator damps as much as the fitted physics: {'; '.join(bad)}" if bad else None


def nan_run(rec: Recording, spec: CableSpec) -> ModelRun:
    """A run of NaNs in the shape of ``rec`` (the fitted model went unstable on it)."""
    k, n = len(rec.t), spec.n_masses
    return ModelRun(np.full((k, 2, 3), np.nan), np.full((k, 2, 3), np.nan), np.full((k, n, 3), np.nan),
                    np.linspace(0.0, spec.length, n))


def rms_of(layout: Layout, loads: list[ModelRun], i: int, kind: str) -> float:
    """Unweighted residual RMS of ``kind`` of recording i over its fitted samples [its units]."""
    rec, keep = layout.recs[i], layout.keep[i]
    d = (predicted(rec, kind, loads[i]) - rec.observed(kind))[keep]
    return float(np.sqrt(np.mean(d**2)))


def holdout_summary(jk, ratio: float, options: FitOptions, blocks: int, per_rec: list[int], window_s: list[float],
                    names: list[str], active: list[int]) -> dict[str, Any]:
    """The held-out residual and the per-window parameter spread (log units) as JSON."""
    out = {"method": "each window left out in turn; the others' linearised refit predicts it",
           "windows": blocks, "windows_per_recording": per_rec, "window_length_s": window_s,
           "limit_ratio": options.max_holdout_ratio}
    if jk is None:
        return {**out, "in_sample_weighted_rms": None, "held_out_weighted_rms": None, "ratio": None}
    own = jk.per_window
    spread = {names[j]: (float(np.nanstd(own[:, a])) if np.isfinite(own[:, a]).sum() >= 2 else None)
              for a, j in enumerate(active)}
    return {**out, "in_sample_weighted_rms": jk.in_sample_rms, "held_out_weighted_rms": jk.held_out_rms,
            "ratio": ratio if math.isfinite(ratio) else None,
            "per_window_estimate_spread_log": spread}


def per_recording_summary(layout: Layout, loads: list[ModelRun], jk,
                          block: np.ndarray) -> list[dict[str, Any]]:
    """Per recording: samples, duration, and per kind the residual RMS [its units], the noise level used and
    the held-out weighted RMS of its windows."""
    out = []
    for i, (rec, ks, kp) in enumerate(zip(layout.recs, layout.kinds, layout.keep)):
        entry: dict[str, Any] = {"name": rec.name or str(i), "samples": len(kp),
                                 "duration_s": float(rec.t[kp[-1]] - rec.t[kp[0]])}
        for kind in ks:
            entry[kind] = {"rms": rms_of(layout, loads, i, kind), "unit": UNITS[kind], "sigma": layout.sigma[kind]}
        if jk is not None:
            mine = np.unique(block[layout.rec_of == i])
            vals = jk.held_out_by_block[mine]
            entry["held_out_weighted_rms"] = float(np.sqrt(np.nanmean(vals**2))) if np.isfinite(vals).any() else None
        out.append(entry)
    return out


def profiles(cost: Callable[[np.ndarray], np.ndarray], theta: np.ndarray, r: np.ndarray, names: list[str],
             half: np.ndarray, scale: float, points: int, bounds: tuple[np.ndarray, np.ndarray]) -> dict[str, Any]:
    """Conditional profile of each parameter (the others held at their fitted values): the cost increase
    (|r|^2 - |r_fit|^2) / (sigma^2 tau_int) at ``points`` log offsets spanning +-1.5 interval half-widths
    (at least +-5 %; clipped to the parameter's bounds). Under the interval's own assumptions about 3.84 at its ends; a much flatter
    profile than that says the data hardly see the parameter."""
    if points <= 0:
        return {}
    base = float(r @ r)
    out: dict[str, Any] = {"kind": "conditional (other parameters held)", "threshold_95": 3.84}
    for j, k in enumerate(names):
        width = 1.5 * (half[j] if math.isfinite(half[j]) else 1.0)
        offsets = np.clip(theta[j] + np.linspace(-1.0, 1.0, points) * max(width, 0.05), bounds[0][j] + 1e-9,
                          bounds[1][j] - 1e-9) - theta[j]
        rise = []
        for off in offsets:
            th = theta.copy()
            th[j] += off
            rr = cost(th)
            rise.append(float((rr @ rr - base) / scale) if scale > 0 else None)
        out[k] = {"log_offsets": offsets.tolist(), "values": (math.exp(theta[j]) * np.exp(offsets)).tolist(),
                  "cost_rise": rise}
    return out


def log_variances(jac: np.ndarray, sigma2: float) -> tuple[np.ndarray, float]:
    """Diagonal of sigma^2 (J^T J)^-1 (inf along directions J does not see) and the condition number of
    J^T J with its columns scaled to unit norm."""
    p = jac.shape[1]
    norms = np.linalg.norm(jac, axis=0)
    if not np.all(norms > 1e-12 * max(float(norms.max()), 1e-300)):
        var = np.full(p, math.inf)
        ok = norms > 1e-12 * max(float(norms.max()), 1e-300)
        if ok.any():
            var[ok], _ = log_variances(jac[:, ok], sigma2)
        return var, math.inf
    scaled = jac / norms
    lam, vec = np.linalg.eigh(scaled.T @ scaled)
    condition = float(lam[-1] / lam[0]) if lam[0] > 0 else math.inf
    tiny = lam <= 1e-14 * lam[-1]
    inv = np.where(tiny, math.inf, 1.0 / np.where(tiny, 1.0, lam))
    var_scaled = np.array([np.sum(np.where(vec[i] ** 2 > 0, vec[i] ** 2 * inv, 0.0)) for i in range(p)])
    return sigma2 * var_scaled / norms**2, condition


# ----- synthetic recordings --------------------------------------------------------------------
def synthetic_recording(spec: CableSpec, motion: Sequence[Motion], duration: float, rate: float = 200.0,
                        noise: float = 0.0, seed: int = 0, span: float | None = None,
                        hold: Sequence[float] = (0.0, 0.0, 0.35), options: FitOptions = FitOptions(),
                        gravity: Sequence[float] = STANDARD_GRAVITY, correlation_time: float = 0.0,
                        moment_noise: float | None = None, markers: Sequence[float] | None = None,
                        marker_noise: float = 0.0) -> Recording:
    """A recording made by the core model itself: the cable clamped between two grippers facing each
    other along x (span [m] apart, default the cable length, centred at ``hold``), moved by ``motion``
    (items with end first = left, last = right: the exact trajectories, not waypoints through
    samples), its end forces sampled at ``rate`` [Hz] with Gaussian noise of standard deviation
    ``noise`` [N] per component (seeded), coloured when ``correlation_time`` [s] > 0 (AR(1), each
    component's noise correlated as exp(-lag / correlation_time), same standard deviation). With
    ``moment_noise`` [N m] (not None) the clamp moments are recorded too, with noise of the same colour.
    With ``markers`` (arc lengths from the first end [m]) the positions of marks there are recorded too
    (kind ``marker``), with Gaussian noise of ``marker_noise`` [m] per coordinate.
    ``source`` says the integrator and dt it was made with."""
    span = spec.length if span is None else check_positive("span", span)
    centre = np.asarray(hold, dtype=float)
    t = np.arange(0.0, check_positive("duration", duration) + 1e-12, 1.0 / check_positive("rate", rate))
    pos = np.empty((len(t), 2, 3))
    quat = np.empty((len(t), 2, 4))
    for arm, end in enumerate(("first", "last")):
        sign = 2 * arm - 1
        disp, _, _, turn = motion_offset(motion, end, t)
        pos[:, arm] = centre + (sign * 0.5 * span, 0.0, 0.0) + disp
        frame0 = Rotation.from_matrix(np.array([[-sign, 0, 0], [0, sign, 0], [0, 0, -1.0]]).T)  # x into the cable
        quat[:, arm] = (Rotation.from_matrix(turn) * frame0).as_quat()
    tangent = np.array([1.0, 0.0, 0.0])
    ends = [EndHolder("clamped", pos[0, arm], tangent, tuple(m for m in motion if m.end == end))
            for arm, end in enumerate(("first", "last"))]
    model = held_model(spec, ends[0], ends[1], gravity)
    state = start_state(model, options.start)
    if state is None:
        raise ParameterError("the synthetic recording's static start did not converge; use start straight")
    run = run_model(model, t, run_integrator(options), options.dt, state, positions=markers is not None)
    if run is None:
        raise ParameterError("the synthetic recording went unstable; use a smaller dt or a gentler motion")
    forces, moments = run.forces, run.moments
    rng = np.random.default_rng(seed)
    marks = None
    if markers is not None:
        s_marks = np.asarray(markers, dtype=float)
        marks = markers_on(run.x, run.s, s_marks) + rng.normal(0.0, marker_noise, (len(t), len(s_marks), 3))
    if noise > 0:
        forces = forces + coloured_noise(rng, forces.shape, noise, correlation_time, 1.0 / rate)
    if moment_noise is not None and moment_noise > 0:
        moments = moments + coloured_noise(rng, moments.shape, moment_noise, correlation_time, 1.0 / rate)
    return Recording(t, pos, quat, forces, moments if moment_noise is not None else None,
                     source={"integrator": run_integrator(options), "dt": options.dt}, markers=marks,
                     marker_s=None if markers is None else np.asarray(markers, dtype=float), length=spec.length)


def coloured_noise(rng: np.random.Generator, shape: tuple[int, ...], std: float, correlation_time: float,
                   sample_dt: float) -> np.ndarray:
    """Gaussian noise of standard deviation ``std`` along axis 0 (time, ``sample_dt`` [s] apart): white for
    ``correlation_time`` 0, else AR(1) with correlation exp(-lag / correlation_time) [s]."""
    white = rng.normal(0.0, std, shape)
    if correlation_time <= 0:
        return white
    a = math.exp(-sample_dt / correlation_time)
    out = np.empty(shape)
    out[0] = white[0]
    for i in range(1, shape[0]):
        out[i] = a * out[i - 1] + math.sqrt(1.0 - a * a) * white[i]
    return out
