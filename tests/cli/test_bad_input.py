"""Every bad input gets one clear line and exit code 2, before any work (issue 11).

Two kinds of proof: the fixed corpus of tests/cli/bad_inputs.py (every subcommand; the share
of clear errors must be 100 %), and property-based tests (hypothesis) that generate bad values
for scene files, capture specs and flags. All run in-process through ``bullet_dlo.cli.main.main``.
"""
from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import bad_inputs
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bullet_dlo.config.capture import PARAMETERS
from bullet_dlo.config.schema import CABLE_BOUNDS, LIMITS

RANGE = re.compile(r"\[|>=|> 0|at most|true or false|one of|integer|mapping|finite")
SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def check(argv: list[str], files: dict[str, object], names: str) -> None:
    """Run one bad input through the corpus runner and assert the clear error."""
    with tempfile.TemporaryDirectory() as root:
        outcome = bad_inputs.run_case(bad_inputs.Case("generated", argv, names, files), Path(root))
    assert outcome.ok, f"{argv} {files}: {outcome.why}: {outcome.stderr!r}"
    assert RANGE.search(outcome.stderr), f"no allowed range in {outcome.stderr!r}"


def test_the_whole_corpus_gets_clear_errors():
    outcomes = bad_inputs.measure()
    misses = [f"{o.case.label}: {o.why}" for o in outcomes if not o.ok]
    assert len(outcomes) > 250
    assert not misses, "\n".join(misses)


# ----- generated values ---------------------------------------------------------------------------
NOT_A_NUMBER = st.one_of(st.text(alphabet="abcxyz -_", min_size=1, max_size=8), st.booleans(),
                         st.lists(st.integers(), min_size=1, max_size=3),
                         st.sampled_from([math.nan, math.inf, -math.inf]))


def outside(lo: float, hi: float) -> st.SearchStrategy:
    """Finite numbers below ``lo`` or above ``hi`` (by more than round-off)."""
    below = st.floats(min_value=-1e300, max_value=lo - max(abs(lo), 1e-9) * 1e-6 - 1e-300, allow_nan=False)
    above = st.floats(min_value=hi + abs(hi) * 1e-6 + 1e-9, max_value=1e300, allow_nan=False)
    return st.one_of(below, above)


SCENE_BOUNDS = {f"cable.{k}": v for k, v in CABLE_BOUNDS.items() if k != "static_friction"}
SCENE_BOUNDS.update({"newton.max_iter": (1, 1000), "bullet.substeps": (1, LIMITS["substeps"])})


@st.composite
def bad_scene(draw):
    key = draw(st.sampled_from(sorted(SCENE_BOUNDS) + ["dt", "duration", "detector.max_strain"]))
    if key in SCENE_BOUNDS:
        value = draw(st.one_of(NOT_A_NUMBER, outside(*SCENE_BOUNDS[key])))
    else:
        value = draw(st.one_of(NOT_A_NUMBER, st.floats(max_value=0.0, allow_nan=False, allow_infinity=False)))
    return key, value


@SETTINGS
@given(bad_scene())
def test_generated_bad_scene_files(case):
    key, value = case
    engine = ["--engine", "bullet"] if key.startswith("bullet") else []
    check(["simulate", "{d}/s.yaml", *engine], {"s.yaml": bad_inputs.with_key(bad_inputs.SCENE, key, value)}, key)


SPEC_BOUNDS = {"camera.width": (1, LIMITS["pixels"]), "camera.height": (1, LIMITS["pixels"]),
               "camera.fps": (0.0, 1000.0), "episode.duration": (1e-3, 3600.0), "max_resamples": (1, 10_000),
               "episode.record_rate": (0.01, 1e5)}


@st.composite
def bad_spec(draw):
    key = draw(st.sampled_from(sorted(SPEC_BOUNDS) + ["sample.length", "sample.n_masses", "seed"]))
    if key.startswith("sample."):
        lo, hi = PARAMETERS[key.split(".")[1]][2]
        value = {"dist": "fixed", "value": draw(st.one_of(NOT_A_NUMBER, outside(lo, hi)))}
    elif key == "seed":
        value = draw(st.one_of(NOT_A_NUMBER, st.integers(max_value=-1), st.floats(0.1, 0.9)))
    else:
        value = draw(st.one_of(NOT_A_NUMBER, outside(*SPEC_BOUNDS[key])))
    return key, value


@SETTINGS
@given(bad_spec())
def test_generated_bad_capture_specs(case):
    key, value = case
    argv = ["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "2"]
    check(argv, {"c.yaml": bad_inputs.with_key(bad_inputs.SPEC, key, value)}, key)


FLAG_VALUES = st.one_of(st.sampled_from(["nan", "inf", "-inf", "0", "-1", "1e300"]),
                        st.floats(max_value=-1e-9, allow_nan=False, allow_infinity=False).map(repr))


@SETTINGS
@given(st.sampled_from(["--dt", "--duration"]), FLAG_VALUES)
def test_generated_bad_simulate_flags(flag, value):
    check(["simulate", "{d}/s.yaml", flag, value], {"s.yaml": bad_inputs.SCENE}, flag)


@SETTINGS
@given(st.sampled_from(["--episodes", "--workers"]),
       st.one_of(st.integers(max_value=0), st.integers(min_value=LIMITS["episodes"] + 1, max_value=10**30)))
def test_generated_bad_capture_counts(flag, value):
    argv = ["capture", "{d}/c.yaml", "--out", "{d}/out", "--episodes", "2", flag, str(value)]
    check(argv, {"c.yaml": bad_inputs.SPEC}, flag)


def test_capture_ranges_lie_inside_the_shared_cable_bounds():
    for key, (lo, hi) in CABLE_BOUNDS.items():
        if key in PARAMETERS and PARAMETERS[key][2]:
            plo, phi = PARAMETERS[key][2]
            assert lo <= plo <= phi <= hi, key


def test_a_generated_valid_scene_still_runs(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(yaml.safe_dump(bad_inputs.SCENE))
    from bullet_dlo.cli.main import main

    assert main(["simulate", str(scene), "--quiet"]) == 0
