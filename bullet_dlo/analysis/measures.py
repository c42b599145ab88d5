"""Error measures on simulated trajectories: every comparison the tests, benchmarks, peers and
:func:`bullet_dlo.analysis.resolve.resolve` make, written once.

* oscillations: frequency from upward zero crossings, amplitude over a full period;
* end forces as a 5 Hz force sensor sees them: means over 0.2 s blocks, RMS difference
  relative to the reference's peak force; the end moments alike (:func:`wrench_error`);
* shapes: largest distance between two polylines with different numbers of masses.
"""
from __future__ import annotations

import numpy as np

FORCE_BLOCK = 0.2
"""Length of the force-averaging blocks [s] (a 5 Hz force sensor)."""


def relative_error(value: float, reference: float) -> float:
    """|value / reference - 1| [-]."""
    return abs(value / reference - 1.0)


# ----- oscillations ------------------------------------------------------------------------------
def upward_crossings(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Times [s] at which y(t), shape (k,), crosses zero upwards (linear interpolation between samples)."""
    idx = np.flatnonzero((y[:-1] < 0.0) & (y[1:] >= 0.0))
    return t[idx] - y[idx] * (t[idx + 1] - t[idx]) / (y[idx + 1] - y[idx])


def zero_crossing_frequency(t: np.ndarray, y: np.ndarray) -> float:
    """Frequency [Hz] of y(t) about zero from its upward crossings; NaN with fewer than two."""
    tc = upward_crossings(t, y)
    if tc.size < 2:
        return float("nan")
    return (tc.size - 1) / (tc[-1] - tc[0])


def period_amplitude(t: np.ndarray, y: np.ndarray, period: int = -1) -> float:
    """Half peak-to-peak of y over one full period (between two upward crossings; ``period`` 0 is
    the first, -1 the last), in the unit of y; NaN with fewer than two crossings."""
    tc = upward_crossings(t, y)
    if tc.size < 2:
        return float("nan")
    i = period % (tc.size - 1)  # full periods: tc[i] to tc[i + 1]
    inside = (t >= tc[i]) & (t <= tc[i + 1])
    return float(0.5 * (y[inside].max() - y[inside].min()))


def amplitude_kept(t: np.ndarray, y: np.ndarray) -> float:
    """Amplitude over the last full period divided by the initial displacement |y[0]| [-]
    (1 means no amplitude lost; a free, undamped oscillation that loses some was damped numerically)."""
    return period_amplitude(t, y, -1) / abs(y[0])


# ----- end forces --------------------------------------------------------------------------------
def block_means(t: np.ndarray, f: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Means of ``f`` (k, ...) over the blocks [edges[i], edges[i+1]) of the sample times ``t`` (k,) [s]."""
    return np.array([f[(t >= lo) & (t < hi)].mean(axis=0) for lo, hi in zip(edges[:-1], edges[1:])])


def block_rms(t: np.ndarray, f: np.ndarray, t_ref: np.ndarray, f_ref: np.ndarray,
              block: float = FORCE_BLOCK) -> float:
    """RMS difference of the ``block``-second means of f (k, 2, 3) against those of f_ref (k_ref, 2, 3), in
    their unit (a run shorter than one block is compared by its last sample)."""
    edges = np.arange(t_ref[0], t_ref[-1] + 1e-12, block)
    if edges.size < 2:
        a, b = f[-1:], f_ref[-1:]
    else:
        a, b = block_means(t, f, edges), block_means(t_ref, f_ref, edges)
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))))


def _peak(f: np.ndarray) -> float:
    return float(np.max(np.abs(f))) if f.size else 0.0


def force_error(t: np.ndarray, f: np.ndarray, t_ref: np.ndarray, f_ref: np.ndarray,
                block: float = FORCE_BLOCK) -> float:
    """RMS difference of end forces f (k, 2, 3) [N] against f_ref (k_ref, 2, 3) [N] in ``block``-second
    means (what a 5 Hz force sensor sees), relative to the reference's peak force [-].

    Pointwise histories are not a fair target: with absolute (air-like) damping only, the stiff
    axial and clamp modes that a move excites ring on, and refining n adds new ones. A run
    shorter than one block is compared by its last sample.
    """
    return block_rms(t, f, t_ref, f_ref, block) / max(_peak(f_ref), 1e-12)


MOMENT_FLOOR = 0.01
"""End moments are judged relative to at least this share of the reference's peak force times the cable's length
[-] (:func:`wrench_error`)."""


def wrench_error(t: np.ndarray, f: np.ndarray, m: np.ndarray, t_ref: np.ndarray, f_ref: np.ndarray,
                 m_ref: np.ndarray, length: float, block: float = FORCE_BLOCK) -> float:
    """The larger of the end forces' error (:func:`force_error` of f against f_ref, (k, 2, 3) [N]) and the end
    moments' m against m_ref ((k, 2, 3) [N m]), measured alike but relative to the larger of the reference's peak
    moment and MOMENT_FLOOR times its peak force times ``length`` [m] [-].

    A wrist sensor reads both: a clamp turned about the cable (torsion) loads it with moments alone, where the forces
    say nothing. The floor keeps moments that are round-off beside the forces (a straight cable hanging from a
    clamp) from being judged on their own."""
    scale = max(_peak(m_ref), MOMENT_FLOOR * _peak(f_ref) * length, 1e-12)
    return max(force_error(t, f, t_ref, f_ref, block), block_rms(t, m, t_ref, m_ref, block) / scale)


# ----- shapes ------------------------------------------------------------------------------------
def shape_error(x: np.ndarray, x_ref: np.ndarray, scale: float) -> float:
    """Largest distance [m] between the polyline x (n, 3) [m], resampled at the reference's masses
    by arc-length fraction, and x_ref (n_ref, 3) [m], divided by ``scale`` [m]."""
    s, s_ref = np.linspace(0.0, 1.0, len(x)), np.linspace(0.0, 1.0, len(x_ref))
    resampled = np.stack([np.interp(s_ref, s, x[:, j]) for j in range(3)], axis=1)
    return float(np.max(np.linalg.norm(resampled - x_ref, axis=1))) / scale
