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
"""
from __future__ import annotations

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
