"""The beam_handling recordings (Mamedov et al., ICRA): a Franka Panda carrying a steel strip.

Reader of the libfranka CSV (:func:`read_beam_csv` -> :class:`BeamRecording`), the strip as a
core cable clamped at the flange and driven by the recorded flange path (:func:`predict_torques`; on the
compliant arm in a closed loop: :mod:`bullet_dlo.reality.beam_arm`),
and Franka's filtered external-torque estimate (:class:`EstimateFilter`, :func:`identify_filter`).

The strip (:class:`Strip`): 0.52 x 0.08 x 0.001 m steel, E 190-205 GPa, density 7870-8070 kg/m^3
(nominal: the midpoints). It is mounted on ``panda_link8`` turned by pi/4 about the flange z axis
(``setup_descr_beam.xacro``); in that beam frame the strip runs along -x from the flange
(its tip points along -x), its width along y, its thickness along z (the flange axis).

**One 3-D run (``strip_model="rectangle"``).** The strip is one core cable with a
rectangle section (width along the section axis d1, thickness along d2) and a material frame
(twist springs G J / l0, G = E / (2 (1 + nu)), nu = 0.3): two bending stiffnesses E I_weak and
E I_strong = (w/t)^2 E I_weak = 6400 E I_weak, twist, and their coupling. It is clamped at the flange
with the flange's full orientation: tangent the strip axis, section axis d1 the width (both from
:class:`Mounting`), and follows the flange's translation and rotation, under the full gravity;
its clamp force and moment (twist moment included) are the load on the flange.

**Two planar runs (``strip_model="planes"``).** The model from before the core had sections: two
superposed planar runs (:class:`PlaneRun`) of an isotropic cable, each with that plane's EI (and
the strip's EA and mass per length) clamped at the flange:

* weak plane, span(axis, normal): flange translation projected onto it, flange rotation about
  the width axis, gravity projected onto it; it gives the clamp force along axis and normal and
  the moment about the width axis;
* strong plane, span(axis, width): translation along the width, rotation about the normal,
  gravity along the width; it gives the force along the width and the moment about the normal.

It neglects twist (the strip's polar inertia is 1.8e-4 kg m^2), the coupling of the planes and the
rotation of the projection axes during the motion (the recorded flange turns by < 0.5 degrees).
On a motion within the weak plane the two models agree (``tests/reality/test_beam_strip.py``); on the
nine recordings their predictions differ by at most 3 % (measured with the rectangle at dt 0.1 ms, when the core
still advanced its twist in a staggered sub-step). The core's BDF2 step now solves the twist with the positions
(one Newton system), and the rectangle's band-passed torque on ocp_Z_15cm is 1.608 / 1.607 / 1.607 / 1.607 N m
at dt 1 / 0.5 / 0.25 / 0.1 ms (planes 1.608): both run at dt 1 ms.

**Which one.** ``rectangle`` is the default: one run per recording whatever the flange does, on the measured flange
path or on the compliant arm (:mod:`bullet_dlo.reality.beam_arm`). ``auto`` (:func:`choose_strip_model`) takes the
planes where they hold, about 15 % cheaper on the compliant arm: each planar run keeps the start pose's axes, so a
flange that turns out of the weak plane (about the strip axis or the thickness normal) leaves the weak run's strip
behind: after a 10 degree turn about the normal its weight moment has not turned at all
(``tests/reality/test_beam_turn.py``; the rectangle's turns by the flange's 10.000 degrees). ``auto`` runs the
planes while that turn stays within :data:`PLANES_MAX_TURN` (the nine recordings: 0.2-0.45 degrees in all), where
the coupling and twist the rectangle adds change nothing measurable (on the compliant arm every held-out ratio of
the two within 0.01, docs/guides/validate.md), and the rectangle beyond.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple
from pathlib import Path

import numpy as np
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from bullet_dlo.analysis.fit_recording import RIGHT_FROM_LEFT, Recording, low_pass_delayed
from bullet_dlo.core.boundary import Waypoints, default_normal
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.kernels.steppers import make_workspace
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality.panda import N_JOINTS, Panda, external_torques

TICK = 1e-3  # [s] libfranka's control period: one row per tick
GROUPS = ("q", "q_d", "dq", "dq_d", "tau_J", "tau_ext_hat_filtered")
COLUMNS = ("duration", "success rate", *(f"{g}[{j}]" for g in GROUPS for j in range(N_JOINTS)))
MOUNT_YAW = math.pi / 4  # [rad] beam frame = flange frame turned about its z (the xacro writes pi as 3.1415)
# one 3-D run of a rectangle-section cable | two planar isotropic runs | per recording, planes while the flange
# keeps the weak plane (:func:`choose_strip_model`)
STRIP_MODELS = ("rectangle", "planes", "auto")
# [s] default steps: with BDF2 the core couples the rectangle's twist into its Newton step, converged at 1 ms
# (module doc; it used to be a staggered first-order sub-step that needed 0.1 ms)
DEFAULT_DT = {"rectangle": 1e-3, "planes": 1e-3, "auto": 1e-3}
PLANES_MAX_TURN = math.radians(1.0)
"""[rad] Largest turn of the flange out of the strip's weak plane (about the strip axis or the thickness normal, from
its start pose) for which ``auto`` keeps the planes: each plane's run keeps its start-pose axes, so a flange turned by
theta about the normal leaves the weak run's weight moment m g L/2 sin(theta) off (``demos/beam_turn.py``: with 1-30
degrees of joint 6 added to ocp_Z_25cm's motion, 0.015 N m RMS per degree on joint 3, and its peak-to-peak over the
first 0.5 s after the motion 1.8 % off at 1 degree, 13 % at 10). The nine beam_handling motions turn the flange by
0.2-0.45 degrees in all."""


def check_strip_model(name: str) -> str:
    """``name`` if it is one of :data:`STRIP_MODELS`, else ParameterError."""
    if name not in STRIP_MODELS:
        raise ParameterError(f"strip model must be one of {', '.join(STRIP_MODELS)}, got {name!r}")
    return name


def off_plane_turn(rot: np.ndarray, mounting: "Mounting") -> float:
    """Largest turn [rad] of the flange rotations ``rot`` (m, 3, 3) from ``rot[0]`` about the strip's axis and its
    thickness normal at the start pose: the part of its rotation the planes cannot follow (a turn about the width
    axis stays in the weak plane)."""
    axis, _, normal = mounting.axes(rot[0])
    rotvec = Rotation.from_matrix(rot @ rot[0].T).as_rotvec()
    return float(np.max(np.hypot(rotvec @ axis, rotvec @ normal), initial=0.0))


def choose_strip_model(requested: str, rot: np.ndarray, mounting: "Mounting") -> tuple[str, str]:
    """The strip model for a recording whose flange takes the rotations ``rot`` (m, 3, 3), and why.

    ``auto``: the planes while the flange turns out of the weak plane by at most :data:`PLANES_MAX_TURN`,
    the rectangle beyond. ``planes`` or ``rectangle`` as asked; the planes beyond the bound with a warning in the
    reason (it starts with ``"warning:"``)."""
    turn = math.degrees(off_plane_turn(rot, mounting))
    bound = math.degrees(PLANES_MAX_TURN)
    if requested == "rectangle":
        return "rectangle", "asked for (the default): one 3-D run, whatever the flange does"
    if turn <= bound:
        return "planes", (f"the flange turns {turn:.2f} deg out of the weak plane, within the planes' "
                          f"{bound:g} deg" + (" (auto)" if requested == "auto" else ""))
    if requested == "auto":
        return "rectangle", (f"auto: the flange turns {turn:.1f} deg out of the weak plane, beyond the planes' "
                             f"{bound:g} deg (their runs keep the start pose's axes)")
    return "planes", (f"warning: the flange turns {turn:.1f} deg out of the weak plane, beyond the planes' {bound:g} "
                      "deg: their runs keep the start pose's axes, so the weight moment and the vibration's plane lag "
                      "the flange; use --strip-model rectangle or auto")


# ----- the recording ---------------------------------------------------------------------------
@dataclass(frozen=True)
class BeamRecording:
    """One libfranka recording at 1 kHz, k rows, 7 joints.

    t: time since the first row [s], (k,) (from the 1 ms tick counter ``duration``);
    q, q_d: measured / desired joint positions [rad], (k, 7); dq, dq_d: joint rates [rad/s];
    tau_J: measured joint torques [N m]; tau_ext_hat_filtered: Franka's filtered external-torque
    estimate [N m] (minus the torque of the load's wrench about the joints, low-pass filtered and
    delayed: see :class:`EstimateFilter`); name: the file's stem.
    """

    t: np.ndarray
    q: np.ndarray
    q_d: np.ndarray
    dq: np.ndarray
    dq_d: np.ndarray
    tau_J: np.ndarray
    tau_ext_hat_filtered: np.ndarray
    name: str = ""

    @property
    def rate(self) -> float:
        """Sample rate [Hz]."""
        return 1.0 / float(np.median(np.diff(self.t)))


MAX_JOINT_ANGLE = 2.0 * math.pi
"""Largest joint angle [rad] a beam_handling recording may hold (a Panda's joints stay within +-3.1 rad)."""


def read_beam_csv(path: str | Path) -> BeamRecording:
    """Read a beam_handling CSV (header ``duration, success rate, q[0..6], q_d[0..6], dq[0..6],
    dq_d[0..6], tau_J[0..6], tau_ext_hat_filtered[0..6]``). Raises ParameterError naming the file
    and what is wrong (missing columns, no rows, non-finite values)."""
    path = Path(path)
    try:
        with path.open(encoding="utf-8") as fh:
            header = [c.strip() for c in fh.readline().split(",")]
    except OSError as err:
        raise ParameterError(f"beam recording {path}: cannot read ({err.strerror})") from None
    except UnicodeDecodeError:
        raise ParameterError(f"beam recording {path.name}: not UTF-8 text (a beam_handling CSV is plain text)") from None
    dupes = sorted({c for c in header if header.count(c) > 1})
    if dupes:
        raise ParameterError(f"beam recording {path.name}: column(s) {', '.join(dupes[:4])} named more than once")
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise ParameterError(f"beam recording {path.name}: missing column(s) {', '.join(missing[:4])}"
                             f"{' ...' if len(missing) > 4 else ''}; a beam_handling CSV has {', '.join(COLUMNS[:3])} "
                             "... tau_ext_hat_filtered[6]")
    try:
        with warnings.catch_warnings():  # (a header alone: loadtxt warns, the row check below says it in one line)
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, encoding="utf-8")
    except (ValueError, UnicodeDecodeError) as err:  # a text cell, a short or long row, a non-UTF-8 byte
        what = " ".join(str(err).split(";")[0].split())[:160]
        raise ParameterError(f"beam recording {path.name}: every row after the header must hold {len(header)} "
                             f"numbers ({what})") from None
    if data.shape[0] < 3 or data.shape[1] != len(header) or not np.all(np.isfinite(data)):
        raise ParameterError(f"beam recording {path.name}: needs at least 3 rows of {len(header)} finite numbers")
    col = {c: i for i, c in enumerate(header)}
    group = {g: data[:, [col[f"{g}[{j}]"] for j in range(N_JOINTS)]] for g in GROUPS}
    worst = float(np.abs(np.concatenate([group["q"], group["q_d"]])).max())
    if worst > MAX_JOINT_ANGLE:
        raise ParameterError(f"beam recording {path.name}: a joint angle of {worst:.4g} rad, beyond +-{MAX_JOINT_ANGLE:g} "
                             "rad (a Panda's joints stay within +-3.1 rad): q and q_d must be in radians")
    ticks = data[:, col["duration"]]
    t = (ticks - ticks[0]) * TICK
    if np.any(np.diff(t) <= 0):
        raise ParameterError(f"beam recording {path.name}: the tick counter 'duration' must increase")
    return BeamRecording(t=t, name=path.stem, **group)


def beam_files(folder: str | Path, what: str = "folder") -> list[Path]:
    """The ``*.csv`` files of ``folder``, sorted; ParameterError naming ``what`` when there are none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ParameterError(f"{what}: {folder} is not a folder (give a folder of beam_handling *.csv files)")
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise ParameterError(f"{what}: no *.csv file in {folder} (give a folder of beam_handling *.csv files)")
    return files


# ----- Franka's estimate filter ----------------------------------------------------------------
@dataclass(frozen=True)
class EstimateFilter:
    """Franka's external-torque estimate as a first-order low-pass (cut-off ``cutoff_hz`` [Hz])
    after a pure delay ``delay_s`` [s], unit static gain. ``source`` says where the numbers come
    from. Default: identified on the nine beam_handling recordings (:func:`identify_filter`)."""

    cutoff_hz: float = 4.7
    delay_s: float = 0.010
    source: str = "default (identified on the 9 beam_handling recordings)"

    def apply(self, y: np.ndarray, rate: float) -> np.ndarray:
        """y [any unit], (k, ...), sampled at ``rate`` [Hz], filtered along axis 0 (starting at rest at y[0])."""
        y = np.asarray(y, dtype=float)
        return low_pass_delayed(y, np.arange(len(y)) / rate, self.cutoff_hz, self.delay_s)

    def response(self, f: np.ndarray) -> np.ndarray:
        """Complex frequency response at f [Hz] (continuous-time form)."""
        f = np.asarray(f, dtype=float)
        return np.exp(-2j * math.pi * f * self.delay_s) / (1 + 1j * f / self.cutoff_hz)


def identify_filter(recordings: list[BeamRecording], panda: Panda, settle: float = 1.0,
                    band_hz: tuple[float, float] = (1.5, 8.0), min_coherence: float = 0.9) -> EstimateFilter:
    """Identify :class:`EstimateFilter` from tau_J (the joint torque sensors) and the estimate.

    After the motion (from ``settle`` s after its end) the arm rings with the strip, so the
    estimate is filter(tau_J - arm inverse dynamics) (the arm's own inertia is what Franka's model
    subtracts; PyBullet's URDF inertias stand in for it). Per recording and joint, the transfer
    function estimate = cross spectrum / input spectrum (Welch, 1.024 s segments); bins in
    ``band_hz`` with coherence above ``min_coherence`` are pooled and a low-pass + delay with unit
    gain fitted to them in least squares.
    """
    from scipy.optimize import least_squares
    from scipy.signal import coherence, csd, welch

    from bullet_dlo.reality.vibration import motion_span

    freqs, values = [], []
    for rec in recordings:
        _, end = motion_span(rec.dq_d)
        s = slice(end + int(settle * rec.rate), None)
        sos = butter(2, 20.0, fs=rec.rate, output="sos")
        dq = sosfiltfilt(sos, rec.dq[s], axis=0)
        ddq = np.gradient(dq, 1.0 / rec.rate, axis=0)
        arm = np.array([panda.inverse_dynamics(q, v, a) for q, v, a in zip(rec.q[s], dq, ddq)])
        for j in range(N_JOINTS):
            u, y = rec.tau_J[s, j] - arm[:, j], rec.tau_ext_hat_filtered[s, j]
            f, puy = csd(u, y, fs=rec.rate, nperseg=1024)
            _, puu = welch(u, fs=rec.rate, nperseg=1024)
            _, coh = coherence(u, y, fs=rec.rate, nperseg=1024)
            keep = (f >= band_hz[0]) & (f <= band_hz[1]) & (coh >= min_coherence)
            freqs.extend(f[keep])
            values.extend(puy[keep] / puu[keep])
    if len(freqs) < 2:
        raise ParameterError("estimate filter: too few coherent frequency bins to identify it; use the default")
    f, h = np.array(freqs), np.array(values)

    def residual(p: np.ndarray) -> np.ndarray:
        e = EstimateFilter(p[0], p[1]).response(f) - h
        return np.r_[e.real, e.imag]

    sol = least_squares(residual, [5.0, 0.01], bounds=([0.1, 0.0], [100.0, 0.1]))
    return EstimateFilter(float(sol.x[0]), float(sol.x[1]),
                          f"identified: tau_J minus arm inverse dynamics -> tau_ext_hat_filtered, {len(recordings)} "
                          f"recording(s), {len(f)} coherent bins in {band_hz[0]}-{band_hz[1]} Hz")


# ----- the strip ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Strip:
    """A rectangular strip [SI]: length, width, thickness [m], youngs_modulus [Pa], density [kg/m^3].
    Nominal: beam_handling's steel strip (E and density the midpoints of the stated ranges)."""

    length: float = 0.52
    width: float = 0.08
    thickness: float = 0.001
    youngs_modulus: float = 197.5e9
    density: float = 7970.0
    poisson_ratio: float = 0.3

    @property
    def mass(self) -> float:
        """[kg]"""
        return self.density * self.length * self.width * self.thickness

    def second_moment(self, plane: str) -> float:
        """I [m^4] for bending in the ``weak`` (about the width axis) or ``strong`` plane."""
        w, t = self.width, self.thickness
        return w * t**3 / 12 if plane == "weak" else t * w**3 / 12

    def cable_spec(self, plane: str, n_masses: int, **damping: float) -> CableSpec:
        """The isotropic core cable with this plane's EI and the strip's EA and mass per length:
        diameter d = 4 sqrt(I/A) (so that I/A is the strip's) and E = EA / (pi d^2 / 4).

        Quadratic air drag (``drag_coefficient`` in ``damping``): the weak-plane run moves the strip face
        first, and its cross-flow velocity (in the plane, normal to the axis) is the face-normal velocity,
        so it gets the law with the strip's width as ``drag_width``; the strong-plane run moves it edge
        first, where a thin plate has no face-normal velocity: no drag (the 1 mm edge's form drag is left
        out)."""
        if damping.get("drag_coefficient", 0.0):
            if plane == "weak":
                damping = {**damping, "drag_width": self.width}
            else:
                damping = {k: v for k, v in damping.items() if k not in ("drag_coefficient", "drag_width")}
        area = self.width * self.thickness
        d = 4.0 * math.sqrt(self.second_moment(plane) / area)
        e_equiv = self.youngs_modulus * area / (math.pi * d**2 / 4)
        return CableSpec(length=self.length, diameter=d, mass=self.mass, youngs_modulus=e_equiv,
                         n_masses=n_masses, **damping)

    def rectangle_spec(self, n_masses: int, **damping: float) -> CableSpec:
        """The core cable with the strip's rectangle section: width along d1, thickness along d2
        (E I1 = E w t^3 / 12 the weak stiffness), twist springs with G = E / (2 (1 + poisson_ratio))."""
        return CableSpec(length=self.length, diameter=self.thickness, mass=self.mass,
                         youngs_modulus=self.youngs_modulus, poisson_ratio=self.poisson_ratio, n_masses=n_masses,
                         section="rectangle", width=self.width, thickness=self.thickness, **damping)


@dataclass(frozen=True)
class Mounting:
    """How the strip sits on the flange: beam frame = flange frame turned by ``yaw`` [rad] about
    its z; the strip runs from the clamp point ``offset`` [m] (beam frame) along the beam frame's
    -x; width along y, thickness along z. ``clamp_mass`` [kg]: a rigid payload at the clamp point
    (the clamp hardware) that Franka's estimate does not know, so its weight change and inertia
    m (g - a) appear in the external torques (:func:`payload_torques`; 0: none)."""

    yaw: float = MOUNT_YAW
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    clamp_mass: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.clamp_mass) and self.clamp_mass >= 0.0):
            raise ParameterError(f"clamp_mass must be a finite mass >= 0 kg, got {self.clamp_mass}")

    def axes(self, flange_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Strip axis (clamp -> tip), width and thickness-normal directions in world, each (3,)."""
        beam = flange_rot @ Rotation.from_euler("z", self.yaw).as_matrix()
        return -beam[:, 0], beam[:, 1], beam[:, 2]

    def clamp_point(self, flange_pos: np.ndarray, flange_rot: np.ndarray) -> np.ndarray:
        """Clamp position(s) [m] for flange pose(s): (3,) or (k, 3)."""
        beam = flange_rot @ Rotation.from_euler("z", self.yaw).as_matrix()
        return flange_pos + beam @ np.asarray(self.offset)


@dataclass(frozen=True)
class PlaneRun:
    """One planar run: its name (weak | strong), the projector P applied to flange translations and
    gravity, the projector applied to rotation vectors, and the projectors that pick the clamp force
    and moment it is responsible for (each (3, 3), world axes)."""

    plane: str
    translate: np.ndarray
    rotate: np.ndarray
    force: np.ndarray
    moment: np.ndarray


def plane_runs(axis: np.ndarray, width: np.ndarray, normal: np.ndarray) -> list[PlaneRun]:
    """The two superposed planar runs of the module doc for strip axes (world, unit)."""
    ww, nn = np.outer(width, width), np.outer(normal, normal)
    weak = np.eye(3) - ww
    return [PlaneRun("weak", weak, ww, weak, ww), PlaneRun("strong", ww, nn, ww, nn)]


@dataclass(frozen=True)
class Numerics:
    """Strip model (``rectangle`` (default) | ``planes`` | ``auto``, module doc), integrator, point masses n, step
    dt [s], the flange-path knot spacing [s] and the low-pass [Hz] applied to q before the kinematics
    (encoder noise would otherwise become huge accelerations at the clamp). BDF2: its numerical
    damping is 100x below the strip's (:func:`free_vibration`)."""

    strip_model: str = "rectangle"
    integrator: str = "bdf2"
    n_masses: int = 20
    dt: float | None = None  # None: DEFAULT_DT of the strip model

    def __post_init__(self) -> None:
        check_strip_model(self.strip_model)
        if self.dt is None:
            object.__setattr__(self, "dt", DEFAULT_DT[self.strip_model])
    knot_step: float = 0.004
    q_cutoff_hz: float = 40.0


@dataclass
class Prediction:
    """Model output for one recording at the recording's times t [s], (k,): clamp force [N] and
    moment about the clamp [N m] exerted by the strip on the flange (world, (k, 3) each), the flange
    wrench [N, N m] (k, 6), external joint torques tau = -J^T w [N m] (k, 7), unfiltered and through
    the estimate filter, both as deviations from t = 0 (with the mounting's clamp payload, if any:
    :func:`payload_torques`); cpu_s: thread CPU time of the runs [s]."""

    t: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    wrench: np.ndarray
    torques: np.ndarray
    torques_filtered: np.ndarray
    cpu_s: float
    simulated_s: float
    warnings: list[str] = field(default_factory=list)
    tip: np.ndarray | None = None  # the strip's free tip [m], (k, 3), world (planes: the weak-plane run's)
    arm_deviation: np.ndarray | None = None  # [rad], (k, 7): the compliant arm's q - q_ref (beam_arm); None: rigid
    strip_model: str = ""  # the model that ran (rectangle | planes) and why (:func:`choose_strip_model`)
    strip_reason: str = ""


def low_passed_q(rec: BeamRecording, numerics: Numerics) -> np.ndarray:
    """The measured joint positions [rad], (k, 7), low-passed (zero phase) at ``numerics.q_cutoff_hz``."""
    return sosfiltfilt(butter(4, numerics.q_cutoff_hz, fs=rec.rate, output="sos"), rec.q, axis=0)


def flange_motion(rec: BeamRecording, panda: Panda, numerics: Numerics, duration: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knot times [s], (m,), flange positions [m], (m, 3), and rotations, (m, 3, 3), over
    [0, duration] every ``knot_step`` from the low-passed measured joint positions."""
    q = low_passed_q(rec, numerics)
    stop = min(duration, float(rec.t[-1]))
    times = np.arange(0.0, stop + 1e-9, numerics.knot_step)
    rows = np.clip(np.searchsorted(rec.t, times), 0, len(rec.t) - 1)
    pos, rot = panda.flange_path(q[rows])
    return times, pos, rot


def payload_torques(panda: Panda, q: np.ndarray, rate: float, mounting: Mounting = Mounting(), mass: float = 1.0,
                    gravity: tuple[float, float, float] = STANDARD_GRAVITY, cutoff_hz: float = 40.0) -> np.ndarray:
    """External joint torques [N m], (k, 7), of a point mass ``mass`` [kg] at the clamp point carried along joint
    rows q [rad], (k, 7), sampled at ``rate`` [Hz], as deviations from the first row.

    The mass exerts w = (m (g - a), r x m (g - a)) on the flange (a [m/s^2] the clamp point's acceleration, r the
    clamp point from the flange origin), so Franka's estimate reports tau = -J^T w = m J_c^T (a - g), J_c the clamp
    point's linear Jacobian: the torque with which the motors carry a mass their model does not contain (for
    m 1 kg it is the regressor :func:`fit_clamp_mass` fits m on). ``a`` is the second difference of the clamp path
    (forward kinematics of q), low-passed at ``cutoff_hz`` [Hz]: PyBullet's poses are single precision, and the
    second difference of 1 ms samples would turn their rounding into 0.1 m/s^2 of noise."""
    q = np.asarray(q, dtype=float)
    fpos, frot = panda.flange_path(q)
    clamp = mounting.clamp_point(fpos, frot)
    dt = 1.0 / rate
    acc = np.gradient(np.gradient(clamp, dt, axis=0), dt, axis=0)
    if len(q) > 27:  # sosfiltfilt's pad length for a 4th-order filter
        acc = sosfiltfilt(butter(4, min(cutoff_hz, 0.45 * rate), fs=rate, output="sos"), acc, axis=0)
    load = mass * (np.asarray(gravity, dtype=float) - acc)  # force of the mass on the flange [N]
    arm = clamp - fpos
    wrench = np.hstack([load, np.cross(arm, load)])
    tau = external_torques(panda.jacobians(q), wrench)
    return tau - tau[0]


def run_plane(strip: Strip, run: PlaneRun, numerics: Numerics, damping: dict[str, float], clamp0: np.ndarray,
              axis: np.ndarray, times: np.ndarray, disp: np.ndarray, rotvec: np.ndarray,
              gravity: np.ndarray, duration: float) -> ClampLoads:
    """One planar run from the static equilibrium at the start pose: recorded times [s], clamp force
    [N] and moment about the clamp [N m] on the holder (world, (k, 3) each) and the run's warnings.
    ``disp`` [m] and ``rotvec`` [rad], (m, 3), are the clamp's motion relative to its start at ``times``."""
    model = plane_model(strip, run, numerics, damping, clamp0, axis, times, disp, rotvec, gravity)
    state = solve_static(model).state()
    return clamp_loads(model, state, numerics, duration, f"the {run.plane}-plane run")


def plane_model(strip: Strip, run: PlaneRun, numerics: Numerics, damping: dict[str, float], clamp0: np.ndarray,
                axis: np.ndarray, times: np.ndarray, disp: np.ndarray, rotvec: np.ndarray,
                gravity: np.ndarray) -> CableModel:
    """The cable of one planar run (:func:`run_plane`): the plane's isotropic core cable clamped at ``clamp0`` [m]
    along ``axis``, driven by the run's projection of the clamp's motion."""
    spec = strip.cable_spec(run.plane, numerics.n_masses, **damping)
    path = Waypoints("first", tuple(times), tuple(map(tuple, disp @ run.translate.T)),
                     tuple(map(tuple, rotvec @ run.rotate.T)), rest=False)
    return CableModel.straight(spec, start=clamp0, direction=axis, ends=("clamped", "free"), motion=[path],
                               gravity=run.translate @ gravity)


class ClampLoads(NamedTuple):
    """One strip run recorded every tick: times t [s], (k,); the force [N] and moment [N m] the strip
    exerts on its clamp (world, (k, 3) each); the run's warnings; the free tip's position [m], (k, 3)."""

    t: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    warnings: list[str]
    tip: np.ndarray


def clamp_loads(model: CableModel, state, numerics: Numerics, duration: float, what: str) -> ClampLoads:
    """Run ``model`` from ``state`` for ``duration`` [s], recording every tick (:class:`ClampLoads`)."""
    every = max(1, int(round(TICK / numerics.dt)))
    res = simulate(model, numerics.integrator, numerics.dt, duration, state=state, record_every=every,
                   max_records=10**7)
    if not res.stable:
        raise ParameterError(f"{what} went unstable ({res.reason} at t = {res.time_to_instability:.4g} s); "
                             "use a smaller --dt")
    return ClampLoads(res.t, res.end_forces[:, 0], res.end_moment_history[:, 0], list(res.warnings), res.x[:, -1])


def clamp_roll(axis: np.ndarray, width: np.ndarray) -> float:
    """Roll [rad] about ``axis`` that turns the clamp's default section axis
    (:func:`~bullet_dlo.core.boundary.default_normal`) onto ``width`` (unit, normal to axis)."""
    d1 = default_normal(axis)
    d2 = np.cross(axis, d1)
    return math.atan2(float(width @ d2), float(width @ d1))


def run_rectangle(strip: Strip, numerics: Numerics, damping: dict[str, float], clamp0: np.ndarray,
                  axes: tuple[np.ndarray, np.ndarray, np.ndarray], times: np.ndarray, disp: np.ndarray,
                  rotvec: np.ndarray, gravity: np.ndarray, duration: float) -> ClampLoads:
    """The strip as one rectangle-section cable clamped with the flange's orientation (``axes``: strip
    axis, width, normal at the start), from its static equilibrium there, driven by the clamp's
    displacement [m] and rotation vector [rad], (m, 3), at ``times`` [s]: as :func:`run_plane`."""
    model = rectangle_model(strip, numerics, damping, clamp0, axes, times, disp, rotvec, gravity)
    state = solve_static(model).state()
    return clamp_loads(model, state, numerics, duration, "the rectangle-strip run")


def rectangle_model(strip: Strip, numerics: Numerics, damping: dict[str, float], clamp0: np.ndarray,
                    axes: tuple[np.ndarray, np.ndarray, np.ndarray], times: np.ndarray, disp: np.ndarray,
                    rotvec: np.ndarray, gravity: np.ndarray) -> CableModel:
    """The cable of :func:`run_rectangle`: the rectangle-section strip clamped at ``clamp0`` [m] with the flange's
    start orientation (``axes``: strip axis, width, normal), driven by the clamp's whole motion."""
    axis, width, _ = axes
    spec = strip.rectangle_spec(numerics.n_masses, **damping)
    path = Waypoints("first", tuple(times), tuple(map(tuple, disp)), tuple(map(tuple, rotvec)), rest=False)
    return CableModel.straight(spec, start=clamp0, direction=axis, ends=("clamped", "free"), motion=[path],
                               gravity=gravity, roll=(clamp_roll(axis, width), 0.0))


def predict_torques(rec: BeamRecording, panda: Panda, strip: Strip = Strip(), damping: dict[str, float] | None = None,
                    numerics: Numerics = Numerics(), estimate: EstimateFilter = EstimateFilter(),
                    mounting: Mounting = Mounting(), duration: float | None = None,
                    gravity: tuple[float, float, float] = STANDARD_GRAVITY) -> Prediction:
    """Predict Franka's external joint torques for ``rec`` from its measured joint trajectory.

    The strip's clamp follows the flange path (forward kinematics of the low-passed measured q);
    the strip model (``numerics.strip_model``, module doc) gives the clamp load; the wrench about the
    flange origin maps to joint torques tau = -J(q)^T w; deviations from t = 0 (the strip at rest
    before the motion), plus the clamp payload's (``mounting.clamp_mass``, :func:`payload_torques`), then
    ``estimate`` applied. ``duration`` [s]: simulated time (default: the whole recording).
    """
    import time as _time

    tic = _time.thread_time()
    duration = float(rec.t[-1]) if duration is None else min(float(duration), float(rec.t[-1]))
    times, pos, rot = flange_motion(rec, panda, numerics, duration)
    clamp = mounting.clamp_point(pos, rot)
    disp = clamp - clamp[0]
    rotvec = Rotation.from_matrix(rot @ rot[0].T).as_rotvec()
    axis, width, normal = mounting.axes(rot[0])
    g = np.asarray(gravity, dtype=float)
    model, reason = choose_strip_model(check_strip_model(numerics.strip_model), rot, mounting)
    if model == "rectangle":
        t, force, moment, warnings, tip = run_rectangle(strip, numerics, damping or {}, clamp[0],
                                                        (axis, width, normal), times, disp, rotvec, g, duration)
    else:
        force = moment = None
        warnings = []
        for run in plane_runs(axis, width, normal):
            t, f, mo, w, run_tip = run_plane(strip, run, numerics, damping or {}, clamp[0], axis, times, disp,
                                             rotvec, g, duration)
            tip = run_tip if run.plane == "weak" else tip
            force = f @ run.force.T + (0 if force is None else force)
            moment = mo @ run.moment.T + (0 if moment is None else moment)
            warnings += [f"{run.plane} plane: {x}" for x in w]
    if reason.startswith("warning:"):
        warnings.append(reason)
    k = min(len(t), int(np.searchsorted(rec.t, t[-1] + 1e-9)))
    t, force, moment, tip = t[:k], force[:k], moment[:k], tip[:k]
    rows = np.clip(np.searchsorted(rec.t, t - 1e-9), 0, len(rec.t) - 1)
    fpos, frot = panda.flange_path(rec.q[rows])
    arm = mounting.clamp_point(fpos, frot) - fpos
    wrench = np.hstack([force, moment + np.cross(arm, force)])
    tau = external_torques(panda.jacobians(rec.q[rows]), wrench)
    tau = tau - tau[0]
    if mounting.clamp_mass:
        tau = tau + payload_torques(panda, low_passed_q(rec, numerics)[rows], 1.0 / TICK, mounting,
                                    mounting.clamp_mass, gravity)
    filtered = estimate.apply(tau, 1.0 / TICK)
    return Prediction(t=t, force=force, moment=moment, wrench=wrench, torques=tau, torques_filtered=filtered,
                      cpu_s=_time.thread_time() - tic, simulated_s=float(t[-1] - t[0]), warnings=warnings,
                      tip=tip, strip_model=model, strip_reason=reason)


def strip_spec(strip: Strip, numerics: Numerics, damping: dict[str, float] | None = None) -> CableSpec:
    """The cable ``numerics.strip_model`` vibrates in the weak plane: the rectangle-section cable, or the
    planar pair's weak-plane run (also for ``auto``: in the weak plane the two agree)."""
    if check_strip_model(numerics.strip_model) == "rectangle":
        return strip.rectangle_spec(numerics.n_masses, **(damping or {}))
    return strip.cable_spec("weak", numerics.n_masses, **(damping or {}))


def free_vibration(strip: Strip, numerics: Numerics, duration: float = 5.0, damping: dict[str, float] | None = None
                   ) -> tuple[float, float]:
    """First-mode frequency [Hz] and damping ratio [-] of the weak-plane cantilever as ``numerics``
    computes it: horizontal (width horizontal, thickness vertical), released at rest from its sag
    under 1.2 g into 1 g, the vertical clamp force fitted with a damped sine over ``duration`` [s].
    Without ``damping`` the ratio is the integrator's numerical damping alone (the robot is not in this run)."""
    from bullet_dlo.reality.vibration import fit_damped_sine

    spec = strip_spec(strip, numerics, damping)
    heavy = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "free"),
                                gravity=(0, 0, -1.2 * 9.81))
    model = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "free"))
    state = solve_static(heavy).state()
    res = simulate(model, numerics.integrator, numerics.dt, duration, state=state,
                   record_every=max(1, int(round(TICK / numerics.dt))))
    if not res.stable:
        return math.nan, math.nan
    f, zeta, _, _ = fit_damped_sine(res.t, res.end_forces[:, 0, 2])
    return f, zeta


def fit_recording(rec: BeamRecording, panda: Panda, strip: Strip = Strip(), mounting: Mounting = Mounting(),
                  estimate: EstimateFilter = EstimateFilter(), numerics: Numerics = Numerics(), step: int = 1,
                  settle: float = 0.5) -> Recording:
    """``rec`` as a :class:`~bullet_dlo.analysis.fit_recording.Recording` for ``bullet-dlo fit``: the strip
    clamped at the mounting's clamp point and following the flange (forward kinematics of the low-passed
    measured q), its tip free; the residual is Franka's filtered external-torque estimate, as changes since
    the first sample (its absolute level carries the arm model's bias), predicted as -J(q)^T of the clamp
    load moved to the flange origin and passed through ``estimate``. The grasp frame: x along the strip
    (clamp to tip), y along its width (the section's d1), so a rectangle-section cable with a material
    frame is held the right way up. ``step``: keep every step-th sample (1 kHz / step). The residual uses
    the samples from ``settle`` [s] after the motion ends (every commanded joint rate below 1e-4 rad/s):
    while the arm moves, the estimate's error from the arm's own dynamics model (0.5-4 N m RMS on some
    joints) is larger than the strip's load."""
    from bullet_dlo.reality.vibration import motion_span

    try:
        _, end = motion_span(rec.dq_d)
    except ValueError as err:
        raise ParameterError(f"beam recording {rec.name}: {err}") from None
    rows = np.arange(0, len(rec.t), max(1, int(step)))
    sos = butter(4, numerics.q_cutoff_hz, fs=rec.rate, output="sos")
    q = sosfiltfilt(sos, rec.q, axis=0)[rows]
    fpos, frot = panda.flange_path(q)
    clamp = mounting.clamp_point(fpos, frot)
    frames = np.empty((len(rows), 3, 3))
    for i, r in enumerate(frot):
        axis, width, _ = mounting.axes(r)
        frames[i] = np.column_stack([axis, width, np.cross(axis, width)])  # right-handed: z = -(thickness normal)
    grasp = Rotation.from_matrix(frames)
    quat = np.stack([grasp.as_quat(), (grasp * RIGHT_FROM_LEFT).as_quat()], axis=1)
    pos = np.stack([clamp, clamp + strip.length * frames[:, :, 0]], axis=1)  # the free tip's entry: where it starts
    shift = np.zeros((len(rows), 6, 12))  # the clamp's (f, m about the clamp) -> the flange's (f, m about its origin)
    shift[:, :3, :3] = shift[:, 3:, 3:6] = np.eye(3)
    arm = clamp - fpos
    shift[:, 3:, :3] = np.array([[[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]] for a in arm])
    linear = -np.einsum("kij,kil->kjl", panda.jacobians(q), shift)  # tau = -J^T w_flange, (k, 7, 12)
    return Recording(rec.t[rows], pos, quat, None, name=rec.name, linear_map=linear,
                     linear_obs=rec.tau_ext_hat_filtered[rows], held=("clamped", "free"), length=strip.length,
                     relative=("linear",), linear_filter=(estimate.cutoff_hz, estimate.delay_s), section_frame=True,
                     use=rec.t[rows] >= rec.t[min(end, len(rec.t) - 1)] + settle)


def with_damping(damping: dict[str, float], name: str, value: float) -> dict[str, float]:
    """A copy of ``damping`` with ``name`` set to ``value``."""
    return {**damping, name: float(value)}


def stepped_start(model: CableModel, state, h: float) -> tuple:
    """What a run of ``model`` stepped by hand (the core's ``advance``) needs to start from ``state``
    (:class:`~bullet_dlo.core.model.CableState`) with steps of h [s]: (kernel arrays, holder plan, the first
    step's held-end samples, x [m] and v [m/s] copies, a step workspace). A cable with a material frame starts from
    the state's twist (a copy), as ``simulate`` does."""
    control = model.control(None)
    twist = state.twist.copy() if getattr(state, "twist", None) is not None else model.twist_state()
    m = model.kernel_arrays(control, twist)
    plan = model.holder_plan(control)
    smp = empty_samples()
    sample_holders(plan, 0.0, h, smp)
    return m, plan, smp, state.x.copy(), state.v.copy(), make_workspace(model.n)


__all__ = ["BeamRecording", "read_beam_csv", "beam_files", "EstimateFilter", "identify_filter", "Strip",
           "Mounting", "payload_torques", "PlaneRun", "plane_runs", "STRIP_MODELS", "PLANES_MAX_TURN", "off_plane_turn",
           "choose_strip_model", "run_rectangle", "rectangle_model", "plane_model", "Numerics",
           "Prediction", "predict_torques", "free_vibration", "fit_recording", "stepped_start"]

