"""Capture specs with a ``motion:`` section (drawn gripper trajectories) and friction-grip parameters:
parsing, errors that name the key, reproducible draws, and older specs keeping their draws and digest."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from bullet_dlo.config.capture import MOVE_KEYS, PARAMETERS, RENAMED, CaptureSpec, parse_distribution
from bullet_dlo.core.boundary import Move, Sine, Waypoints, parse_motion
from bullet_dlo.core.validate import ParameterError

ROOT = Path(__file__).resolve().parents[2]
SPECS = ROOT / "demos" / "specs"
# the parameters and their order before the grip ones existed: their draws must never change
# ("friction" is named dynamic_friction since the one-vocabulary rename; same place, same draws)
OLD_KEYS = ("length", "diameter", "mass", "youngs_modulus", "n_masses", "damping", "damping_rate", "internal_damping",
            "dynamic_friction", "dt", "integrator", "robot", "hold_height", "displacement_x", "displacement_y",
            "displacement_z", "speed", "move_start", "noise_std", "sensor_rate")


def U(low: float, high: float) -> dict:
    return {"dist": "uniform", "low": low, "high": high}


SINE = {"type": "sine", "end": "last", "amplitude": [0, 0, U(0.01, 0.03)], "frequency": U(0.5, 2.0),
        "phase": {"dist": "normal", "mean": 0.0, "std": 0.5}, "start": 0.2, "duration": 1.0, "ramp": U(0.0, 0.2)}
PATH = {"type": "waypoints", "end": "first", "times": [0.1, U(0.4, 0.6), {"dist": "choice", "values": [0.9, 1.1]}],
        "displacements": [[0, 0, 0], [0.02, 0, U(0.0, 0.03)], [0.03, 0, 0]],
        "rotations": [[0, 0, 0], [0, 0, U(-0.3, 0.3)], [0, 0, 0]]}
TURN = {"type": "move", "end": "last", "displacement": [U(-0.02, 0.0), 0, 0], "rotation": [0, 0, U(0.1, 0.4)],
        "start": {"dist": "log_uniform", "low": 0.1, "high": 0.3}, "duration": 0.5}


def spec_with(motion: list | None = None, **sample) -> CaptureSpec:
    data = {"seed": 4, "sample": sample}
    if motion is not None:
        data["motion"] = motion
    return CaptureSpec.from_dict(data)


def old_draw(spec: CaptureSpec, index: int, attempt: int = 0) -> dict:
    """Draws as made before motion and grips: the old keys in order from [seed, index, attempt], then noise_seed."""
    rng = np.random.default_rng([spec.seed, index, attempt])
    out = {}
    for key in OLD_KEYS:
        kind, default, bounds = PARAMETERS[key]
        out[key] = (spec.sample.get(key) or parse_distribution(key, default)).sample(rng, kind, bounds)
    out["noise_seed"] = int(rng.integers(2**31 - 1))
    return out


def test_drawn_entries_build_core_items_within_their_ranges():
    spec = spec_with([SINE, PATH, TURN])
    for index in range(40):
        drawn = spec.draw(index)["motion"]
        json.dumps(drawn)  # JSON-able: stored as the episode's params
        sine, path, turn = parse_motion(drawn)
        assert isinstance(sine, Sine) and isinstance(path, Waypoints) and isinstance(turn, Move)
        assert 0.01 <= sine.amplitude[2] <= 0.03 and 0.5 <= sine.frequency <= 2.0 and 0.0 <= sine.ramp <= 0.2
        assert sine.amplitude[:2] == (0.0, 0.0) and sine.start == 0.2 and sine.duration == 1.0
        assert 0.4 <= path.times[1] <= 0.6 and path.times[2] in (0.9, 1.1) and path.times[0] == 0.1
        assert 0.0 <= path.displacements[1][2] <= 0.03 and -0.3 <= path.rotations[1][2] <= 0.3
        assert 0.1 <= turn.start <= 0.3 and -0.02 <= turn.displacement[0] <= 0.0 and 0.1 <= turn.rotation[2] <= 0.4
    # a spec without distributions draws exactly what it says
    fixed = {"type": "sine", "end": "last", "amplitude": [0, 0, 0.02], "frequency": 1.5}
    assert parse_motion(spec_with([fixed]).draw(3)["motion"]) == (Sine("last", (0, 0, 0.02), 1.5),)


def test_motion_draws_are_reproducible_per_seed_index_and_attempt():
    spec = spec_with([SINE, PATH, TURN])
    again = CaptureSpec.from_dict(json.loads(json.dumps(spec.to_dict())))
    assert again == spec and again.digest() == spec.digest()
    assert spec.draw(5)["motion"] == again.draw(5)["motion"] == spec.draw_motion(5)
    assert spec.draw(5)["motion"] != spec.draw(6)["motion"]
    assert spec.draw(5, attempt=1)["motion"] != spec.draw(5)["motion"]
    other_seed = CaptureSpec.from_dict({**spec.to_dict(), "seed": 5})
    assert other_seed.draw(5)["motion"] != spec.draw(5)["motion"]
    # the draws do not depend on how the entries' keys were written
    shuffled = [dict(reversed(list(e.items()))) for e in (SINE, PATH, TURN)]
    assert spec_with(shuffled).draw(5)["motion"] == spec.draw(5)["motion"]


def test_motion_leaves_the_sample_draws_alone():
    sample = {"length": U(0.2, 0.4), "robot": {"dist": "choice", "values": ["kuka", "panda"]}, "noise_std": U(0, 0.02)}
    plain, moving = spec_with(None, **sample), spec_with([SINE, TURN], **sample)
    for index in range(5):
        a, b = plain.draw(index), moving.draw(index)
        assert {k: v for k, v in a.items() if k not in MOVE_KEYS} == {k: v for k, v in b.items() if k != "motion"}
        assert not set(MOVE_KEYS) & set(b)  # the default move's parameters are not stored: they do not apply


def test_an_old_spec_keeps_its_draws_and_digest():
    raw = yaml.safe_load((SPECS / "dr_small.yaml").read_text())
    spec = CaptureSpec.from_dict(raw)
    for index in range(6):
        drawn = spec.draw(index)
        assert {k: drawn[k] for k in (*OLD_KEYS, "noise_seed")} == old_draw(spec, index)
        assert (drawn["grip"], drawn["grip_force"], drawn["grip_static_friction"], drawn["grip_dynamic_friction"],
                drawn["grip_reach"]) == ("clamp", 5.0, 0.5, 0.4, 0.02)  # DualArmSpec's defaults: a clamp
        assert "motion" not in drawn
    # the digest hashes the spec in the form it had before (no motion, no grip keys), built here from the file
    episode = {k: float(v) for k, v in raw["episode"].items()}
    old_form = {"seed": raw["seed"], "episode": episode, "policy": raw["policy"], "max_resamples": 20,
                "camera": {"fps": 0.0, "width": 160, "height": 120}, "resolve_tol": 0.02,
                "sample": {k: dict(v) for k, v in raw["sample"].items()}}
    for dist in old_form["sample"].values():
        for key in ("low", "high"):
            if key in dist:
                dist[key] = float(dist[key])
    # ... and under the sample keys' names before the one-vocabulary rename (friction, not dynamic_friction)
    legacy = {**old_form, "sample": {{v: k for k, v in RENAMED.items()}.get(k, k): v
                                     for k, v in old_form["sample"].items()}}
    assert "friction" in legacy["sample"] and "dynamic_friction" in old_form["sample"]
    digest = hashlib.sha256(json.dumps(legacy, sort_keys=True, default=str).encode()).hexdigest()[:16]
    assert spec.to_dict() == json.loads(json.dumps(old_form)) and spec.digest() == digest
    assert spec_with([SINE]).digest() != spec_with(None).digest()


def test_grip_parameters_are_drawn_after_the_old_ones():
    grip = {"grip": {"dist": "choice", "values": ["clamp", "friction"]}, "grip_force": U(1.0, 8.0),
            "grip_static_friction": U(0.5, 0.8), "grip_dynamic_friction": U(0.2, 0.5), "grip_reach": U(0.01, 0.05)}
    plain, gripping = spec_with(None, n_masses={"dist": "choice", "values": [8, 10]}), \
        spec_with(None, n_masses={"dist": "choice", "values": [8, 10]}, **grip)
    grips = set()
    for index in range(40):
        a, b = plain.draw(index), gripping.draw(index)
        assert {k: a[k] for k in (*OLD_KEYS, "noise_seed")} == {k: b[k] for k in (*OLD_KEYS, "noise_seed")}
        assert 1.0 <= b["grip_force"] <= 8.0 and 0.01 <= b["grip_reach"] <= 0.05
        assert 0.2 <= b["grip_dynamic_friction"] <= 0.5 <= b["grip_static_friction"] <= 0.8  # mu_d <= mu_s in every draw
        grips.add(b["grip"])
    assert grips == {"clamp", "friction"}
    # touching ranges are allowed (every draw still has mu_d <= mu_s)
    spec_with(None, grip_static_friction=U(0.4, 0.6), grip_dynamic_friction=U(0.1, 0.4))


@pytest.mark.parametrize("motion, sample, needle", [
    ({"type": "sine", "end": "last"}, {}, "motion must be a non-empty list of motion entries"),
    ([], {}, "motion must be a non-empty list of motion entries (type: move | waypoints | sine), got []"),
    ([3], {}, "motion[0] must be a mapping, got int"),
    ([{"type": "spin", "end": "last"}], {}, "motion[0].type must be one of move, waypoints, sine, got 'spin'"),
    ([SINE, {"type": "sine", "end": "last", "frequency": -1}], {},
     "motion[1].frequency [Hz] must be in [0.001, 1000.0], got -1"),
    ([{"type": "sine", "end": "last", "frequency": U(0.0, 2.0)}], {},
     "motion[0].frequency.low = 0.0 is outside the allowed range [0.001, 1000.0]"),
    ([{"type": "sine", "end": "last", "frequency": {"dist": "gauss", "mean": 1}}], {},
     "motion[0].frequency.dist must be one of uniform"),
    ([{"type": "sine", "end": "last", "frequency": {"dist": "uniform", "low": 1}}], {},
     "motion[0].frequency (uniform) needs exactly high, low"),
    ([{"type": "sine", "end": "last", "amplitude": [0, 0, U(0.05, 0.01)]}], {}, "motion[0].amplitude[2]: low (0.05)"),
    ([{"type": "sine", "end": "last", "amplitude": [0, 0]}], {}, "motion[0].amplitude must be [x, y, z]"),
    ([{"type": "sine", "end": "last", "phase": "late"}], {},
     "motion[0].phase [rad] must be a number in [-6.2832, 6.2832], got 'late'"),
    ([{"type": "sine", "end": "last", "duration": 1.0, "ramp": U(0.1, 0.6)}], {},
     "motion[0].ramp can be drawn above half the duration"),
    ([{"end": "last", "rotation": [0, 0, U(-7.0, 0.0)]}], {}, "motion[0].rotation[2].low = -7.0 is outside"),
    ([{"end": "last", "start": -1}], {}, "motion[0].start [s] must be in [0.0, 3600.0], got -1"),
    ([{"end": "last", "duration": {"dist": "fixed", "value": 0}}], {}, "motion[0].duration.value = 0"),
    ([{"end": "middle"}], {}, "motion[0]: motion end must be 'first' or 'last'"),
    ([{"displacement": [0, 0, 0.01]}], {}, "motion[0]: move motion entry needs 'end'"),
    ([{"end": "last", "speed": 0.1}], {}, "motion[0]: unknown move motion key(s) speed"),
    ([{**PATH, "times": [0.1, U(0.4, 1.0), 0.9]}], {}, "motion[0].times[2] can be drawn at or before times[1]"),
    ([{**PATH, "displacements": [[U(0, 0.01), 0, 0], [0, 0, 0], [0, 0, 0]]}], {},
     "motion[0].displacements[0] must be [0, 0, 0]"),
    ([{**PATH, "displacements": [[0, 0, 0], [0, 0, 0]]}], {}, "motion[0]: waypoints displacements must be 3"),
    ([PATH, {**PATH, "end": "first"}], {}, "motion: at most one waypoints entry per end"),
    ([SINE], {"speed": 0.1}, "sample.speed sets the default straight move"),
    ([SINE], {"displacement_z": 0.01}, "sample.displacement_z sets the default straight move"),
    (None, {"grip": "glue"}, "sample.grip: unknown grip 'glue'; known: clamp, friction"),
    (None, {"grip": U(0, 1)}, "sample.grip must be a choice or fixed"),
    (None, {"grip_force": 0.0}, "sample.grip_force.value = 0.0 is outside the allowed range [0.001, 1000.0]"),
    (None, {"grip_reach": U(0.0, 0.1)}, "sample.grip_reach.low = 0.0 is outside the allowed range"),
    (None, {"grip_static_friction": U(0.3, 0.6)}, "sample.grip_dynamic_friction can be drawn above sample.grip_static_friction (up to "
                                             "0.4 > 0.3)"),
    (None, {"grip_dynamic_friction": {"dist": "normal", "mean": 0.2, "std": 0.05}},
     "sample.grip_dynamic_friction can be drawn above sample.grip_static_friction"),
])
def test_bad_motion_and_grip_entries_are_refused_naming_the_key(motion, sample, needle):
    with pytest.raises(ParameterError) as info:
        spec_with(motion, **sample)
    assert needle in str(info.value)
    assert "\n" not in str(info.value)


def test_the_example_spec_loads_round_trips_and_draws():
    spec = CaptureSpec.from_yaml(SPECS / "capture_motion.yaml")
    assert CaptureSpec.from_dict(spec.to_dict()) == spec
    kinds = [type(m) for m in parse_motion(spec.draw(0)["motion"])]
    assert kinds == [Sine, Waypoints]
    assert {spec.draw(i)["grip"] for i in range(10)} == {"clamp", "friction"}
