"""Residual-vibration metrics of a joint-torque signal after a rest-to-rest motion (issue 21).

All times in seconds, torques in N m, frequencies in Hz. Given a sampled signal y(t):

* the motion ends at the first sample after the last one where any |dq_d| >= 1e-4 rad/s
  (:func:`motion_span`);
* the signal studied is the deviation of the external torque from its mean at rest before the
  motion starts (:func:`deviation`);
* frequency and damping ratio: a damped sine A exp(-zeta omega_n t) sin(omega_d t + phi) + c
  least-squares fitted over [end + 1 s, end + 6 s]; ``frequency_hz`` is the damped frequency
  omega_d / (2 pi) (it differs from omega_n / (2 pi) by a factor sqrt(1 - zeta^2), 1 - 2e-4 at
  zeta = 0.02);
* ``p2p_torque``: peak-to-peak of the 1.5-8 Hz band (4th-order Butterworth, zero phase, over
  the whole signal) over [end + 1 s, end + 2 s];
* ``sine_amplitude``: the amplitude at end + 1.5 s of a sine at the signal's fitted frequency (and decay),
  least-squares fitted over the same [end + 1 s, end + 2 s] with a constant and a linear trend
  (:func:`sine_amplitude`): the level of the mode alone. Content in the band at other frequencies (the arm
  settling, Franka's model errors) adds to the peak-to-peak but is nearly orthogonal to the sine over the
  window's three cycles, so it barely moves this one.

The damping law (how zeta depends on the amplitude): :func:`envelope` (sines at the mode's frequency over windows of
a few cycles), :func:`fit_decay_law` (closed-form decays of dA/dt = -zeta(A) omega A for :data:`DECAY_LAWS`: viscous,
drag zeta0 + c A, friction zeta0 + b / A, power zeta_ref (A/A_ref)^p, fitted on ln A, one envelope or several with
the law shared), :func:`best_decay_law` (Akaike criterion and effect size) and :func:`local_damping` (zeta over
successive spans).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt

REST_SPEED = 1e-4  # [rad/s]: |dq_d| below it on every joint is rest
SINE_WINDOW = (1.0, 6.0)  # [s] after the motion's end
P2P_WINDOW = (1.0, 2.0)  # [s] after the motion's end
BAND = (1.5, 8.0)  # [Hz]


@dataclass(frozen=True)
class Vibration:
    """Metrics of one signal: frequency_hz [Hz] (damped), damping_ratio [-], p2p_torque [N m],
    amplitude [N m] (the damped sine's amplitude at end + 1 s, fitted over 1-6 s), fit_rms [N m] (residual of
    that fit), sine_amplitude [N m] (:func:`sine_amplitude` over the p2p window, at its centre)."""

    frequency_hz: float
    damping_ratio: float
    p2p_torque: float
    amplitude: float
    fit_rms: float
    sine_amplitude: float = float("nan")

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def motion_span(dq_d: np.ndarray, threshold: float = REST_SPEED) -> tuple[int, int]:
    """Indices (start, end) of a rest-to-rest motion in desired joint rates dq_d [rad/s], (k, 7):
    start = the first sample where any |dq_d| >= threshold, end = one past the last such sample.
    Raises ValueError when the desired rates never leave rest."""
    moving = np.any(np.abs(dq_d) >= threshold, axis=1)
    if not moving.any():
        raise ValueError(f"the desired joint rates never exceed {threshold} rad/s: no motion to end")
    idx = np.flatnonzero(moving)
    return int(idx[0]), int(idx[-1]) + 1


def deviation(y: np.ndarray, start: int) -> np.ndarray:
    """``y`` (k, ...) minus its mean over the samples before ``start`` (at least one)."""
    return y - np.mean(y[:max(start, 1)], axis=0)


def band(y: np.ndarray, rate: float, low: float = BAND[0], high: float = BAND[1]) -> np.ndarray:
    """Zero-phase 4th-order Butterworth band-pass [low, high] Hz of y (k,) sampled at ``rate`` [Hz]."""
    sos = butter(4, [low, high], btype="bandpass", fs=rate, output="sos")
    return sosfiltfilt(sos, y)


def window(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """Boolean mask of times t [s] in [t0, t1]."""
    return (t >= t0) & (t <= t1)


def fit_damped_sine(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares fit of A exp(-zeta omega_n (t - t0)) sin(omega_d (t - t0) + phi) + c to y(t).

    Returns (damped frequency [Hz], damping ratio [-], amplitude A at t0 [units of y], residual
    RMS); t0 = t[0]. Start values: the spectral peak (zero-padded FFT) and the ratio of the RMS in
    the first and last quarter of the window.
    """
    s = t - t[0]
    y0 = y - y.mean()
    n_fft = 1 << int(np.ceil(np.log2(len(y) * 8)))
    spec = np.abs(np.fft.rfft(y0 * np.hanning(len(y)), n_fft))
    freqs = np.fft.rfftfreq(n_fft, s[1] - s[0])
    spec[freqs < 0.5] = 0.0
    f0 = freqs[np.argmax(spec)]
    q = len(y) // 4
    rms_a, rms_b = np.std(y0[:q]), np.std(y0[-q:]) + 1e-30
    sigma0 = max(np.log(max(rms_a / rms_b, 1.0 + 1e-6)) / (s[-q // 2] - s[q // 2]), 1e-3)
    amp0 = np.sqrt(2.0) * rms_a * np.exp(sigma0 * s[q // 2])

    def model(p: np.ndarray) -> np.ndarray:
        amp, sigma, omega, phi, c = p
        return amp * np.exp(-sigma * s) * np.sin(omega * s + phi) + c

    best = None
    for phi0 in np.linspace(0.0, 2 * np.pi, 4, endpoint=False):  # the phase is the one multimodal unknown
        sol = least_squares(lambda p: model(p) - y, [amp0, sigma0, 2 * np.pi * f0, phi0, y.mean()],
                            x_scale=[amp0 + 1e-12, sigma0, 2 * np.pi * f0, 1.0, amp0 + 1e-12])
        if best is None or sol.cost < best.cost:
            best = sol
    amp, sigma, omega, _, _ = best.x
    if amp < 0:
        amp = -amp
    omega_n = np.hypot(omega, sigma)
    rms = float(np.sqrt(np.mean(best.fun**2)))
    return float(abs(omega) / (2 * np.pi)), float(sigma / omega_n), float(amp), rms


def sine_amplitude(t: np.ndarray, y: np.ndarray, frequency_hz: float, damping_ratio: float = 0.0) -> float:
    """Amplitude [units of y] at the centre of t of the sine at ``frequency_hz`` [Hz] (damped frequency) decaying
    at ``damping_ratio`` [-], least-squares fitted to y(t) with a constant and a linear trend.

    The model y ~ exp(-sigma s) (a sin(omega_d s) + b cos(omega_d s)) + c + d s, s = t - centre, is linear in
    (a, b, c, d) once the frequency and the decay sigma = zeta omega_d / sqrt(1 - zeta^2) are given, so the fit
    is one linear solve; the amplitude is hypot(a, b). A component at another frequency f2 and amplitude B moves
    it by about B |sin(pi dF T) / (pi dF T)| <= B / (pi dF T) (dF = |f2 - f|, T the window [s]: over 1 s at most
    0.22 B for dF >= 1 Hz and 0.05 B at dF 2.1 Hz), where a peak-to-peak takes up to its whole 2 B; broadband noise
    of RMS sigma adds about sigma sqrt(2 / samples). With zeta = 0 it is the window's mean amplitude (within (sigma T)^2 / 24 of
    the centre's). Needs at least 8 samples and at least half a period in the window."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if not (np.isfinite(frequency_hz) and frequency_hz > 0 and 0.0 <= damping_ratio < 1.0):
        raise ValueError(f"frequency_hz must be > 0 and damping_ratio in [0, 1), got {frequency_hz}, {damping_ratio}")
    if len(t) < 8 or (t[-1] - t[0]) * frequency_hz < 0.5:
        raise ValueError(f"the window holds {len(t)} samples over {t[-1] - t[0] if len(t) else 0:.3g} s: the sine "
                         f"fit needs at least 8 samples and half a period ({0.5 / frequency_hz:.3g} s)")
    s = t - 0.5 * (t[0] + t[-1])
    omega_d = 2 * np.pi * frequency_hz
    envelope = np.exp(-damping_ratio * omega_d / np.sqrt(1.0 - damping_ratio**2) * s)
    basis = np.stack([envelope * np.sin(omega_d * s), envelope * np.cos(omega_d * s), np.ones_like(s), s], axis=1)
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return float(np.hypot(coef[0], coef[1]))


def residual_vibration(t: np.ndarray, y: np.ndarray, t_end: float) -> Vibration:
    """The metrics of the module doc for a torque deviation y [N m] (k,) at times t [s] (uniform),
    the motion having ended at ``t_end`` [s]."""
    rate = 1.0 / float(np.median(np.diff(t)))
    w = window(t, t_end + SINE_WINDOW[0], t_end + SINE_WINDOW[1])
    if w.sum() < 50:
        raise ValueError(f"less than 50 samples in [end + {SINE_WINDOW[0]}, end + {SINE_WINDOW[1]}] s")
    f, zeta, amp, rms = fit_damped_sine(t[w], y[w])
    b = band(y, rate)
    level = window(t, t_end + P2P_WINDOW[0], t_end + P2P_WINDOW[1])
    p2p = float(np.ptp(b[level]))
    # the mode's level over the p2p window: its own frequency and decay from the 1-6 s fit (a negative fitted
    # decay, a growing signal, is taken as none: the window's mean amplitude)
    sine = sine_amplitude(t[level], y[level], f, min(max(zeta, 0.0), 0.5))
    return Vibration(frequency_hz=f, damping_ratio=zeta, p2p_torque=p2p, amplitude=amp, fit_rms=rms,
                     sine_amplitude=sine)


def most_affected_joint(t: np.ndarray, dev: np.ndarray, t_end: float) -> int:
    """The joint whose 1.5-8 Hz band of the torque deviation dev [N m], (k, 7), has the largest
    peak-to-peak over [end + 1 s, end + 2 s]."""
    rate = 1.0 / float(np.median(np.diff(t)))
    w = window(t, t_end + P2P_WINDOW[0], t_end + P2P_WINDOW[1])
    return int(np.argmax([np.ptp(band(dev[:, j], rate)[w]) for j in range(dev.shape[1])]))


def damping_by_amplitude(t: np.ndarray, y: np.ndarray, t_end: float, spans: tuple[tuple[float, float], ...] = (
        (1.0, 3.0), (3.0, 6.0), (6.0, 9.0))) -> list[dict[str, float]]:
    """Damping ratio of damped sines fitted over successive windows after ``t_end`` [s] (default
    [1, 3], [3, 6], [6, 9] s), with the fitted amplitude at each window's start [N m]: the damping's
    amplitude dependence. Windows running past the signal, or too short, are left out."""
    rows = []
    for a, b in spans:
        w = window(t, t_end + a, t_end + b)
        if w.sum() < 200 or t[-1] < t_end + b - 0.01:
            continue
        f, zeta, amp, _ = fit_damped_sine(t[w], y[w])
        rows.append({"from_s": a, "to_s": b, "frequency_hz": f, "damping_ratio": zeta, "amplitude": amp})
    return rows


# ----- air drag on a strip vibrating broadside ------------------------------------------------------
RHO_AIR = 1.2  # [kg/m^3]
# kappa = int |phi|^3 / int phi^2 over the first clamped-free mode phi normalised to 1 at the tip
# (Euler-Bernoulli, beta L = 1.8751): 0.1847 L / 0.2500 L
MODE_DRAG_SHAPE = 0.7389


def drag_damping_ratio(drag_coefficient: float, tip_amplitude: float, strip, rho_air: float = RHO_AIR) -> float:
    """Equivalent damping ratio [-] of the first mode of a clamped-free strip under quadratic air drag on
    its face, f = -1/2 rho_air C_d w |v| v per length [N/m] (v the face-normal velocity), at tip amplitude A [m].

    Projected on the tip-normalised mode phi, the modal equation is q'' + c |q'| q' + omega^2 q = 0 with
    c = rho_air C_d kappa / (2 rho_s t) [1/m] (w cancels; kappa = :data:`MODE_DRAG_SHAPE`). The energy
    lost per cycle, c (8/3) omega^2 A^3 per unit modal mass, over 4 pi times the energy omega^2 A^2 / 2,
    gives zeta = 4 c A / (3 pi) = 2 rho_air C_d kappa A / (3 pi rho_s t): linear in the amplitude, so the
    amplitude decays as 1/A(t) = 1/A0 + zeta(A) omega t / A. ``strip``: anything with ``density``
    [kg/m^3] and ``thickness`` [m] (e.g. :class:`bullet_dlo.reality.beam.Strip`).
    """
    return 2 * rho_air * drag_coefficient * MODE_DRAG_SHAPE * tip_amplitude / (3 * np.pi * strip.density
                                                                                * strip.thickness)


# ----- what a rest-to-rest motion leaves in a mode ---------------------------------------------------
# First clamped-free bending mode (Euler-Bernoulli, beta L = 1.8751): int x phi dx / int phi dx = 0.7264 L.
# The mode is forced by the base's translation plus its rotation times that lever, so the motion of the
# strip-axis point 0.7264 L from the clamp, normal to the strip, is the mode's whole forcing.
MODE_FORCING_LEVER = 0.7264


def residual_excitation(t: np.ndarray, x: np.ndarray, t_end: float, frequency_hz: float,
                        damping_ratio: float = 0.0) -> float:
    """Amplitude [units of x] that a base motion x(t) leaves in an oscillator
    u'' + 2 zeta omega u' + omega^2 u = -x'' at the end ``t_end`` [s] of the motion.

    x [m] (k,) at times t [s] (uniform) starts at rest (x' = 0); omega = 2 pi ``frequency_hz`` [Hz] is the
    undamped frequency, zeta = ``damping_ratio`` [-] acts during the motion. Duhamel's integral gives the free
    vibration's amplitude after T as |int_0^T x''(s) exp((-zeta omega + i omega_d) (T - s)) ds| / omega_d,
    omega_d = omega sqrt(1 - zeta^2); for zeta = 0 this is the Fourier transform of the
    base acceleration at omega over omega (zero for a motion that cancels the mode). x'' by finite differences
    of x (so x should be smooth: a low-passed path). For a strip's first mode, x is the normal motion of the
    point ``MODE_FORCING_LEVER`` L along the strip from its clamp (translation plus rotation's lever).
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if not (frequency_hz > 0 and 0.0 <= damping_ratio < 1.0):
        raise ValueError(f"frequency_hz must be > 0 and damping_ratio in [0, 1), got {frequency_hz}, {damping_ratio}")
    keep = t <= t_end + 1e-12
    t, x = t[keep], x[keep]
    a = np.gradient(np.gradient(x, t), t)
    omega = 2 * np.pi * frequency_hz
    omega_d = omega * np.sqrt(1.0 - damping_ratio**2)
    kernel = np.exp((-damping_ratio * omega + 1j * omega_d) * (t[-1] - t))
    return float(abs(np.trapezoid(a * kernel, t)) / omega_d)


# ----- the damping law: how the decay rate depends on the amplitude ---------------------------------
# zeta(A) of the envelope equation dA/dt = -zeta(A) omega A (slowly varying amplitude, one mode):
#   viscous   zeta = zeta0                   (linear damping: A = A0 exp(-zeta0 omega t))
#   drag      zeta = zeta0 + c A             (plus quadratic drag, zeta0 + 4 c' A / (3 pi) for c'|v|v)
#   friction  zeta = zeta0 + b / A           (plus Coulomb friction: A falls by 2 pi b per cycle)
#   power     zeta = zeta_ref (A / A_ref)^p  (p 0 viscous, 1 quadratic, -1 Coulomb; A_ref the data's geometric mean)
DECAY_LAWS = ("viscous", "drag", "friction", "power")
LAW_PARAMETERS = {"viscous": ("zeta0",), "drag": ("zeta0", "c"), "friction": ("zeta0", "b"),
                  "power": ("zeta_ref", "p")}


def envelope(t: np.ndarray, y: np.ndarray, t_end: float, frequency_hz: float, cycles: float = 2.0,
             start: float = 1.0, stop: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The decay envelope of y(t) (one mode at ``frequency_hz`` [Hz]): amplitudes of sines at that frequency
    least-squares fitted with a constant and a linear trend (:func:`sine_amplitude`, no decay) over windows of
    ``cycles`` periods, one period apart, from ``start`` to ``stop`` s after ``t_end`` [s] (default: the signal's
    end). Returns the window centres [s after t_end], the amplitudes [units of y] and the fits' residual RMS
    [units of y] (what is not the mode: noise, other frequencies). Within a window of 2 cycles the decay biases the
    amplitude by (zeta omega T)^2 / 6 relative, 1e-3 at zeta 0.02: negligible."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if not (np.isfinite(frequency_hz) and frequency_hz > 0 and cycles >= 1.0):
        raise ValueError(f"frequency_hz must be > 0 and cycles >= 1, got {frequency_hz}, {cycles}")
    period = 1.0 / frequency_hz
    half = 0.5 * cycles * period
    last = (t[-1] - t_end) if stop is None else min(stop, t[-1] - t_end)
    omega = 2 * np.pi * frequency_hz
    centres, amps, rms = [], [], []
    c = start + half
    while c + half <= last + 1e-12:
        w = window(t, t_end + c - half, t_end + c + half)
        s = t[w] - (t_end + c)
        basis = np.stack([np.sin(omega * s), np.cos(omega * s), np.ones_like(s), s], axis=1)
        coef = np.linalg.lstsq(basis, y[w], rcond=None)[0]
        centres.append(c)
        amps.append(np.hypot(coef[0], coef[1]))
        rms.append(np.sqrt(np.mean((y[w] - basis @ coef) ** 2)))
        c += period
    if len(centres) < 4:
        raise ValueError(f"the envelope needs at least 4 windows of {cycles} cycles between end + {start} s and "
                         f"end + {last:.3g} s, got {len(centres)}")
    return np.array(centres), np.array(amps), np.array(rms)


def local_damping(t: np.ndarray, a: np.ndarray, omega: float, span: int = 3) -> list[tuple[float, float]]:
    """(amplitude, damping ratio) over successive spans of ``span`` + 1 envelope points (t [s], a [any unit]):
    zeta = -(slope of ln a) / omega [rad/s], at the span's geometric-mean amplitude. The model-free picture of
    zeta(A) that :func:`fit_decay_law` condenses."""
    out = []
    for i in range(0, len(t) - span, span):
        sl = slice(i, i + span + 1)
        slope = np.polyfit(t[sl], np.log(a[sl]), 1)[0]
        out.append((float(np.exp(np.mean(np.log(a[sl])))), float(-slope / omega)))
    return out


def decay_model(law: str, params: dict[str, float], a0: float, t: np.ndarray, omega: float) -> np.ndarray:
    """Amplitude a(t) [units of a0] of dA/dt = -zeta(A) omega A from a(0) = a0 under ``law`` (module constants;
    closed forms). ``params`` as :data:`LAW_PARAMETERS` (``power`` also needs ``a_ref``). The friction law's
    amplitude reaches 0 in finite time: held at a0 * 1e-9 from there (the oscillation has stopped)."""
    t = np.asarray(t, dtype=float)
    x = params["zeta0"] * omega * t if "zeta0" in params else None
    if law == "viscous":
        return a0 * np.exp(-x)
    if law == "drag":  # 1/A = (1/a0) e^x + c omega t (e^x - 1) / x
        grow = np.where(x > 1e-12, np.expm1(x) / np.where(x > 1e-12, x, 1.0), 1.0 + 0.5 * x)
        return 1.0 / (np.exp(x) / a0 + params["c"] * omega * t * grow)
    if law == "friction":  # A = a0 e^-x - b omega t (1 - e^-x) / x
        shrink = np.where(x > 1e-12, -np.expm1(-x) / np.where(x > 1e-12, x, 1.0), 1.0 - 0.5 * x)
        return np.maximum(a0 * np.exp(-x) - params["b"] * omega * t * shrink, a0 * 1e-9)
    if law == "power":  # A^-p = a0^-p + p k omega t, k = zeta_ref a_ref^-p; log1p keeps p -> 0 (viscous) exact
        p, k = params["p"], params["zeta_ref"] * params["a_ref"] ** (-params["p"])
        g = k * omega * t * a0**p
        if abs(p) < 1e-9:
            return a0 * np.exp(-g)
        return a0 * np.exp(-np.log1p(np.maximum(p * g, -1.0 + 1e-15)) / p)
    raise ValueError(f"law must be one of {', '.join(DECAY_LAWS)}, got {law!r}")


@dataclass(frozen=True)
class DecayLaw:
    """A damping law fitted to one or more decay envelopes (:func:`fit_decay_law`): ``law`` (:data:`DECAY_LAWS`),
    its shared ``params`` (:data:`LAW_PARAMETERS`; amplitudes in the envelopes' unit), the initial amplitude of each
    envelope, ``rms_log`` [-] (RMS of ln(fitted / measured amplitude): the relative misfit), ``points``, the
    Akaike criterion ``aic`` [-] (n ln(RSS/n) + 2 k: lower is better; the envelope's windows overlap by half, so
    neighbouring points are correlated and a difference needs to be about twice the usual 2-10 to count) and the
    ``amplitude_range`` (min, max) the data cover."""

    law: str
    params: dict[str, float]
    a0: tuple[float, ...]
    rms_log: float
    points: int
    aic: float
    amplitude_range: tuple[float, float] = (math.nan, math.nan)

    def amplitude_share(self) -> float:
        """The largest share [-] of the amplitude-dependent term in zeta over the data's amplitude range (drag: at
        the largest amplitude, friction: at the smallest; power: 1 - the ratio of its ends; viscous: 0)."""
        lo, hi = self.amplitude_range
        p = self.params
        if self.law == "drag":
            return float(p["c"] * hi / (p["zeta0"] + p["c"] * hi)) if p["c"] > 0 else 0.0
        if self.law == "friction":
            return float(p["b"] / lo / (p["zeta0"] + p["b"] / lo)) if p["b"] > 0 else 0.0
        if self.law == "power":
            z = self.damping_ratio(np.array([lo, hi]))
            return float(1.0 - z.min() / z.max())
        return 0.0

    def damping_ratio(self, amplitude: np.ndarray | float) -> np.ndarray:
        """zeta(A) [-] of the law at amplitude(s) A [envelope unit]."""
        a = np.asarray(amplitude, dtype=float)
        p = self.params
        if self.law == "viscous":
            return np.full_like(a, p["zeta0"])
        if self.law == "drag":
            return p["zeta0"] + p["c"] * a
        if self.law == "friction":
            return p["zeta0"] + p["b"] / a
        return p["zeta_ref"] * (a / p["a_ref"]) ** p["p"]

    def to_dict(self) -> dict:
        return {"law": self.law, "params": dict(self.params), "a0": list(self.a0), "rms_log": self.rms_log,
                "points": self.points, "aic": self.aic, "amplitude_range": list(self.amplitude_range),
                "amplitude_share": self.amplitude_share()}


def fit_decay_law(series: list[tuple[np.ndarray, np.ndarray, float]], law: str) -> DecayLaw:
    """Fit ``law`` to envelopes ``series`` = [(t [s], a [unit], omega [rad/s]), ...] with the law's parameters
    shared and each envelope's initial amplitude free: least squares on ln a (relative errors: a decay spans a
    decade). Bounds: zeta0, c, b >= 0, zeta_ref > 0, p in [-3, 3]."""
    if law not in DECAY_LAWS:
        raise ValueError(f"law must be one of {', '.join(DECAY_LAWS)}, got {law!r}")
    series = [(np.asarray(t, float), np.asarray(a, float), float(w)) for t, a, w in series]
    if any(np.any(a <= 0) or len(a) != len(t) for t, a, _ in series):
        raise ValueError("each envelope needs as many positive amplitudes as times")
    names = LAW_PARAMETERS[law]
    a_ref = float(np.exp(np.mean(np.concatenate([np.log(a) for _, a, _ in series]))))
    # start: the pooled log-slope's damping ratio
    zeta_s = float(np.median([max(-np.polyfit(t, np.log(a), 1)[0] / w, 1e-4) for t, a, w in series]))
    starts = {"zeta0": zeta_s, "c": 0.0, "b": 0.0, "zeta_ref": zeta_s, "p": 0.0}
    lower = {"zeta0": 0.0, "c": 0.0, "b": 0.0, "zeta_ref": 1e-8, "p": -3.0}
    upper = {"zeta0": 1.0, "c": np.inf, "b": np.inf, "zeta_ref": 1.0, "p": 3.0}
    scale = {"zeta0": zeta_s, "c": zeta_s / a_ref, "b": zeta_s * a_ref, "zeta_ref": zeta_s, "p": 1.0}
    n_law = len(names)

    def unpack(x: np.ndarray) -> tuple[dict[str, float], np.ndarray]:
        params = {k: float(v) for k, v in zip(names, x[:n_law])}
        if law == "power":
            params["a_ref"] = a_ref
        return params, np.exp(x[n_law:])

    def residual(x: np.ndarray) -> np.ndarray:
        params, a0 = unpack(x)
        return np.concatenate([np.log(decay_model(law, params, a0i, t, w)) - np.log(a)
                               for (t, a, w), a0i in zip(series, a0)])

    log_a0 = [np.log(a[0]) for _, a, _ in series]
    tries = [[starts[k] for k in names]]
    if law == "drag":
        tries.append([0.5 * zeta_s, 0.5 * zeta_s / a_ref])
    if law == "friction":
        tries.append([0.5 * zeta_s, 0.5 * zeta_s * a_ref])
    best = None
    for x_law in tries:
        x0 = np.array([*[min(max(v, lower[k] + 1e-9), upper[k]) for k, v in zip(names, x_law)], *log_a0])
        sol = least_squares(residual, x0, bounds=([lower[k] for k in names] + [-np.inf] * len(series),
                                                  [upper[k] for k in names] + [np.inf] * len(series)),
                            x_scale=np.array([scale[k] for k in names] + [1.0] * len(series)))
        if best is None or sol.cost < best.cost:
            best = sol
    params, a0 = unpack(best.x)
    n = best.fun.size
    rss = float(np.sum(best.fun**2))
    k = len(best.x)
    every = np.concatenate([a for _, a, _ in series])
    return DecayLaw(law, params, tuple(float(v) for v in a0), float(np.sqrt(rss / n)), n,
                    float(n * np.log(max(rss, 1e-300) / n) + 2 * k), (float(every.min()), float(every.max())))


def decay_laws(series: list[tuple[np.ndarray, np.ndarray, float]]) -> dict[str, DecayLaw]:
    """Every law of :data:`DECAY_LAWS` fitted to the same envelopes (:func:`fit_decay_law`)."""
    return {law: fit_decay_law(series, law) for law in DECAY_LAWS}


def best_decay_law(fits: dict[str, DecayLaw], margin: float = 10.0, share: float = 0.1) -> str:
    """The law the envelopes ask for: a two-parameter law (drag, friction) beats viscous only when its Akaike
    criterion is lower by more than ``margin`` (10: the overlapping windows' correlation, :class:`DecayLaw`) and its
    amplitude-dependent term is at least ``share`` of zeta somewhere in the data's range (a real effect, not a
    1e-4 tweak that noise pays for); of drag and friction the lower criterion; ``viscous`` otherwise.
    (``power`` is the diagnostic that places the data between the three: its exponent p.)"""
    best = "viscous"
    for law in ("drag", "friction"):
        if fits[law].amplitude_share() < share:
            continue
        if fits[law].aic < fits[best].aic - (margin if best == "viscous" else 0.0):
            best = law
    return best
