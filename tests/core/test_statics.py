"""Static shapes against beam and bar theory, and the convergence order of both discretisations."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import (
    cantilever_convergence,
    cantilever_deflection,
    cantilever_model,
    hanging_elongation,
    hanging_model,
    small_deflection_spec,
)
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static


@pytest.fixture(scope="module")
def convergence():
    return {r["n_masses"]: r for r in cantilever_convergence((5, 10, 20, 40))}


def test_default_discretisation_meets_targets(convergence):
    assert abs(convergence[10]["default"]) <= 0.02
    assert abs(convergence[20]["default"]) <= 0.005


def test_default_converges_at_second_order(convergence):
    for n_coarse, n_fine in ((10, 20), (20, 40)):
        # error ~ (L/(n-1))^2: halving the segment length quarters it
        ratio = convergence[n_coarse]["default"] / convergence[n_fine]["default"]
        h_ratio = (n_fine - 1) / (n_coarse - 1)
        order = math.log(ratio) / math.log(h_ratio)
        assert 1.9 < order < 2.1, order


def test_paper_discretisation_is_first_order_and_worse(convergence):
    for n_coarse, n_fine in ((10, 20), (20, 40)):
        ratio = convergence[n_coarse]["paper"] / convergence[n_fine]["paper"]
        order = math.log(ratio) / math.log((n_fine - 1) / (n_coarse - 1))
        assert 0.8 < order < 1.2, order
    for n in (5, 10, 20, 40):
        assert abs(convergence[n]["paper"]) > 5 * abs(convergence[n]["default"])


def test_cantilever_clamp_moment_balances_weight():
    spec = small_deflection_spec(10)
    model = cantilever_model(spec)
    from bullet_dlo.core.kernels.forces import clamp_torque

    res = solve_static(model)
    tau = clamp_torque(model.kernel_arrays(), res.x, np.zeros_like(res.x), model.holder_plan().start_dir, 0)
    weight = spec.mass * 9.81
    # moment of the weight about the clamp: (L/2) M g about +y (arm shortened by the tiny sag only)
    assert tau[1] == pytest.approx(weight * spec.length / 2, rel=1e-3)
    assert abs(tau[0]) < 1e-9 and abs(tau[2]) < 1e-9


@pytest.mark.parametrize("n", [2, 5, 17])
@pytest.mark.parametrize("modulus", [1e6, 126e6])
def test_hanging_cable_stretch_matches_bar_theory(n, modulus):
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus)
    res = solve_static(hanging_model(spec))
    elongation = res.x[0, 2] - res.x[-1, 2] - spec.length
    # geometric nonlinearity is strain^2-small; trapezoidal lumping makes the sum exact
    assert elongation == pytest.approx(hanging_elongation(spec), rel=1e-3)


def test_static_solver_reports_convergence():
    spec = CableSpec.lv2017(n_masses=15)
    model = CableModel.straight(spec, ends=("clamped", "clamped"))
    res = solve_static(model)
    assert res.converged and res.iterations < 50
    assert np.all(np.isfinite(res.x))
    assert res.x[7, 2] < 0.5  # it sags
    assert cantilever_deflection(spec) > 0


@pytest.mark.parametrize("n", [640, 1000])
def test_fine_cantilever_converges_to_beam_theory(n):
    """Issue 26: at n >= ~500 a fixed force floor (k_s * eps * |x|, growing with n) exceeded the start's
    residual (one node's weight, shrinking with n): 'converged' at iteration 0, tip error -100 %."""
    spec = small_deflection_spec(n)
    res = solve_static(cantilever_model(spec))
    assert res.converged and res.iterations > 0
    error = cantilever_convergence((n,))[0]
    # second order: |error| ~ 9e-6 at n = 320, below 2e-6 at n = 640; round-off ~5e-7 beyond
    assert abs(error["default"]) < 2e-6, error
    assert 0.2e-2 < error["paper"] < 0.5e-2, error  # first order: 0.73 % at n = 320


def test_start_is_never_taken_for_converged():
    """No step taken, not converged: a residual below some floor proves nothing."""
    res = solve_static(cantilever_model(small_deflection_spec(1000)), max_iter=0)
    assert not res.converged and res.iterations == 0


@pytest.mark.parametrize("twist", [False, True])
@pytest.mark.parametrize("n", [8, 16])
@pytest.mark.parametrize("shorter", [1e-7, -1e-6])
def test_gravity_off_clamps_a_hair_off_the_cable_length_converge_to_the_bar_force(twist, n, shorter):
    """Gravity off, both ends clamped ``shorter`` [m] closer than the cable's length (negative: farther), tangents
    5e-8 rad apart, as two grippers hold a cable to the IK's precision: converged, and the clamps carry the bar's
    force E A shorter / L, equal and opposite. Before, the potential's round-off floor scaled with the load alone
    (none here): the steps at round-off were refused and the solve ended unconverged at 1e-12 N (a dual-arm scene
    with gravity off refused its settled start)."""
    from bullet_dlo.core.kernels.forces import total_forces
    from bullet_dlo.core.model import default_normal

    spec = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=n, twist=twist)
    d0, d1 = np.array([1.0, 0.0, -5e-8]), np.array([1.0, 5e-8, 5e-8])
    model = CableModel.straight(spec, (0.0, 0.0, 0.35), d0 / np.linalg.norm(d0), ("clamped", "clamped"), (),
                                (0.0, 0.0, 0.0))
    end = np.array([spec.length - shorter, 0.0, 0.35])
    d1 /= np.linalg.norm(d1)
    model = replace(model, last=replace(model.last, position=end, direction=d1, normal=default_normal(d1)))
    start = model.x0 + np.outer(np.linspace(0.0, 1.0, n), end - model.x0[-1])
    res = solve_static(model, start)
    assert res.converged
    f = np.zeros_like(res.x)
    total_forces(model.kernel_arrays(), res.x, np.zeros_like(res.x), model.holder_plan().start_dir, f)
    bar = spec.youngs_modulus * math.pi * spec.diameter ** 2 / 4 * shorter / spec.length  # [N] compression
    assert f[0, 0] == pytest.approx(-bar, rel=1e-3)  # the cable pushes the first clamp back (pulls, if longer)
    assert np.abs(f[0] + f[-1]).max() < 1e-6 * abs(bar)
