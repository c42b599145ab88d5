"""The strip on a compliant arm: the Panda's joint impedance identified, and the arm-strip closed loop.

**The arm under its controller** (:class:`ArmImpedance`, :func:`identify_arm`). After a beam_handling motion the
arm rings with the strip; its link-side joint torques ``tau_J`` follow the tracking error e = q - q_d as a joint
impedance, tau_J - tau_J(rest) = -K e - D de/dt per joint (K [N m/rad], D [N m s/rad], diagonal), identified by
least squares on the 1.5-8 Hz band of the fit recordings from ``settle`` to ``settle + span`` s after each motion
(pooled over the recordings; R^2 per joint reported). The link dynamics are the URDF's rigid arm,
M(q) q'' + c + g = tau_J + J^T w (w the load's wrench on the flange), so about the reference path the error obeys

    M(q) e'' + D e' + K e = -tau_ext + tau_other(t),      tau_ext = -J(q)^T w  (Franka's external torque).

Checked on the recordings (``tests/reality/test_beam_arm.py``): driven by the real strip's external torque (the
estimate with its filter undone), this model reproduces the measured tracking error of joints 0, 2 and 4 on
Xdown_15cm with gain 0.9-1.0 and correlation 0.97-0.99 (0.67-1.02 and 0.84-0.99 on joints 0, 1, 2, 4 of the Xdown/Xup
15/25 cm files). Joints whose pooled R^2 is below :data:`MIN_R2` (joints 0 and 2 on the Z motions, which barely move
them) are held rigid, and so are the wrist joints 5 and 6 (R^2 0.1-0.3 on the recordings: they barely move either,
and their small inertia would make the staggered step below ring against the strip's stiff clamp).

**The closed loop** (:func:`predict_torques_compliant`; its steps in one compiled call,
:func:`bullet_dlo.reality.arm_loop.run_arm_loop`). The arm's deviation delta from a reference joint path
q_ref obeys M(q_ref) delta'' + D delta' + K delta = -(tau_ext,model - tau_sub) on its compliant joints; the strip's
clamp follows FK(q_ref) + J(q_ref) delta (first order in delta, a few mrad at most), step by step at the strip's dt:
the strip's clamp load at t gives tau_ext,model, one arm step (Newmark average acceleration, no numerical damping)
gives delta at t + dt, the strip steps to t + dt with its clamp there (a one-step lag; halving dt changes the
goal's peak-to-peak by 0.1-0.3 %). The rectangle strip (the default) is stepped in the loop whole: the deviation moves
its clamp's position, tangent and section axis (the full rotation J(q_ref)[3:] delta), and its clamp load, twist
moment and strong plane's inertia included, is what the arm feels. Of the planes only the weak-plane run is stepped
in the loop: their strong plane (first mode near 240 Hz) is a rigid part of the arm, its load along q_ref from a
prescribed run and its inertia against delta in the arm's mass matrix (stepped in the loop, the planes' strong run
with the one-step lag rang the loop at 200 Hz). Both were measured stable on the nine recordings with joints 0-4
compliant, driven by the measured path and by q_d, and they give the same held-out ratios (docs/guides/validate.md).
Taking the rectangle's rigid strong-plane inertia into the arm's mass matrix as well (the lagged part of its load
cancelled) made the loop unstable instead: on ocp_Xup_35cm driven by q_d the joint torques grew to 70 N m at 7.3 s.

* ``drive="measured"`` (substitution): q_ref = the measured q and tau_sub = the real strip's external torque
  (Franka's estimate with the identified filter undone: advanced by its delay, plus its derivative over the
  cut-off rate, low-passed at 20 Hz). A model strip that loads the arm as the real one did leaves the measured
  path unchanged (delta = 0); where it loads it differently (another frequency, amplitude or damping) the arm
  answers its own strip, as the real arm answered the real one. Everything the model does not explain (the arm's
  own tracking error, friction, Franka's model errors) stays in the measured path.
* ``drive="desired"``: q_ref = q_d and tau_sub = 0: the full loop from the command, with nothing else moving the
  arm (the arm's own tracking error during the motion is missing).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from bullet_dlo.core.integrators import NewtonOptions, make_stepper
from bullet_dlo.core.kernels.monitor import clamp_moments, end_forces
from bullet_dlo.core.model import STANDARD_GRAVITY
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality.beam import (
    TICK,
    BeamRecording,
    EstimateFilter,
    Mounting,
    Numerics,
    Prediction,
    Strip,
    choose_strip_model,
    flange_motion,
    low_passed_q,
    payload_torques,
    PlaneRun,
    plane_model,
    plane_runs,
    rectangle_model,
    run_plane,
    stepped_start,
)
from bullet_dlo.reality.arm_loop import (ARM_UNSTABLE, STRIP_UNSTABLE, Arm, Coupling, Law, LoopRecords,
                                         newmark_step, run_arm_loop)
from bullet_dlo.reality.panda import N_JOINTS, Panda, external_torques
from bullet_dlo.reality.vibration import BAND, motion_span

ARM_MODES = ("measured", "compliant", "loop")  # clamp on the measured path | substitution | full loop from q_d
MIN_R2 = 0.5  # [-] a joint whose impedance law explains less of its torque band is held rigid
SETTLE = 0.3  # [s] after the motion's end: the identification window starts there
SPAN = 5.7  # [s] length of the identification window
MAX_DEVIATION = 0.05  # [rad] an arm deviation beyond it is an unstable loop (the real ones are a few mrad)
SUB_CUTOFF_HZ = 20.0  # [Hz] low-pass of the de-filtered estimate (undoing the filter amplifies noise)


def check_arm_mode(name: str) -> str:
    """``name`` if it is one of :data:`ARM_MODES`, else ParameterError."""
    if name not in ARM_MODES:
        raise ParameterError(f"--arm must be one of {', '.join(ARM_MODES)}, got {name!r}")
    return name


@dataclass(frozen=True)
class ArmImpedance:
    """The arm's joint impedance under its controller: stiffness K [N m/rad] and damping D [N m s/rad], (7,)
    each; r2: the share of the joint-torque band the law explains per joint [-]; compliant: joints that follow
    the law (the others are held rigid); source: where the numbers come from."""

    stiffness: np.ndarray
    damping: np.ndarray
    r2: np.ndarray
    compliant: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("stiffness", "damping", "r2"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float).reshape(N_JOINTS))
        comp = np.asarray(self.compliant, dtype=bool).reshape(N_JOINTS)
        if np.any(comp & ~(self.stiffness > 0)) or np.any(comp & ~(self.damping >= 0)):
            raise ParameterError("arm impedance: a compliant joint needs stiffness > 0 and damping >= 0")
        object.__setattr__(self, "compliant", comp)

    def to_dict(self) -> dict[str, Any]:
        return {"stiffness_nm_per_rad": self.stiffness.tolist(), "damping_nms_per_rad": self.damping.tolist(),
                "r2": self.r2.tolist(), "compliant_joints": np.flatnonzero(self.compliant).tolist(),
                "source": self.source,
                "law": "tau_J - tau_J(rest) = -K (q - q_d) - D (dq - dq_d) per joint, 1.5-8 Hz band, "
                       f"{SETTLE}-{SETTLE + SPAN} s after each motion; joints with R^2 < {MIN_R2} held rigid"}


def _band(y: np.ndarray, rate: float) -> np.ndarray:
    """1.5-8 Hz band of y along axis 0 (zero phase)."""
    sos = butter(4, BAND, btype="bandpass", fs=rate, output="sos")
    return sosfiltfilt(sos, y, axis=0)


def identify_arm(recordings: list[BeamRecording], settle: float = SETTLE, span: float = SPAN,
                 min_r2: float = MIN_R2) -> ArmImpedance:
    """Joint impedance (module doc) by least squares on the recordings' band after each motion, pooled."""
    rows: list[list[np.ndarray]] = [[] for _ in range(N_JOINTS)]
    rhs: list[list[np.ndarray]] = [[] for _ in range(N_JOINTS)]
    for rec in recordings:
        try:
            start, end = motion_span(rec.dq_d)
        except ValueError as err:
            raise ParameterError(f"beam recording {rec.name}: {err}") from None
        a, b = end + int(settle * rec.rate), end + int((settle + span) * rec.rate)
        if b > len(rec.t):
            raise ParameterError(f"beam recording {rec.name}: the arm identification needs {settle + span} s "
                                 "after the motion")
        e = _band(rec.q - rec.q_d, rec.rate)[a:b]
        de = _band(rec.dq - rec.dq_d, rec.rate)[a:b]
        tau = _band(rec.tau_J - rec.tau_J[:max(start, 1)].mean(axis=0), rec.rate)[a:b]
        for j in range(N_JOINTS):
            rows[j].append(np.column_stack([e[:, j], de[:, j]]))
            rhs[j].append(tau[:, j])
    k, d, r2 = np.zeros(N_JOINTS), np.zeros(N_JOINTS), np.zeros(N_JOINTS)
    for j in range(N_JOINTS):
        a, y = np.vstack(rows[j]), np.concatenate(rhs[j])
        c = np.linalg.lstsq(a, y, rcond=None)[0]
        k[j], d[j] = -c[0], -c[1]
        r2[j] = 1.0 - float(np.sum((y - a @ c) ** 2)) / max(float(np.sum(y**2)), 1e-300)
    compliant = (r2 >= min_r2) & (k > 0) & (d >= 0)
    compliant[5:] = False  # the wrist: inertia too small for the staggered loop (predict_torques_compliant)
    return ArmImpedance(k, np.where(d >= 0, d, 0.0), r2, compliant,
                        f"identified on {len(recordings)} recording(s): tau_J against q - q_d after the motions")


def strip_torque_real(rec: BeamRecording, estimate: EstimateFilter, cutoff_hz: float = SUB_CUTOFF_HZ) -> np.ndarray:
    """The real strip's external joint torques [N m], (k, 7), as deviations from rest before the motion:
    Franka's estimate with ``estimate`` undone (first-order low-pass: y + y'/omega_c; delay: read it later),
    low-passed at ``cutoff_hz`` [Hz] (zero phase) first."""
    start = motion_span(rec.dq_d)[0]
    y = rec.tau_ext_hat_filtered - rec.tau_ext_hat_filtered[:max(start, 1)].mean(axis=0)
    y = sosfiltfilt(butter(4, cutoff_hz, fs=rec.rate, output="sos"), y, axis=0)
    tau = y + np.gradient(y, 1.0 / rec.rate, axis=0) / (2 * math.pi * estimate.cutoff_hz)
    lag = int(round(estimate.delay_s * rec.rate))
    return np.vstack([tau[lag:], np.repeat(tau[-1:], lag, axis=0)]) if lag else tau


def mass_matrices(panda: Panda, q: np.ndarray, every: int = 10) -> np.ndarray:
    """The arm's joint-space inertia [kg m^2], (k, 7, 7), along joint rows q [rad], (k, 7): evaluated every
    ``every`` rows and held in between (it changes by well under 1 % over 10 ms of these motions)."""
    out = np.empty((len(q), N_JOINTS, N_JOINTS))
    for i in range(0, len(q), every):
        out[i:i + every] = panda.mass_matrix(q[i])
    return out


class ArmLoop:
    """The arm's deviation delta [rad] from q_ref on its compliant joints, advanced by Newmark's average
    acceleration (trapezoidal, no numerical damping) with the forcing held over a step: the step of the compiled
    loop (:func:`bullet_dlo.reality.arm_loop.run_arm_loop`) one call at a time.

    mass: (k, 7, 7) joint inertia along the reference rows (every ``row_dt`` s); impedance: K, D and which
    joints are compliant; h: step [s]."""

    def __init__(self, mass: np.ndarray, impedance: ArmImpedance, h: float, row_dt: float = TICK):
        self.idx = np.flatnonzero(impedance.compliant)
        nc = len(self.idx)
        self.arm = Arm(self.idx, np.ascontiguousarray(mass[:, self.idx][:, :, self.idx]),
                       impedance.stiffness[self.idx].copy(), impedance.damping[self.idx].copy(), np.zeros(nc),
                       np.zeros(nc), np.zeros(nc), MAX_DEVIATION)
        self.h, self.row_dt = float(h), float(row_dt)

    q = property(lambda self: self.arm.q, doc="deviation [rad] of the compliant joints")
    v = property(lambda self: self.arm.v, doc="its rate [rad/s]")
    a = property(lambda self: self.arm.a, doc="its acceleration [rad/s^2]")

    def row(self, t: float) -> int:
        return min(int(t / self.row_dt + 1e-9), len(self.arm.mass) - 1)

    def full(self, y: np.ndarray) -> np.ndarray:
        """A compliant-joint vector as (7,) with zeros at the rigid joints."""
        out = np.zeros(N_JOINTS)
        out[self.idx] = y
        return out

    def step(self, t: float, force: np.ndarray) -> None:
        """From t to t + h under joint torques ``force`` [N m], (7,) (held over the step)."""
        newmark_step(self.arm, np.ascontiguousarray(force, dtype=float), self.row(t + self.h), self.h)


def predict_torques_compliant(rec: BeamRecording, panda: Panda, impedance: ArmImpedance, strip: Strip = Strip(),
                              damping: dict[str, float] | None = None, numerics: Numerics = Numerics(),
                              estimate: EstimateFilter = EstimateFilter(), mounting: Mounting = Mounting(),
                              duration: float | None = None, drive: str = "measured",
                              gravity: tuple[float, float, float] = STANDARD_GRAVITY,
                              amplitude_damping: float = 0.0) -> Prediction:
    """:func:`~bullet_dlo.reality.beam.predict_torques` with the strip on the compliant arm (module doc):
    ``drive`` ``"measured"`` (substitution about the measured q) or ``"desired"`` (full loop from q_d). The strip
    model as :func:`~bullet_dlo.reality.beam.choose_strip_model` picks it: the planes' weak run stepped in the loop
    (their strong run prescribed, its rigid inertia in the arm's), or the rectangle stepped in the loop whole. The
    returned prediction carries the arm's deviation (``arm_deviation`` [rad], (k, 7)). ``amplitude_damping`` c
    [1/m]: the measured damping law's amplitude-dependent part, zeta = c A (A the strip's tip amplitude), as the
    weak-plane run's bending dampers set each step (:class:`bullet_dlo.reality.beam_law.AmplitudeDamping`; the planes
    only: a file that runs the rectangle under ``auto`` leaves it out with a warning); 0: none."""
    if impedance.compliant[5:].any():
        raise ParameterError("the arm-strip loop holds the wrist joints 5 and 6 rigid (their inertia is too small for "
                             "the staggered step against the strip's stiff strong-plane clamp); give an impedance with "
                             "compliant joints among 0-4")
    if numerics.strip_model == "rectangle" and amplitude_damping:
        raise ParameterError("--amplitude-damping sets the planes' weak-plane bending dampers; use --strip-model "
                             "planes or auto")
    if drive not in ("measured", "desired"):
        raise ParameterError(f"drive must be measured or desired, got {drive!r}")
    tic = time.thread_time()
    damping = damping or {}
    duration = float(rec.t[-1]) if duration is None else min(float(duration), float(rec.t[-1]))
    ref = rec if drive == "measured" else BeamRecording(rec.t, rec.q_d.copy(), rec.q_d, rec.dq_d, rec.dq_d, rec.tau_J,
                                                        rec.tau_ext_hat_filtered, rec.name)
    times, pos, rot = flange_motion(ref, panda, numerics, duration)
    chosen, reason = choose_strip_model(numerics.strip_model, rot, mounting)
    warnings = [reason] if reason.startswith("warning:") else []
    if amplitude_damping and chosen != "planes":
        warnings.append(f"--amplitude-damping left out for {rec.name}: it runs with the planes strip only")
        amplitude_damping = 0.0
    clamp = mounting.clamp_point(pos, rot)
    disp = clamp - clamp[0]
    rotvec = Rotation.from_matrix(rot @ rot[0].T).as_rotvec()
    axes = mounting.axes(rot[0])
    axis, width, normal = axes
    g = np.asarray(gravity, dtype=float)
    h = float(numerics.dt)
    n_steps = int(round(duration / h))
    every = max(1, int(round(TICK / h)))
    k_rows = n_steps // every + 1
    t_rec = np.arange(k_rows) * TICK
    src = np.clip(np.searchsorted(rec.t, t_rec - 1e-9), 0, len(rec.t) - 1)  # recording rows of the record times
    q_ref = low_passed_q(ref, numerics)[src]
    jac = panda.jacobians(q_ref)  # (k, 6, 7) of the flange origin (the clamp: offset 0 or a rigid point)
    mass = mass_matrices(panda, q_ref)
    if mounting.clamp_mass:  # the clamp payload is rigid on the flange: part of the arm's inertia
        mass = mass + mounting.clamp_mass * np.einsum("kij,kil->kjl", jac[:, :3], jac[:, :3])
    payload = (payload_torques(panda, q_ref, 1.0 / TICK, mounting, mounting.clamp_mass, gravity)
               if mounting.clamp_mass else np.zeros((k_rows, N_JOINTS)))
    sub = strip_torque_real(rec, estimate)[src] if drive == "measured" else np.zeros((k_rows, N_JOINTS))
    lever = clamp[0] - pos[0]  # [m] flange origin -> clamp (rigid; it turns by < 0.5 degrees here)
    if chosen == "planes":
        run = plane_runs(*axes)[0]
        model = plane_model(strip, run, numerics, damping, clamp[0], axis, times, disp, rotvec, g)
        w_strong, added = _strong_plane(strip, numerics, damping, clamp[0], axes, times, disp, rotvec, g, duration,
                                        jac, lever, k_rows)
        mass = mass + added
    else:  # the rectangle in the loop whole: its strong plane's inertia is in its own clamp load
        run = PlaneRun("both", np.eye(3), np.eye(3), np.eye(3), np.eye(3))
        model = rectangle_model(strip, numerics, damping, clamp[0], axes, times, disp, rotvec, g)
        w_strong, added = np.zeros((k_rows, 6)), np.zeros((k_rows, N_JOINTS, N_JOINTS))
    stepper = make_stepper(numerics.integrator, h, NewtonOptions())
    m, plan, smp, x, v, ws = stepped_start(model, solve_static(model).state(), h)
    law = Law(np.zeros(5), np.zeros((2, 3)), np.zeros(0))
    if amplitude_damping:
        from bullet_dlo.reality.beam_law import AmplitudeDamping, first_omega

        law = AmplitudeDamping(m, amplitude_damping, first_omega(strip), damping.get("internal_damping", 0.0), x,
                               smp.dir[0, 0]).law
    force, moment = np.zeros((2, 3)), np.zeros((2, 3))
    end_forces(m, x, v, smp.dir[0], smp.acc[0], force)
    clamp_moments(m, x, v, smp.dir[0], moment)
    f0 = run.force @ force[0]
    w0 = np.concatenate([f0, run.moment @ moment[0] + np.cross(lever, f0)])  # the stepped run's wrench at rest
    recs = LoopRecords(np.zeros((k_rows, 6)), np.zeros((k_rows, N_JOINTS)), np.zeros((k_rows, N_JOINTS)),
                       np.zeros((k_rows, 3)), np.zeros(3))
    recs.w[0], recs.tip[0] = w0, x[-1]
    arm = ArmLoop(mass, impedance, h).arm
    tau_strong = external_torques(jac, w_strong) - external_torques(jac[0], w_strong[0])  # (k, 7), prescribed
    coupling = Coupling(np.ascontiguousarray(jac), tau_strong + payload - sub, run.translate, run.rotate, run.force,
                        run.moment, np.asarray(lever, dtype=float), external_torques(jac[0], w0), TICK)
    run_arm_loop(stepper, m, plan, smp, x, v, ws, arm, coupling, law, recs, n_steps, every)
    status, failures, t_stop = int(recs.out[0]), int(recs.out[1]), float(recs.out[2])
    if status == STRIP_UNSTABLE:
        raise ParameterError(f"the {chosen} strip on the compliant arm went unstable at t = {t_stop:.4g} s; "
                             "use a smaller --dt")
    if status == ARM_UNSTABLE:
        raise ParameterError(f"the arm-strip loop went unstable at t = {t_stop:.4g} s (arm deviation above "
                             f"{MAX_DEVIATION} rad); use a smaller --dt")
    w_rec, dev_rec, acc_rec, tip = recs.w, recs.dev, recs.acc, recs.tip
    w_rec = w_rec + w_strong
    keep = min(k_rows, int(np.searchsorted(rec.t, t_rec[-1] + 1e-9)))  # as predict_torques: the recording's rows
    t_rec, w_rec, dev_rec, acc_rec, tip, jac, payload, added = (
        a[:keep] for a in (t_rec, w_rec, dev_rec, acc_rec, tip, jac, payload, added))
    tau = external_torques(jac, w_rec)
    # plus the planes' rigid strong plane's inertia against the deviation (in the arm's mass matrix in the loop)
    tau = tau - tau[0] + payload + np.einsum("kij,kj->ki", added, acc_rec)
    filtered = estimate.apply(tau, 1.0 / TICK)
    warnings += [] if not failures else [f"Newton did not converge in {failures} strip steps"]
    moment = w_rec[:, 3:] - np.cross(lever, w_rec[:, :3])
    return Prediction(t=t_rec, force=w_rec[:, :3].copy(), moment=moment, wrench=w_rec, torques=tau,
                      torques_filtered=filtered, cpu_s=time.thread_time() - tic, simulated_s=float(t_rec[-1]),
                      warnings=warnings, tip=tip, arm_deviation=dev_rec, strip_model=chosen, strip_reason=reason)


def _strong_plane(strip: Strip, numerics: Numerics, damping: dict[str, float], clamp0: np.ndarray,
                  axes: tuple[np.ndarray, np.ndarray, np.ndarray], times: np.ndarray, disp: np.ndarray,
                  rotvec: np.ndarray, gravity: np.ndarray, duration: float, jac: np.ndarray, lever: np.ndarray,
                  k_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The planes' strong plane as a rigid part of the arm (E I 6400x the weak one, first mode near 240 Hz): its
    wrench on the flange [N, N m] along the reference path, (k, 6), from a prescribed run, and its rigid inertia
    against the arm's deviation [kg m^2], (k, 7, 7) (translation along the width, rotation about the normal).
    Stepped in the loop, the planes' strong run rang the loop at 200 Hz through its one-step lag."""
    axis, width, normal = axes
    _, strong_run = plane_runs(*axes)
    strong = run_plane(strip, strong_run, numerics, damping, clamp0, axis, times, disp, rotvec, gravity, duration)
    f_s = strong.force[:k_rows] @ strong_run.force.T
    w_strong = np.hstack([f_s, strong.moment[:k_rows] @ strong_run.moment.T + np.cross(lever, f_s)])
    if len(w_strong) < k_rows:
        w_strong = np.vstack([w_strong, np.repeat(w_strong[-1:], k_rows - len(w_strong), axis=0)])
    sigma = float(np.cross(normal, axis) @ width)
    m_s, length = strip.mass, strip.length
    rigid = np.array([[m_s, sigma * m_s * length / 2], [sigma * m_s * length / 2, m_s * length**2 / 3]])
    j_s = np.stack([np.einsum("i,kij->kj", width, jac[:, :3]), np.einsum("i,kij->kj", normal, jac[:, 3:])], axis=1)
    return w_strong, np.einsum("kai,ab,kbj->kij", j_s, rigid, j_s)


__all__ = ["ARM_MODES", "ArmImpedance", "identify_arm", "strip_torque_real", "ArmLoop", "predict_torques_compliant",
           "check_arm_mode"]
