"""Issue 21: several recordings of one cable are trials that differ by more than their noise (DEFORM's trials alone
gave damping_rate 0.09-0.58 1/s). The fit's interval for their common value counts recordings, not samples."""
from __future__ import annotations

import numpy as np
from scipy import stats

from bullet_dlo.analysis.fit import FitOptions, fit_cable, synthetic_recording
from bullet_dlo.analysis.fit_stats import recording_random_effects
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.spec import CableSpec

TYPICAL = CableSpec.lv2017(n_masses=8, damping_rate=2.0, internal_damping=0.01)
MOTION = [Sine("first", (0.0, 0.0, 0.02), 1.5, start=0.2, ramp=0.2, rotation=(0.0, 0.2, 0.0))]


def test_three_recordings_that_differ_give_an_interval_as_wide_as_their_spread():
    """Three recordings made with damping rates exp(-0.3), 1 and exp(0.3) times 2 1/s (5 mN of white noise): each
    recording alone determines its own rate far better than they differ, so the common value's 95 % half-width in
    log space is Student's t(2) x 0.3 / sqrt(3) = 0.745 (the between-recording variance is their spread's).
    Within [0.8, 1.6] x that, and holding 2 1/s. The window jackknife, counting each
    recording's windows as independent samples, gave 0.14: a confident interval that excluded two of the three."""
    spread, rates = 0.3, 2.0 * np.exp([-0.3, 0.0, 0.3])
    recs = [synthetic_recording(TYPICAL.with_(damping_rate=float(c)), MOTION, 1.0, rate=200.0, noise=0.005, seed=i)
            for i, c in enumerate(rates)]
    res = fit_cable(recs, TYPICAL, ["damping_rate"], FitOptions(max_evaluations=30, profile_points=0,
                                                                 max_relative_se=1.0))  # show the interval
    lo, hi = res.intervals["damping_rate"]
    half = 0.5 * np.log(hi / lo)
    expected = stats.t.ppf(0.975, 2) * spread / np.sqrt(3)
    assert 0.8 * expected <= half <= 1.6 * expected and lo <= 2.0 <= hi, (half, expected, lo, hi)
    assert res.interval_method.endswith("damping_rate: recordings")


def test_recording_random_effects_is_dersimonian_laird_over_the_recordings_own_estimates():
    """A linear model y = theta + e in three recordings of 50 samples whose own means differ (0.1, -0.2, 0.4) with
    noise of SD 0.05: the half-width is t(2) sqrt(1 / sum 1 / (v_i + tau^2)), v_i = s_i^2 / 50, tau^2 = (Q - 2) /
    (sum w - sum w^2 / sum w), computed here by hand; recordings that agree within their noise get tau^2 = 0;
    parameters that no recording determines alone get none (inf)."""
    rng = np.random.default_rng(3)
    rec_of = np.repeat(np.arange(3), 50)
    for own in (np.array([0.1, -0.2, 0.4]), np.zeros(3)):
        e = 0.05 * rng.standard_normal(150)
        r = -(own[rec_of] + e)  # residual at theta = 0 of data y = own + e, J = 1
        jac = np.ones((150, 1))
        half, used = recording_random_effects(r, jac, rec_of, 1.0, 0.95)
        y = np.array([own[i] + e[rec_of == i].mean() for i in range(3)])
        v = np.array([e[rec_of == i].var(ddof=1) / 50 for i in range(3)])
        w = 1 / v
        q = np.sum(w * (y - np.sum(w * y) / np.sum(w)) ** 2)
        tau2 = max(0.0, (q - 2) / (w.sum() - (w ** 2).sum() / w.sum()))
        assert used[0] == 3 and abs(half[0] - stats.t.ppf(0.975, 2) * np.sqrt(1 / np.sum(1 / (v + tau2)))) < 1e-9
        assert (tau2 > 0.04) if own.any() else (tau2 < 1e-4)
    blind = np.stack([np.ones(150), np.zeros(150)], axis=1)  # the second parameter moves nothing
    assert np.isinf(recording_random_effects(r, blind, rec_of, 1.0, 0.95)[0]).all()


def test_the_coverage_demo_runs_a_draw():
    """``demos/fit_recordings_coverage.py`` (the docs' 40-draw figure) runs and reports its count."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "demos" / "fit_recordings_coverage.py"
    out = subprocess.run([sys.executable, str(script), "1", "11"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert re.fullmatch(r"held the typical value in [01] of 1 draws; [01] called not identifiable\n", out.stdout)
