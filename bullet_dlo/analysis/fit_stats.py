"""What a fit's residual says about its uncertainty: whiteness, time-window intervals, the verdict.

The Jacobian standard error sigma^2 (J^T J)^-1 assumes independent residuals. A wrist force
residual is not: coloured sensor noise and, above all, what the model does not have
(model discrepancy) are correlated over many samples, and the Jacobian error then shrinks as
1/sqrt(samples) while the real error does not. This module gives the pieces a fit reports
instead (all pure numpy/scipy, on a residual r (m,) and its Jacobian J (m, p) in log parameters,
whose rows are grouped into channels of consecutive samples):

* :func:`whiteness`: the residual's normalised autocorrelation (pooled over channels), the
  integrated autocorrelation time tau_int = 1 + 2 sum rho_l (Geyer's initial positive sequence)
  in samples and seconds, the effective sample size m / tau_int, and a Ljung-Box test; and the
  *envelope* time, the lag after which |rho| stays below 1/e: an oscillating residual (a mode the
  model puts at the wrong frequency) has a short tau_int, its lobes cancelling, but a long envelope,
  and windows must be long against that;
* :func:`block_jackknife`: the recordings cut into time windows at least
  ``WINDOW_TAUS`` tau_int long; each window left out in turn, the other windows' linearised
  refit (theta_-b = theta - (J_-b^T J_-b)^-1 J_-b^T r_-b) gives the parameter spread
  (delete-a-block jackknife variance) and the left-out window's predicted residual (held-out RMS);
* :func:`hac_variances`: the Newey-West (Bartlett) sandwich variance with bandwidth from tau_int,
  the same idea without windows;
* :func:`t_quantile`: Student's t quantile for intervals from B windows (B - 1 degrees of freedom).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

WINDOW_TAUS = 5.0  # a window is at least this many residual correlation times long
MAX_LAG = 400  # longest lag [samples] of the autocorrelation


@dataclass(frozen=True)
class Whiteness:
    """Residual autocorrelation summary.

    rho: pooled normalised autocorrelation at lags 0..len-1 [-]; tau_samples: integrated
    autocorrelation time [samples] (1 for white noise); tau_s: the same [s]; samples: residual
    entries m; effective_samples: m / tau_samples; ljung_box: Q statistic over ``lags`` lags;
    p_value: its chi^2 tail probability (small: not white); white: p_value >= 0.01;
    envelope_samples: lags after which |rho| stays below 1/e [samples] (the whole computed range when
    it never does); window_tau_s: the correlation time windows are cut by, max(tau, envelope) [s].
    """

    rho: np.ndarray
    tau_samples: float
    tau_s: float
    samples: int
    effective_samples: float
    ljung_box: float
    lags: int
    p_value: float
    white: bool
    envelope_samples: float = 1.0
    window_tau_s: float = 0.0

    def to_dict(self) -> dict:
        """The JSON-able summary (the first 10 autocorrelations)."""
        return {"lag1_autocorrelation": float(self.rho[1]) if len(self.rho) > 1 else 0.0,
                "autocorrelation_first_lags": [float(v) for v in self.rho[:10]],
                "integrated_autocorrelation_time_samples": self.tau_samples,
                "integrated_autocorrelation_time_s": self.tau_s, "samples": self.samples,
                "effective_samples": self.effective_samples, "ljung_box_q": self.ljung_box,
                "ljung_box_lags": self.lags, "p_value": self.p_value, "white": self.white,
                "envelope_time_samples": self.envelope_samples, "window_correlation_time_s": self.window_tau_s}


def pooled_autocorrelation(channels: list[np.ndarray], max_lag: int) -> np.ndarray:
    """Autocorrelation at lags 0..max_lag of several residual channels (each 1-D, mean removed
    per channel), pooled: sum over channels of the lagged products / sum of the squares."""
    num = np.zeros(max_lag + 1)
    den = 0.0
    for c in channels:
        c = np.asarray(c, dtype=float) - float(np.mean(c))
        n = len(c)
        den += float(c @ c)
        if n < 2:
            continue
        spec = np.fft.rfft(c, 2 * n)
        acov = np.fft.irfft(spec * np.conj(spec))[: min(max_lag + 1, n)]
        num[: len(acov)] += acov
    return num / den if den > 0 else np.r_[1.0, np.zeros(max_lag)]


def integrated_time(rho: np.ndarray) -> float:
    """tau_int = 1 + 2 sum_{l>=1} rho_l [samples], as Geyer's initial positive sequence estimate
    -1 + 2 sum_k (rho_2k + rho_2k+1) over the leading positive pairs; at least 1."""
    tau = -1.0
    for k in range(0, len(rho) - 1, 2):
        pair = float(rho[k] + rho[k + 1])
        if pair <= 0.0:
            break
        tau += 2.0 * pair
    return max(1.0, tau)


def envelope_time(rho: np.ndarray) -> float:
    """Lags [samples] after which |rho| stays below 1/e (len(rho) when it never settles there); at least 1."""
    above = np.flatnonzero(np.abs(rho) >= math.exp(-1.0))
    return float(max(1, above[-1] + 1 if len(above) else 1))


def whiteness(channels: list[np.ndarray], sample_dt: float, lags: int = 20) -> Whiteness:
    """Whiteness of residual ``channels`` (1-D arrays of consecutive samples ``sample_dt`` [s] apart)."""
    length = min(len(c) for c in channels)
    max_lag = int(min(MAX_LAG, max(2, length - 1)))
    rho = pooled_autocorrelation(channels, max_lag)
    tau = integrated_time(rho)
    m = int(sum(len(c) for c in channels))
    h = int(min(lags, max_lag))
    n_per = m / len(channels)
    q = float(n_per * (n_per + 2) * np.sum(rho[1: h + 1] ** 2 / (n_per - np.arange(1, h + 1))))
    p = float(stats.chi2.sf(q * len(channels), h * len(channels)))  # channels pooled as independent series
    env = envelope_time(rho)
    return Whiteness(rho, tau, tau * sample_dt, m, m / tau, q, h, p, p >= 0.01, env, max(tau, env) * sample_dt)


def window_bounds(k: int, windows: int) -> list[tuple[int, int]]:
    """``windows`` contiguous sample ranges [start, stop) covering 0..k as evenly as possible."""
    edges = np.linspace(0, k, windows + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def windows_for(duration: float, tau_s: float, max_windows: int) -> int:
    """Windows a recording of ``duration`` [s] is cut into: each at least WINDOW_TAUS tau_s [s] long,
    at most ``max_windows``; 0 when not even one such window fits."""
    if tau_s <= 0:
        return max_windows
    return int(min(max_windows, math.floor(duration / (WINDOW_TAUS * tau_s))))


@dataclass(frozen=True)
class Jackknife:
    """Delete-a-window jackknife in log parameters.

    var_log: jackknife variances (p,); leave_out: theta_-b - theta (B, p); per_window:
    each window's own linearised estimate - theta (B, p) (nan where a window alone does not
    determine them); held_out_rms / in_sample_rms: residual RMS of the windows predicted by the
    others' refit vs of the fit itself (weighted units); held_out_by_block: (B,) RMS of each left-out window.
    """

    var_log: np.ndarray
    leave_out: np.ndarray
    per_window: np.ndarray
    held_out_rms: float
    in_sample_rms: float
    held_out_by_block: np.ndarray

    @property
    def blocks(self) -> int:
        """Number of windows B."""
        return int(self.leave_out.shape[0])


def _solve(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray | None:
    """Least-squares step (J^T J)^-1 J^T rhs (None if J has a blind direction)."""
    if jac.shape[0] < jac.shape[1]:
        return None
    sol, _, rank, _ = np.linalg.lstsq(jac, rhs, rcond=1e-10)
    return sol if rank == jac.shape[1] else None


def block_jackknife(r: np.ndarray, jac: np.ndarray, block: np.ndarray) -> Jackknife:
    """The delete-a-window jackknife of a least-squares fit linearised at its optimum.

    r: residual (m,); jac: its Jacobian (m, p) in log parameters; block: window index 0..B-1 of
    each residual row (m,). The left-out refit of window b is theta - (J_-b^T J_-b)^-1 J_-b^T r_-b;
    its prediction of window b is r_b + J_b (theta_-b - theta).
    """
    nb = int(block.max()) + 1
    p = jac.shape[1]
    leave = np.full((nb, p), np.nan)
    own = np.full((nb, p), np.nan)
    held_sq = np.zeros(nb)
    held_n = np.zeros(nb)
    for b in range(nb):
        inside = block == b
        out = ~inside
        step = _solve(jac[out], r[out])
        if step is not None:
            leave[b] = -step
            pred = r[inside] + jac[inside] @ leave[b]
            held_sq[b] = float(pred @ pred)
            held_n[b] = inside.sum()
        alone = _solve(jac[inside], r[inside])
        if alone is not None:
            own[b] = -alone
    ok = np.all(np.isfinite(leave), axis=1)
    if ok.sum() >= 2:
        dev = leave[ok] - leave[ok].mean(axis=0)
        var = (ok.sum() - 1) / ok.sum() * np.sum(dev**2, axis=0)
    else:
        var = np.full(p, math.inf)
    held = math.sqrt(held_sq[ok].sum() / max(held_n[ok].sum(), 1)) if ok.any() else math.inf
    by_block = np.where(held_n > 0, np.sqrt(held_sq / np.maximum(held_n, 1)), np.nan)
    return Jackknife(var, leave, own, held, math.sqrt(float(r @ r) / len(r)), by_block)


def recording_random_effects(r: np.ndarray, jac: np.ndarray, rec_of: np.ndarray, tau_samples: float,
                             level: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-widths in log space of a random-effects interval over the recordings of a fit, and the number of
    recordings it used, each (p,): inf where fewer than two recordings determine the parameters alone.

    ``r`` (m,) and ``jac`` (m, p): the weighted residual and its Jacobian in log parameters at the pooled optimum;
    ``rec_of`` (m,): each row's recording; ``tau_samples``: the residual's integrated autocorrelation time
    [samples] (a recording's own variance is the white-noise one times it). Each recording's own linearised estimate
    y_i and its variance v_i; the between-recording variance tau^2 of DerSimonian and Laird (0 when the recordings
    agree within their noise); the common value's variance 1 / sum 1 / (v_i + tau^2), with Student's t at k - 1
    degrees of freedom for k recordings.

    Why: the window jackknife takes a recording's windows as independent, but recordings of one cable can differ
    by more than their noise (handling, temperature, the cable's history: DEFORM's trials alone gave damping_rate
    0.09-0.58 1/s); then only the number of recordings says how well their common value is known."""
    n, p = int(rec_of.max()) + 1, jac.shape[1]
    half, used = np.full(p, math.inf), np.zeros(p, dtype=int)
    if n < 2:
        return half, used
    own, var = np.full((n, p), np.nan), np.full((n, p), np.nan)  # stay nan where a recording alone is blind
    for i in range(n):
        rows = rec_of == i
        if rows.sum() <= p:  # no residual dof left to estimate its noise
            continue
        step = _solve(jac[rows], r[rows])
        if step is None:
            continue
        own[i] = -step  # the recording's own estimate, from the pooled optimum
        left = r[rows] - jac[rows] @ step  # its residual there
        s2 = float(left @ left) / (rows.sum() - p) * max(tau_samples, 1.0)
        var[i] = np.diag(np.linalg.inv(jac[rows].T @ jac[rows])) * s2
    for a in range(p):
        ok = np.isfinite(own[:, a]) & np.isfinite(var[:, a])
        k = int(ok.sum())
        if k < 2:
            continue
        y, v = own[ok, a], np.maximum(var[ok, a], 1e-300)
        w = 1.0 / v
        q = float(np.sum(w * (y - np.sum(w * y) / np.sum(w)) ** 2))  # Cochran's Q
        tau2 = max(0.0, (q - (k - 1)) / (np.sum(w) - np.sum(w ** 2) / np.sum(w)))
        half[a] = float(stats.t.ppf(0.5 + level / 2, k - 1)) * math.sqrt(1.0 / np.sum(1.0 / (v + tau2)))
        used[a] = k
    return half, used


def hac_variances(r: np.ndarray, jac: np.ndarray, channel_of: np.ndarray, sample_of: np.ndarray,
                  bandwidth: int) -> np.ndarray:
    """Newey-West variances of log parameters: (J^T J)^-1 S (J^T J)^-1 with S the Bartlett-weighted
    autocovariance (lags up to ``bandwidth`` samples) of the per-sample score s_t = sum over the
    entries of sample t of J r; entries of different channels at the same sample are summed first.

    channel_of: an id per residual row of its recording (rows of different recordings never
    correlate); sample_of: its sample index within the recording.
    """
    p = jac.shape[1]
    jtj = jac.T @ jac
    try:
        inv = np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return np.full(p, math.inf)
    meat = np.zeros((p, p))
    contrib = jac * r[:, None]
    for rec in np.unique(channel_of):
        rows = channel_of == rec
        k = int(sample_of[rows].max()) + 1
        score = np.zeros((k, p))
        np.add.at(score, sample_of[rows], contrib[rows])
        meat += score.T @ score
        for lag in range(1, min(bandwidth, k - 1) + 1):
            w = 1.0 - lag / (bandwidth + 1.0)
            g = score[lag:].T @ score[:-lag]
            meat += w * (g + g.T)
    return np.diag(inv @ meat @ inv).copy()


def t_quantile(blocks: int, level: float = 0.95) -> float:
    """Two-sided Student's t quantile with ``blocks`` - 1 degrees of freedom (normal for >= 200)."""
    dof = max(1, blocks - 1)
    return float(stats.t.ppf(0.5 + level / 2, dof)) if dof < 200 else float(stats.norm.ppf(0.5 + level / 2))
