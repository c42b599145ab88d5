"""DEFORM with a curved rest shape (reality/deform.py RestShape, identify_rest_shape, fit_rest_shape): the knots are
checked, the rest angles are kappa l0, and on recordings made by the model with a hidden set the identification
recovers it and the prediction error falls; on the real DLO3 (when ../shared/data is present) the option runs."""
from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.cli.validate import add_deform_arguments
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality import deform
from bullet_dlo.reality.deform import (
    Numerics,
    RestShape,
    cable_spec,
    fit_rest_shape,
    identify_rest_shape,
    l1,
    load_trial,
    predict,
)

pytestmark = pytest.mark.core
DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "deform"
HIDDEN = {"bending_per_mass": 0.05, "damping_rate": 1.5, "internal_damping": 0.004}
KAPPA = 4.0  # hidden rest curvature [1/m]
NUM = Numerics(n_masses=11, dt=2e-3)
PAIR = 0.02  # outer held marker beyond each clamp [m]


def test_rest_shape_refuses_bad_knots_with_one_line():
    with pytest.raises(ParameterError, match="strictly increasing"):
        RestShape((0.5, 0.2), (1.0, 1.0))
    with pytest.raises(ParameterError, match=">= 0"):
        RestShape((0.2, 0.5), (1.0, -0.1))
    with pytest.raises(ParameterError, match="one kappa each"):
        RestShape((0.2, 0.5), (1.0,))


def test_rest_angles_are_kappa_times_the_segment_length_and_zero_at_the_clamps():
    rest = RestShape((0.25, 0.75), (2.0, 6.0))
    b = rest.angles(5, 0.8)  # nodes at sigma 0, .25, .5, .75, 1; l0 = 0.2 m
    assert np.allclose(b, [0.0, 2.0 * 0.2, 4.0 * 0.2, 6.0 * 0.2, 0.0])


def synthetic_trial(path: Path, motion, kappa: float, duration: float = 1.5) -> None:
    """A DEFORM-format pickle made by the core model with HIDDEN and a uniform rest curvature ``kappa`` [1/m]:
    a 0.5 m cable clamped 0.3 m apart (horizontal clamps), static, then moved; a marker at every node and
    an outer held marker 2 cm beyond each clamp, 100 Hz."""
    spec = cable_spec(0.5, HIDDEN, NUM.n_masses)
    model = CableModel.straight(spec, start=(0.0, 0.0, 1.0), motion=motion)
    span = np.array([0.3, 0.0, 0.0])
    first = model.first
    last = type(model.last)("clamped", first.position + span, model.last.direction, model.last.moves)
    arrays = model.arrays._replace(rest_angle=RestShape((0.0, 1.0), (kappa, kappa)).angles(spec.n_masses, 0.5))
    x_line = first.position + np.outer(np.linspace(0, 1, model.n), span)
    model = CableModel(spec, first, last, model.gravity, arrays, x_line)
    x0 = model.x0.copy()
    x0[1:-1, 2] -= 0.15 * np.sin(np.pi * np.linspace(0, 1, model.n))[1:-1]
    x0[1:-1, 1] += 0.03 * np.sin(np.pi * np.linspace(0, 1, model.n))[1:-1]  # off the plane: the set picks one
    res0 = solve_static(model, x0)
    assert res0.converged
    res = simulate(model, NUM.integrator, NUM.dt, duration, state=CableState(res0.x, np.zeros_like(res0.x), 0.0),
                   record_every=5, max_records=10**6)
    assert res.stable
    x = res.x[: round(duration * 100) + 1]
    d = np.array([1.0, 0.0, 0.0])
    markers = np.concatenate([(x[:, 0] - PAIR * d)[:, None], x, (x[:, -1] + PAIR * d)[:, None]], axis=1)
    path.write_bytes(pickle.dumps(markers.transpose(0, 2, 1).tolist()))


@pytest.fixture(scope="module")
def curved_trials(tmp_path_factory):
    folder = tmp_path_factory.mktemp("curved")
    motions = [(Move("last", (0.05, 0.12, 0.06), 0.1, 0.6),),
               (Move("first", (0.0, -0.08, 0.05), 0.0, 0.5), Move("last", (0.0, 0.08, -0.03), 0.3, 0.7))]
    for k, motion in enumerate(motions):
        synthetic_trial(folder / f"{k}.pkl", motion, KAPPA)
    return [load_trial(p) for p in sorted(folder.glob("*.pkl"))]


def test_the_hidden_set_changes_the_shape_beyond_the_tolerance(curved_trials):
    """The straight model with the true parameters misses these recordings by far more than the curved one."""
    straight = np.mean([l1(predict(r, HIDDEN, NUM)[0], r) for r in curved_trials])
    true = RestShape((0.0, 1.0), (KAPPA, KAPPA))
    curved = np.mean([l1(predict(r, HIDDEN, NUM, rest=true)[0], r) for r in curved_trials])
    assert curved < 1e-4 < 0.1 * straight, (curved, straight)


def test_fit_recovers_the_hidden_set_parameters_and_markers(curved_trials):
    """From straight: the first identification step (mean turning at the markers) lowers the error, the least
    squares on the marker positions then finds the rest curvature at every knot within 10 % of the truth, the
    three parameters within 5 %, and the marker error falls below a tenth of the straight model's."""
    rest, history = identify_rest_shape(curved_trials, HIDDEN, NUM, iterations=1)
    assert history[1] < history[0]
    rest, f, info = fit_rest_shape(curved_trials, HIDDEN, NUM, max_evaluations=30)
    assert np.all(np.abs(np.asarray(rest.kappa) / KAPPA - 1.0) < 0.1), rest.kappa
    for k, v in HIDDEN.items():
        assert abs(f.values[k] / v - 1.0) < 0.05, (k, f.values[k])
    after = np.mean([l1(predict(r, f.values, NUM, rest=rest)[0], r) for r in curved_trials])
    assert after < 0.1 * info["train_l1_straight"], (after, info)


@pytest.mark.skipif(not (DATA / "DLO3").is_dir(), reason=f"DEFORM data not found at {DATA} (../shared/data/deform)")
def test_validate_deform_rest_shape_on_real_dlo3_reports_both(tmp_path):
    """Bounded: 2 train, 1 eval trial, n = 11, a handful of runs. --rest-shape writes the shape, the
    straight model's eval L1 beside it, and stays stable."""
    import argparse
    import json

    parser = argparse.ArgumentParser()
    add_deform_arguments(parser)
    out = tmp_path / "dlo3.json"
    args = parser.parse_args([str(DATA / "DLO3"), "--json", str(out), "--max-train-trials", "2", "--max-eval-trials",
                              "1", "--max-evaluations", "6", "--n-masses", "11", "--no-numerics-check", "--no-plots",
                              "--rest-shape"])
    assert deform.main(args) == 0
    got = json.loads(out.read_text())
    shape = got["rest_shape"]
    assert len(shape["sigma"]) == len(shape["kappa_per_m"]) > 3 and min(shape["kappa_per_m"]) >= 0
    assert math.isfinite(got["eval_l1"]) and math.isfinite(got["straight"]["eval_l1"])
    assert all(r["stable"] for r in got["trials"]["eval"].values())
