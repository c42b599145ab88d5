"""The vibration level: the fitted sine's amplitude against the band's peak-to-peak (issue 21).

A peak-to-peak takes everything in the 1.5-8 Hz band; the amplitude of a sine at the signal's own frequency,
least-squares fitted over the same window, takes the mode alone. On synthetic signals with a known amplitude the
fitted sine recovers it in noise and beside an off-frequency component, where the peak-to-peak does not; on the
real recordings it agrees with the damped sine fitted over 1-6 s, while the peak-to-peak departs on the file with
other content in its band.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.reality.vibration import band, residual_vibration, sine_amplitude

F, ZETA, AMP = 2.93, 0.012, 0.8  # [Hz], [-], [N m]: the strip's first mode as the joints see it
RATE = 1000.0  # [Hz]
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "beam_handling"


def mode(s: np.ndarray, amp: float = AMP, phase: float = 0.4) -> np.ndarray:
    """The damped first mode, amplitude ``amp`` at s = 0 [N m]; s [s] from the motion's end."""
    wn = 2 * math.pi * F / math.sqrt(1 - ZETA**2)
    return amp * np.exp(-ZETA * wn * s) * np.sin(2 * math.pi * F * s + phase)


def amplitude_at(s: float, amp: float = AMP) -> float:
    return amp * math.exp(-ZETA * 2 * math.pi * F / math.sqrt(1 - ZETA**2) * s)


def test_sine_amplitude_recovers_a_known_damped_sine_in_noise_offset_and_drift():
    rng = np.random.default_rng(3)
    t = np.arange(1.0, 2.0 + 0.5 / RATE, 1 / RATE)  # the p2p window, end + 1-2 s
    clean = mode(t)
    y = clean + 0.3 + 0.05 * (t - 1.0) + rng.normal(0.0, 0.1, len(t))  # Franka's offset, a slow drift, noise
    got = sine_amplitude(t, y, F, ZETA)
    # the amplitude at the window's centre, within the noise's sqrt(2 / samples) = 0.0045 N m (3 sigma)
    assert got == pytest.approx(amplitude_at(1.5), abs=3 * 0.1 * math.sqrt(2 / len(t)))
    # without the decay: the window's mean amplitude, within (sigma T)^2 / 24 of the centre's
    sigma = ZETA * 2 * math.pi * F
    assert sine_amplitude(t, y, F) == pytest.approx(amplitude_at(1.5), rel=(sigma * 1.0) ** 2 / 24 + 0.01)


@pytest.mark.parametrize("f2, ratio", [(5.0, 0.5), (4.4, 1.0), (1.8, 0.6)])
def test_sine_amplitude_ignores_an_off_frequency_component_where_p2p_does_not(f2, ratio):
    """Another component in the band (the arm settling, Franka's model errors) at f2 dying out within seconds,
    amplitude ratio x the mode's at end + 1 s: p2p takes it in, the fitted sine moves by about ratio /
    (pi |f2 - F| T) of the mode's amplitude or less."""
    t = np.arange(0.0, 12.0, 1 / RATE)
    end = 2.0
    s = np.clip(t - end, 0.0, None)
    clean = mode(s)
    other = ratio * AMP * np.exp(-(s - 1.0) / 0.8) * np.sin(2 * math.pi * f2 * s + 1.1) * (t > end)
    y = clean + other
    w = (t >= end + 1.0) & (t <= end + 2.0)
    truth = amplitude_at(1.5)
    got = sine_amplitude(t[w], y[w], F, ZETA)
    bound = ratio * AMP / (math.pi * abs(f2 - F) * 1.0)
    assert abs(got - truth) <= bound
    assert got == pytest.approx(truth, rel=0.15)  # the level within the goal's 15 %
    p2p = np.ptp(band(y, RATE)[w])
    clean_p2p = np.ptp(band(clean, RATE)[w])
    assert p2p / clean_p2p > 1.15  # the peak-to-peak is off by more than the goal's tolerance
    # residual_vibration reports both: its sine level at the mode, its p2p with the other content
    v = residual_vibration(t, y, end)
    assert v.frequency_hz == pytest.approx(F, rel=0.01)
    assert v.sine_amplitude == pytest.approx(truth, rel=0.15)
    assert v.p2p_torque == pytest.approx(p2p)


def test_the_two_level_measures_agree_on_a_clean_mode():
    """Without other content p2p / 2 lies between the envelope at the window's start and one period later (the band
    filter's gain at F is 1 within 1e-5), and the sine's amplitude is the envelope at the centre."""
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 12.0, 1 / RATE)
    end = 2.0
    y = mode(np.clip(t - end, 0.0, None)) + rng.normal(0.0, 0.005, len(t))
    v = residual_vibration(t, y, end)
    assert v.sine_amplitude == pytest.approx(amplitude_at(1.5), rel=0.01)
    assert amplitude_at(1.0 + 1 / F) * 0.99 <= v.p2p_torque / 2 <= amplitude_at(1.0) * 1.01


def test_sine_amplitude_bad_input():
    t = np.arange(0.0, 1.0, 1e-3)
    with pytest.raises(ValueError, match="frequency_hz"):
        sine_amplitude(t, np.sin(t), 0.0)
    with pytest.raises(ValueError, match="damping_ratio"):
        sine_amplitude(t, np.sin(t), 2.9, 1.0)
    with pytest.raises(ValueError, match="half a period"):
        sine_amplitude(t[:100], np.sin(t[:100]), 2.9)


def test_on_the_recordings_the_sine_level_agrees_with_the_decay_fit_where_p2p_does_not():
    """Measured signals of the nine recordings: the sine over end + 1-2 s against the damped sine fitted over
    1-6 s, evaluated at 1.5 s (two fits of the mode, one of them on five times the data). They agree on every file;
    p2p / 2 departs from the latter by much more on Xup_35cm, whose band holds other content."""
    from bullet_dlo.reality.beam import beam_files, read_beam_csv
    from bullet_dlo.reality.beam_validate import measure

    if not DATA.is_dir():
        pytest.skip(f"beam_handling recordings not found at {DATA} (see ../shared/data/README.md)")
    sine, p2p = {}, {}
    for path in beam_files(DATA, "data"):
        m = measure(read_beam_csv(path))
        v = m.vibration
        decay = math.exp(-v.damping_ratio * 2 * math.pi * v.frequency_hz / math.sqrt(1 - v.damping_ratio**2) * 0.5)
        envelope = v.amplitude * decay  # the 1-6 s fit's amplitude at end + 1.5 s
        sine[path.stem] = v.sine_amplitude / envelope
        p2p[path.stem] = v.p2p_torque / (2 * envelope)
    assert len(sine) == 9
    assert all(abs(r - 1) < 0.15 for r in sine.values()), sine  # measured 0.955-1.094
    worst = "ocp_Xup_35cm_0.57s_1"
    assert p2p[worst] - 1 > 3 * abs(sine[worst] - 1), (p2p[worst], sine[worst])
