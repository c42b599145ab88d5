"""Cable parameters from measured wrist forces: least squares on the force residual, with standard errors.

The forward model is the core engine (:func:`bullet_dlo.core.engine.simulate`, no PyBullet):
both cable ends clamped, each following its gripper's recorded grasp pose as a waypoint path
(:class:`~bullet_dlo.core.boundary.Waypoints`, C2 through the recorded poses), started from
the static equilibrium at the first pose (or straight). Its end forces (the force the cable
exerts on each holder) are compared with the tared world-frame wrist forces at the recorded
times; ``scipy.optimize.least_squares`` varies the parameters in log space.

Uncertainty, from the Jacobian J of the residual (m rows) in log parameters at the optimum:
cov = sigma^2 (J^T J)^-1 with sigma^2 = |r|^2 / (m - p); the standard error of a parameter is
its value times the square root of its diagonal entry (delta method). A parameter is reported
not identifiable from the motion when its relative standard error exceeds ``max_relative_se``
or its direction in J^T J is (near-)singular; ``condition`` is the condition number of J^T J
with columns scaled to unit norm (1: independent effects; large: parameters trade off).

Grasp frames follow the dual-arm convention (:class:`bullet_dlo.robots.dual_arm.DualArmPhysics`):
the left arm (index 0) holds the cable's first end and its grasp x axis points along the cable;
the right arm's x axis points into the cable, i.e. along minus the cable tangent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Sequence

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from bullet_dlo.core.boundary import EndHolder, Motion, Waypoints, motion_offset
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState, build_arrays
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError, check_int, check_positive

BOUNDS = {  # allowed range of each fittable parameter (SI), also its log-space box
    "youngs_modulus": (1e3, 1e13),
    "damping_rate": (1e-6, 1e4),
    "internal_damping": (1e-9, 1.0),
    "damping": (1e-9, 1e3),
    "mass": (1e-6, 1e3),
}
GUESS = {"youngs_modulus": 1e8, "damping_rate": 1.0, "internal_damping": 1e-3, "damping": 1e-3}
CLAMP_SIGN = (1.0, -1.0)
"""Cable tangent = sign * grasp-frame x axis, per arm (left, right)."""


def default_parameters(fit_mass: bool) -> list[str]:
    """The CableSpec fields fitted by default: E and the damping terms the spec has (k_d otherwise), and the mass."""
    names = {f.name for f in fields(CableSpec)}
    damping = [k for k in ("internal_damping", "damping_rate") if k in names] or ["damping"]
    return ["youngs_modulus", *damping] + (["mass"] if fit_mass else [])


@dataclass(frozen=True)
class Recording:
    """What a fit needs from a measurement, arms in the order (left, right), k samples.

    t: times [s], (k,), increasing; grasp_pos: grasp-frame positions [m], (k, 2, 3); grasp_quat:
    grasp-frame orientations as quaternions (x, y, z, w), (k, 2, 4); force: tared wrist forces on
    the tool in world frame [N], (k, 2, 3) (the force the cable exerts on each gripper).
    """

    t: np.ndarray
    grasp_pos: np.ndarray
    grasp_quat: np.ndarray
    force: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        k = len(t)
        if t.ndim != 1 or k < 3 or np.any(np.diff(t) <= 0):
            raise ParameterError("recording t must hold at least 3 strictly increasing times [s]")
        for name, width in (("grasp_pos", 3), ("grasp_quat", 4), ("force", 3)):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (k, 2, width) or not np.all(np.isfinite(a)):
                raise ParameterError(f"recording {name} must be finite with shape ({k}, 2, {width})")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "t", t)

    def clamp_directions(self) -> np.ndarray:
        """Cable tangent held by each gripper (unit), (k, 2, 3)."""
        out = np.empty_like(self.grasp_pos)
        for arm in (0, 1):
            out[:, arm] = CLAMP_SIGN[arm] * Rotation.from_quat(self.grasp_quat[:, arm]).as_matrix()[:, :, 0]
        return out


@dataclass(frozen=True)
class FitOptions:
    """How the forward model runs and the fit stops.

    integrator, dt [s]: the core engine's; start: ``static`` (equilibrium at the first poses)
    or ``straight`` (at rest, straight between the first poses); knot_rate: waypoints per second
    taken from the recorded poses [Hz]; skip: seconds at the start left out of the residual;
    max_evaluations: forward runs allowed; max_relative_se: above it a parameter is called not
    identifiable; max_condition: above it J^T J is called near-singular.
    """

    integrator: str = "implicit_midpoint"
    dt: float = 1e-3
    start: str = "static"
    knot_rate: float = 1000.0
    skip: float = 0.0
    max_evaluations: int = 60
    max_relative_se: float = 0.3
    max_condition: float = 1e8

    def __post_init__(self) -> None:
        check_positive("dt", self.dt)
        check_positive("knot_rate", self.knot_rate)
        check_int("max_evaluations", self.max_evaluations, 2)
        if self.start not in ("static", "straight"):
            raise ParameterError(f"start must be static or straight, got {self.start!r}")
        if not self.skip >= 0:
            raise ParameterError(f"skip must be >= 0 [s], got {self.skip!r}")


@dataclass
class FitResult:
    """Fitted parameters with standard errors, the identifiability verdict and the fitted forces.

    values, standard_errors: by CableSpec field name (SI); relative_se: standard error / value;
    identifiable: by name; condition: of the column-scaled J^T J; sigma: residual standard
    deviation [N]; rms: residual RMS [N]; forces: model end forces at the recorded times [N],
    (k, 2, 3); spec: the fitted cable.
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

    def to_dict(self) -> dict[str, Any]:
        """The JSON-able summary (no arrays)."""
        finite = lambda v: float(v) if math.isfinite(v) else None  # noqa: E731 (JSON has no inf)
        return {
            "parameters": {k: {"value": self.values[k], "standard_error": finite(self.standard_errors[k]),
                               "relative_standard_error": finite(self.relative_se[k]),
                               "identifiable": self.identifiable[k]} for k in self.values},
            "condition": finite(self.condition), "sigma_N": self.sigma, "rms_N": self.rms,
            "evaluations": self.evaluations, "success": self.success, "message": self.message,
            "warnings": self.warnings, "cable": self.spec.to_dict(),
        }


# ----- the forward model -----------------------------------------------------------------------
def holder_paths(rec: Recording, knot_rate: float) -> tuple[EndHolder, EndHolder]:
    """Both ends clamped at the first recorded poses, following the recorded poses as waypoint paths.

    Knots: the recorded samples thinned to about ``knot_rate`` [Hz] (always the first and last);
    times are taken from the recording's start (t - t[0]).
    """
    step = max(1, int(round(1.0 / (knot_rate * float(np.median(np.diff(rec.t)))))))
    idx = np.unique(np.r_[np.arange(0, len(rec.t), step), len(rec.t) - 1])
    t = rec.t[idx] - rec.t[0]
    dirs = rec.clamp_directions()
    holders = []
    for arm, end in enumerate(("first", "last")):
        pos = rec.grasp_pos[idx, arm]
        rot = Rotation.from_quat(rec.grasp_quat[idx, arm])
        rel = (rot * rot[0].inv()).as_rotvec()  # turn since the start, world axes [rad]
        path = Waypoints(end, tuple(t), tuple(map(tuple, pos - pos[0])), tuple(map(tuple, rel)), rest=False)
        holders.append(EndHolder("clamped", rec.grasp_pos[0, arm].copy(), dirs[0, arm].copy(), (path,)))
    return holders[0], holders[1]


def held_model(spec: CableSpec, first: EndHolder, last: EndHolder,
               gravity: Sequence[float] = STANDARD_GRAVITY) -> CableModel:
    """A cable between two held ends, laid on the straight line between their start positions."""
    n = spec.n_masses
    x0 = first.position + np.outer(np.linspace(0.0, 1.0, n), last.position - first.position)
    g = np.asarray(gravity, dtype=float)
    return CableModel(spec, first, last, g, build_arrays(spec, first.mode, last.mode, g), x0)


def model_forces(spec: CableSpec, rec: Recording, options: FitOptions = FitOptions(),
                 gravity: Sequence[float] = STANDARD_GRAVITY) -> np.ndarray | None:
    """End forces [N] of the core model following the recorded grasp poses, at the recorded times, (k, 2, 3);
    None if the run went unstable."""
    model = held_model(spec, *holder_paths(rec, options.knot_rate), gravity)
    return run_forces(model, rec.t - rec.t[0], options)


def run_forces(model: CableModel, t: np.ndarray, options: FitOptions) -> np.ndarray | None:
    """End forces [N] of ``model`` at times ``t`` [s] from 0, (k, 2, 3), started as ``options.start``
    says; None if the run went unstable."""
    state = model.initial_state()
    if options.start == "static":
        state = CableState(solve_static(model).x, np.zeros((model.n, 3)), 0.0)
    res = simulate(model, options.integrator, options.dt, float(t[-1]) + options.dt, state=state,
                   record_every=1, max_records=10**9)
    if not res.stable:
        return None
    out = np.empty((len(t), 2, 3))
    for arm in (0, 1):
        for j in range(3):
            out[:, arm, j] = np.interp(t, res.t, res.end_forces[:, arm, j])
    return out


# ----- the fit ---------------------------------------------------------------------------------
def fit_cable(rec: Recording, spec: CableSpec, parameters: Sequence[str] | None = None,
              options: FitOptions = FitOptions(), gravity: Sequence[float] = STANDARD_GRAVITY,
              guess: dict[str, float] | None = None) -> FitResult:
    """Identify ``parameters`` (CableSpec field names; default :func:`default_parameters` with the
    mass fitted) of a cable whose other fields (length, diameter, n_masses, ...) are those of ``spec``.

    Start values: ``guess``, else the spec's value when > 0, else :data:`GUESS`. Returns a
    :class:`FitResult`; never raises for a motion that does not determine a parameter (that is
    reported, with a warning), only for bad input (ParameterError).
    """
    names = list(parameters) if parameters is not None else default_parameters(fit_mass=True)
    allowed = {f.name for f in fields(CableSpec)} & set(BOUNDS)
    bad = [k for k in names if k not in allowed]
    if bad or not names or len(set(names)) != len(names):
        raise ParameterError(f"fit parameters must be distinct names from {', '.join(sorted(allowed))}, got {names}")
    start = {k: float((guess or {}).get(k) or getattr(spec, k) or GUESS[k]) for k in names}
    lo = np.log([BOUNDS[k][0] for k in names])
    hi = np.log([BOUNDS[k][1] for k in names])
    theta0 = np.clip(np.log([start[k] for k in names]), lo + 1e-9, hi - 1e-9)
    keep = (rec.t - rec.t[0]) >= options.skip
    if keep.sum() < len(names) + 2:
        raise ParameterError(f"skip {options.skip} s leaves too few samples to fit {len(names)} parameters")
    scale = float(np.abs(rec.force[keep]).max()) + 1e-9
    runs = [0]

    def trial(theta: np.ndarray) -> CableSpec:
        return spec.with_(**{k: float(math.exp(v)) for k, v in zip(names, theta)})

    def residual(theta: np.ndarray) -> np.ndarray:
        runs[0] += 1
        f = model_forces(trial(theta), rec, options, gravity)
        if f is None:  # unstable: a large, smooth-ish penalty keeps the solver away
            return np.full(int(keep.sum()) * 6, 10.0 * scale)
        return (f - rec.force)[keep].reshape(-1)

    sol = least_squares(residual, theta0, bounds=(lo, hi), method="trf", diff_step=1e-3, x_scale=1.0,
                        max_nfev=options.max_evaluations, xtol=1e-8, ftol=1e-10)
    return summarise(sol, names, trial(sol.x), rec, options, gravity, runs[0])


def summarise(sol, names: list[str], fitted: CableSpec, rec: Recording, options: FitOptions,
              gravity: Sequence[float], evaluations: int) -> FitResult:
    """Standard errors and identifiability from ``sol`` (a least_squares result in log parameters)."""
    r, jac = sol.fun, np.asarray(sol.jac)
    m, p = len(r), len(names)
    sigma2 = float(r @ r) / max(m - p, 1)
    var_log, condition = log_variances(jac, sigma2)
    values = {k: float(getattr(fitted, k)) for k in names}
    rel = {k: float(math.sqrt(v)) if math.isfinite(v) else math.inf for k, v in zip(names, var_log)}
    se = {k: values[k] * rel[k] for k in names}
    at_bound = {k: bool(abs(x - math.log(BOUNDS[k][0])) < 1e-6 or abs(x - math.log(BOUNDS[k][1])) < 1e-6)
                for k, x in zip(names, sol.x)}
    ident = {k: bool(rel[k] <= options.max_relative_se and not at_bound[k]) for k in names}
    warnings = []
    for k in names:
        if not ident[k]:
            why = "at its bound" if at_bound[k] else f"relative standard error {rel[k]:.3g}"
            warnings.append(f"{k} is not identifiable from this motion ({why}; J^T J condition {condition:.3g})")
    if condition > options.max_condition:
        warnings.append(f"J^T J is near-singular (condition {condition:.3g}): parameters trade off against each other")
    forces = model_forces(fitted, rec, options, gravity)
    forces = np.full_like(rec.force, np.nan) if forces is None else forces
    return FitResult(values, se, rel, ident, condition, math.sqrt(sigma2), float(np.sqrt(np.mean(r**2))),
                     evaluations, bool(sol.success), str(sol.message), fitted, forces, warnings)


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
                        gravity: Sequence[float] = STANDARD_GRAVITY) -> Recording:
    """A recording made by the core model itself: the cable clamped between two grippers facing each
    other along x (span [m] apart, default the cable length, centred at ``hold``), moved by ``motion``
    (items with end first = left, last = right: the exact trajectories, not waypoints through
    samples), its end forces sampled at ``rate`` [Hz] with Gaussian noise of standard deviation
    ``noise`` [N] per component (seeded)."""
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
    forces = run_forces(held_model(spec, ends[0], ends[1], gravity), t, options)
    if forces is None:
        raise ParameterError("the synthetic recording went unstable; use a smaller dt or a gentler motion")
    forces = forces + np.random.default_rng(seed).normal(0.0, noise, forces.shape) if noise > 0 else forces
    return Recording(t, pos, quat, forces)
