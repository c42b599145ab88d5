"""The beam_handling strip's damping law, measured from the recordings alone (issue 21).

Per recording, the decay envelope of the most affected joint's residual vibration
(:func:`bullet_dlo.reality.vibration.envelope`: sines at the measured frequency over windows of two cycles, one
cycle apart, from end + 1 s to the recording's end) is fitted with each damping law of
:data:`~bullet_dlo.reality.vibration.DECAY_LAWS` (zeta constant, zeta0 + c A, zeta0 + b / A, zeta_ref (A/A_ref)^p;
:func:`~bullet_dlo.reality.vibration.fit_decay_law`), first per file in N m, then across files in the strip's tip
amplitude [m], with the law's parameters shared and each file's initial amplitude free.

**Torque to tip amplitude, without a simulation** (:func:`torque_per_tip`). In its first clamped-free mode
(Euler-Bernoulli, beta L = 1.8751, mode shape phi normalised to 1 at the tip) a strip of mass m' per length
vibrating at omega with tip amplitude A loads the clamp, by d'Alembert, with the force m' omega^2 A int phi dx along
the strip's normal and the moment m' omega^2 A int x phi dx about its width axis; the joint torques are
J(q)^T of that wrench at the rest pose after the motion, through Franka's estimate filter's gain at the measured
frequency. The arm's compliance (1-2 % on the frequency) and gravity are left out of this scale: a few per cent.

**The law in the model** (:class:`AmplitudeDamping`, ``validate beam --amplitude-damping``). The recordings ask for
zeta = zeta0 + c A (``demos/beam_damping_law.py``; docs/guides/validate.md, "The damping law, measured"): the damping
grows with the amplitude. Quadratic air drag on the strip's face gives that law
(:func:`~bullet_dlo.reality.vibration.drag_damping_ratio`, :func:`law_drag_coefficient`: C_d 15-18), and so would
micro-slip in the clamp (friction energy per cycle ~ A^3); the decays cannot tell them apart. The core's drag acts on
the strip's velocity through the air, so a C_d measured on a small oscillation would also brake the strip's 1 m/s
translation during the motion, where a plate's C_d is about 2. The law therefore enters as a damping of the strip's
deformation only, with an existing parameter: the weak-plane run's Kelvin-Voigt bending dampers (``internal_damping``
tau; first-mode zeta = omega_1 tau / 2) set each step from the current tip amplitude, in the stepped arm-strip loop
(:func:`bullet_dlo.reality.beam_arm.predict_torques_compliant`). The linear share zeta0 stays with ``damping_rate``,
fitted with the law held. On held-out motions it does not improve the goals' counts (docs): off by default.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from bullet_dlo.reality.beam import BeamRecording, EstimateFilter, Mounting, Strip, stepped_start
from bullet_dlo.reality.panda import Panda
from bullet_dlo.reality.vibration import (
    DECAY_LAWS,
    DecayLaw,
    best_decay_law,
    drag_damping_ratio,
    envelope,
    fit_decay_law,
    local_damping,
)

BETA_L = 1.8751040687119611  # first root of 1 + cos(x) cosh(x) = 0 (clamped-free)
ENVELOPE_START = 1.0  # [s] after the motion's end: the first envelope window (the sine window starts there)


def mode_integrals(samples: int = 2001) -> tuple[float, float]:
    """(int_0^L phi dx / L, int_0^L x phi dx / L^2) [-] of the first clamped-free mode phi normalised to 1 at the
    tip (trapezoid rule on ``samples`` points; 0.3915 and 0.2844)."""
    x = np.linspace(0.0, 1.0, samples) * BETA_L
    sigma = (math.cosh(BETA_L) + math.cos(BETA_L)) / (math.sinh(BETA_L) + math.sin(BETA_L))
    phi = np.cosh(x) - np.cos(x) - sigma * (np.sinh(x) - np.sin(x))
    phi = phi / phi[-1]
    s = x / BETA_L
    return float(np.trapezoid(phi, s)), float(np.trapezoid(s * phi, s))


def modal_wrench_per_tip(strip: Strip, frequency_hz: float, axis: np.ndarray, width: np.ndarray,
                         normal: np.ndarray) -> np.ndarray:
    """The wrench [N, N m per m of tip amplitude], (6,), that the strip's first weak-plane mode at ``frequency_hz``
    [Hz] puts on its clamp (force along ``normal``, moment about the clamp: axis x normal), module doc; world axes
    (axis: clamp -> tip, unit vectors)."""
    i0, i1 = mode_integrals()
    m_per_l = strip.mass / strip.length
    w2 = (2 * math.pi * frequency_hz) ** 2
    force = m_per_l * w2 * i0 * strip.length * np.asarray(normal, float)
    moment = m_per_l * w2 * i1 * strip.length**2 * np.cross(axis, normal)
    return np.r_[force, moment]


def torque_per_tip(panda: Panda, q: np.ndarray, strip: Strip, frequency_hz: float,
                   estimate: EstimateFilter = EstimateFilter(), mounting: Mounting = Mounting()) -> np.ndarray:
    """Amplitude of Franka's external-torque estimate per tip amplitude of the first mode [N m / m], (7,), at joint
    angles q [rad] (7,): |J(q)^T w| of :func:`modal_wrench_per_tip` about the flange origin, times the estimate
    filter's gain at ``frequency_hz`` [Hz]."""
    pos, rot = panda.flange_pose(q)
    axis, width, normal = mounting.axes(rot)
    w = modal_wrench_per_tip(strip, frequency_hz, axis, width, normal)
    arm = mounting.clamp_point(pos, rot) - pos
    w = np.r_[w[:3], w[3:] + np.cross(arm, w[:3])]
    return np.abs(panda.jacobian(q).T @ w) * abs(estimate.response(frequency_hz))


@dataclass(frozen=True)
class FileDecay:
    """One recording's decay: name, joint, damped frequency [Hz], envelope times [s after the motion's end],
    amplitudes [N m] and residual RMS [N m], the torque per tip amplitude [N m / m], the per-file law fits (N m)
    and the local damping ratios [(tip amplitude [m], zeta)]."""

    name: str
    joint: int
    frequency_hz: float
    times: np.ndarray
    torque_amplitude: np.ndarray
    residual_rms: np.ndarray
    torque_per_tip: float
    fits: dict[str, DecayLaw]
    local: list[tuple[float, float]]

    @property
    def omega(self) -> float:
        return 2 * math.pi * self.frequency_hz

    @property
    def tip_amplitude(self) -> np.ndarray:
        """[m]"""
        return self.torque_amplitude / self.torque_per_tip

    def summary(self) -> dict[str, Any]:
        """The compact JSON entry: the law the envelope asks for, the drag law in tip amplitude (zeta0 [-], c [1/m]),
        each law's relative misfit, the power law's exponent and the tip amplitudes covered [m]."""
        drag = self.fits["drag"].params
        return {"best_law": best_decay_law(self.fits), "zeta0": drag["zeta0"], "c_per_m": drag["c"] * self.torque_per_tip,
                "power_exponent": self.fits["power"].params["p"],
                "rms_log": {k: v.rms_log for k, v in self.fits.items()},
                "tip_amplitude_m": [float(self.tip_amplitude[0]), float(self.tip_amplitude[-1])],
                "torque_per_tip": self.torque_per_tip, "joint": self.joint}

    def to_dict(self) -> dict[str, Any]:
        return {"joint": self.joint, "frequency_hz": self.frequency_hz,
                "torque_amplitude_first_last": [float(self.torque_amplitude[0]), float(self.torque_amplitude[-1])],
                "tip_amplitude_first_last_m": [float(self.tip_amplitude[0]), float(self.tip_amplitude[-1])],
                "torque_per_tip": self.torque_per_tip, "best_law": best_decay_law(self.fits),
                "fits_torque_units": {k: v.to_dict() for k, v in self.fits.items()},
                "local_damping": [{"tip_amplitude_m": a, "damping_ratio": z} for a, z in self.local]}


def file_decay(rec: BeamRecording, panda: Panda, strip: Strip = Strip(), estimate: EstimateFilter = EstimateFilter(),
               mounting: Mounting = Mounting(), start: float = ENVELOPE_START) -> FileDecay:
    """The decay envelope of ``rec``'s most affected joint from ``start`` s after the motion and every law fitted
    to it (module doc)."""
    from bullet_dlo.reality.beam_validate import measure

    m = measure(rec)
    f = m.vibration.frequency_hz
    times, amps, rms = envelope(rec.t, m.dev[:, m.joint], m.t_end, f, start=start)
    rest = rec.q[min(m.end + int(round(start * rec.rate)), len(rec.q) - 1)]
    scale = float(torque_per_tip(panda, rest, strip, f, estimate, mounting)[m.joint])
    fits = {law: fit_decay_law([(times, amps, 2 * math.pi * f)], law) for law in DECAY_LAWS}
    local = [(a / scale, z) for a, z in local_damping(times, amps, 2 * math.pi * f)]
    return FileDecay(rec.name, m.joint, f, times, amps, rms, scale, fits, local)


def shared_laws(decays: list[FileDecay]) -> dict[str, DecayLaw]:
    """Every law fitted across ``decays`` in tip amplitude [m]: parameters shared, each file's initial amplitude
    free."""
    series = [(d.times, d.tip_amplitude, d.omega) for d in decays]
    return {law: fit_decay_law(series, law) for law in DECAY_LAWS}


def measured_law(recs: list[BeamRecording], panda: Panda, strip: Strip = Strip(),
                 estimate: EstimateFilter = EstimateFilter(), mounting: Mounting = Mounting()) -> dict[str, Any]:
    """The damping law of ``recs`` from their decays alone (module doc), JSON-ready: per file
    (:meth:`FileDecay.summary`), every law fitted across them in tip amplitude [m] (``shared``), the law they ask for
    and the face-drag coefficient of the shared drag law's slope."""
    decays = [file_decay(r, panda, strip, estimate, mounting) for r in recs]
    shared = shared_laws(decays)
    return {"per_file": {d.name: d.summary() for d in decays},
            "shared": {k: v.to_dict() for k, v in shared.items()},
            "best_law": best_decay_law(shared),
            "drag_coefficient_equivalent": law_drag_coefficient(shared["drag"], strip),
            "what": "decay envelope of the most affected joint (sines at the measured frequency over 2-cycle windows "
                    f"from end + {ENVELOPE_START} s to the recording's end), laws zeta0 / zeta0 + c A / zeta0 + b / A / "
                    "zeta_ref (A/A_ref)^p fitted on ln A; A the tip amplitude from the first mode's clamp load "
                    "through J^T and the estimate filter (no model run)"}


def law_drag_coefficient(law: DecayLaw, strip: Strip = Strip()) -> float:
    """The face-drag coefficient C_d [-] whose modal damping ratio has the slope of a ``drag`` law fitted in tip
    amplitude [m] (zeta = zeta0 + c A: C_d = c / :func:`~bullet_dlo.reality.vibration.drag_damping_ratio` per unit
    C_d and amplitude)."""
    if law.law != "drag":
        raise ValueError(f"law_drag_coefficient needs a 'drag' law, got {law.law!r}")
    return law.params["c"] / drag_damping_ratio(1.0, 1.0, strip)


def law_window_ratio(law: DecayLaw, decay: FileDecay) -> float:
    """The damping ratio [-] that the issue's metric (a damped sine fitted over end + 1-6 s,
    :func:`~bullet_dlo.reality.vibration.fit_damped_sine`) would measure on a decay following ``law`` (fitted in tip
    amplitude [m]) from the file's first envelope amplitude: what the law says that file's damping ratio is."""
    from bullet_dlo.reality.vibration import SINE_WINDOW, decay_model, fit_damped_sine

    t = np.arange(SINE_WINDOW[0], SINE_WINDOW[1], 1e-3)
    params = dict(law.params)
    a0 = float(decay.tip_amplitude[0])
    amp = decay_model(law.law, params, a0, t - decay.times[0], decay.omega)
    return fit_damped_sine(t, amp * np.sin(decay.omega * t))[1]


# ----- the law in the model: amplitude-dependent Kelvin-Voigt damping of the strip's bending ------------------------
AMPLITUDE_DAMPING_MAX = 10.0  # [1/m] the largest slope c the model takes (zeta 0.1 at a 1 cm tip amplitude)
SMOOTHING_PERIODS = 0.5  # the amplitude estimate's low-pass time constant, in first-mode periods


def first_omega(strip: Strip) -> float:
    """The strip's first weak-plane bending frequency [rad/s] as an Euler-Bernoulli cantilever,
    beta_1^2 sqrt(E I_weak / (rho A)), beta_1 L = 1.8751 (gravity left out: 18.7 rad/s nominal)."""
    area = strip.width * strip.thickness
    return BETA_L**2 / strip.length**2 * math.sqrt(strip.youngs_modulus * strip.second_moment("weak")
                                                   / (strip.density * area))


class AmplitudeDamping:
    """The measured law zeta = zeta0 + c A in a stepped strip run (module doc): the bending dampers' rate
    tau(A) = tau0 + 2 c A / omega_1 [s] (Kelvin-Voigt: the first mode's damping ratio is omega_1 tau / 2), A [m] the
    current tip amplitude of the strip's vibration relative to its clamp. The linear part zeta0 stays with the model's
    own parameters (``damping_rate``, ``internal_damping`` tau0). It acts on the strip's deformation only, not on its
    motion through the air with the clamp.

    A is estimated each step from the tip's deflection e from the clamp's tangent line, minus the deflection at rest
    (the sag), and its rate: A = sqrt(|e|^2 + |de/dt|^2 / omega_1^2) (exact for the first mode alone), low-passed
    over :data:`SMOOTHING_PERIODS` periods (the higher modes' share then averages out). ``m``: the kernel arrays of the
    run (their ``c_bend`` is written: it must be the run's own copy, as :meth:`CableModel.control` makes it).
    """

    def __init__(self, m, slope: float, omega: float, tau0: float, x: np.ndarray, direction: np.ndarray) -> None:
        from bullet_dlo.core.validate import ParameterError
        from bullet_dlo.reality.arm_loop import Law

        if not (math.isfinite(slope) and 0.0 <= slope <= AMPLITUDE_DAMPING_MAX):
            raise ParameterError(f"amplitude_damping must be in [0, {AMPLITUDE_DAMPING_MAX:g}] 1/m, got {slope}")
        self.m = m
        d = np.asarray(direction, dtype=float)
        d = d / np.linalg.norm(d)
        r = x[-1] - x[0]
        rest = r - (r @ d) * d  # the tip's deflection from the clamp's tangent line at rest (the sag) [m]
        # the state the compiled step carries (arm_loop.law_update); the strip starts at rest: amplitude 0
        self.law = Law(np.array([slope, omega, tau0, 0.0, SMOOTHING_PERIODS], dtype=float), np.stack([rest, rest]),
                       np.array(m.k_bend, dtype=float))

    @property
    def amplitude(self) -> float:
        """The current amplitude estimate [m]."""
        return float(self.law.par[3])

    def update(self, x: np.ndarray, direction: np.ndarray, h: float) -> float:
        """After a step of h [s] to positions x [m] (n, 3) with the clamp's tangent ``direction``: new amplitude
        estimate, new dampers (in ``m.c_bend``) for the next step. Returns the amplitude [m]."""
        from bullet_dlo.reality.arm_loop import law_update

        law_update(self.law, self.m, np.ascontiguousarray(x, dtype=float),
                   np.ascontiguousarray(direction, dtype=float), float(h))
        return self.amplitude


def law_free_decay(strip: Strip, slope: float, n_masses: int = 12, dt: float = 1e-3, duration: float = 6.0,
                   integrator: str = "bdf2", damping: dict[str, float] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The weak-plane cantilever (the planes strip's weak run, horizontal, weightless) released from its sag under
    1 g, stepped with :class:`AmplitudeDamping` of ``slope`` c [1/m]: times [s], the vertical clamp force [N] and
    the law's amplitude estimate [m] per step. Its decay follows zeta = c A (plus the integrator's and ``damping``'s
    linear share): the check that the model carries the measured law (``tests/reality/test_beam_law.py``)."""
    from bullet_dlo.core.integrators import NewtonOptions, make_stepper
    from bullet_dlo.core.kernels.holders import sample_holders
    from bullet_dlo.core.kernels.monitor import end_forces
    from bullet_dlo.core.kernels.steppers import advance
    from bullet_dlo.core.model import CableModel
    from bullet_dlo.core.statics import solve_static

    damping = dict(damping or {})
    spec = strip.cable_spec("weak", n_masses, **damping)
    axis = np.array([1.0, 0.0, 0.0])
    sagged = CableModel.straight(spec, start=(0, 0, 0), direction=axis, ends=("clamped", "free"),
                                 gravity=(0, 0, -9.81))
    model = CableModel.straight(spec, start=(0, 0, 0), direction=axis, ends=("clamped", "free"), gravity=(0, 0, 0))
    m, plan, smp, x, v, ws = stepped_start(model, solve_static(sagged).state(), dt)
    law = AmplitudeDamping(m, slope, first_omega(strip), damping.get("internal_damping", 0.0), model.x0,
                           smp.dir[0, 0])
    stepper = make_stepper(integrator, dt, NewtonOptions())
    steps = int(round(duration / dt))
    force = np.zeros((2, 3))
    t, fz, amp = np.arange(1, steps + 1) * dt, np.zeros(steps), np.zeros(steps)
    for i in range(steps):
        sample_holders(plan, i * dt, dt, smp)
        advance(stepper, m, x, v, smp, ws, i > 0)
        end_forces(m, x, v, smp.dir[2], smp.acc[2], force)
        fz[i] = force[0, 2]
        amp[i] = law.update(x, smp.dir[2, 0], dt)
    return t, fz, amp
