"""DEFORM: gravity's direction in the motion-capture frame and quadratic air drag as extra fitted
parameters (``validate deform --fit-gravity-tilt / --fit-drag``, issue 21), on recordings made by the
model itself with a known tilt."""
from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.cli.validate import add_deform_arguments
from bullet_dlo.core.boundary import Move, Sine
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import STANDARD_GRAVITY, CableModel, CableState, build_arrays
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.reality import deform
from bullet_dlo.reality.deform import Numerics, cable_spec, fit, gravity_of, jackknife, load_trial

pytestmark = pytest.mark.core
HIDDEN = {"bending_per_mass": 0.05, "damping_rate": 1.5, "internal_damping": 0.004,
          "gravity_tilt_x": 0.06, "gravity_tilt_y": -0.04}
NUM = Numerics(n_masses=11, dt=2e-3)
PAIR = 0.02  # outer held marker beyond each clamp [m]
MOTIONS = [
    (Move("last", (0.05, 0.12, 0.06), 0.1, 0.6),),
    (Sine("first", (0.0, 0.04, 0.0), 1.3, ramp=0.3, duration=1.5),),
    (Move("first", (0.0, -0.08, 0.05), 0.0, 0.5), Move("last", (0.0, 0.08, -0.03), 0.3, 0.7)),
]


def test_gravity_of_turns_minus_z_by_the_two_tilts_and_keeps_its_magnitude():
    """No tilt: the standard gravity; tilts tx, ty: |g| kept, the angle off -z is atan(sqrt(tan^2 tx + tan^2 ty))
    and the horizontal part points along (tan tx, tan ty)."""
    assert np.allclose(gravity_of({}), STANDARD_GRAVITY, atol=1e-15)
    g = gravity_of({"gravity_tilt_x": 0.06, "gravity_tilt_y": -0.04})
    assert math.isclose(np.linalg.norm(g), np.linalg.norm(STANDARD_GRAVITY), rel_tol=1e-14)
    off = math.acos(-g[2] / np.linalg.norm(g))
    assert math.isclose(off, math.atan(math.hypot(math.tan(0.06), math.tan(-0.04))), rel_tol=1e-12)
    assert math.isclose(g[0] / g[1], math.tan(0.06) / math.tan(-0.04), rel_tol=1e-12)


def test_drag_per_mass_becomes_the_cores_quadratic_drag():
    """drag_per_mass k [1/m]: the core's segment constant 1/2 rho_air C_d d l0 over the segment's mass is k."""
    spec = cable_spec(0.5, {**HIDDEN, "drag_per_mass": 0.3}, 11)
    assert math.isclose(spec.drag_constant / (deform.LINEAR_DENSITY * spec.rest_length), 0.3, rel_tol=1e-12)
    assert cable_spec(0.5, HIDDEN, 11).drag_coefficient == 0.0


def tilted_trial(path: Path, motion, values: dict, duration: float = 1.5, noise: float = 0.002, seed: int = 0) -> None:
    """A DEFORM-format pickle made by the core model with ``values`` (gravity tilted as they say): a 0.5 m
    cable clamped 0.3 m apart, static at the start under the tilted gravity, then moved by ``motion``;
    markers at every node and an outer held marker 2 cm beyond each clamp, 100 Hz, noise [m] on the free ones."""
    spec = cable_spec(0.5, values, NUM.n_masses)
    g = gravity_of(values)
    plain = CableModel.straight(spec, start=(0.0, 0.0, 1.0), motion=motion)
    span = np.array([0.3, 0.0, 0.0])
    first = plain.first
    last = type(plain.last)("clamped", first.position + span, plain.last.direction, plain.last.moves)
    model = CableModel(spec, first, last, g, build_arrays(spec, "clamped", "clamped", g),
                       first.position + np.outer(np.linspace(0, 1, plain.n), span))
    x0 = model.x0.copy()
    x0[1:-1, 2] -= 0.15 * np.sin(np.pi * np.linspace(0, 1, model.n))[1:-1]
    x0 = solve_static(model, x0).x
    res = simulate(model, NUM.integrator, NUM.dt, duration, state=CableState(x0, np.zeros_like(x0), 0.0),
                   record_every=5, max_records=10**6)
    assert res.stable
    x = res.x[: round(duration * 100) + 1]
    x[:, 1:-1] += np.random.default_rng(seed).normal(0.0, noise, x[:, 1:-1].shape)
    d = np.array([1.0, 0.0, 0.0])
    markers = np.concatenate([(x[:, 0] - PAIR * d)[:, None], x, (x[:, -1] + PAIR * d)[:, None]], axis=1)
    path.write_bytes(pickle.dumps(markers.transpose(0, 2, 1).tolist()))


@pytest.fixture(scope="module")
def tilted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tilted")
    for seed in range(3):
        tilted_trial(folder / f"{seed}.pkl", MOTIONS[seed], HIDDEN, seed=seed)
    return [load_trial(p) for p in sorted(folder.glob("*.pkl"))]


def test_fit_recovers_a_hidden_gravity_tilt_within_its_interval(tilted):
    """Made by the model with gravity tilted 3.4 deg towards +x and 2.3 deg towards -y (2 mm marker noise):
    fitted with the three parameters, both tilts' leave-one-trial-out intervals cover the truth; the tilt
    across the chord (y: it swings the sag plane sideways) lands within 0.5 deg (three trials: its interval, with
    Student's t at 2 dof, is about 6 deg wide and not called identifiable); the
    tilt along the chord (x: it only shifts the sag towards one clamp) is seen far more weakly, and its
    interval says so (wider than the y one). The residual falls to the noise's level; with the tilts set to 0 it rises."""
    f = fit(tilted, NUM, max_evaluations=28, guess={k: HIDDEN[k] for k in deform.PARAMETERS},
            extra=("gravity_tilt_x", "gravity_tilt_y"))
    params = jackknife(f)
    for k in ("gravity_tilt_x", "gravity_tilt_y"):
        p = params[k]
        assert p["interval_95"][0] <= HIDDEN[k] <= p["interval_95"][1], (k, p)
        assert p["unit"] == "rad"
    y, x = params["gravity_tilt_y"], params["gravity_tilt_x"]
    assert abs(y["value"] - HIDDEN["gravity_tilt_y"]) < math.radians(0.5), y
    assert y["trials"] == 3 and y["t_quantile"] > 4.0  # three trials: Student's t with 2 dof, not 1.96
    assert np.diff(x["interval_95"])[0] > 2 * np.diff(y["interval_95"])[0]
    rms = lambda res: float(np.sqrt(np.mean(np.concatenate(res) ** 2)))
    assert rms(f.residuals) < 2.5 * 0.002  # the noise, and what it does to the start (as in test_deform.py)
    level = deform.Residual(tilted, NUM).per_trial(deform.theta_of(f.values, deform.PARAMETERS))  # tilts set to 0
    assert rms(level) > 1.05 * rms(f.residuals), (rms(level), rms(f.residuals))


def test_fit_refuses_an_unknown_extra_parameter(tilted):
    with pytest.raises(ParameterError, match="extra: 'wind' is not"):
        fit(tilted, NUM, max_evaluations=4, extra=("wind",))


def test_validate_deform_with_fit_gravity_tilt_writes_the_tilts_and_the_untilted_stage(tmp_path):
    """``validate deform --fit-gravity-tilt`` (bounded: 2 train, 1 eval trial, n = 11, a few runs): the tilts in
    rad among the parameters, gravity's vector of magnitude |g|, and the same fit's first stage (no tilt) beside
    it; --rest-shape with it is refused in one line."""
    import argparse
    import json

    for split, seeds in (("train", (0, 1)), ("eval", (2,))):
        (tmp_path / split).mkdir()
        for seed in seeds:
            tilted_trial(tmp_path / split / f"{seed}.pkl", MOTIONS[seed], HIDDEN, duration=1.0, seed=seed)
    parser = argparse.ArgumentParser()
    add_deform_arguments(parser)
    common = ["--json", str(tmp_path / "o.json"), "--n-masses", "11", "--max-evaluations", "8",
              "--no-numerics-check", "--no-plots", "--fit-gravity-tilt"]
    assert deform.main(parser.parse_args([str(tmp_path), *common])) == 0
    out = json.loads((tmp_path / "o.json").read_text())
    assert out["parameters"]["gravity_tilt_y"]["unit"] == "rad"
    assert set(deform.PARAMETERS) < set(out["parameters"])
    assert math.isclose(np.linalg.norm(out["gravity_m_per_s2"]), 9.81, rel_tol=1e-12)
    g = gravity_of({k: out["parameters"][k]["value"] for k in ("gravity_tilt_x", "gravity_tilt_y")})
    assert np.allclose(out["gravity_m_per_s2"], g)
    assert out["straight"]["parameters"]["gravity_tilt_y"] == 0.0 and math.isfinite(out["straight"]["eval_l1"])
    with pytest.raises(ParameterError, match="--rest-shape cannot be combined") as err:
        deform.main(parser.parse_args([str(tmp_path), *common, "--rest-shape"]))
    assert "\n" not in str(err.value)


def test_jackknife_states_an_unseen_parameter_without_overflowing():
    """Leave-one-out fits that run off to exp(1000) (a parameter the data do not see, e.g. drag at its lower
    bound) give the box as the interval and 'not identifiable', not an OverflowError."""
    names = deform.PARAMETERS + ("drag_per_mass",)
    values = {**HIDDEN, "drag_per_mass": 1e-4}
    theta = deform.theta_of(values, names)
    jac = [np.ones((4, 4)), np.ones((4, 4))]
    f = deform.Fit(deform.values_of(theta, names), theta, jac, [np.zeros(4)] * 2, 1, 0.0, 1.0, "", names)
    loo = np.array([theta, theta + np.array([0.0, 0.0, 0.0, 2000.0])])
    p = jackknife(f, loo)["drag_per_mass"]
    assert p["interval_95"] == list(deform.EXTRA_BOUNDS["drag_per_mass"]) and not p["identifiable"]
