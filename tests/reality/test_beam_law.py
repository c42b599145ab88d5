"""The damping-law analysis (bullet_dlo.reality.vibration, beam_law) against decays of known law, the modal scale
against the core cantilever, the measured law carried by the model, and the law the recordings ask for."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from bullet_dlo.reality.beam import Strip
from bullet_dlo.reality.beam_law import BETA_L, law_free_decay, modal_wrench_per_tip, mode_integrals
from bullet_dlo.reality.vibration import (
    MODE_FORCING_LEVER,
    best_decay_law,
    decay_laws,
    envelope,
    fit_damped_sine,
    fit_decay_law,
    sine_amplitude,
)

BEAM_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "beam_handling"

F = 3.0  # [Hz]
OMEGA = 2 * math.pi * F


def ringdown(zeta0: float = 0.0, quad: float = 0.0, coulomb: float = 0.0, a0: float = 1.0, duration: float = 10.0,
             noise: float = 0.01, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """x'' + 2 zeta0 omega x' + quad |x'| x' + coulomb sign(x') + omega^2 x = 0 from x = a0 at rest, sampled at
    1 kHz, plus white noise of RMS ``noise``. Its envelope laws (averaging over a cycle): quadratic drag adds
    zeta = 4 quad A / (3 pi); Coulomb friction takes 4 coulomb / omega^2 per cycle, zeta = b / A with
    b = 2 coulomb / (pi omega^2)."""
    def rhs(_t, s):
        x, v = s
        return [v, -2 * zeta0 * OMEGA * v - quad * abs(v) * v - coulomb * math.tanh(v / 1e-4) - OMEGA**2 * x]

    t = np.arange(0.0, duration, 1e-3)
    sol = solve_ivp(rhs, (0.0, duration), [a0, 0.0], t_eval=t, rtol=1e-9, atol=1e-12, method="LSODA")
    return t, sol.y[0] + noise * np.random.default_rng(seed).standard_normal(len(t))


def laws_of(t: np.ndarray, y: np.ndarray):
    times, amps, _ = envelope(t, y, 0.0, F, start=0.5)
    return decay_laws([(times, amps, OMEGA)])


@pytest.mark.parametrize("truth, kwargs, expected", [
    ("viscous", {"zeta0": 0.01}, {"zeta0": 0.01}),
    ("drag", {"zeta0": 0.005, "quad": 0.02 * 3 * math.pi / 4}, {"zeta0": 0.005, "c": 0.02}),
    ("friction", {"zeta0": 0.005, "coulomb": 0.0015 * math.pi * OMEGA**2 / 2}, {"zeta0": 0.005, "b": 0.0015}),
])
def test_the_law_analysis_recovers_the_law_of_a_synthetic_decay(truth, kwargs, expected):
    """Envelope (two-cycle sines) + closed-form decays fitted on ln A: the Akaike choice is the true law and its
    parameters come back within 3 % (the slope / decrement) and 10 % (the linear share), through 1 % noise."""
    fits = laws_of(*ringdown(**kwargs))
    assert best_decay_law(fits) == truth
    for name, value in expected.items():
        assert fits[truth].params[name] == pytest.approx(value, rel=0.03 if name != "zeta0" or truth == "viscous"
                                                         else 0.10)
    if truth != "viscous":  # the linear law cannot follow it
        assert fits["viscous"].rms_log > 5 * fits[truth].rms_log


@pytest.mark.parametrize("kwargs, exponent", [({"quad": 0.02 * 3 * math.pi / 4}, 1.0),
                                              ({"coulomb": 0.0015 * math.pi * OMEGA**2 / 2}, -1.0)])
def test_the_power_law_exponent_places_pure_drag_and_pure_friction(kwargs, exponent):
    """zeta = zeta_ref (A / A_ref)^p: p = 1 for quadratic drag alone, -1 for Coulomb friction alone (within 0.1)."""
    assert laws_of(*ringdown(**kwargs))["power"].params["p"] == pytest.approx(exponent, abs=0.1)


def test_a_shared_law_across_envelopes_in_different_units():
    """Two drag decays of the same law in tip amplitude, seen through different torque scales (15 and 22 N m per m)
    from different starting amplitudes: converted back, the shared fit returns the law's slope and each start."""
    series = []
    for a0, scale, seed in ((0.06, 15.0, 2), (0.03, 22.0, 3)):
        t, y = ringdown(zeta0=0.004, quad=0.4 / scale * 3 * math.pi / 4, a0=a0 * scale, noise=0.01 * a0 * scale, seed=seed)
        times, amps, _ = envelope(t, y, 0.0, F, start=0.5)
        series.append((times, amps / scale, OMEGA))
    law = fit_decay_law(series, "drag")
    assert law.params["c"] == pytest.approx(0.4, rel=0.05)
    assert law.params["zeta0"] == pytest.approx(0.004, rel=0.15)


def test_mode_integrals_are_the_clamped_free_closed_forms():
    """int phi / (L phi(L)) = sigma / (beta L) for the first clamped-free mode, and the lever int x phi / int phi is
    the 0.7264 L that the excitation analysis uses."""
    i0, i1 = mode_integrals()
    sigma = (math.cosh(BETA_L) + math.cos(BETA_L)) / (math.sinh(BETA_L) + math.sin(BETA_L))
    assert i0 == pytest.approx(sigma / BETA_L, rel=1e-5)
    assert i1 / i0 == pytest.approx(MODE_FORCING_LEVER, abs=1e-4)


def test_the_modal_clamp_load_per_tip_amplitude_matches_the_core_cantilever():
    """The weightless weak-plane strip (n 12, BDF2) ringing from its sag: its clamp force per tip amplitude is
    m' omega^2 L int phi (the scale that turns the recordings' torques into tip amplitudes) within 2 %."""
    strip = Strip()
    t, fz, amp = law_free_decay(strip, 0.0, duration=2.0)
    f = fit_damped_sine(t, fz)[0]
    w = (t >= 0.5) & (t <= 1.5)
    per_tip = sine_amplitude(t[w], fz[w], f) / np.mean(amp[w])
    expected = np.linalg.norm(modal_wrench_per_tip(strip, f, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                                                   np.array([0, 0, 1.0]))[:3])
    assert per_tip == pytest.approx(expected, rel=0.02)


def test_the_model_strip_decays_with_the_measured_law():
    """The strip with AmplitudeDamping c = 0.5 1/m (zeta = c A_tip in its bending dampers, set each step from its
    amplitude) decays as the law says: the drag law fitted to its clamp-force envelope, in tip amplitude, has slope
    c within 5 % and is chosen over the linear one; without it (c 0) the decay has no amplitude dependence and BDF2's
    numerical damping is all (zeta < 1e-3). Fails on the old code (no amplitude-dependent damping)."""
    strip = Strip()
    results = {}
    for c, duration in ((0.0, 2.0), (0.5, 4.0)):
        t, fz, amp = law_free_decay(strip, c, n_masses=8, duration=duration)
        f = fit_damped_sine(t, fz)[0]
        times, force_amp, _ = envelope(t, fz, 0.0, f, start=0.2)
        tip = force_amp * np.interp(times, t, amp)[0] / force_amp[0]  # the force envelope in tip amplitude [m]
        results[c] = decay_laws([(times, tip, 2 * math.pi * f)])
    assert best_decay_law(results[0.5]) == "drag"
    assert results[0.5]["drag"].params["c"] == pytest.approx(0.5, rel=0.05)
    assert results[0.0]["viscous"].params["zeta0"] < 1e-3
    assert results[0.0]["drag"].params["c"] < 0.02


@pytest.mark.bullet
def test_the_recordings_ask_for_damping_that_grows_with_the_amplitude():
    """On four beam_handling decays (two X, two Z; no model run): across files the law zeta0 + c A_tip beats the
    linear one (Akaike lower by > 50), Coulomb friction gets no share (b ~ 0), the X and Z pairs give the same slope
    within 30 %, and the per-file fits choose drag (demos/beam_damping_law.py: drag on 6 of 9, viscous on the three
    smallest decays, friction on none)."""
    if not BEAM_DATA.is_dir():
        pytest.skip(f"beam_handling recordings not found at {BEAM_DATA} (see ../shared/data/README.md)")
    from bullet_dlo.reality.beam import read_beam_csv
    from bullet_dlo.reality.beam_law import file_decay, shared_laws
    from bullet_dlo.reality.panda import Panda

    with Panda() as panda:
        decays = [file_decay(read_beam_csv(BEAM_DATA / f"ocp_{stem}_1.csv"), panda)
                  for stem in ("Xdown_15cm_0.35s", "Xup_25cm_0.44s", "Z_15cm_0.42s", "Z_35cm_0.61s")]
    assert [best_decay_law(d.fits) for d in decays] == ["drag"] * 4
    shared = shared_laws(decays)
    assert shared["drag"].aic < shared["viscous"].aic - 50
    assert shared["friction"].params["b"] < 1e-6
    slopes = [shared_laws([d for d in decays if f"_{k}" in d.name])["drag"].params["c"] for k in "XZ"]
    assert slopes[0] == pytest.approx(slopes[1], rel=0.3)


@pytest.mark.bullet
@pytest.mark.parametrize("args, word", [(["--amplitude-damping", "soft"], "--amplitude-damping"),
                                        (["--amplitude-damping", "11"], "--amplitude-damping"),
                                        (["--amplitude-damping", "0.4", "--arm", "measured"], "--arm compliant"),
                                        (["--amplitude-damping", "0.4"], "--strip-model planes or auto")])
def test_validate_beam_bad_amplitude_damping_is_one_line_exit_2(tmp_path, capsys, args, word):
    from bullet_dlo.cli.main import main

    code = main(["validate", "beam", str(tmp_path), str(tmp_path), "--json", str(tmp_path / "o.json"), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and word in err


@pytest.mark.bullet
def test_the_law_enters_the_arm_strip_loop_prediction():
    """predict_torques_compliant with amplitude_damping c: a joint-0 swing of the Panda (0.15 rad in 0.35 s, a stiff
    arm in the loop from q_d, so the clamp is at rest after the motion) rings with an added damping ratio of c times the
    strip's tip amplitude over the window (within 25 %: the amplitude falls by about 2x over it); with c = 0 the
    prediction is the old one. Fails on the old code (no such argument)."""
    pytest.importorskip("pybullet")
    from bullet_dlo.reality.beam import BeamRecording, EstimateFilter, Numerics
    from bullet_dlo.reality.beam_arm import ArmImpedance, predict_torques_compliant
    from bullet_dlo.reality.panda import Panda

    t = np.arange(0.0, 2.6, 1e-3)
    q0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785])
    s = np.clip((t - 0.1) / 0.35, 0.0, 1.0)[:, None]
    q = q0 + np.r_[0.15, np.zeros(6)] * (10 * s**3 - 15 * s**4 + 6 * s**5)
    dq = np.r_[0.15, np.zeros(6)] * (30 * s**2 - 60 * s**3 + 30 * s**4) / 0.35
    zero = np.zeros_like(q)
    rec = BeamRecording(t=t, q=q, q_d=q, dq=dq, dq_d=dq, tau_J=zero, tau_ext_hat_filtered=zero, name="swing")
    stiff = ArmImpedance(np.full(7, 1e7), np.full(7, 1e3), np.ones(7), np.arange(7) < 5)
    # the planes: the loop's model (the swing turns the flange 8.6 deg about the vertical, beyond auto's bound)
    est, numerics, slope = EstimateFilter(4.2, 0.0065), Numerics(strip_model="planes", n_masses=8), 1.0
    window = (t >= 0.8) & (t <= 2.5)
    zeta, tip_amp = {}, {}
    with Panda() as panda:
        for c in (0.0, slope):
            pred = predict_torques_compliant(rec, panda, stiff, Strip(), {}, numerics, est, drive="desired",
                                             amplitude_damping=c)
            w = window[:len(pred.t)]
            zeta[c] = fit_damped_sine(pred.t[w], pred.torques[w, 0])[1]
            tip = pred.tip[w] - pred.tip[w].mean(axis=0)
            f = fit_damped_sine(pred.t[w], pred.torques[w, 0])[0]
            tip_amp[c] = math.sqrt(sum(sine_amplitude(pred.t[w], tip[:, i], f) ** 2 for i in range(3)))
    assert tip_amp[slope] > 0.003  # the swing leaves millimetres at the tip: a measurable law
    assert zeta[0.0] < 2e-3  # no strip damping: BDF2's and the stiff arm's are all
    assert zeta[slope] - zeta[0.0] == pytest.approx(slope * tip_amp[slope], rel=0.25)
