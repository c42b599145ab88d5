"""Predicted critical steps against measured stability boundaries; implicit methods at robot
rates; the instability detector."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import DetectorOptions, simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt, critical_dt_from_modes, damping_bounds, stiffness_spectrum
from bullet_dlo.core.statics import solve_static


def study(modulus, n, damping=0.01, move=(0.0, 0.0, 0.005)):
    """The study's scenario: both ends clamped at rest length, last end moved 5 mm."""
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=damping)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", move, 0.02, 0.05)])


@pytest.mark.parametrize("modulus", [126e6, 1002.6e6])
@pytest.mark.parametrize("n", [10, 40])
@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_prediction_brackets_measured_boundary(modulus, n, integrator):
    model = study(modulus, n)
    start = solve_static(model).state()
    h_crit = critical_dt(model, integrator)
    below = simulate(model, integrator, 0.9 * h_crit, 0.2, state=start, max_records=3)
    above = simulate(model, integrator, 1.1 * h_crit, 0.2, state=start, max_records=3)
    assert below.stable, below.reason
    assert not above.stable
    assert 0.0 < above.time_to_instability < 0.2


def test_closed_forms_without_damping():
    w2 = np.array([4.0e6, 1.0e8])  # omega = 2e3, 1e4 rad/s
    assert critical_dt_from_modes("symplectic_euler", w2, 0.0) == pytest.approx(2.0 / 1e4)
    assert critical_dt_from_modes("rk4", w2, 0.0) == pytest.approx(2.0 * math.sqrt(2.0) / 1e4, rel=1e-6)
    assert critical_dt_from_modes("explicit_euler", w2, 0.0) == 0.0
    assert critical_dt_from_modes("explicit_euler", w2, 50.0) == pytest.approx(50.0 / 1e8)
    assert critical_dt_from_modes("implicit_euler", w2, 0.0) is None
    # damping lowers the symplectic limit: h = (-g + sqrt(g^2 + 4 w^2)) / w^2
    g = 3.0e3
    assert critical_dt_from_modes("symplectic_euler", w2, g) == pytest.approx((-g + math.sqrt(g * g + 4e8)) / 1e8)


def test_spectrum_matches_two_mass_closed_form():
    """Two masses, first pinned: one axial mode omega^2 = k/m and two zero-stiffness ones."""
    spec = CableSpec.lv2017(n_masses=2)
    model = CableModel.straight(spec, ends=("pinned", "free"), gravity=(0, 0, 0))
    w2 = stiffness_spectrum(model)
    assert w2[-1] == pytest.approx(spec.k_stretch / spec.point_masses()[1], rel=1e-12)
    assert np.allclose(w2[:2], 0.0, atol=1e-6 * w2[-1])


def test_explicit_euler_without_damping_is_detected_unstable():
    model = study(126e6, 10, damping=0.0)
    res = simulate(model, "explicit_euler", 1e-5, 1.0)
    assert not res.stable and res.reason is not None
    assert 0 < res.time_to_instability < 1.0
    assert res.steps == round(res.time_to_instability / 1e-5)  # stopped where it was detected


def test_damping_bounds_are_consistent():
    model = study(126e6, 10, damping=0.01)
    b = damping_bounds(model, 1e-6)
    w_max = math.sqrt(stiffness_spectrum(model)[-1])
    assert b.omega_max == pytest.approx(w_max)
    # explicit Euler: stable iff gamma >= dt w^2, i.e. k_d >= k_d_min
    assert (critical_dt(model, "explicit_euler") >= 1e-6) == (model.spec.damping >= b.k_d_min_explicit_euler)


STABILITY_GRID = [(e, n, dt) for e in (1e6, 1e8, 1e10) for n in (10, 50, 200) for dt in (1e-3, 1 / 60)]


def _scenarios(spec):
    yield "study", CableModel.straight(spec, ends=("clamped", "clamped"),
                                       motion=[Move("last", (0.0, 0.0, 0.005), 0.1, 0.1)])
    yield "swing", CableModel.straight(spec, ends=("clamped", "free"))
    yield "big move", CableModel.straight(spec, ends=("clamped", "clamped"),
                                          motion=[Move("last", (-0.15, 0.05, 0.1), 0.1, 0.5, (0.0, 1.0, 0.0))])


@pytest.mark.parametrize("modulus,n,dt", STABILITY_GRID)
def test_dissipative_implicit_methods_stable_at_robot_rates(modulus, n, dt):
    """implicit_euler and bdf2: stable at 1 kHz and 60 Hz for E 1 MPa..10 GPa, n up to 200, undamped,
    in the study's scenario, a free swing from horizontal and a 20 cm move with a 57 degree turn."""
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=0.0)
    for name, model in _scenarios(spec):
        for integrator in ("implicit_euler", "bdf2"):
            res = simulate(model, integrator, dt, 1.5, max_records=3)
            assert res.stable, (name, integrator, res.reason, res.time_to_instability)
            assert np.all(np.isfinite(res.final_state.x))


@pytest.mark.parametrize("modulus,n,dt", STABILITY_GRID)
def test_implicit_midpoint_stable_in_study_scenario(modulus, n, dt):
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=0.0)
    name, model = next(_scenarios(spec))
    res = simulate(model, "implicit_midpoint", dt, 1.5, max_records=3)
    assert res.stable, (res.reason, res.time_to_instability)


def test_detector_thresholds_are_configurable():
    model = study(126e6, 10)
    strict = simulate(model, "implicit_euler", 1e-3, 0.3, detector=DetectorOptions(max_strain=1e-9))
    assert not strict.stable and strict.reason == "segment strain beyond bound"
    relaxed = simulate(model, "implicit_euler", 1e-3, 0.3)
    assert relaxed.stable
