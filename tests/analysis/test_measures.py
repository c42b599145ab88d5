"""Error measures against signals whose answers are known exactly."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.measures import (
    amplitude_kept,
    force_error,
    period_amplitude,
    relative_error,
    shape_error,
    upward_crossings,
    wrench_error,
    zero_crossing_frequency,
)


def test_frequency_from_zero_crossings():
    t = np.linspace(0.0, 1.0, 4001)
    y = np.sin(2 * math.pi * 7.3 * t + 0.4)
    assert zero_crossing_frequency(t, y) == pytest.approx(7.3, rel=1e-5)
    assert np.all(np.diff(upward_crossings(t, y)) == pytest.approx(1 / 7.3, rel=1e-4))
    assert math.isnan(zero_crossing_frequency(t, np.cos(t)))  # no full period


def test_amplitude_kept_measures_decay_over_the_last_period():
    t = np.linspace(0.0, 2.0, 20001)
    rate, f = 0.5, 5.0
    y = -np.exp(-rate * t) * np.cos(2 * math.pi * f * t)
    tc = upward_crossings(t, y)
    # half peak-to-peak over the last period: the envelope at the maxima a quarter and three quarters in
    expected = 0.5 * (np.exp(-rate * (tc[-2] + 0.25 / f)) + np.exp(-rate * (tc[-2] + 0.75 / f)))
    assert amplitude_kept(t, y) == pytest.approx(expected, rel=1e-3)
    assert period_amplitude(t, y, 0) > period_amplitude(t, y, -1)
    assert amplitude_kept(t, -np.cos(2 * math.pi * f * t)) == pytest.approx(1.0, rel=1e-4)


def test_force_error_sees_block_means_not_ripple():
    t = np.linspace(0.0, 0.6, 601)
    ref = np.zeros((t.size, 2, 3))
    ref[:, :, 2] = -0.15  # each holder carries half of a 0.3 N weight
    assert force_error(t, ref, t, ref) == 0.0
    offset = ref.copy()
    offset[:, 0, 2] += 0.003  # one end off by 3 mN in every block
    assert force_error(t, offset, t, ref) == pytest.approx(0.003 / math.sqrt(2) / 0.15, rel=1e-9)
    ripple = ref.copy()
    ripple[:, :, 2] += 0.05 * np.sin(2 * math.pi * 50.0 * t)[:, None]  # whole periods in every 0.2 s block
    assert force_error(t, ripple, t, ref) < 1e-3  # what a 5 Hz sensor sees: nothing
    short = t[t < 0.1]
    assert force_error(short, offset[: short.size], short, ref[: short.size]) == pytest.approx(0.003 / math.sqrt(2) / 0.15)


def test_wrench_error_judges_moments_as_forces_and_round_off_not_at_all():
    """A clamp turned about the cable loads it with moments alone: their error counts as the forces' does, relative
    to their peak; moments at round-off beside a force (a straight cable hanging from a clamp) count for nothing."""
    t = np.linspace(0.0, 0.6, 601)
    none = np.zeros((t.size, 2, 3))
    torque = none.copy()
    torque[:, 1, 0] = 0.02  # a torsion moment of 20 mN m on the last clamp
    off = torque.copy()
    off[:, 1, 0] += 0.001  # 1 mN m off in every block
    assert force_error(t, none, t, none) == 0.0  # the forces say nothing
    assert wrench_error(t, none, off, t, none, torque, 0.5) == pytest.approx(0.001 / math.sqrt(2) / 0.02, rel=1e-9)
    weight = none.copy()
    weight[:, :, 2] = -0.15
    forces_off = weight.copy()
    forces_off[:, 0, 2] += 0.003
    tiny = none + 1e-17
    assert wrench_error(t, forces_off, tiny, t, weight, none, 0.5) == pytest.approx(
        force_error(t, forces_off, t, weight), rel=1e-12)
    # a moment as large as the floor (1 % of the peak force times the length) is judged against it
    small = none.copy()
    small[:, 0, 1] = 0.01 * 0.15 * 0.5
    assert wrench_error(t, weight, 2 * small, t, weight, small, 0.5) == pytest.approx(1 / math.sqrt(2), rel=1e-9)


def test_shape_error_resamples_by_arc_length():
    line = lambda n: np.stack([np.linspace(0.0, 0.3, n), np.zeros(n), np.zeros(n)], axis=1)  # noqa: E731
    assert shape_error(line(10), line(19), 1.0) == pytest.approx(0.0, abs=1e-15)
    shifted = line(10) + (0.0, 0.0, 0.002)
    assert shape_error(shifted, line(19), 0.01) == pytest.approx(0.2)
    assert relative_error(1.02, 1.0) == pytest.approx(0.02)
