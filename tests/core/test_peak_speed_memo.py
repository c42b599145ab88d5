"""The held ends' peak speed (the large-move warning's input, sampled at 20,000 times before a run) is sampled once
per motion: a fit runs one recording's motion tens of times with other parameters, and the sampling cost as much
as a short run (0.14 s). Another motion is sampled anew, so its warning is its own."""
from __future__ import annotations

from bullet_dlo.core import engine
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

SPEC = CableSpec.lv2017(n_masses=6)


def _run(amplitude: float, youngs_modulus: float = SPEC.youngs_modulus) -> list[str]:
    motion = [Sine("last", (0.0, 0.0, amplitude), 5.0)]
    model = CableModel.straight(SPEC.with_(youngs_modulus=youngs_modulus), ends=("clamped", "clamped"), motion=motion)
    return [w for w in simulate(model, "implicit_euler", 1 / 60, 2 / 60).warnings if "segment lengths per step" in w]


def test_a_motion_run_again_samples_its_peak_speed_once_and_another_motion_anew(monkeypatch):
    monkeypatch.setattr(engine, "_PEAK_MEMO", {}, raising=False)  # what earlier tests in this process left
    calls = []
    sample = engine.peak_speeds
    monkeypatch.setattr(engine, "peak_speeds", lambda *args: (calls.append(args[1:3]), sample(*args))[1])
    segment = SPEC.length / (SPEC.n_masses - 1)
    fast = 2.0 * segment * 60 / (2 * 3.141592653589793 * 5.0)  # peak speed x dt = 2 segments
    assert _run(1e-3) == [] and len(calls) == 1
    assert _run(1e-3, 2 * SPEC.youngs_modulus) == [] and len(calls) == 1  # same motion, other cable: remembered
    assert len(_run(fast)) == 1 and len(calls) == 2  # another motion: sampled, and it warns
    assert _run(1e-3) == [] and len(calls) == 2  # the first motion's answer kept


def test_a_fine_step_samples_the_motion_not_the_steps(monkeypatch):
    """At dt 1 us a 0.4 s run was sampled 1.6 million times (6 s of CPU) for a move of 0.1 s; now 100 times per
    shortest feature, and the peak is still the minimum-jerk closed form 1.875 d / T."""
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.engine import fastest_held_move

    monkeypatch.setattr(engine, "_PEAK_MEMO", {}, raising=False)
    counts = []
    sample = engine.peak_speeds
    monkeypatch.setattr(engine, "peak_speeds", lambda *args: (counts.append(args[2]), sample(*args))[1])
    model = CableModel.straight(SPEC, ends=("clamped", "clamped"), motion=[Move("last", (0.0, 0.0, 0.01), 0.1, 0.1)])
    _, end, speed = fastest_held_move(model, 1e-6, 0.4)
    assert end == "last" and abs(speed - 1.875 * 0.01 / 0.1) < 1e-3 * speed
    assert counts == [401]  # 100 per 0.1 s move over 0.4 s, not 4 per step (1.6 million)
