"""``validate beam``: fit the strip's damping on some beam_handling recordings, predict others.

For every recording the residual vibration of the most affected joint is measured and predicted
(:mod:`bullet_dlo.reality.vibration`): the model is :func:`bullet_dlo.reality.beam.predict_torques`
with nominal material constants and one fitted damping parameter.

**Damping fit** (:func:`fit_damping`). The first mode (2.9-3.0 Hz) is the only one Franka's
4.7 Hz estimate filter lets through, so one damping parameter is all the vibration can identify:
``damping_rate`` c [1/s] (default; mass-proportional drag, the linear stand-in for the air drag
that damps a wide thin strip, the same at any n) adds zeta = c / (2 omega_1); ``internal_damping``
tau [s] (Kelvin-Voigt) adds zeta = omega_1 tau / 2 and damps higher modes more. Either way the
predicted damping ratio is linear in the parameter, so per fit recording two runs (the parameter
at 0 and at a trial value) give the value that matches that recording's measured damping ratio.
The fitted value is the mean over the fit recordings; its interval is their spread (min-max),
and a leave-one-out check predicts each fit recording's damping ratio from the others' mean.
The run at 0 also shows how much damping the arm brings: through the measured flange path (``arm``
``measured``: the recorded arm's reaction to the real strip) or through the arm's identified joint impedance the
model strip loads (``compliant``, the default, and ``loop``: :mod:`bullet_dlo.reality.beam_arm`).

The measured damping is amplitude dependent (larger at large amplitude): reported per recording
over successive windows and as a fitted law (below).

**Quadratic air drag** (``drag``, :func:`fit_damping_drag`): the core's face drag law
(``drag_coefficient`` C_d, air) on the strip, either held at a given C_d (``damping`` fitted with it) or
fitted with ``damping_rate`` on the fit recordings' damping ratios over successive windows of each decay
(the amplitude dependence separates C_d A from c). Per predicted file ``p2p_at_end`` (the band's
peak-to-peak over the first 0.5 s after the motion) tells an excitation miss from a damping miss.

**The level** (:func:`file_result`): beside the band's peak-to-peak over end + 1-2 s, ``sine_amplitude`` (the
amplitude of a sine at the signal's own frequency fitted over the same window,
:func:`~bullet_dlo.reality.vibration.sine_amplitude`) for measurement and model, its ratio, and ``within_goal`` with the
same 15 %; the summary's ``goals`` counts the files within each goal (:data:`GOALS`).

**The damping law** (:mod:`bullet_dlo.reality.beam_law`). Every run measures the law of FIT_DIR's decays from the
recordings alone (``parameters.damping_law``; per predicted file ``measured.decay_law``): the decays follow
zeta = zeta0 + c A_tip (c 0.35-0.43 1/m), not a constant, not Coulomb friction. ``amplitude_damping`` (``--amplitude-damping
law``) puts c into the strip's bending dampers, set each step from its amplitude (the loop arms only); it is held while
``damping`` is fitted with it. Off by default: it does not improve the held-out counts (docs/guides/validate.md).

**Clamp payload** (``clamp_mass``, :func:`fit_clamp_mass`): a rigid mass at the clamp (the clamp hardware)
that Franka's estimate does not know adds m J_c^T (a - g) to the external torques; linear in m, so it is fitted
by least squares on the fit recordings' torque residual (1.5-8 Hz band, all joints, whole recording: the motion's
flange accelerations identify it) before the damping, and held.
"""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality.beam import (
    BeamRecording,
    EstimateFilter,
    Mounting,
    Numerics,
    Prediction,
    Strip,
    beam_files,
    free_vibration,
    identify_filter,
    low_passed_q,
    payload_torques,
    predict_torques,
    read_beam_csv,
)
from bullet_dlo.reality.beam_arm import ArmImpedance, check_arm_mode, identify_arm, predict_torques_compliant
from bullet_dlo.reality.beam_law import AMPLITUDE_DAMPING_MAX, file_decay, measured_law
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import (
    SINE_WINDOW,
    band,
    damping_by_amplitude,
    deviation,
    most_affected_joint,
    motion_span,
    residual_vibration,
)

DAMPING_NAMES = ("damping_rate", "internal_damping")
TRIAL = {"damping_rate": 0.4, "internal_damping": 1e-3}  # trial values [1/s], [s]: each adds zeta ~ 0.01 at 2.95 Hz
BENDING = {
    "rectangle": "one 3-D run of a rectangle-section cable with a material frame (E I_weak, E I_strong, twist G J, "
                 "nu 0.3), clamped with the flange's full orientation (tangent the strip axis, section axis the width)",
    "planes": "two superposed planar runs (weak EI about the width axis, strong EI about the normal) of an isotropic "
              "cable: no plane coupling, no twist",
    "auto": "per recording: the planes while the flange turns out of the weak plane by at most 1 degree, the "
            "rectangle beyond (each file's strip_model and strip_model_reason)",
}
STRIP_LIMITS = {
    "rectangle": "the twist is solved with the positions in BDF2's Newton step (the implicit Euler and midpoint "
                 "steps too; other integrators advance it in a staggered first-order sub-step): on ocp_Z_15cm the "
                 "band-passed torque p2p is 1.608 / 1.607 N m at dt 1 / 0.1 ms (planes 1.608), hence dt 1e-3 s",
    "planes": "the strip's two bending planes are two superposed isotropic-cable runs: plane coupling, twist and the "
              "turning of the projection axes are left out (--strip-model rectangle has them: within 3 % on these "
              "recordings)",
    "auto": "the planes where the flange keeps the weak plane (plane coupling and twist left out: within 3 % of "
            "the rectangle on the nine recordings), the rectangle where it turns out of it by more than 1 degree",
}
ARM_LIMITS = {
    "measured": "the clamp follows the flange path of the measured joint angles, and after the motion that path "
                "carries the arm's reaction to the real strip (the arm under its controller is compliant and lossy at "
                "3 Hz): about half of the model's damping ratio comes through it (driven by q_d instead, the model "
                "keeps only damping_rate's 0.0065), and only while the model's frequency matches the real one (E 2 % "
                "lower: the predicted damping ratio falls to 0.7-0.9x at the same damping_rate); the strip on the "
                "compliant arm in a closed loop is --arm compliant / loop",
    "compliant": "the strip on the arm's joint impedance (K, D per joint identified from tau_J against q - q_d, "
                 "the URDF's inertia), substituted about the measured path with the real strip's torque (Franka's "
                 "estimate, filter undone): it uses the predicted recording's own torque to take the real strip's "
                 "reaction out of its measured path, so it is a replay of a known motion, not a prediction of a new "
                 "one (--arm loop is); joints whose impedance the identifying folder does not determine (R^2 < 0.5) "
                 "and the wrist are rigid",
    "loop": "the strip on the arm's joint impedance in the full loop from q_d: nothing else moves the arm (the arm's "
            "own tracking error during the motion, from its dynamics and Franka's model errors, is missing); joints "
            "whose impedance the identifying folder does not determine (R^2 < 0.5) and the wrist are rigid",
}
LIMITS = [
    "the damping is amplitude dependent and the default model's is linear: the measured decays (no model run, "
    "demos/beam_damping_law.py; `damping_law` in the JSON) follow zeta = zeta0 + c A_tip, c 0.43 1/m (X files) and "
    "0.36 1/m (Z files), zeta0 0.002-0.005, over tip amplitudes 4-75 mm (6 of 9 files choose it over a constant zeta, "
    "the 3 smallest decays cannot tell, none Coulomb friction); that law alone gives the 1-6 s damping ratio of 7 of 9 "
    "files within 30 % held out between the folders. In the model (--amplitude-damping law: the strip's bending "
    "dampers set from its amplitude each step; off by default) it does not improve the held-out counts: with the arm "
    "identified on all nine it matches the damping ratio without fitted linear damping (7 of 9), but the 15/25 cm X "
    "files fall to 0.63-0.74x at end + 1-2 s (p2p 2-3 of 9 within 15 % against 4-6 linear): the linear damping fitted "
    "to 1-6 s had absorbed a first-second decay and an end-of-motion level (end ratio 0.59-0.97) that the model gets "
    "wrong, and the model strip already gets zeta 0.003-0.012 and up to 0.22 1/m of the slope from the arm and the "
    "replayed path",
    "the motions are vibration-suppressing (optimal-control) motions: the residual vibration is a small remainder of "
    "the motion's excitation, and the model leaves 0.5-1.5x the measured one on the same measured path (q timing "
    "+-10 ms, the window +-0.2 s and the damping law change it by a few per cent)",
    "Franka's estimate filter modelled as a first-order low-pass + delay identified from tau_J; the arm's own "
    "inertia is removed with PyBullet's URDF inertias, not Franka's model",
    "nominal E and density (midpoints of 190-205 GPa, 7870-8070 kg/m^3): about +-2 % in frequency",
    "the clamp hardware is unknown: the clamp point is the flange origin; its mass, which Franka's estimate does not "
    "know, is in the model only with --clamp-mass (0.36-0.62 kg fitted per recording; it is most of the "
    "difference in the first 0.5 s after the motion, p2p_at_end, and changes the goal's window by <= 0.1x)",
    "rms_torque_error includes what the strip does not cause: Franka's estimate has a pose-dependent bias (about "
    "1 N m on joint 3 after a 25 cm Z move, constant once at rest) and the arm's unmodelled dynamics during the "
    "motion; the vibration metrics are immune to the offset (fitted constant, band-pass)",
]


@dataclass(frozen=True)
class ArmSetting:
    """The arm the strip hangs on (``--arm``): mode ``compliant`` (substitution about the measured q) or ``loop``
    (the full loop from q_d), with the joint impedance identified on FIT_DIR (:mod:`bullet_dlo.reality.beam_arm`)."""

    mode: str
    impedance: ArmImpedance

    @property
    def drive(self) -> str:
        return "measured" if self.mode == "compliant" else "desired"


def predict(rec: BeamRecording, panda: Panda, strip: Strip, damping: dict[str, float], numerics: Numerics,
            estimate: EstimateFilter, mounting: Mounting = Mounting(), duration: float | None = None,
            arm: ArmSetting | None = None) -> Prediction:
    """:func:`~bullet_dlo.reality.beam.predict_torques` (clamp on the measured flange path, ``arm`` None) or
    :func:`~bullet_dlo.reality.beam_arm.predict_torques_compliant` (the strip on the compliant arm)."""
    law = float(damping.get("amplitude_damping", 0.0))
    damping = {k: v for k, v in damping.items() if k != "amplitude_damping"}
    if arm is None:
        if law:
            raise ParameterError("--amplitude-damping runs in the stepped arm-strip loop: use --arm compliant or loop")
        return predict_torques(rec, panda, strip, damping, numerics, estimate, mounting, duration=duration)
    return predict_torques_compliant(rec, panda, arm.impedance, strip, damping, numerics, estimate, mounting,
                                     duration=duration, drive=arm.drive, amplitude_damping=law)


@dataclass(frozen=True)
class Measured:
    """A recording's measurement: motion span (start, end indices), t_end [s], the joint j, the
    torque deviation [N m] (k, 7), its :class:`~bullet_dlo.reality.vibration.Vibration` on joint j."""

    start: int
    end: int
    t_end: float
    joint: int
    dev: np.ndarray
    vibration: Any


def measure(rec: BeamRecording) -> Measured:
    """The issue's measurement on the recording's external-torque estimate."""
    try:
        start, end = motion_span(rec.dq_d)
    except ValueError as err:
        raise ParameterError(f"beam recording {rec.name}: {err}") from None
    t_end = float(rec.t[min(end, len(rec.t) - 1)])
    if rec.t[-1] < t_end + SINE_WINDOW[1]:
        raise ParameterError(f"beam recording {rec.name}: ends {rec.t[-1] - t_end:.2f} s after the motion; "
                             f"the vibration metrics need {SINE_WINDOW[1]} s")
    dev = deviation(rec.tau_ext_hat_filtered, start)
    joint = most_affected_joint(rec.t, dev, t_end)
    return Measured(start, end, t_end, joint, dev, residual_vibration(rec.t, dev[:, joint], t_end))


def predicted_vibration(pred: Prediction, m: Measured):
    """The vibration metrics of the prediction on the measured recording's joint and motion end."""
    return residual_vibration(pred.t, pred.torques_filtered[:, m.joint], m.t_end)


@dataclass(frozen=True)
class DampingFit:
    """Fitted damping: name, value (mean over fit recordings), per-recording values, interval
    (min, max over them), the undamped model's damping ratio per recording, the leave-one-out
    predicted/measured damping-ratio ratios, and the model runs used."""

    name: str
    value: float
    per_file: dict[str, float]
    interval: tuple[float, float]
    undamped_ratio: dict[str, float]
    loo_ratio: dict[str, float]
    runs: int
    frequency_ratio: dict[str, float]  # measured / predicted frequency of the undamped runs

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["interval"] = list(self.interval)
        d["interval_meaning"] = "min-max of the values that match each fit recording's measured damping ratio"
        return d


def fit_damping(recs: list[BeamRecording], measured: list[Measured], panda: Panda, name: str, strip: Strip,
                numerics: Numerics, estimate: EstimateFilter, fixed: dict[str, float] | None = None,
                mounting: Mounting = Mounting(), arm: ArmSetting | None = None) -> DampingFit:
    """Per recording, the ``name`` value whose predicted damping ratio equals the measured one
    (linear in the parameter: two runs, module doc); the mean, min-max and leave-one-out.
    ``fixed``: other model parameters held in every run (e.g. ``{"drag_coefficient": 8.0}``)."""
    if name not in DAMPING_NAMES:
        raise ParameterError(f"--damping must be one of {', '.join(DAMPING_NAMES)}, got {name!r}")
    trial = TRIAL[name]
    fixed = dict(fixed or {})
    per_file, zeta0, slope, freq = {}, {}, {}, {}
    for rec, m in zip(recs, measured):
        duration = m.t_end + SINE_WINDOW[1] + 0.05
        runs = [predicted_vibration(predict(rec, panda, strip, {**fixed, name: c}, numerics, estimate,
                                            mounting, duration=duration, arm=arm), m) for c in (0.0, trial)]
        z = [r.damping_ratio for r in runs]
        freq[rec.name] = m.vibration.frequency_hz / runs[0].frequency_hz
        slope[rec.name] = (z[1] - z[0]) / trial
        zeta0[rec.name] = z[0]
        per_file[rec.name] = max(0.0, (m.vibration.damping_ratio - z[0]) / slope[rec.name])
    values = np.array(list(per_file.values()))
    loo = {}
    for (key, m) in zip(per_file, measured):
        others = np.mean([v for k, v in per_file.items() if k != key]) if len(per_file) > 1 else per_file[key]
        loo[key] = (zeta0[key] + slope[key] * others) / m.vibration.damping_ratio
    return DampingFit(name, float(values.mean()), per_file, (float(values.min()), float(values.max())),
                      zeta0, loo, 2 * len(recs), freq)


ARM_MODES_DOC = {
    "measured": "the clamp follows the flange path of the measured joint angles (rigid: the recorded path carries the "
                "arm's reaction to the real strip)",
    "compliant": "the strip on the arm's identified joint impedance, substituted about the measured path: q = q_meas + "
                 "delta, M delta'' + D delta' + K delta = -(tau_model - tau_real), stepped with the strip",
    "loop": "the strip on the arm's identified joint impedance in the full loop from the desired path: q = q_d + e, "
            "M e'' + D e' + K e = -tau_model (nothing else moves the arm)",
}
AMPLITUDE_SPANS = ((1.0, 2.5), (2.5, 4.0), (4.0, 5.5), (5.5, 7.0), (7.0, 9.0))  # [s] after the motion's end
DRAG_TRIAL = 8.0  # trial C_d [-]: about the low-KC plate value (validate.md), adds zeta ~ 0.002-0.005
TRANSIENT_ZETA = 0.05  # a window whose measured damping ratio is above it still carries the motion's transient


@dataclass(frozen=True)
class DragFit:
    """``damping_rate`` [1/s] and ``drag_coefficient`` C_d [-] fitted together on the fit recordings'
    damping ratios over successive windows (:data:`AMPLITUDE_SPANS`): windows, measured and predicted (at
    the solution, linearised) damping ratios and torque amplitudes [N m] per recording; residual RMS [-];
    the model runs used."""

    damping_rate: float
    drag_coefficient: float
    windows: dict[str, list[dict[str, float]]]
    residual_rms: float
    linear_only_residual_rms: float
    runs: int

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["method"] = ("bounded linear least squares (both >= 0) of the predicted damping ratio per window, linearised "
                       "by runs at (0, 0), (0.4 1/s, 0), (0, C_d 8) and refined once about the solution, against "
                       f"the measured ones; windows {AMPLITUDE_SPANS} s after the motion's end, those with a measured "
                       f"damping ratio above {TRANSIENT_ZETA} (the motion's transient) left out")
        return d


def _window_ratios(t: np.ndarray, y: np.ndarray, t_end: float) -> dict[float, dict[str, float]]:
    """Damping ratio and amplitude per :data:`AMPLITUDE_SPANS` window of y [N m], keyed by the window's start [s]."""
    return {w["from_s"]: w for w in damping_by_amplitude(t, y, t_end, AMPLITUDE_SPANS)}


def fit_damping_drag(recs: list[BeamRecording], measured: list[Measured], panda: Panda, strip: Strip,
                     numerics: Numerics, estimate: EstimateFilter, mounting: Mounting = Mounting(),
                     arm: ArmSetting | None = None) -> DragFit:
    """Fit ``damping_rate`` c and ``drag_coefficient`` C_d on the fit recordings: the amplitude dependence of
    the measured damping (windows of each decay) is what separates the quadratic law (zeta ~ C_d A) from the
    linear one (zeta ~ c). Per recording the predicted window damping ratios are linearised in (c, C_d) by
    finite differences; a bounded least-squares solve, then one refinement about the solution."""
    from scipy.optimize import lsq_linear

    trial = np.array([TRIAL["damping_rate"], DRAG_TRIAL])
    per, runs = [], 0

    def ratios(rec: BeamRecording, m: Measured, p: np.ndarray) -> dict[float, dict[str, float]]:
        nonlocal runs
        runs += 1
        pred = predict(rec, panda, strip, {"damping_rate": float(p[0]), "drag_coefficient": float(p[1])},
                       numerics, estimate, mounting, duration=m.t_end + AMPLITUDE_SPANS[-1][1] + 0.05, arm=arm)
        return _window_ratios(pred.t, pred.torques_filtered[:, m.joint], m.t_end)

    for rec, m in zip(recs, measured):
        meas = _window_ratios(rec.t, m.dev[:, m.joint], m.t_end)
        keep = [k for k, w in meas.items() if w["damping_ratio"] < TRANSIENT_ZETA]
        base = ratios(rec, m, np.zeros(2))
        with_c = ratios(rec, m, np.array([trial[0], 0.0]))
        with_cd = ratios(rec, m, np.array([0.0, trial[1]]))
        keep = [k for k in keep if k in base and k in with_c and k in with_cd]
        per.append((rec, m, meas, keep, base, with_c, with_cd))

    def system(at: np.ndarray, zeta_at: list[dict[float, dict[str, float]]]) -> tuple[np.ndarray, np.ndarray]:
        rows, rhs = [], []
        for (rec, m, meas, keep, base, with_c, with_cd), z_at in zip(per, zeta_at):
            for k in keep:
                a = (with_c[k]["damping_ratio"] - base[k]["damping_ratio"]) / trial[0]
                b = (with_cd[k]["damping_ratio"] - base[k]["damping_ratio"]) / trial[1]
                rows.append([a, b])
                rhs.append(meas[k]["damping_ratio"] - z_at[k]["damping_ratio"] + a * at[0] + b * at[1])
        return np.array(rows), np.array(rhs)

    zero = np.zeros(2)
    mat, rhs = system(zero, [p[4] for p in per])
    sol = lsq_linear(mat, rhs, bounds=(0.0, np.inf)).x
    at_sol = [ratios(p[0], p[1], sol) for p in per]  # refine once about the first solution
    for p, z in zip(per, at_sol):
        p[3][:] = [k for k in p[3] if k in z]
    mat, rhs = system(sol, at_sol)
    sol = lsq_linear(mat, rhs, bounds=(0.0, np.inf)).x
    resid = mat @ sol - rhs
    linear_only = lsq_linear(mat[:, :1], rhs, bounds=(0.0, np.inf))  # C_d = 0, same linearisation
    lin_rms = float(np.sqrt(np.mean((mat[:, :1] @ linear_only.x - rhs) ** 2)))
    windows, i = {}, 0
    for (rec, m, meas, keep, base, *_), z in zip(per, at_sol):
        rows = []
        for k in keep:
            rows.append({"from_s": k, "measured_damping_ratio": meas[k]["damping_ratio"],
                         "predicted_damping_ratio": meas[k]["damping_ratio"] + float(resid[i]),
                         "measured_amplitude": meas[k]["amplitude"], "predicted_amplitude": z[k]["amplitude"]})
            i += 1
        windows[rec.name] = rows
    return DragFit(float(sol[0]), float(sol[1]), windows, float(np.sqrt(np.mean(resid**2))), lin_rms, runs)


CLAMP_MASS_MAX = 10.0  # [kg] the largest clamp payload --clamp-mass accepts


@dataclass(frozen=True)
class ClampMassFit:
    """The clamp payload [kg] fitted on the fit recordings (:func:`fit_clamp_mass`): value (pooled least squares),
    per recording, their min-max, and the RMS [N m] of the band-passed residual over all joints without and with it."""

    value: float
    per_file: dict[str, float]
    interval: tuple[float, float]
    residual_rms_without: float
    residual_rms_with: float

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["interval"] = list(self.interval)
        d["method"] = ("linear least squares of the 1.5-8 Hz band of (measured - predicted) external torques, all 7 "
                       "joints, the whole recording, on the band of the estimate-filtered torques of a 1 kg point mass "
                       "at the clamp point, m J_c^T (a - g); the motion's flange accelerations (several m/s^2) "
                       "identify it; interval: min-max of the per-recording values")
        return d


def fit_clamp_mass(recs: list[BeamRecording], preds: list[Prediction], panda: Panda, numerics: Numerics,
                   estimate: EstimateFilter, mounting: Mounting = Mounting()) -> ClampMassFit:
    """Fit the clamp payload m [kg] (:attr:`Mounting.clamp_mass`) on recordings and their predictions made without it.

    The payload adds m times a known signal (:func:`~bullet_dlo.reality.beam.payload_torques` of 1 kg, through the
    estimate filter) to the external torques, so m is the linear least-squares coefficient of that signal against
    the prediction's residual, measured - predicted. Both are band-passed to 1.5-8 Hz (the vibration metrics' band:
    Franka's pose-dependent bias, a slow offset, stays out) over all joints and the whole recording; the motion's
    flange accelerations (several m/s^2, against a few cm/s^2 while the strip rings) identify it."""
    num, den, per, rows_all = 0.0, 0.0, {}, []
    for rec, pred in zip(recs, preds):
        k = len(pred.t)
        start = motion_span(rec.dq_d)[0]
        reg = payload_torques(panda, low_passed_q(rec, numerics)[:k], rec.rate, replace(mounting, clamp_mass=1.0))
        x = np.stack([band(c, rec.rate) for c in estimate.apply(reg, rec.rate).T], axis=1)
        y = np.stack([band(c, rec.rate) for c in (deviation(rec.tau_ext_hat_filtered, start)[:k]
                                                  - pred.torques_filtered).T], axis=1)
        per[rec.name] = float(np.sum(x * y) / np.sum(x * x))
        num, den = num + float(np.sum(x * y)), den + float(np.sum(x * x))
        rows_all.append((x, y))
    m = num / den
    res0 = math.sqrt(sum(float(np.sum(y**2)) for _, y in rows_all) / sum(y.size for _, y in rows_all))
    res1 = math.sqrt(sum(float(np.sum((y - m * x) ** 2)) for x, y in rows_all) / sum(y.size for _, y in rows_all))
    values = list(per.values())
    return ClampMassFit(float(m), per, (float(min(values)), float(max(values))), res0, res1)


def numerics_check(strip: Strip, numerics: Numerics, damping: dict[str, float]) -> dict[str, Any]:
    """Numerical damping and convergence in n of the weak-plane cantilever (:func:`free_vibration`, the chosen
    strip model):
    the undamped run's damping ratio with the chosen integrator (and implicit Euler for contrast),
    and the frequency at n/2, n, 2n with the observed order and the Richardson-extrapolated limit."""
    ns = [max(4, numerics.n_masses // 2), numerics.n_masses, 2 * numerics.n_masses]
    freqs = [free_vibration(strip, replace(numerics, n_masses=n))[0] for n in ns]
    _, zeta_num = free_vibration(strip, numerics)
    _, zeta_euler = free_vibration(strip, replace(numerics, integrator="implicit_euler"))
    f_model, zeta_model = free_vibration(strip, numerics, damping=damping)
    d1, d2 = freqs[1] - freqs[0], freqs[2] - freqs[1]
    order = math.log2(abs(d1 / d2)) if d2 != 0 and d1 != 0 else math.nan
    limit = freqs[2] + d2 / (2**order - 1) if math.isfinite(order) and order > 0 else math.nan
    return {"numerical_damping_ratio": zeta_num, "implicit_euler_damping_ratio": zeta_euler,
            "model_damping_ratio_free_cantilever": zeta_model, "model_frequency_hz_free_cantilever": f_model,
            "convergence_n": ns, "convergence_frequency_hz": freqs, "observed_order": order,
            "extrapolated_frequency_hz": limit,
            "relative_discretisation_error": abs(freqs[1] - limit) / limit if math.isfinite(limit) else math.nan,
            "what": "weak-plane cantilever, horizontal, released from its sag under 1.2 g; damped sine fitted "
                    "to the vertical clamp force over 5 s"}


END_WINDOW = (0.0, 0.5)  # [s] after the motion's end: the vibration the motion leaves, before it decays
# the reality issue's goals on held-out motions, |predicted / measured - 1| at most: frequency 2 %, damping ratio 30 %,
# peak-to-peak 15 %; the fitted sine's amplitude (the level of the mode alone) gets the peak-to-peak's 15 %
GOALS = {"frequency_hz": 0.02, "damping_ratio": 0.30, "p2p_torque": 0.15, "sine_amplitude": 0.15}


def p2p_at_end(t: np.ndarray, y: np.ndarray, t_end: float) -> float:
    """Peak-to-peak [N m] of the 1.5-8 Hz band of y over :data:`END_WINDOW` after the motion's end (about
    1.5 cycles: what the excitation left; the damping takes 4-10 % of it by the window's end)."""
    rate = 1.0 / float(np.median(np.diff(t)))
    w = (t >= t_end + END_WINDOW[0]) & (t <= t_end + END_WINDOW[1])
    return float(np.ptp(band(y, rate)[w]))


def file_result(rec: BeamRecording, m: Measured, pred: Prediction) -> dict[str, Any]:
    """One recording's entry of the JSON: joint, measured, predicted, ratios, RMS errors, cost.

    ``p2p_at_end`` (measured, predicted, ratio): the band's peak-to-peak over the first 0.5 s after the
    motion (:func:`p2p_at_end`): if its ratio is as far off as ``p2p_torque``'s (end + 1-2 s), the miss
    comes from the excitation (arm model, Franka filter, tracking), not from the damping."""
    pv = predicted_vibration(pred, m)
    k = len(pred.t)
    err = pred.torques_filtered - m.dev[:k]
    meas = {**m.vibration.to_dict(), "damping_by_amplitude": damping_by_amplitude(rec.t, m.dev[:, m.joint], m.t_end),
            "motion_end_s": m.t_end, "p2p_at_end": p2p_at_end(rec.t, m.dev[:, m.joint], m.t_end)}
    predicted = {"frequency_hz": pv.frequency_hz, "damping_ratio": pv.damping_ratio, "p2p_torque": pv.p2p_torque,
                 "sine_amplitude": pv.sine_amplitude, "amplitude": pv.amplitude,
                 "p2p_at_end": p2p_at_end(pred.t, pred.torques_filtered[:, m.joint], m.t_end)}
    ratio = {k2: predicted[k2] / meas[k2] for k2 in ("frequency_hz", "damping_ratio", "p2p_torque", "sine_amplitude",
                                                      "p2p_at_end")}
    return {"joint": m.joint, "measured": meas, "predicted": predicted, "ratio": ratio,
            "within_goal": {k2: bool(abs(ratio[k2] - 1.0) <= tol) for k2, tol in GOALS.items()},
            "rms_torque_error": float(np.sqrt(np.mean(err[:, m.joint] ** 2))),
            "rms_torque_error_all_joints": float(np.sqrt(np.mean(err**2))),
            "rms_measured_deviation": float(np.sqrt(np.mean(m.dev[:k, m.joint] ** 2))),
            "strip_model": pred.strip_model, "strip_model_reason": pred.strip_reason,
            "simulated_s": pred.simulated_s, "cpu_s": pred.cpu_s, "warnings": pred.warnings}


def read_in(path: Path, what: str) -> BeamRecording:
    """:func:`read_beam_csv`, its errors naming the folder argument ``what``."""
    try:
        return read_beam_csv(path)
    except ParameterError as err:
        raise ParameterError(f"{what}: {err}") from None


def measure_in(rec: BeamRecording, what: str) -> Measured:
    """:func:`measure`, its errors naming the folder argument ``what``."""
    try:
        return measure(rec)
    except ParameterError as err:
        raise ParameterError(f"{what}: {err}") from None


def _mode_or_number(value, option: str, modes: tuple[str, ...], lo: float, hi: float, what: str, unit: str):
    """``value`` as one of the words ``modes`` or a finite number in [lo, hi] (in ``unit``); else a
    ParameterError naming ``option`` and what it allows."""
    if value in modes:
        return value
    allowed = f"{option} must be {', '.join(modes)} or {what} in [{lo:g}, {hi:g}]{unit}"
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{allowed}, got {value!r}") from None
    if not (math.isfinite(number) and lo <= number <= hi):
        raise ParameterError(f"{allowed}, got {number:g}")
    return number


def validate_beam(fit_dir: str | Path, predict_dir: str | Path, *, damping: str = "damping_rate",
                  numerics: Numerics = Numerics(), strip: Strip = Strip(), estimate: EstimateFilter | None = None,
                  duration: float | None = None, limit_files: int | None = None, check_numerics: bool = True,
                  fit_youngs_modulus: bool = False, drag: str | float = "off", clamp_mass: str | float = "off",
                  arm: str | None = None, arm_dir: str | Path | None = None,
                  amplitude_damping: str | float = "off", log=print) -> tuple[dict[str, Any], dict[str, tuple[BeamRecording, Measured, Prediction]]]:
    """Fit ``damping`` on the recordings of ``fit_dir``, predict those of ``predict_dir``.

    estimate: Franka's filter (default: identified on ``fit_dir``); duration: simulated seconds of each
    prediction (default: the whole recording); limit_files: use only the first files of each folder.
    drag: the strip's quadratic air drag (``drag_coefficient`` C_d of :class:`~bullet_dlo.core.spec.CableSpec`,
    air 1.204 kg/m^3 on the face): ``"off"`` (default), ``"fit"`` (C_d and ``damping_rate`` fitted together on
    ``fit_dir`` from the damping's amplitude dependence, :func:`fit_damping_drag`; needs ``damping`` =
    ``damping_rate``) or a number (C_d held, ``damping`` fitted with it).
    clamp_mass: a rigid payload at the clamp that Franka's estimate does not know (:attr:`Mounting.clamp_mass`):
    ``"off"`` (default), ``"fit"`` (fitted on ``fit_dir`` first, :func:`fit_clamp_mass`, then held while the
    damping is fitted) or a mass [kg] in [0, 10].
    arm: how the strip's clamp moves (:mod:`bullet_dlo.reality.beam_arm`): ``"measured"`` (the flange path of the
    measured q), ``"compliant"`` (the strip on the arm's joint impedance identified on ``fit_dir``, substituted about
    the measured q) or ``"loop"`` (the same arm in the full loop driven by q_d); None (default): ``"compliant"``
    (better on the held-out files: docs/guides/validate.md), with any strip model; ``arm_dir``: the
    folder whose recordings identify the arm's impedance instead of ``fit_dir`` (the controller is one for all
    motions, but a folder of Z motions does not move joints 0 and 2 enough to identify them).
    amplitude_damping: the measured damping law's amplitude-dependent part, zeta = c A_tip
    (:mod:`bullet_dlo.reality.beam_law`), in the strip's bending dampers of the arm-strip loop: ``"off"`` (default),
    ``"law"`` (c [1/m] of the drag law zeta0 + c A fitted across FIT_DIR's decay envelopes, from the recordings alone,
    then held while ``damping`` is fitted with it) or a slope c [1/m] in [0, 10]. Needs ``arm`` compliant or loop.
    Every run reports the measured law per file (``measured.decay_law``) and across the fit files
    (``parameters.damping_law``).
    Returns the JSON-ready summary and, per predicted file, (recording, measurement, prediction).
    """
    if arm is None:
        arm = "compliant"
    check_arm_mode(arm)
    amplitude_damping = _mode_or_number(amplitude_damping, "--amplitude-damping", ("off", "law"), 0.0,
                                        AMPLITUDE_DAMPING_MAX, "a slope", " 1/m")
    if amplitude_damping != "off" and arm == "measured":
        raise ParameterError("--amplitude-damping runs in the stepped arm-strip loop: use --arm compliant or loop")
    if amplitude_damping != "off" and numerics.strip_model == "rectangle":
        raise ParameterError("--amplitude-damping sets the planes' weak-plane bending dampers; use --strip-model "
                             "planes or auto")
    if drag == "fit" and damping != "damping_rate":
        raise ParameterError("--drag-coefficient fit fits C_d together with damping_rate: use --damping damping_rate")
    drag = _mode_or_number(drag, "--drag-coefficient", ("off", "fit"), 0.0, 1e3, "a number", "")
    clamp_mass = _mode_or_number(clamp_mass, "--clamp-mass", ("off", "fit"), 0.0, CLAMP_MASS_MAX, "a mass", " kg")
    fit_files = beam_files(fit_dir, "FIT_DIR")[:limit_files]
    pred_files = beam_files(predict_dir, "PREDICT_DIR")[:limit_files]
    fit_recs = [read_in(f, "FIT_DIR") for f in fit_files]
    pred_recs = [read_in(f, "PREDICT_DIR") for f in pred_files]
    fit_meas = [measure_in(r, "FIT_DIR") for r in fit_recs]
    pred_meas = {r.name: measure_in(r, "PREDICT_DIR") for r in pred_recs}  # (before the fit: a bad file fails at once)
    tic = time.thread_time()
    arm_setting = None
    if arm != "measured":
        arm_recs = fit_recs if arm_dir is None else [read_in(f, "--arm-dir") for f in beam_files(arm_dir, "--arm-dir")]
        arm_setting = ArmSetting(arm, identify_arm(arm_recs))
        imp = arm_setting.impedance
        log("arm joint impedance (joints " + ", ".join(map(str, np.flatnonzero(imp.compliant))) + " compliant): K "
            + " ".join(f"{k:.0f}" for k in imp.stiffness) + " N m/rad, D " + " ".join(f"{d:.1f}" for d in imp.damping)
            + " N m s/rad, R^2 " + " ".join(f"{r:.2f}" for r in imp.r2))
    with Panda() as panda:
        if estimate is None:
            log(f"identifying Franka's estimate filter on {len(fit_recs)} recording(s) ...")
            estimate = identify_filter(fit_recs, panda)
        log(f"estimate filter: {estimate.cutoff_hz:.3g} Hz low-pass + {1e3 * estimate.delay_s:.3g} ms delay; "
            f"fitting {damping} on {len(fit_recs)} recording(s) ...")
        fixed = {} if drag in ("off", "fit") else {"drag_coefficient": float(drag)}
        law_fit = measured_law(fit_recs, panda, strip, estimate)
        if amplitude_damping != "off":
            slope = law_fit["shared"]["drag"]["params"]["c"] if amplitude_damping == "law" else amplitude_damping
            fixed["amplitude_damping"] = float(slope)
            log(f"amplitude-dependent damping zeta = c A_tip, c {slope:.4g} 1/m "
                + ("(the drag law across FIT_DIR's decays)" if amplitude_damping == "law" else "(given)"))
        mounting, mass_fit = Mounting(), None
        if clamp_mass == "fit":  # the payload is linear and independent of the damping: one run per fit file
            log(f"fitting the clamp payload on {len(fit_recs)} recording(s) ...")
            preds = [predict(r, panda, strip, {**fixed, damping: TRIAL[damping]}, numerics, estimate,
                             duration=duration, arm=arm_setting) for r in fit_recs]
            mass_fit = fit_clamp_mass(fit_recs, preds, panda, numerics, estimate)
            mounting = Mounting(clamp_mass=mass_fit.value)
            lo, hi = mass_fit.interval
            log(f"clamp payload {mass_fit.value:.3g} kg (per file {lo:.3g}-{hi:.3g})")
        elif clamp_mass != "off":
            mounting = Mounting(clamp_mass=float(clamp_mass))
        fitted = fit_damping(fit_recs, fit_meas, panda, damping, strip, numerics, estimate, fixed, mounting,
                                 arm_setting)
        e_note = "nominal (midpoint of 190-205 GPa)"
        if fit_youngs_modulus:  # f ~ sqrt(E) for the bending part (gravity's share does not scale): one update
            scale = float(np.median(list(fitted.frequency_ratio.values()))) ** 2
            strip = replace(strip, youngs_modulus=strip.youngs_modulus * scale)
            e_note = (f"fitted: nominal x {scale:.4f}, the median (f measured / f predicted)^2 over the fit recordings")
            log(f"E {strip.youngs_modulus / 1e9:.4g} GPa; refitting {damping} ...")
            fitted = fit_damping(fit_recs, fit_meas, panda, damping, strip, numerics, estimate, fixed, mounting,
                                 arm_setting)
        params = {**fixed, fitted.name: fitted.value}
        drag_fit = None
        if drag == "fit":
            log(f"fitting damping_rate and drag_coefficient on {len(fit_recs)} recording(s) (amplitude windows) ...")
            drag_fit = fit_damping_drag(fit_recs, fit_meas, panda, strip, numerics, estimate, mounting,
                                        arm_setting)
            params = {"damping_rate": drag_fit.damping_rate, "drag_coefficient": drag_fit.drag_coefficient}
            log(f"damping_rate {drag_fit.damping_rate:.4g} 1/s, drag_coefficient {drag_fit.drag_coefficient:.4g}")
        files, details = {}, {}
        for rec in pred_recs:
            log(f"predicting {rec.name} ...")
            m = pred_meas[rec.name]
            pred = predict(rec, panda, strip, params, numerics, estimate, mounting, duration=duration, arm=arm_setting)
            files[rec.name] = file_result(rec, m, pred)
            files[rec.name]["measured"]["decay_law"] = file_decay(rec, panda, strip, estimate).summary()
            details[rec.name] = (rec, m, pred)
    simulated = sum(f["simulated_s"] for f in files.values())
    goals = {k: {"within": sum(f["within_goal"][k] for f in files.values()), "of": len(files), "tolerance": tol}
             for k, tol in GOALS.items()}
    cpu = sum(f["cpu_s"] for f in files.values())
    summary = {
        "files": files,
        "parameters": {**params, damping + "_fit": fitted.to_dict(), "damping_law": law_fit,
                       "amplitude_damping_source": ("off: linear damping only" if amplitude_damping == "off" else
                                                    "the drag law's slope across FIT_DIR's decay envelopes" if
                                                    amplitude_damping == "law" else "given"),
                       **({"drag_fit": drag_fit.to_dict()} if drag_fit is not None else {}),
                       "drag": ("off" if drag == "off" else
                                "quadratic air drag on the strip's face, 1/2 rho_air C_d w |v_n| v_n per length, "
                                "rho_air 1.204 kg/m^3, C_d " + ("fitted on FIT_DIR with damping_rate" if drag == "fit"
                                                                 else "given")),
                       "clamp_mass": mounting.clamp_mass,
                       "clamp_mass_source": ("off: no payload at the clamp" if clamp_mass == "off" else
                                             "fitted on FIT_DIR" if clamp_mass == "fit" else "given"),
                       **({"clamp_mass_fit": mass_fit.to_dict()} if mass_fit is not None else {}),
                       "youngs_modulus": strip.youngs_modulus,
                       "density": strip.density, "length": strip.length, "width": strip.width,
                       "thickness": strip.thickness, "mass": strip.mass,
                       "youngs_modulus_source": e_note,
                       "material": "density and geometry nominal (midpoints of the stated ranges)"},
        "fit_files": [r.name for r in fit_recs],
        "arm": {"mode": arm, "what": ARM_MODES_DOC[arm],
                **({"impedance": arm_setting.impedance.to_dict(),
                    "identified_on": [r.name for r in arm_recs]} if arm_setting is not None else {})},
        "model": {"integrator": numerics.integrator, "n": numerics.n_masses, "dt": numerics.dt,
                  "knot_step_s": numerics.knot_step, "q_cutoff_hz": numerics.q_cutoff_hz,
                  "strip_model": numerics.strip_model, "bending": BENDING[numerics.strip_model],
                  "strip_models_run": {k: [name for name, f in files.items() if f["strip_model"] == k]
                                       for k in ("planes", "rectangle")},
                  "torque_sign": "tau = -J^T w, w the strip's wrench on the flange about its origin"},
        "estimate_filter": {"cutoff_hz": estimate.cutoff_hz, "delay_s": estimate.delay_s, "source": estimate.source,
                            "gain_at_2.9_hz": float(abs(estimate.response(2.9))),
                            "phase_deg_at_2.9_hz": float(np.degrees(np.angle(estimate.response(2.9))))},
        "goals": {**goals, "rule": "|predicted / measured - 1| <= tolerance, per predicted file"},
        "cost_per_simulated_second": cpu / simulated if simulated else math.nan,
        "total_cpu_s": time.thread_time() - tic,
        "limits": [STRIP_LIMITS[numerics.strip_model], ARM_LIMITS[arm], *LIMITS],
    }
    if check_numerics:
        summary["numerics"] = numerics_check(strip, numerics, params)
    return summary, details


def table(summary: dict[str, Any]) -> str:
    """Measured vs predicted per file (frequency, damping ratio, p2p, the fitted sine's amplitude) with ratios, the
    p2p ratio over the first 0.5 s after the motion (``end ratio``: the excitation), the RMS error, and how many
    files meet each goal."""
    lines = [f"{'file':28s} {'j':>2s} {'f meas':>7s} {'f pred':>7s} {'ratio':>6s} {'z meas':>7s} {'z pred':>7s} "
             f"{'ratio':>6s} {'p2p meas':>8s} {'p2p pred':>8s} {'ratio':>6s} {'sine meas':>9s} {'sine pred':>9s} "
             f"{'ratio':>6s} {'end ratio':>9s} {'rms err':>7s}"]
    for name, f in summary["files"].items():
        me, pr, ra = f["measured"], f["predicted"], f["ratio"]
        lines.append(f"{name:28s} {f['joint']:2d} {me['frequency_hz']:7.3f} {pr['frequency_hz']:7.3f} "
                     f"{ra['frequency_hz']:6.3f} {me['damping_ratio']:7.4f} {pr['damping_ratio']:7.4f} "
                     f"{ra['damping_ratio']:6.2f} {me['p2p_torque']:8.3f} {pr['p2p_torque']:8.3f} "
                     f"{ra['p2p_torque']:6.2f} {me['sine_amplitude']:9.3f} {pr['sine_amplitude']:9.3f} "
                     f"{ra['sine_amplitude']:6.2f} {ra['p2p_at_end']:9.2f} {f['rms_torque_error']:7.3f}")
    if "goals" in summary:
        g = summary["goals"]
        lines.append("within goal (held out): " + ", ".join(
            f"{label} {g[k]['within']} of {g[k]['of']}" for k, label in (
                ("frequency_hz", "frequency 2 %"), ("damping_ratio", "damping ratio 30 %"),
                ("p2p_torque", "p2p 15 %"), ("sine_amplitude", "sine amplitude 15 %"))))
    return "\n".join(lines)


def plot_file(rec: BeamRecording, m: Measured, pred: Prediction, png: Path) -> None:
    """Measured external-torque deviation of joint j and the prediction (filtered; unfiltered thin) [N m] vs t [s]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    j = m.joint
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.plot(rec.t, m.dev[:, j], color="k", lw=0.8, label="measured (tau_ext_hat_filtered - rest)")
    ax.plot(pred.t, pred.torques[:, j], color="C1", lw=0.5, alpha=0.6, label="predicted, unfiltered")
    ax.plot(pred.t, pred.torques_filtered[:, j], color="C0", lw=1.0, ls="--", label="predicted, Franka filter")
    for a in (m.t_end, m.t_end + 1.0, m.t_end + 6.0):
        ax.axvline(a, color="0.6", lw=0.6)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"joint {j} torque deviation [N m]")
    ax.set_title(f"{rec.name}: measured vs predicted (lines: motion end, end + 1 s, end + 6 s)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
