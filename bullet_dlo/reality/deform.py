"""DEFORM motion capture (Chen et al., CoRL 2024): read it, fit the cable model on train, predict eval.

Data (github.com/roahmlab/DEFORM, ``data_set/DLOk/{train,eval}/*.pkl``): one trial per pickle,
500 frames at 100 Hz of 12-13 markers along a real cable, shape (T, 3, m), metres, z up. Markers
0, 1 and the last two are held rigidly by two robots' grippers; the others hang free.

The model (core engine, no PyBullet): the cable between the two *inner* held markers (1 and
m - 2), both ends clamped, each clamp at its inner held marker with the pair's direction and
following the recorded pair as a C2 waypoint path (knots at ``knot_rate``). A pair of markers
fixes the clamp's direction but not its roll about the cable axis; the core model has no
twist, so the roll would not enter anyway. It starts from the first frame's shape and
velocity (the recordings start mid-motion at up to 0.4 m/s, so a static equilibrium would be
a wrong start; the authors also start from the first frames), and runs open-loop for the full
5 s. Model markers: the mass chain interpolated linearly at the markers' arc lengths; the held
markers are those of the recording (as in the authors' metric, where they are given).

Only E/rho enters (shapes under gravity and prescribed motion do not see the mass): the fit
varies E with a guessed mass per length :data:`LINEAR_DENSITY` and diameter :data:`DIAMETER`
and reports EI/(rho A) [m^4/s^2]. The authors' metric, L1: mean absolute coordinate error
over all markers and frames [m].

Numerics: bdf2, n = 21, dt = 2 ms. With all damping off, its numerical damping of the first
swing mode is a damping ratio of 0.0003-0.0012, against 0.06-0.18 from the fitted damping
(implicit Euler's own is 0.007, a tenth of the physical). The eval L1 (3 eval trials) changes
from n = 21 to 81 by 0.2 mm on DLO1 and DLO3 and by 0.4 mm (5 %) on DLO2 (:func:`convergence`):
discretisation is a small part of the error; ``--n-masses 41`` halves it at twice the cost.

Measured (``bullet-dlo validate deform ../shared/data/deform/DLOk --json OUT --intervals refit``,
8 train trials, all 14 eval trials), eval L1 against the authors' logged DEFORM eval loss and a
frozen shape: DLO1 12.2 mm (11.1-14.0; frozen 56.6), DLO2 7.7 mm (10.2; frozen 52.9), DLO3
7.9 mm (9.9; frozen 48.4); train L1 11.6 / 7.5 / 7.9 mm (no overfit). DLO1's mean is carried by
trial 67 (44 mm: the real cable swings over the top, the model's does not) and 61 (20 mm).
With ``--twist`` (linearised intervals): 12.3 / 7.5 / 7.7 mm, within 0.2 mm of the above at 1.5x
the cost: with the grippers' roll unknown and no rest curvature, twist hardly changes the shape.
Curved rest shape (``--rest-shape``, :class:`RestShape`, :func:`fit_rest_shape`): the real cables keep a
set (the mean turning between marker chords at DLO1's third free marker exceeds the straight model's by
14.5 +- 2.0 degrees in every eval trial, ``demos/deform_diagnose.py``). A rest curvature at the free
markers' places (:mod:`bullet_dlo.core.kernels.rest_shape`: its magnitude, the plane free) fitted on train
lowers the eval L1 of DLO3 from 8.0 to 6.6 mm, DLO1's from 12.2 to 11.9 and DLO2's from 7.7 to 7.6 mm
(``demos/deform_rest_shape.py``, docs/guides/validate.md).

Where the rest of the error is (``demos/deform_diagnose.py``, DLO2, 4 eval trials): sideways (horizontal,
normal to the chord between the clamps) about twice the vertical and along-chord parts; flat over the
5 s (no drift); the start matches (0.4 mm at t = 0), and the model started from the measured state at
any frame has most of its open-loop error within 0.2 s: the model answers the held ends' motion with a
smaller sideways swing in some trials (half the measured, 60-70 ms late, in trial 41), which neither the
damping (less of it: worse), the grip's direction (the cable's tangent at the grip is within 4 degrees
of the held pair's) nor any roll convention for the grippers (kept level: 13.7 mm instead of 7.5)
explains. What limits the match: :data:`LIMITS`.

Ruled out too (``--fit-gravity-tilt``, ``--fit-drag``, ``demos/deform_hypotheses.py``; docs/guides/validate.md):
a tilted capture frame (the fitted tilts across the chord exclude each other between cables that share the
rig, +2.8..+5.3 deg on DLO1 against -6.4..-4.0 on DLO3, and the eval L1 moves by -0.4..+0.3 mm while the
train L1 falls by up to 1.1: a body force that overfits), quadratic air drag (at most 0.1 mm), and the
markers' arc lengths (frame 0 against the trial's or the cable's median distances: within 0.15 mm; the
chord lengths are right to 1.5 %). The steady part of the error (per free marker, the same in every trial)
bounds any steady correction: removed as learned on train, eval L1 11.4 / 7.15 / 6.2 mm on DLO1-3.
"""
from __future__ import annotations

import argparse
import io
import json
import math
import pickle
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from bullet_dlo.analysis.fit_recording import RIGHT_FROM_LEFT, Recording
from bullet_dlo.core.boundary import EndHolder, Waypoints, default_normal
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState, build_arrays
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_in_range, check_int, check_positive
from bullet_dlo.reality.recording import MarkerRecording

RATE = 100.0  # DEFORM frame rate [Hz]
DIAMETER = 0.01  # guessed cable diameter [m]: sets EA/EI = 16/d^2 only (the cable stays near-inextensible)
LINEAR_DENSITY = 0.1  # guessed mass per length [kg/m]: shapes see only E/rho
PARAMETERS = ("bending_per_mass", "damping_rate", "internal_damping")
UNITS = {"bending_per_mass": "m^4/s^2", "damping_rate": "1/s", "internal_damping": "s"}
BOUNDS = {"bending_per_mass": (1e-5, 10.0), "damping_rate": (1e-3, 100.0), "internal_damping": (1e-6, 0.1)}
GUESS = {"bending_per_mass": 0.03, "damping_rate": 1.0, "internal_damping": 3e-3}
STIFFNESS_GRID = (0.003, 0.01, 0.03, 0.1, 0.3, 1.0)  # EI/(rho A) tried first [m^4/s^2]: the cables differ 30x
EXTRA_UNITS = {"gravity_tilt_x": "rad", "gravity_tilt_y": "rad", "drag_per_mass": "1/m"}
"""Optional parameters (:func:`fit`'s ``extra``): the motion-capture frame's tilt, gravity's direction
(-g_z) turned by gravity_tilt_x towards +x and gravity_tilt_y towards +y (g = |g| (tan tx, tan ty, -1) /
norm), and quadratic air drag per mass, 1/2 rho_air C_d d / (rho A) [1/m] (force per length
1/2 rho_air C_d d |v_n| v_n; shapes see only its ratio to the mass per length)."""
EXTRA_BOUNDS = {"gravity_tilt_x": (-0.3, 0.3), "gravity_tilt_y": (-0.3, 0.3), "drag_per_mass": (1e-4, 50.0)}
EXTRA_GUESS = {"gravity_tilt_x": 0.0, "gravity_tilt_y": 0.0, "drag_per_mass": 0.1}
LINEAR_PARAMETERS = frozenset({"gravity_tilt_x", "gravity_tilt_y"})  # fitted as they are (others in logs)
AIR_DENSITY = 1.204  # [kg/m^3], the core's default fluid
AUTHORS_EVAL_L1 = {"DLO1": (0.0111, 0.0140), "DLO2": (0.0102, 0.0102), "DLO3": (0.0099, 0.0099)}
"""The authors' logged DEFORM eval losses [m] (range over their logs), for the table."""


# ----- reading ---------------------------------------------------------------------------------
class RestrictedUnpickler(pickle.Unpickler):
    """Unpickles plain containers, numbers and numpy arrays only; any other global is refused.

    A pickle can name any importable callable (``os.system``...) and have it called on load;
    here only numpy's array and dtype reconstruction may be named.
    """

    ALLOWED: frozenset[tuple[str, str]] = frozenset({
        ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
        ("numpy", "ndarray"), ("numpy", "dtype"), ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
    })

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in self.ALLOWED:
            return super().find_class(module, name)
        raise ParameterError(f"pickle: global {module}.{name} is not allowed (only plain lists/numbers and "
                             "numpy arrays: numpy.core.multiarray._reconstruct, numpy.ndarray, numpy.dtype)")


DT_MIN = 1e-5
"""Smallest model step [s] the DEFORM commands take (a fit at 1e-5 s runs 200x the default's steps)."""
MAX_MARKER_DISTANCE = 100.0
"""Largest marker coordinate accepted [m] (as the fit's recordings: a larger one is a unit mistake)."""


def read_pickle(path: str | Path) -> np.ndarray:
    """One DEFORM trial: marker positions [m], shape (T, 3, m), through :class:`RestrictedUnpickler`."""
    path = Path(path)
    try:
        raw = RestrictedUnpickler(io.BytesIO(path.read_bytes())).load()
    except ParameterError as err:
        raise ParameterError(f"{path}: {err}") from None
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError, IndexError) as err:
        raise ParameterError(f"{path}: not a readable pickle of marker positions ({err})") from None
    try:  # (a ragged list is no array: numpy refuses it in either call)
        unreal = np.iscomplexobj(raw) or (isinstance(raw, np.ndarray) and raw.dtype.kind not in "biuf")
    except (ValueError, TypeError):
        raise ParameterError(f"{path}: markers must be a (T, 3, m) array of numbers [m]") from None
    if unreal:
        raise ParameterError(f"{path}: markers must be real numbers [m] (got {np.asarray(raw).dtype})")
    try:
        a = np.asarray(raw, dtype=float)
    except (ValueError, TypeError):
        raise ParameterError(f"{path}: markers must be a (T, 3, m) array of numbers [m]") from None
    if a.ndim != 3 or a.shape[1] != 3 or a.shape[0] < 3 or a.shape[2] < 5 or not np.all(np.isfinite(a)):
        raise ParameterError(f"{path}: markers must be a finite (T >= 3, 3, m >= 5) array [m], got shape {a.shape}")
    far = float(np.abs(a).max())
    if far > MAX_MARKER_DISTANCE:
        raise ParameterError(f"{path}: a marker {far:.4g} m from the origin, above {MAX_MARKER_DISTANCE:g} m: markers "
                             "must be in metres")
    return a


def arc_lengths(points: np.ndarray) -> np.ndarray:
    """Arc length of each marker from the first [m], (m,): cumulative distances between neighbours
    in ``points`` [m], (m, 3) (a chord underestimates a curved cable between markers by about
    (l kappa)^2 / 24: 0.04 % for 10 cm at 1/(0.5 m))."""
    d = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(d <= 0):
        raise ParameterError("markers: two neighbouring markers coincide; arc lengths need distinct positions")
    return np.r_[0.0, np.cumsum(d)]


def load_trial(path: str | Path) -> MarkerRecording:
    """A DEFORM trial as a :class:`MarkerRecording` (arc lengths from the first frame)."""
    a = read_pickle(path)
    x = np.ascontiguousarray(a.transpose(0, 2, 1))
    return MarkerRecording(Path(path).stem, np.arange(len(x)) / RATE, x, arc_lengths(x[0]))


def read_recording(path: str | Path, smooth: int = 5) -> Recording:
    """A DEFORM trial as a :class:`~bullet_dlo.analysis.fit_recording.Recording` for ``bullet-dlo fit``:
    both ends clamped at the inner held markers, each following its held pair (despiked, smoothed over
    ``smooth`` frames; the grasp frame's roll carried by parallel transport, since a pair fixes no roll);
    the free markers as the ``marker`` kind at their arc lengths from the first clamp; the cable's
    length between the clamps; the first frame's shape and velocity as the start (the trials begin
    mid-motion). The same model as :func:`build_model`, through the fit's own machinery."""
    rec = load_trial(path)
    clean = cleaned(rec, (*rec.first_pair, *rec.last_pair), smooth)
    s0 = rec.s[rec.first_pair[1] % rec.n_markers]
    pos, quat = np.empty((len(rec.t), 2, 3)), np.empty((len(rec.t), 2, 4))
    for arm, end in enumerate(("first", "last")):
        pos[:, arm], d = clean.clamp(end)
        frames = transported_frames(d) * (Rotation.identity() if arm == 0 else RIGHT_FROM_LEFT)
        quat[:, arm] = frames.as_quat()
    free = rec.free
    return Recording(rec.t, pos, quat, None, name=rec.name, markers=rec.markers[:, free],
                     marker_s=rec.s[free] - s0, length=float(rec.s[rec.last_pair[0] % rec.n_markers] - s0),
                     initial=(rec.s - s0, rec.markers[0], first_velocity(rec, smooth)))


def transported_frames(d: np.ndarray) -> Rotation:
    """Frames whose x axis follows the unit directions ``d`` (k, 3), each turned from the previous by the
    smallest rotation (parallel transport: no roll about the axis is invented)."""
    first = np.column_stack([d[0], default_normal(d[0]), np.cross(d[0], default_normal(d[0]))])
    return transport(d) * Rotation.from_matrix(first)


def transport(d: np.ndarray) -> Rotation:
    """The turns from direction d[0] to each d[k] (unit, (k, 3)), each the previous one followed by the
    smallest rotation from d[k - 1] to d[k]: (k,) rotations, the first the identity."""
    turn = [Rotation.identity()]
    for a, b in zip(d[:-1], d[1:]):
        axis = np.cross(a, b)
        angle = math.atan2(float(np.linalg.norm(axis)), float(a @ b))
        turn.append(Rotation.from_rotvec(axis / (np.linalg.norm(axis) + 1e-300) * angle) * turn[-1])
    return Rotation.concatenate(turn)


def cleaned(rec: MarkerRecording, markers: Sequence[int], smooth: int) -> MarkerRecording:
    """``rec`` with the given markers despiked and smoothed over ``smooth`` frames (the held pairs: motion
    capture jitter would become large accelerations of the clamps)."""
    clean = replace(rec, markers=rec.markers.copy())
    for i in markers:
        clean.markers[:, i] = smoothed(despiked(rec.markers[:, i]), smooth)
    return clean


def first_velocity(rec: MarkerRecording, smooth: int) -> np.ndarray:
    """Marker velocities [m/s] at frame 0, (m, 3): a cubic Savitzky-Golay derivative over the first frames."""
    from scipy.signal import savgol_filter

    h = float(rec.t[1] - rec.t[0])
    return savgol_filter(rec.markers[:11], max(5, smooth | 1), 3, deriv=1, delta=h, axis=0, mode="interp")[0]


def trial_files(folder: Path, what: str) -> list[Path]:
    """The ``*.pkl`` files of ``folder``, sorted by number; ParameterError if none."""
    if not folder.is_dir():
        raise ParameterError(f"{what}: folder {folder} does not exist (DLO_DIR must hold train/ and eval/ with *.pkl)")
    files = sorted(folder.glob("*.pkl"), key=lambda p: (len(p.stem), p.stem))
    if not files:
        raise ParameterError(f"{what}: no *.pkl trial in {folder}")
    return files


# ----- the model -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Numerics:
    """How the model runs: integrator, n point masses, step dt [s], waypoint knots per second
    taken from the recorded held pairs [Hz], and the held poses' smoothing window [frames]
    (odd; 1: none; motion capture jitter turns into large accelerations otherwise); twist: give
    the cable the core's material frame (twist springs with Poisson's ratio 0.3; the clamps' roll
    follows the pairs by parallel transport, i.e. no roll is invented)."""

    integrator: str = "bdf2"
    n_masses: int = 21
    dt: float = 2e-3
    knot_rate: float = 50.0
    smooth: int = 5
    twist: bool = False

    def __post_init__(self) -> None:
        check_int("n_masses", self.n_masses, 4, 2000)
        check_in_range("dt", self.dt, DT_MIN, 0.01)  # (at most the frame interval; below DT_MIN a fit runs for days)
        check_positive("knot_rate", self.knot_rate)
        check_int("smooth", self.smooth, 1, 51)


def cable_spec(length: float, values: dict[str, float], n_masses: int, twist: bool = False) -> CableSpec:
    """The core cable for ``values`` (bending_per_mass EI/(rho A) [m^4/s^2], damping_rate [1/s],
    internal_damping [s], optionally drag_per_mass [1/m]) with the guessed mass and diameter, with a
    material frame if ``twist``. drag_per_mass k becomes the core's quadratic drag with C_d =
    2 k (rho A) / (rho_air d) on the guessed mass per length and diameter."""
    probe = CableSpec(length=length, diameter=DIAMETER, mass=LINEAR_DENSITY * length, youngs_modulus=1.0)
    e = values["bending_per_mass"] * LINEAR_DENSITY / probe.second_moment
    cd = 2.0 * values.get("drag_per_mass", 0.0) * LINEAR_DENSITY / (AIR_DENSITY * DIAMETER)
    return probe.with_(youngs_modulus=e, n_masses=n_masses, damping_rate=values["damping_rate"],
                       internal_damping=values["internal_damping"], twist=bool(twist),
                       drag_coefficient=cd, fluid_density=AIR_DENSITY)


def gravity_of(values: dict[str, float]) -> np.ndarray:
    """Gravity [m/s^2], (3,), in the motion-capture frame: -|g| z turned by ``gravity_tilt_x`` towards +x
    and ``gravity_tilt_y`` towards +y [rad] (0 when absent): |g| (tan tx, tan ty, -1) / norm."""
    u = np.array([math.tan(values.get("gravity_tilt_x", 0.0)), math.tan(values.get("gravity_tilt_y", 0.0)), -1.0])
    return float(np.linalg.norm(STANDARD_GRAVITY)) * u / np.linalg.norm(u)


def smoothed(x: np.ndarray, window: int) -> np.ndarray:
    """``x`` (k, ...) smoothed along axis 0 by a cubic Savitzky-Golay filter of ``window`` frames (1: as is)."""
    if window < 5:
        return x.copy()
    from scipy.signal import savgol_filter
    return savgol_filter(x, window | 1, 3, axis=0, mode="interp")


def despiked(x: np.ndarray, window: int = 7, tol: float = 0.005) -> np.ndarray:
    """``x`` (k, 3) [m] with samples farther than ``tol`` [m] from their ``window``-frame running median
    replaced by that median (motion-capture glitches: some held markers jump by centimetres for a frame)."""
    from scipy.ndimage import median_filter
    med = median_filter(x, size=(window, 1), mode="nearest")
    bad = np.linalg.norm(x - med, axis=1) > tol
    out = x.copy()
    out[bad] = med[bad]
    return out


def clamp_holder(rec: MarkerRecording, end: str, num: Numerics) -> EndHolder:
    """The clamp at ``end`` following the recorded held pair: position of the inner held marker,
    direction of the pair (turned by parallel transport, so that no roll is invented), as a C2
    waypoint path through knots every 1/knot_rate s. The pair's markers are despiked and smoothed first."""
    pair = rec.first_pair if end == "first" else rec.last_pair
    pos, d = cleaned(rec, pair, num.smooth).clamp(end)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    step = max(1, round(1.0 / (num.knot_rate * float(np.median(np.diff(rec.t))))))
    idx = np.unique(np.r_[np.arange(0, len(rec.t), step), len(rec.t) - 1])
    rot = transport(d[idx]).as_rotvec()  # smallest rotation from one knot's direction to the next
    path = Waypoints(end, tuple(rec.t[idx] - rec.t[0]), tuple(map(tuple, pos[idx] - pos[idx[0]])),
                     tuple(map(tuple, rot)), rest=False)
    return EndHolder("clamped", pos[0].copy(), d[0].copy(), (path,))


def first_frames(rec: MarkerRecording, s_nodes: np.ndarray, num: Numerics) -> tuple[np.ndarray, np.ndarray]:
    """Node positions [m] and velocities [m/s], (n, 3), at arc lengths ``s_nodes`` [m] from the
    first frames: a cubic spline in arc length through the markers of frame 0, and through the
    markers' velocities (a cubic Savitzky-Golay derivative over the first frames)."""
    pos = CubicSpline(rec.s, rec.markers[0], axis=0)(s_nodes)
    vel = CubicSpline(rec.s, first_velocity(rec, num.smooth), axis=0)(s_nodes)
    return pos, vel


@dataclass(frozen=True)
class RestShape:
    """A curved rest shape: rest curvature magnitude kappa [1/m] (>= 0) at fractions ``sigma`` of the
    cable's length between the clamps (0: first clamp, 1: last), linear in between and constant beyond
    the ends; the model's interior nodes get the rest turning angle kappa(sigma_i) l0
    (:mod:`bullet_dlo.core.kernels.rest_shape`: the energy 1/2 k_b (beta - beta0)^2, a cable that keeps a
    set whose plane is free to turn). ``sigma`` strictly increasing."""

    sigma: tuple[float, ...]
    kappa: tuple[float, ...]

    def __post_init__(self) -> None:
        sg, kp = np.asarray(self.sigma, dtype=float), np.asarray(self.kappa, dtype=float)
        if sg.ndim != 1 or sg.shape != kp.shape or len(sg) < 1 or np.any(np.diff(sg) <= 0):
            raise ParameterError("rest shape: sigma must be strictly increasing fractions of the length, "
                                 "one kappa each")
        if not np.all(np.isfinite(kp)) or np.any(kp < 0):
            raise ParameterError("rest shape: kappa must be finite rest curvatures >= 0 [1/m]")

    def angles(self, n: int, length: float) -> np.ndarray:
        """Rest turning angles [rad] of the n nodes of a cable of ``length`` [m] (clamp nodes 0)."""
        l0 = length / (n - 1)
        out = np.interp(np.linspace(0.0, 1.0, n), self.sigma, self.kappa) * l0
        out[0] = out[-1] = 0.0
        return out


def build_model(rec: MarkerRecording, values: dict[str, float], num: Numerics,
                gravity: Sequence[float] | None = None, rest: RestShape | None = None
                ) -> tuple[CableModel, CableState, np.ndarray]:
    """The clamped cable between the inner held markers (with the curved ``rest`` shape if given; gravity
    [m/s^2] as given, else :func:`gravity_of` ``values``, i.e. -9.81 z without tilts), its
    start state (first frames) and the markers' arc lengths along it [m] (negative / beyond the length
    for the outer held markers)."""
    s0 = rec.s[rec.first_pair[1] % rec.n_markers]
    s1 = rec.s[rec.last_pair[0] % rec.n_markers]
    spec = cable_spec(float(s1 - s0), values, num.n_masses, num.twist)
    first, last = clamp_holder(rec, "first", num), clamp_holder(rec, "last", num)
    s_nodes = s0 + np.linspace(0.0, spec.length, spec.n_masses)
    x0, v0 = first_frames(rec, s_nodes, num)
    x0[0], x0[-1] = first.position, last.position
    g = gravity_of(values) if gravity is None else np.asarray(gravity, dtype=float)
    arrays = build_arrays(spec, "clamped", "clamped", g)
    if rest is not None:
        arrays = arrays._replace(rest_angle=rest.angles(spec.n_masses, spec.length))
    model = CableModel(spec, first, last, g, arrays, x0)
    return model, CableState(x0, v0, 0.0), rec.s - s0


def predict(rec: MarkerRecording, values: dict[str, float], num: Numerics,
            gravity: Sequence[float] | None = None, rest: RestShape | None = None
            ) -> tuple[np.ndarray | None, float]:
    """Model marker positions [m], (k, m, 3), open-loop over the whole recording (held markers
    as recorded), and the thread CPU time of the run [s]; None if the run went unstable. ``gravity``
    [m/s^2]: as given, else from ``values`` (:func:`gravity_of`)."""
    model, state, s = build_model(rec, values, num, gravity, rest)
    duration = float(rec.t[-1] - rec.t[0])
    every = max(1, round(float(rec.t[1] - rec.t[0]) / num.dt))
    tic = time.thread_time()
    res = simulate(model, num.integrator, num.dt, duration, state=state, record_every=every, max_records=10**7)
    cpu = time.thread_time() - tic
    if not res.stable:
        return None, cpu
    xs = res.x[:len(rec.t)]
    if len(xs) < len(rec.t):
        return None, cpu
    out = rec.markers.copy()
    s_nodes = np.linspace(0.0, model.spec.length, model.n)
    for k in rec.free:
        j = int(np.clip(np.searchsorted(s_nodes, s[k]) - 1, 0, model.n - 2))
        w = (s[k] - s_nodes[j]) / (s_nodes[j + 1] - s_nodes[j])
        out[:, k] = (1.0 - w) * xs[:, j] + w * xs[:, j + 1]
    return out, cpu


def l1(pred: np.ndarray, rec: MarkerRecording) -> float:
    """The authors' metric: mean absolute coordinate error over all markers and frames [m]."""
    return float(np.mean(np.abs(pred - rec.markers)))


def _l1_or_nan(pred: np.ndarray | None, rec: MarkerRecording) -> float:
    return l1(pred, rec) if pred is not None else math.nan


def frozen(rec: MarkerRecording) -> np.ndarray:
    """The frozen-shape baseline: the free markers stay where the first frame has them, (k, m, 3)."""
    out = rec.markers.copy()
    out[:, rec.free] = rec.markers[0, rec.free]
    return out


# ----- the fit ---------------------------------------------------------------------------------
@dataclass
class Fit:
    """Parameters fitted on a set of trials (by name, SI; see :data:`UNITS`) and what the fit saw.

    values: at the optimum; theta: their logs; jac: per-trial Jacobians of the residual in log
    parameters at the optimum, residuals: per-trial residuals [m] there; evaluations: forward
    runs of the whole set; cpu_s: thread CPU time of those runs [s]; simulated_s: seconds simulated.
    """

    values: dict[str, float]
    theta: np.ndarray
    jac: list[np.ndarray]
    residuals: list[np.ndarray]
    evaluations: int
    cpu_s: float
    simulated_s: float
    message: str
    names: tuple[str, ...] = PARAMETERS
    without_extra: dict[str, float] | None = None  # with ``extra``: the three fitted with the extras held at their guess


def values_of(theta: np.ndarray, names: Sequence[str] = PARAMETERS) -> dict[str, float]:
    """Parameter values (SI) of ``theta``: logs of the values, but the tilts (:data:`LINEAR_PARAMETERS`) as they are."""
    return {k: float(v if k in LINEAR_PARAMETERS else math.exp(v)) for k, v in zip(names, theta)}


def theta_of(values: dict[str, float], names: Sequence[str]) -> np.ndarray:
    """The inverse of :func:`values_of`."""
    return np.array([values[k] if k in LINEAR_PARAMETERS else math.log(values[k]) for k in names])


def bounds_of(name: str) -> tuple[float, float]:
    """A parameter's box (SI), :data:`BOUNDS` or :data:`EXTRA_BOUNDS`."""
    return BOUNDS[name] if name in BOUNDS else EXTRA_BOUNDS[name]


def unit_of(name: str) -> str:
    return UNITS[name] if name in UNITS else EXTRA_UNITS[name]


class Residual:
    """Free-marker residuals [m] of a set of trials as a function of the log parameters, every
    ``every``-th frame; an unstable run gives a large constant residual (10 cm per coordinate)."""

    def __init__(self, recs: Sequence[MarkerRecording], num: Numerics, every: int = 5,
                 rest: RestShape | None = None, names: Sequence[str] = PARAMETERS,
                 fixed: dict[str, float] | None = None):
        self.recs, self.num, self.every, self.rest = list(recs), num, every, rest
        self.names, self.fixed = tuple(names), dict(fixed or {})  # fixed: values not fitted (e.g. a known tilt)
        self.evaluations, self.cpu_s, self.simulated_s = 0, 0.0, 0.0

    def trial(self, rec: MarkerRecording, theta: np.ndarray) -> np.ndarray:
        pred, cpu = predict(rec, {**self.fixed, **values_of(theta, self.names)}, self.num, rest=self.rest)
        self.cpu_s += cpu
        self.simulated_s += float(rec.t[-1] - rec.t[0])
        size = len(rec.t[::self.every]) * len(rec.free) * 3
        if pred is None:
            return np.full(size, 0.1)
        return (pred - rec.markers)[::self.every][:, rec.free].reshape(-1)

    def per_trial(self, theta: np.ndarray) -> list[np.ndarray]:
        self.evaluations += 1
        return [self.trial(rec, theta) for rec in self.recs]

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return np.concatenate(self.per_trial(theta))


def valley_probe(res: Residual, sol, lo: np.ndarray, hi: np.ndarray, f_scale: float, max_evaluations: int,
                 reach: float = 1.0):
    """Where the optimiser stopped, try ``reach`` either way (in the logs) along the direction the data see least
    (the last right singular vector of the loss-weighted Jacobian at the stop); if either point costs less, descend
    again from the better one with the runs left. The trust region collapses in a long flat valley (the damping terms
    trading off): DLO1 fitted on 24 train trials stopped (xtol, 26 runs) at damping_rate 1.06, internal_damping
    0.0025, where the 8-trial optimum (0.48, 0.0158) costs those 24 trials 6 % less. Two runs of the set."""
    v = np.linalg.svd(np.asarray(sol.jac), full_matrices=False)[2][-1]
    soft = lambda r: float(np.sum(2.0 * (np.sqrt(1.0 + (r / f_scale) ** 2) - 1.0)))
    best, best_x = 2.0 * float(sol.cost) * f_scale**-2, None  # least_squares' cost is f_scale^2 / 2 * that sum
    for sign in (1.0, -1.0):
        x = np.clip(sol.x + sign * reach * v, lo + 1e-6, hi - 1e-6)
        c = soft(res(x))
        if c < best:
            best, best_x = c, x
    left = max_evaluations - res.evaluations
    if best_x is None or left < 6:
        return sol
    again = least_squares(res, best_x, bounds=(lo, hi), method="trf", loss="soft_l1", f_scale=f_scale,
                          diff_step=0.05, max_nfev=max(1, (left - 4) // 4), xtol=1e-3, ftol=1e-4)
    return again if again.cost < sol.cost else sol


def fit(recs: Sequence[MarkerRecording], num: Numerics, max_evaluations: int = 60,
        guess: dict[str, float] | None = None, every: int = 5, f_scale: float = 0.02,
        rest: RestShape | None = None, extra: Sequence[str] = ()) -> Fit:
    """Least squares (scipy trust region, in log parameters) on the free-marker residuals of all
    ``recs`` at once, with about ``max_evaluations`` forward runs of the set in all (an iteration
    costs four: one run and three for the finite-difference Jacobian). The loss is soft-L1 with scale ``f_scale`` [m]: the metric is an L1, and a
    trial where the real cable swings over the top while the model's does not should not steer
    the fit alone. Without a ``guess`` it starts from the best of :data:`STIFFNESS_GRID` (the cost
    is flat far from the optimum). At the optimum, per-trial Jacobians by forward differences (5 % steps).
    ``rest``: the cable's curved rest shape (held fixed).

    ``extra``: optional parameters of :data:`EXTRA_UNITS` (gravity_tilt_x, gravity_tilt_y, drag_per_mass)
    fitted too: first the three with the extras held at their guess (``guess``, else :data:`EXTRA_GUESS`),
    then all together from there with about ``max_evaluations`` more runs (forward differences with steps
    0.005 rad for the tilts, 0.05 in the logs of the others; an iteration costs one run per parameter + 1)."""
    extra = tuple(extra)
    for k in extra:
        if k not in EXTRA_UNITS:
            raise ParameterError(f"extra: {k!r} is not a parameter one can add (one of {', '.join(EXTRA_UNITS)})")
    guess = dict(guess or {})
    held = {k: float(guess.pop(k, EXTRA_GUESS[k])) for k in extra}
    for k in list(guess):
        if k not in PARAMETERS:
            guess.pop(k)
    res = Residual(recs, num, every, rest, fixed=held)
    if not guess:
        soft = lambda r: float(np.sum(np.sqrt(1.0 + (r / f_scale) ** 2)))
        costs = [soft(res(np.log([b, GUESS["damping_rate"], GUESS["internal_damping"]]))) for b in STIFFNESS_GRID]
        guess = {"bending_per_mass": STIFFNESS_GRID[int(np.argmin(costs))]}
    start = {**GUESS, **guess}
    lo = np.log([BOUNDS[k][0] for k in PARAMETERS])
    hi = np.log([BOUNDS[k][1] for k in PARAMETERS])
    theta0 = np.clip(np.log([start[k] for k in PARAMETERS]), lo + 1e-6, hi - 1e-6)
    sol = least_squares(res, theta0, bounds=(lo, hi), method="trf", loss="soft_l1", f_scale=f_scale,
                        diff_step=0.05, max_nfev=max(1, (max_evaluations - res.evaluations - 4) // 4),
                        xtol=1e-3, ftol=1e-4)
    sol = valley_probe(res, sol, lo, hi, f_scale, max_evaluations)
    if not extra:
        base = res.per_trial(sol.x)
        jac = [np.empty((len(r), len(PARAMETERS))) for r in base]
        for j in range(len(PARAMETERS)):
            step = np.zeros(len(PARAMETERS))
            step[j] = 0.05
            for i, r in enumerate(res.per_trial(sol.x + step)):
                jac[i][:, j] = (r - base[i]) / 0.05
        return Fit(values_of(sol.x), sol.x.copy(), jac, base, res.evaluations, res.cpu_s, res.simulated_s,
                   str(sol.message))
    names = PARAMETERS + extra
    joint = Residual(recs, num, every, rest, names)
    steps = np.array([0.005 if k in LINEAR_PARAMETERS else 0.05 for k in names])
    lo = theta_of({k: bounds_of(k)[0] for k in names}, names)
    hi = theta_of({k: bounds_of(k)[1] for k in names}, names)
    theta0 = np.clip(np.r_[sol.x, theta_of(held, extra)], lo + 1e-6, hi - 1e-6)

    def jacobian(theta: np.ndarray) -> np.ndarray:
        base = joint(theta)
        out = np.empty((len(base), len(names)))
        for j, h in enumerate(steps):
            out[:, j] = (joint(theta + h * np.eye(len(names))[j]) - base) / h
        return out

    sol = least_squares(joint, theta0, jac=jacobian, bounds=(lo, hi), method="trf", loss="soft_l1",
                        f_scale=f_scale, x_scale="jac", max_nfev=max(1, max_evaluations // (len(names) + 2)),
                        xtol=1e-3, ftol=1e-4)
    base = joint.per_trial(sol.x)
    jac = [np.empty((len(r), len(names))) for r in base]
    for j, h in enumerate(steps):
        for i, r in enumerate(joint.per_trial(sol.x + h * np.eye(len(names))[j])):
            jac[i][:, j] = (r - base[i]) / h
    return Fit(values_of(sol.x, names), sol.x.copy(), jac, base, res.evaluations + joint.evaluations,
               res.cpu_s + joint.cpu_s, res.simulated_s + joint.simulated_s, str(sol.message), names,
               {**held, **values_of(theta0[:len(PARAMETERS)])})


def turning_angles(x: np.ndarray) -> np.ndarray:
    """Turning angle [rad] between the chords to the neighbouring markers at every interior marker,
    (k, m - 2), of marker positions ``x`` [m], (k, m, 3)."""
    a = np.diff(x, axis=1)
    a /= np.linalg.norm(a, axis=2, keepdims=True)
    return np.arccos(np.clip(np.einsum("kmj,kmj->km", a[:, :-1], a[:, 1:]), -1.0, 1.0))


def free_sigma(rec: MarkerRecording) -> np.ndarray:
    """The free markers' places as fractions of the length between the clamps (inner held markers), (f,)."""
    s0, s1 = rec.s[rec.first_pair[1] % rec.n_markers], rec.s[rec.last_pair[0] % rec.n_markers]
    return (rec.s[rec.free] - s0) / (s1 - s0)


def identify_rest_shape(recs: Sequence[MarkerRecording], values: dict[str, float], num: Numerics,
                        iterations: int = 3, start: RestShape | None = None) -> tuple[RestShape, list[float]]:
    """The rest curvature that makes the model's mean turning at each free marker that of the recordings.

    The turning angle between marker chords at a free marker, averaged over every frame of every trial,
    measures how bent the cable is there on average; the model's (run open-loop with ``values``) is
    compared to it and the rest curvature there raised by the excess over the markers' spacing:
    kappa_j += (turn_measured_j - turn_model_j) / spacing_j, clipped at 0, ``iterations`` times (each a run
    of every trial; the model's mean turning rises by less than the rest angle does, so the step does
    not overshoot). Profile knots: the free markers' mean places (fractions of the clamp-to-clamp
    length). Returns the rest shape and the mean train L1 [m] before each update and after the last.
    """
    sigma = np.mean([free_sigma(r) for r in recs], axis=0)
    cols = [r.free - 1 for r in recs]  # turning_angles index of each free marker
    measured = np.mean([turning_angles(r.markers)[:, c].mean(axis=0) for r, c in zip(recs, cols)], axis=0)
    spacing = np.mean([0.5 * (r.s[r.free + 1] - r.s[r.free - 1]) for r in recs], axis=0)
    kappa = np.zeros(len(sigma)) if start is None else np.interp(sigma, start.sigma, start.kappa)
    history: list[float] = []
    for it in range(iterations + 1):
        rest = RestShape(tuple(sigma), tuple(kappa))
        preds = [predict(r, values, num, rest=rest)[0] for r in recs]
        if any(p is None for p in preds):
            raise ParameterError("rest shape: the model went unstable while identifying it")
        history.append(float(np.mean([l1(p, r) for p, r in zip(preds, recs)])))
        if it == iterations:
            break
        model_turn = np.mean([turning_angles(p)[:, c].mean(axis=0) for p, c in zip(preds, cols)], axis=0)
        kappa = np.maximum(kappa + (measured - model_turn) / spacing, 0.0)
    return RestShape(tuple(sigma), tuple(kappa)), history


def fit_rest_shape(recs: Sequence[MarkerRecording], values: dict[str, float], num: Numerics,
                   max_evaluations: int = 60, every: int = 5, f_scale: float = 0.02,
                   kappa_max: float = 30.0) -> tuple[RestShape, Fit, dict[str, Any]]:
    """A curved rest shape and the three parameters, fitted on ``recs``.

    Start: one step of :func:`identify_rest_shape` from straight (the measured mean turning at each free
    marker in excess of the straight model's, over the marker spacing). Then the rest curvature at the
    free markers' places (bounded to [0, ``kappa_max``] 1/m) by the same soft-L1 least squares on the
    free-marker positions as :func:`fit` (``values`` held), and last the three parameters again with that
    shape held (a third of the budget). ``max_evaluations``: forward runs of the set for the shape, about.
    Returns the shape, the parameters' :class:`Fit` and what the shape fit saw (knots, L1s, evaluations).
    """
    start, hist = identify_rest_shape(recs, values, num, iterations=1)
    sigma = np.asarray(start.sigma)
    res = Residual(recs, num, every)

    def residual(kappa: np.ndarray) -> np.ndarray:
        res.rest = RestShape(tuple(sigma), tuple(np.maximum(kappa, 0.0)))
        return np.concatenate(res.per_trial(np.log([values[k] for k in PARAMETERS])))

    k0 = np.clip(np.asarray(start.kappa), 0.0, kappa_max - 1e-6)
    sol = least_squares(residual, k0, bounds=(np.zeros_like(k0), np.full_like(k0, kappa_max)), method="trf",
                        loss="soft_l1", f_scale=f_scale, diff_step=0.05, x_scale=1.0,
                        max_nfev=max(1, max_evaluations // (len(k0) + 1)), xtol=1e-3, ftol=1e-4)
    rest = RestShape(tuple(sigma), tuple(np.maximum(sol.x, 0.0)))
    f = fit(recs, num, max(8, max_evaluations // 3), guess=values, every=every, f_scale=f_scale, rest=rest)
    f.cpu_s += res.cpu_s
    f.simulated_s += res.simulated_s
    info = {"sigma": list(rest.sigma), "kappa_per_m": list(rest.kappa), "train_l1_straight": hist[0],
            "train_l1_first_step": hist[1], "evaluations": res.evaluations + 2, "message": str(sol.message)}
    return rest, f, info


def linearised_loo(f: Fit, f_scale: float = 0.02) -> np.ndarray:
    """Log parameters with each trial left out, linearised: one Gauss-Newton step of the soft-L1
    problem (IRLS weights 1/sqrt(1 + (r/f_scale)^2)) from the optimum on the other trials'
    Jacobians, (N, 3). Cheap (no runs), good while the optimum moves little."""
    w = [1.0 / np.sqrt(np.sqrt(1.0 + (r / f_scale) ** 2)) for r in f.residuals]  # sqrt of the IRLS weights
    jw = [j * wi[:, None] for j, wi in zip(f.jac, w)]
    rw = [r * wi for r, wi in zip(f.residuals, w)]
    thetas = []
    for out in range(len(jw)):
        J = np.concatenate([x for i, x in enumerate(jw) if i != out])
        r = np.concatenate([x for i, x in enumerate(rw) if i != out])
        step, *_ = np.linalg.lstsq(J, -r, rcond=1e-10)
        thetas.append(f.theta + step)
    return np.array(thetas)


def refit_loo(recs: Sequence[MarkerRecording], f: Fit, num: Numerics, max_evaluations: int = 20,
              rest: RestShape | None = None) -> np.ndarray:
    """Log parameters with each trial left out, refitted from the full fit's optimum, (N, 3) (``rest`` held)."""
    thetas = []
    for out in range(len(recs)):
        g = fit([r for i, r in enumerate(recs) if i != out], num, max_evaluations, guess=f.values, rest=rest,
                extra=f.names[len(PARAMETERS):])
        f.cpu_s, f.simulated_s = f.cpu_s + g.cpu_s, f.simulated_s + g.simulated_s
        thetas.append(g.theta)
    return np.array(thetas)


def remaining_step(f: Fit, f_scale: float = 0.02) -> np.ndarray:
    """The Gauss-Newton step of the soft-L1 problem on all trials from where the fit stopped, (p,) in log parameters:
    about 0 at an optimum. Along a direction the data hardly see the optimiser stops early (DLO1 on 24 trials: xtol
    after 26 runs, 0.14 short in log internal_damping); :func:`jackknife` widens each interval by it."""
    w = [1.0 / np.sqrt(np.sqrt(1.0 + (r / f_scale) ** 2)) for r in f.residuals]
    j = np.concatenate([x * wi[:, None] for x, wi in zip(f.jac, w)])
    r = np.concatenate([x * wi for x, wi in zip(f.residuals, w)])
    return np.linalg.lstsq(j, -r, rcond=1e-10)[0]


def per_trial_estimates(f: Fit, f_scale: float = 0.02) -> np.ndarray:
    """Each trial's own estimate of the log parameters, linearised, (N, p): one Gauss-Newton step of the soft-L1
    problem on that trial alone from the pooled optimum (IRLS weights as :func:`linearised_loo`); a row is nan where
    the trial alone does not determine every parameter (its Jacobian has a blind direction). Their spread is how much
    the trials disagree, whatever weight the pooled fit gives each."""
    out = np.full((len(f.jac), len(f.theta)), np.nan)
    for i, (j, r) in enumerate(zip(f.jac, f.residuals)):
        w = 1.0 / np.sqrt(np.sqrt(1.0 + (r / f_scale) ** 2))
        step, _, rank, _ = np.linalg.lstsq(j * w[:, None], -r * w, rcond=1e-8)
        if rank == len(f.theta):
            out[i] = f.theta + step
    return out


TRADE_OFF = ("damping_rate", "internal_damping")
"""The pair that trades off: drag on the masses (c) and Kelvin-Voigt damping of the bending (tau) both damp the swings,
c + tau omega^2 for a mode of angular frequency omega."""


def trial_information(f: Fit, f_scale: float = 0.02) -> list[np.ndarray]:
    """Each trial's information on the log parameters, J^T W J with the soft-L1 IRLS weights, (p, p) per trial."""
    out = []
    for j, r in zip(f.jac, f.residuals):
        jw = j / np.sqrt(np.sqrt(1.0 + (r / f_scale) ** 2))[:, None]
        out.append(jw.T @ jw)
    return out


def trial_intervals(centre: np.ndarray, loo: np.ndarray, own: np.ndarray, weights: np.ndarray, level: float = 0.95
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Trial-clustered standard errors of ``centre`` (p,) from N trials. The pooled fit is about a weighted mean of
    the trials' own estimates ``own`` (N, p), weighted by their information ``weights`` (N, p); with trials that
    differ, its variance is s^2 / n_eff, s the sample SD of ``own`` and n_eff = (sum w)^2 / sum w^2 the effective
    number of trials (inf where a trial alone does not determine a parameter). Beside it the leave-one-trial-out
    jackknife's sqrt((N-1)/N sum (loo_i - mean)^2); the larger is used, with Student's t at n_eff - 1 degrees of
    freedom (at least 1). Returns jackknife, between-trial and used standard errors, t and n_eff, each (p,).

    Why: residuals within a trial are correlated over many frames and markers (on DLO1 over 3-16 samples at 20 Hz,
    and neighbouring markers together), so the independent units are trials, not samples; and a few trials carry
    the fit (DLO1 on 8 trials: n_eff 3.4 for EI/(rho A), 1.1-1.3 for the damping terms), where the jackknife alone
    with z 1.96 gave 8- and 24-trial intervals that excluded each other."""
    n = len(loo)
    w = np.asarray(weights, dtype=float)
    n_eff = np.minimum(w.sum(axis=0) ** 2 / np.maximum((w ** 2).sum(axis=0), 1e-300), n)
    from scipy import stats  # here: importing it costs every CLI call 0.7 s (the parser imports this module)

    t = stats.t.ppf(0.5 + level / 2, np.maximum(n_eff - 1.0, 1.0))
    if n < 2:
        inf = np.full(len(centre), math.inf)
        return inf, inf, inf, t, n_eff
    jk = np.sqrt((n - 1) / n * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    with np.errstate(invalid="ignore"):
        between = np.where(np.all(np.isfinite(own), axis=0), np.nanstd(own, axis=0, ddof=1) / np.sqrt(n_eff), math.inf)
    return jk, between, np.maximum(jk, between), t, n_eff


def agreed_damping(f: Fit, loo: np.ndarray, own: np.ndarray, level: float = 0.95,
                   f_scale: float = 0.02, step: np.ndarray | None = None) -> dict[str, Any] | None:
    """The damping the data determine when the two damping terms trade off: c + tau omega^2 [1/s] (twice the decay
    rate it gives a mode of angular frequency omega). Its log moves by (1 - s, s) . (d log c, d log tau), s = tau
    omega^2 / (c + tau omega^2); omega is where that is the pooled fit's best-determined direction of the two (the
    leading eigenvector of their information, the other parameters profiled out); None when that direction has
    mixed signs (no omega gives it). Value, trial-clustered interval (:func:`trial_intervals`, widened by the
    combination's share of ``step``, :func:`remaining_step`), per-trial values."""
    if not all(k in f.names for k in TRADE_OFF) or not np.all(np.isfinite(own)):
        return None
    ic, it = (f.names.index(k) for k in TRADE_OFF)
    w8 = [1.0 / np.sqrt(np.sqrt(1.0 + (r / f_scale) ** 2)) for r in f.residuals]
    jw = np.concatenate([j * w[:, None] for j, w in zip(f.jac, w8)])
    h = jw.T @ jw
    d = [ic, it]
    o = [k for k in range(len(f.names)) if k not in d]
    schur = h[np.ix_(d, d)] - (h[np.ix_(d, o)] @ np.linalg.solve(h[np.ix_(o, o)], h[np.ix_(o, d)]) if o else 0.0)
    v = np.linalg.eigh(schur)[1][:, -1]
    if v[0] * v[1] <= 0:
        return None
    share = float(v[1] / (v[0] + v[1]))
    c, tau = f.values[TRADE_OFF[0]], f.values[TRADE_OFF[1]]
    w = math.sqrt(share * c / ((1.0 - share) * tau))
    comb = lambda th: np.log(np.exp(th[..., ic]) + np.exp(th[..., it]) * w ** 2)
    centre = comb(f.theta)
    u = np.zeros(len(f.names))
    u[ic], u[it] = 1.0 - share, share  # d comb / d theta at the fit
    info = np.array([[u @ h @ u] for h in trial_information(f, f_scale)])
    jk, between, se, t, n_eff = trial_intervals(np.array([centre]), comb(loo)[:, None], comb(own)[:, None], info, level)
    short = 0.0 if step is None else abs(float(comb(f.theta + step) - centre))
    half = min(float(t[0]) * float(se[0]) + short, 700.0)
    return {"name": "damping_rate + internal_damping * omega^2", "unit": "1/s", "omega_rad_s": w,
            "value": float(math.exp(centre)),
            "interval_95": [float(math.exp(centre - half)), float(math.exp(centre + half))],
            "identifiable": bool(2 * half < math.log(3.0)), "per_trial": [float(x) for x in np.exp(comb(own))],
            "log_standard_error": {"jackknife": float(jk[0]), "between_trials": float(between[0])},
            "effective_trials": float(n_eff[0]), "t_quantile": float(t[0])}


def jackknife(f: Fit, thetas: np.ndarray | None = None, level: float = 0.95, trade_off_correlation: float = 0.5
              ) -> dict[str, dict[str, Any]]:
    """Trial-clustered 95 % intervals (:func:`trial_intervals`) from leave-one-trial-out fits ``thetas`` (N, p) in
    log parameters (default: :func:`linearised_loo`) and each trial's own estimate (:func:`per_trial_estimates`):
    value * exp(+-(t se + |step|)), t Student's at n_eff - 1 degrees of freedom, step the fit's :func:`remaining_step`,
    clipped to :data:`BOUNDS`. A parameter is called
    identifiable when its interval spans less than a factor of 3, it is not at a bound, and the data see it
    (Jacobian column at least 1 % of the largest). Where ``damping_rate`` and ``internal_damping`` are each not
    identifiable, or the trials' own values of them correlate (|r| >= ``trade_off_correlation``) and either is not,
    both are reported not identifiable with ``trades_off_with`` and the combination the data determine is given
    under ``"agreed_damping"`` (:func:`agreed_damping`); each term's interval then
    becomes an upper bound (``upper_bound_only``): from the box's lower bound to the combination's upper one over the
    term's weight (1 for damping_rate, omega^2 for internal_damping), since neither can exceed the combination."""
    thetas = linearised_loo(f) if thetas is None else np.asarray(thetas)
    own = per_trial_estimates(f)
    n = len(thetas)
    info = np.array([np.diag(h) for h in trial_information(f)])
    jk, between, se, tq, n_eff = trial_intervals(f.theta, thetas, own, info, level)
    step = remaining_step(f)
    seen = np.linalg.norm(np.concatenate(f.jac), axis=0)
    out: dict[str, dict[str, Any]] = {}
    for j, k in enumerate(f.names):
        b_lo, b_hi = bounds_of(k)
        t = float(tq[j])
        if k in LINEAR_PARAMETERS:  # a tilt: value +- t se [rad]; identifiable when the interval is under 0.05 rad wide
            half = t * se[j] + abs(step[j])
            lo, hi = max(f.values[k] - half, b_lo), min(f.values[k] + half, b_hi)
            at_bound = min(abs(f.theta[j] - b_lo), abs(f.theta[j] - b_hi)) < 0.005
            narrow = hi - lo < 0.05
        else:
            spread = min(t * se[j] + abs(step[j]), 700.0)  # a parameter the data do not see: an overflowing spread
            lo = max(f.values[k] * math.exp(-spread), b_lo)  # the fit's box bounds the interval
            hi = min(f.values[k] * math.exp(spread), b_hi)
            at_bound = min(abs(f.theta[j] - math.log(b_lo)), abs(f.theta[j] - math.log(b_hi))) < 0.05
            narrow = hi / lo < 3.0
        ident = bool(narrow and seen[j] >= 0.01 * seen.max() and not at_bound)
        loo = thetas[:, j] if k in LINEAR_PARAMETERS else np.exp(np.minimum(thetas[:, j], 700.0))
        mine = own[:, j] if k in LINEAR_PARAMETERS else np.exp(np.minimum(own[:, j], 700.0))
        out[k] = {"value": f.values[k], "unit": unit_of(k), "interval_95": [lo, hi], "identifiable": ident,
                  "leave_one_out": [float(x) for x in loo], "per_trial": [float(x) for x in mine],
                  "standard_error_log": {"jackknife": float(jk[j]), "between_trials": float(between[j])},
                  "remaining_step_log": float(step[j]), "t_quantile": t, "trials": n,
                  "effective_trials": float(n_eff[j]), "at_bound": bool(at_bound)}
    if all(k in out for k in TRADE_OFF) and n > 2:
        a, b = (f.names.index(k) for k in TRADE_OFF)
        ok = np.all(np.isfinite(own[:, [a, b]]), axis=1)
        r = float(np.corrcoef(own[ok][:, [a, b]].T)[0, 1]) if ok.sum() > 2 else math.nan
        either = not (out[TRADE_OFF[0]]["identifiable"] and out[TRADE_OFF[1]]["identifiable"])
        if either and (not math.isfinite(r) or abs(r) >= trade_off_correlation
                       or not (out[TRADE_OFF[0]]["identifiable"] or out[TRADE_OFF[1]]["identifiable"])):
            agreed = agreed_damping(f, thetas, own, level, step=step)
            for k, other in (TRADE_OFF, TRADE_OFF[::-1]):
                out[k]["identifiable"] = False
                out[k]["trades_off_with"] = other
                out[k]["trade_off_correlation"] = r
                if agreed is not None:  # each term alone is at most the whole combination
                    weight = 1.0 if k == TRADE_OFF[0] else agreed["omega_rad_s"] ** 2
                    out[k]["interval_95"] = [bounds_of(k)[0], min(max(agreed["interval_95"][1] / weight,
                                                                      out[k]["interval_95"][1]), bounds_of(k)[1])]
                    out[k]["upper_bound_only"] = True
            if agreed is not None:
                out["agreed_damping"] = agreed
    return out


# ----- numerics --------------------------------------------------------------------------------
def swing_test(values: dict[str, float], length: float, num: Numerics, damped: bool, duration: float = 6.0
               ) -> tuple[float, float]:
    """Frequency [Hz] and damping ratio of the first out-of-plane (pendulum) mode of the cable hanging
    between two clamps 0.6 L apart: released from the static shape under a sideways push of 20 % of its
    weight, the mid node's sideways motion fitted by log decrement of its peaks. ``damped``: with
    the fitted damping (else none: what is left is the integrator's numerical damping)."""
    spec = cable_spec(length, values, num.n_masses, num.twist)
    if not damped:
        spec = spec.with_(damping_rate=0.0, internal_damping=0.0)
    span = 0.6 * length
    first = EndHolder("clamped", np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    last = EndHolder("clamped", np.array([span, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    g = np.asarray(STANDARD_GRAVITY)
    s = np.linspace(0.0, 1.0, spec.n_masses)
    x0 = np.stack([span * s, np.zeros_like(s), 1.0 - 0.3 * length * np.sin(np.pi * s)], axis=1)
    model = CableModel(spec, first, last, g, build_arrays(spec, "clamped", "clamped", g), x0)
    push = np.zeros((model.n, 3))
    push[:, 1] = 0.2 * 9.81 * spec.point_masses()
    from bullet_dlo.core.statics import solve_static
    x = solve_static(model, x0, f_ext=push).x
    res = simulate(model, num.integrator, num.dt, duration, state=CableState(x, np.zeros_like(x), 0.0),
                   record_every=max(1, round(0.005 / num.dt)), max_records=10**6)
    y = res.x[:, model.n // 2, 1]
    return decay(res.t, y - np.mean(y[len(y) // 2:]) if not damped else y)


def decay(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Frequency [Hz] and damping ratio of a decaying oscillation y(t) about 0, from its positive peaks."""
    i = np.flatnonzero((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:]) & (y[1:-1] > 0)) + 1
    if len(i) < 3:
        return math.nan, math.nan
    a, b, c = y[i - 1], y[i], y[i + 1]
    shift = 0.5 * (a - c) / (a - 2 * b + c)  # parabola through three samples: the peak between them
    tp = t[i] + shift * (t[i + 1] - t[i])
    yp = b - 0.25 * (a - c) * shift
    period = float((tp[-1] - tp[0]) / (len(tp) - 1))
    slope = np.polyfit(tp, np.log(yp), 1)[0]  # amplitude ~ exp(-zeta omega t)
    omega = 2 * math.pi / period
    return 1.0 / period, float(-slope / omega)


def convergence(recs: Sequence[MarkerRecording], values: dict[str, float], num: Numerics,
                ns: Sequence[int] = (11, 21, 41, 81)) -> list[dict[str, float]]:
    """Mean L1 [m] of ``recs`` and the first swing mode's frequency [Hz] at each n (same dt, integrator)."""
    rows = []
    length = float(np.median([r.s[r.last_pair[0] % r.n_markers] - r.s[r.first_pair[1]] for r in recs]))
    for n in ns:
        nn = replace(num, n_masses=int(n))
        errs = [predict(r, values, nn)[0] for r in recs]
        l1s = [l1(p, r) if p is not None else math.nan for p, r in zip(errs, recs)]
        rows.append({"n_masses": int(n), "l1_m": float(np.mean(l1s)),
                     "swing_frequency_hz": swing_test(values, length, nn, damped=False)[0]})
    return rows


def numerics_report(recs: Sequence[MarkerRecording], values: dict[str, float], num: Numerics,
                    check_n: bool = True) -> dict[str, Any]:
    """Numerical vs physical damping of the first swing mode (see :func:`swing_test`) with the
    chosen integrator, n and dt; implicit Euler's beside it; and convergence in n on ``recs``."""
    length = float(np.median([r.s[r.last_pair[0] % r.n_markers] - r.s[r.first_pair[1]] for r in recs]))
    f0, z_num = swing_test(values, length, num, damped=False)
    _, z_phys = swing_test(values, length, num, damped=True)
    _, z_ie = swing_test(values, length, replace(num, integrator="implicit_euler"), damped=False)
    out = {"first_swing_mode_hz": f0, "numerical_damping_ratio": z_num, "damped_ratio_with_fit": z_phys,
           "implicit_euler_numerical_damping_ratio": z_ie,
           "method": "cable clamped 0.6 L apart, released from a sideways push; log decrement of the mid "
                     "node's swing over 6 s, with all damping off (numerical) and with the fitted damping"}
    if check_n:
        out["convergence"] = convergence(recs, values, num)
    return out


LIMITS = [
    ("the grippers' roll is unknown (a marker pair fixes only a direction): the sideways (out-of-plane) error "
     "dominates, is there within 0.2 s of a restart from the measured state, and no roll convention removes it "
     "(--twist with the roll by parallel transport: within 0.5 mm; with the grippers kept level: twice the error)"),
    ("a curved rest shape: real cables keep a set (DLO1: 14.5 deg more turning than the straight model at its "
     "third free marker in every trial); --rest-shape fits its magnitude (the plane free), which needs the "
     "material frame and the grippers' roll to be fixed to the cable"),
    ("real cables sometimes swing over the top where the model's does not (e.g. DLO1 eval 67, 44 mm) and in "
     "some trials swing sideways twice as far as the model's"),
    "damping law: linear drag + Kelvin-Voigt; damping_rate and internal_damping trade off",
    ("not a tilted capture frame, air drag or misplaced markers (--fit-gravity-tilt: tilts inconsistent between "
     "cables, eval within 0.4 mm; --fit-drag: within 0.1 mm); a steady per-marker correction learned on train "
     "would leave 11.4 / 7.15 / 6.2 mm on DLO1-3: the rest is the swings' size and phase"),
    ("mass and diameter are guessed: shapes see only EI/(rho A); held markers are given (counted as 0 "
     "error, as in the authors' metric)"),
]


def pick(files: list[Path], most: int | None) -> list[Path]:
    """At most ``most`` of ``files``, evenly spread (all if None)."""
    if most is None or most >= len(files):
        return files
    return [files[i] for i in np.unique(np.linspace(0, len(files) - 1, most).round().astype(int))]


def main(args: argparse.Namespace) -> int:
    """Fit on DLO_DIR/train, predict DLO_DIR/eval open-loop, write the JSON and plots, print a table."""
    root = Path(args.dlo_dir)
    if not root.is_dir():
        raise ParameterError(f"DLO_DIR: {root} is not a folder (it must hold train/ and eval/ with *.pkl trials)")
    num = Numerics()  # (an option not given keeps its default)
    n_masses = check_int("--n-masses", num.n_masses if args.n_masses is None else args.n_masses, 4, 2000)
    dt = check_in_range("--dt", num.dt if args.dt is None else args.dt, DT_MIN, 0.01)  # (the command line's names)
    num = Numerics(integrator=args.integrator or num.integrator, n_masses=n_masses, dt=dt, twist=bool(args.twist))
    most_train = check_int("--max-train-trials", args.max_train_trials, 2)  # (the intervals leave one trial out)
    most_eval = None if args.max_eval_trials is None else check_int("--max-eval-trials", args.max_eval_trials, 1)
    max_eval = check_int("--max-evaluations", args.max_evaluations, 2)
    plot_dir = None if args.no_plots else Path(args.plots) if args.plots else Path(args.json).parent
    if plot_dir is not None and plot_dir.exists() and not plot_dir.is_dir():
        raise ParameterError(f"--plots: {plot_dir} is a file, not a folder")
    train = [load_trial(p) for p in pick(trial_files(root / "train", "train"), most_train)]
    if len(train) < 2:
        raise ParameterError(f"DLO_DIR: {root / 'train'} holds {len(train)} trial, at least 2 are needed (the fit's "
                             "intervals leave one trial out)")
    evals = [load_trial(p) for p in pick(trial_files(root / "eval", "eval"), most_eval)]
    extra = (("gravity_tilt_x", "gravity_tilt_y") if getattr(args, "fit_gravity_tilt", False) else ()) + \
        (("drag_per_mass",) if getattr(args, "fit_drag", False) else ())
    if extra and getattr(args, "rest_shape", False):
        raise ParameterError("--rest-shape cannot be combined with --fit-gravity-tilt or --fit-drag "
                             "(the rest-shape fit holds gravity along -z and no drag)")
    f = fit(train, num, max_evaluations=max_eval, extra=extra)
    rest, rest_info, straight = None, None, None
    if f.without_extra is not None:  # the same fit's first stage (extras at their guess), for before/after
        straight = {"eval_l1": float(np.mean([_l1_or_nan(predict(r, f.without_extra, num)[0], r) for r in evals])),
                    "train_l1": float(np.mean([_l1_or_nan(predict(r, f.without_extra, num)[0], r) for r in train])),
                    "parameters": dict(f.without_extra)}
    if getattr(args, "rest_shape", False):
        straight = {"eval_l1": float(np.mean([_l1_or_nan(predict(r, f.values, num)[0], r) for r in evals])),
                    "train_l1": float(np.mean([_l1_or_nan(predict(r, f.values, num)[0], r) for r in train])),
                    "parameters": dict(f.values)}
        rest, f, rest_info = fit_rest_shape(train, f.values, num, max_evaluations=max_eval)
    params = jackknife(f, refit_loo(train, f, num, rest=rest) if args.intervals == "refit" else None)
    rows = {"train": {}, "eval": {}}
    preds = {}
    for split, recs in (("train", train), ("eval", evals)):
        for rec in recs:
            pred, _ = predict(rec, f.values, num, rest=rest)
            preds[(split, rec.name)] = pred
            rows[split][rec.name] = {"l1_m": l1(pred, rec) if pred is not None else None,
                                     "frozen_l1_m": l1(frozen(rec), rec), "stable": pred is not None}
    mean = lambda split, key: float(np.mean([r[key] if r[key] is not None else np.nan
                                             for r in rows[split].values()]))
    summary = {
        "dataset": str(root), "cable": root.name,
        "eval_l1": mean("eval", "l1_m"), "train_l1": mean("train", "l1_m"),
        "frozen_eval_l1": mean("eval", "frozen_l1_m"), "frozen_train_l1": mean("train", "frozen_l1_m"),
        "authors_deform_eval_l1": AUTHORS_EVAL_L1.get(root.name),
        "metric": "mean absolute coordinate error over all markers and frames [m] (held markers as recorded)",
        "trials": rows, "parameters": params,
        "guessed": {"linear_density_kg_per_m": LINEAR_DENSITY, "diameter_m": DIAMETER,
                    "youngs_modulus_Pa": cable_spec(1.0, f.values, num.n_masses).youngs_modulus,
                    **({"drag_coefficient": cable_spec(1.0, f.values, num.n_masses).drag_coefficient}
                       if "drag_per_mass" in f.values else {})},
        "gravity_m_per_s2": [float(g) for g in gravity_of(f.values)],
        "fit": {"evaluations": f.evaluations, "message": f.message, "train_trials": [r.name for r in train],
                "loss": "soft_l1, scale 0.02 m, free markers every 5th frame",
                "intervals": f"95 %, trial-clustered: Student's t (N - 1 dof) x the larger of the leave-one-trial-out "
                             f"jackknife ({args.intervals}) and the trials' own spread / sqrt(N), widened by the fit's "
                             f"remaining Gauss-Newton step; a damping pair that trades off gives its combination "
                             f"(agreed_damping) and upper bounds only"},
        "numerics": {**asdict(num)},
        "cost": {"cpu_s_per_simulated_s": f.cpu_s / f.simulated_s, "clock": "time.thread_time",
                 "fit_cpu_s": f.cpu_s},
        "limits": LIMITS,
    }
    if rest is not None:
        summary["rest_shape"] = rest_info
    if straight is not None:
        summary["straight"] = straight
    if not args.no_numerics_check:
        summary["numerics"].update(numerics_report(evals[:3], f.values, num))
    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=1, default=float))
    plots = []
    if plot_dir is not None:
        plots = plot_trials(plot_dir, out.stem, [(r, preds[("eval", r.name)]) for r in evals])
    print_table(summary)
    print("outputs: " + ", ".join(str(p.resolve()) for p in (out, *plots)))  # (as bullet_dlo.cli.outputs words it)
    return 0


def print_table(summary: dict[str, Any]) -> None:
    """The per-trial errors and the fitted parameters, as text."""
    print(f"{summary['cable']}: eval L1 {1e3 * summary['eval_l1']:.1f} mm (frozen shape "
          f"{1e3 * summary['frozen_eval_l1']:.1f} mm; authors' DEFORM {summary['authors_deform_eval_l1']}), "
          f"train L1 {1e3 * summary['train_l1']:.1f} mm")
    print(f"{'split':6} {'trial':>6} {'L1 [mm]':>9} {'frozen [mm]':>12}")
    for split in ("train", "eval"):
        for name, row in summary["trials"][split].items():
            v = "unstable" if row["l1_m"] is None else f"{1e3 * row['l1_m']:.1f}"
            print(f"{split:6} {name:>6} {v:>9} {1e3 * row['frozen_l1_m']:>12.1f}")
    for k, p in summary["parameters"].items():
        lo, hi = p["interval_95"]
        what = f"at most {hi:.3g}" if p.get("upper_bound_only") else f"{lo:.3g} - {hi:.3g}"
        name = f"{k} (omega {p['omega_rad_s']:.2f} rad/s)" if "omega_rad_s" in p else k
        print(f"{name:18} {p['value']:.4g} {p['unit']} (95 %: {what})"
              + ("" if p["identifiable"] else "  not identifiable")
              + (f", trades off with {p['trades_off_with']}" if "trades_off_with" in p else ""))
    num = summary["numerics"]
    if "numerical_damping_ratio" in num:
        print(f"{num['integrator']} n={num['n_masses']} dt={num['dt']}: first swing mode {num['first_swing_mode_hz']:.3f} Hz, "
              f"numerical damping ratio {num['numerical_damping_ratio']:.2g} vs {num['damped_ratio_with_fit']:.2g} "
              f"with the fitted damping (implicit Euler {num['implicit_euler_numerical_damping_ratio']:.2g})")
        for row in num.get("convergence", []):
            print(f"  n={row['n_masses']:4d}: L1 {1e3 * row['l1_m']:.2f} mm, swing mode {row['swing_frequency_hz']:.4f} Hz")
    if "rest_shape" in summary:
        rs, st = summary["rest_shape"], summary["straight"]
        print(f"rest shape: kappa [1/m] {' '.join(f'{k:.2f}' for k in rs['kappa_per_m'])} at sigma "
              f"{' '.join(f'{x:.2f}' for x in rs['sigma'])}; straight rest shape: "
              f"eval L1 {1e3 * st['eval_l1']:.1f} mm, "
              f"train L1 {1e3 * st['train_l1']:.1f} mm")
    elif "straight" in summary:
        st = summary["straight"]
        print(f"without the extra parameters (first stage of the same fit): eval L1 {1e3 * st['eval_l1']:.1f} mm, "
              f"train L1 {1e3 * st['train_l1']:.1f} mm")
    print(f"cost {summary['cost']['cpu_s_per_simulated_s']:.3g} CPU s per simulated s")
    print("limits of the match: " + "; ".join(summary["limits"]))


def plot_trials(folder: Path, stem: str, trials: list[tuple[MarkerRecording, np.ndarray | None]]) -> list[Path]:
    """One PNG per eval trial: x, y, z of three free markers over time, measured vs predicted; returns their paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for rec, pred in trials:
        fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
        free = rec.free
        chosen = free[[len(free) // 4, len(free) // 2, (3 * len(free)) // 4]]
        for ax, j, label in zip(axes, range(3), "xyz"):
            for c, k in zip(("C0", "C1", "C2"), chosen):
                ax.plot(rec.t, rec.markers[:, k, j], c, lw=1.2, label=f"marker {k} measured")
                if pred is not None:
                    ax.plot(rec.t, pred[:, k, j], c + "--", lw=1.0, label=f"marker {k} model")
            ax.set_ylabel(f"{label} [m]")
        axes[0].legend(fontsize=7, ncol=3)
        axes[-1].set_xlabel("t [s]")
        err = "unstable" if pred is None else f"L1 {1e3 * l1(pred, rec):.1f} mm"
        fig.suptitle(f"{stem}: trial {rec.name}, open-loop prediction ({err})")
        fig.tight_layout()
        written.append(folder / f"{stem}.{rec.name}.png")
        fig.savefig(written[-1], dpi=80)
        plt.close(fig)
    return written
