"""Dynamics against physics: force balance, bending frequency, energy, order of accuracy,
held-end motion."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import cantilever_frequency, cantilever_model, measured_cantilever_frequency
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt


@pytest.mark.parametrize("integrator", ["implicit_euler", "bdf2"])
def test_static_hold_end_forces_balance_weight(integrator):
    spec = CableSpec.lv2017(n_masses=10, damping=0.05)
    model = CableModel.straight(spec, ends=("clamped", "clamped"))
    res = simulate(model, integrator, 1e-3, 6.0)
    assert res.stable
    f = res.end_forces[-1]
    weight = spec.mass * 9.81
    assert f[0, 2] + f[1, 2] == pytest.approx(-weight, rel=1e-3)  # the cable pulls the holders down
    assert f[0, 0] == pytest.approx(-f[1, 0], abs=1e-3 * weight)  # horizontal pulls equal and opposite
    assert f[0, 2] == pytest.approx(f[1, 2], rel=1e-3)  # symmetric hold: half the weight each
    assert f[0, 0] > 0.5 * weight  # a cable held at rest length sags and pulls the ends inwards


def test_end_forces_include_clamp_torque_share():
    """Cantilever: all of the weight goes into the single clamp."""
    spec = CableSpec.lv2017(n_masses=10, damping=0.05, youngs_modulus=5e9)
    model = cantilever_model(spec)
    res = simulate(model, "implicit_euler", 1e-3, 4.0)
    assert res.end_forces[-1, 0, 2] == pytest.approx(-spec.mass * 9.81, rel=1e-3)
    assert res.end_moments[0, 1] == pytest.approx(spec.mass * 9.81 * spec.length / 2, rel=1e-2)


@pytest.mark.parametrize("integrator,dt", [("symplectic_euler", 2e-5), ("implicit_midpoint", 1e-3), ("bdf2", 1e-3)])
def test_cantilever_first_frequency_within_3_percent(integrator, dt):
    spec = CableSpec.lv2017(n_masses=20)
    f = measured_cantilever_frequency(spec, integrator, dt)
    assert f == pytest.approx(cantilever_frequency(spec), rel=0.03)


@pytest.mark.parametrize("integrator,fraction", [("symplectic_euler", 0.9), ("symplectic_euler", 0.5),
                                                 ("implicit_midpoint", None)])
def test_undamped_energy_does_not_grow(integrator, fraction):
    spec = CableSpec.lv2017(n_masses=10, damping=0.0)
    model = cantilever_model(spec)  # released straight under gravity: large swinging motion
    dt = 1e-3 if fraction is None else fraction * critical_dt(model, integrator)
    res = simulate(model, integrator, dt, 2.0, max_records=4001)
    assert res.stable
    e = res.energy
    swing = spec.mass * 9.81 * spec.length  # energy scale of the motion
    k = len(e) // 10
    assert abs(np.mean(e[-k:]) - np.mean(e[:k])) < 0.01 * swing  # no drift
    assert np.max(np.abs(e - e[0])) < 0.05 * swing  # bounded oscillation only


def test_damping_dissipates_energy():
    spec = CableSpec.lv2017(n_masses=10, damping=0.02)
    res = simulate(cantilever_model(spec), "implicit_euler", 1e-3, 2.0)
    assert np.all(np.diff(res.energy) <= 1e-12)


def _order(integrator, dts, spec, duration=0.2):
    model = cantilever_model(spec)
    ref = simulate(model, "rk4", min(dts) / 16, duration).final_state.x
    errs = [np.max(np.abs(simulate(model, integrator, dt, duration).final_state.x - ref)) for dt in dts]
    return [math.log(errs[i] / errs[i + 1], 2) for i in range(len(errs) - 1)], errs


@pytest.mark.parametrize("integrator,order", [("explicit_euler", 1), ("symplectic_euler", 1), ("rk4", 4),
                                              ("implicit_euler", 1), ("bdf2", 2), ("implicit_midpoint", 2)])
def test_convergence_order(integrator, order):
    spec = CableSpec.lv2017(n_masses=5, youngs_modulus=1e6, damping=0.05)
    dt0 = 4e-5 if integrator == "explicit_euler" else (2e-4 if integrator in ("rk4", "symplectic_euler") else 2e-3)
    orders, errs = _order(integrator, [dt0, dt0 / 2, dt0 / 4], spec)
    assert all(abs(p - order) < 0.35 for p in orders), (orders, errs)


def test_held_end_follows_prescribed_motion():
    spec = CableSpec.lv2017(n_masses=10, damping=0.01)
    move = Move("last", (0.0, 0.02, 0.01), start=0.1, duration=0.2, rotation=(0.0, 0.0, 0.3))
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move])
    res = simulate(model, "implicit_euler", 1e-3, 0.5, record_every=1)
    x_end = res.x[:, -1]
    assert np.allclose(x_end[res.t <= 0.1], model.x0[-1])
    assert np.allclose(x_end[-1], model.x0[-1] + [0.0, 0.02, 0.01], atol=1e-12)
    mid = np.argmin(np.abs(res.t - 0.2))  # minimum-jerk: half way at half time
    assert np.allclose(x_end[mid], model.x0[-1] + [0.0, 0.01, 0.005], atol=1e-9)
    v_end = res.v[:, -1]
    assert np.max(np.abs(v_end[:, 1])) == pytest.approx(1.875 * 0.02 / 0.2, rel=1e-3)  # peak of 30 t^2(1-t)^2
    assert np.allclose(v_end[-1], 0.0)


def test_state_and_input_validation():
    spec = CableSpec.lv2017(n_masses=4)
    model = CableModel.straight(spec)
    from bullet_dlo.core.validate import ParameterError

    with pytest.raises(ParameterError, match="dt must be a finite number > 0"):
        simulate(model, "rk4", 0.0, 1.0)
    with pytest.raises(ParameterError, match="dt"):
        simulate(model, "rk4", float("nan"), 1.0)
    with pytest.raises(ParameterError, match="integrator must be one of"):
        simulate(model, "leapfrog", 1e-3, 1.0)
    with pytest.raises(ParameterError, match="duration"):
        simulate(model, "rk4", 1e-3, -1.0)
    with pytest.raises(ParameterError, match="shape"):
        simulate(model, "rk4", 1e-3, 1.0, state=CableState(np.zeros((3, 3)), np.zeros((3, 3))))
    with pytest.raises(ParameterError, match="free end cannot follow"):
        CableModel.straight(spec, ends=("clamped", "free"), motion=[Move("last", (0, 0, 0.01))])
    with pytest.raises(ParameterError, match="layout direction must be a non-zero direction"):
        CableModel.straight(spec, direction=(0, 0, 0))
