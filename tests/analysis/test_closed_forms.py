"""Closed forms and the reference set-ups: self-consistency and limits with known answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import (
    CLAMP_HEIGHT,
    cantilever_angular_frequency,
    cantilever_deflection,
    cantilever_frequency,
    cantilever_release,
    capstan_lift_off,
    capstan_ratio,
    catenary,
    release_gravity,
    small_deflection_spec,
    with_damping_rate,
)
from bullet_dlo.core.spec import CableSpec


def test_catenary_satisfies_its_length_and_weight():
    span, length, w = 0.25, 0.3, 2.0
    sag, h, v = catenary(span, length, w)
    a = h / w  # the catenary's parameter H / w [m]
    assert 2 * a * math.sinh(span / (2 * a)) == pytest.approx(length, rel=1e-9)
    assert sag == pytest.approx(a * (math.cosh(span / (2 * a)) - 1), rel=1e-12)
    assert v == pytest.approx(w * length / 2)  # each end carries half the weight


def test_catenary_shallow_limit_is_the_parabola():
    """Nearly taut: sag = sqrt(3 s (L - s) / 8) and H = w s^2 / (8 sag) to first order."""
    span, length, w = 1.0, 1.0005, 1.0
    sag, h, _ = catenary(span, length, w)
    assert sag == pytest.approx(math.sqrt(3 * span * (length - span) / 8), rel=1e-3)
    assert h == pytest.approx(w * span**2 / (8 * sag), rel=1e-3)


def test_cantilever_closed_forms_scale_as_beam_theory():
    spec = CableSpec.lv2017()
    stiffer = spec.with_(youngs_modulus=4 * spec.youngs_modulus)
    assert cantilever_deflection(stiffer) == pytest.approx(cantilever_deflection(spec) / 4)
    assert cantilever_frequency(stiffer) == pytest.approx(2 * cantilever_frequency(spec))
    assert cantilever_angular_frequency(spec) == pytest.approx(2 * math.pi * cantilever_frequency(spec))
    assert cantilever_deflection(small_deflection_spec(10)) == pytest.approx(1e-3 * spec.length)


def test_release_gravity_and_start_shape():
    spec = small_deflection_spec(20)
    g = release_gravity(spec, 2e-3)
    assert cantilever_deflection(spec, g) == pytest.approx(2e-3 * spec.length)
    model, start = cantilever_release(spec, 2e-3)
    assert np.allclose(model.gravity, 0.0) and np.all(start.v == 0.0)
    tip = CLAMP_HEIGHT - start.x[-1, 2]
    assert tip == pytest.approx(2e-3 * spec.length, rel=0.005)  # second-order discretisation, n = 20


def test_with_damping_rate():
    spec = with_damping_rate(CableSpec.lv2017(n_masses=7), 5.0)
    assert spec.damping_rate == pytest.approx(5.0) and spec.damping == 0.0  # the n-independent drag key
    assert spec.damping_coefficients() == pytest.approx(5.0 * spec.point_masses())


@pytest.mark.parametrize("theta", [math.pi / 2, math.pi, 2 * math.pi])
@pytest.mark.parametrize("mu", [0.0, 0.2, 0.5])
def test_capstan_of_a_weightless_string_is_the_exponential(theta, mu):
    assert capstan_ratio(theta, mu, 0.02, 0.5) == pytest.approx(math.exp(mu * theta), rel=1e-12)


@pytest.mark.parametrize("mu", [0.1, 0.4, 0.8])
def test_capstan_with_weight_is_the_arc_equation_integrated(mu):
    """Over the top of a horizontal cylinder, both sides hanging (theta = pi): the analytic arc solution against the
    known closed form w rho (2 mu / (1 + mu^2)) (1 + exp(mu pi)) and against the arc's equation integrated
    numerically (the tension's balance along and across the arc with friction, independent of the solution)."""
    from scipy.integrate import solve_ivp
    rho, t_s, w = 0.022, 0.5, 0.8
    tight = capstan_ratio(math.pi, mu, rho, t_s, weight_per_length=w) * t_s
    assert tight == pytest.approx(t_s * math.exp(mu * math.pi)
                                  + w * rho * 2 * mu / (1 + mu * mu) * (1 + math.exp(mu * math.pi)), rel=1e-12)

    def along(s, t):  # s from the slack side; alpha the position angle, pi - s / rho
        a = math.pi - s[0] / rho if np.ndim(s) else math.pi - s / rho
        pressure = t[0] / rho + w * math.sin(a)  # normal balance: p = T kappa - w (e_z . n), n inwards
        return [mu * pressure - w * math.cos(a)]  # tangential: friction against the slip plus gravity along t

    sol = solve_ivp(along, (0.0, math.pi * rho), [t_s], rtol=1e-11, atol=1e-13)
    assert sol.y[0, -1] == pytest.approx(tight, rel=1e-8)


def test_stiff_capstan_frictionless_is_balanced_at_any_stiffness():
    """Without friction the far tensions are equal whatever the rod's stiffness (sliding the rod along itself does
    no work): the lift-off loads' tangential parts, T cos Delta, match only at equal tensions."""
    for bend in (1e-6, 1e-5, 1e-4):
        assert capstan_ratio(math.pi, 0.0, 0.022, 0.5, bend) == pytest.approx(1.0, abs=1e-12)


def test_stiff_capstan_falls_below_the_string_at_second_order_in_the_lift_off():
    """ratio / exp(mu theta) - 1 -> -(1 + mu^2) (Delta_s^2 - Delta_t^2) / 2 as the bend length shrinks (the
    first-order terms of the two lift-off points cancel), and a stiffer rod holds less."""
    mu, theta, rho, t_s = 0.4, math.pi, 0.022, 0.5
    previous = 1.0
    for bend in (1e-7, 1e-6, 1e-5, 1e-4):
        ratio = capstan_ratio(theta, mu, rho, t_s, bend)
        d_s = capstan_lift_off(bend, t_s, rho)
        d_t = capstan_lift_off(bend, ratio * t_s, rho)
        predicted = -(1 + mu * mu) * (d_s ** 2 - d_t ** 2) / 2
        relative = ratio / math.exp(mu * theta) - 1.0
        assert relative < 0 and relative < previous
        previous = relative
        if d_s < 0.05:
            assert relative == pytest.approx(predicted, rel=0.1)


def test_capstan_lift_off_is_the_elastica_and_refuses_a_rod_that_does_not_wrap():
    # the free part's first integral at the lift-off: B kappa^2 / 2 = T (1 - cos Delta) with kappa = 1 / rho
    bend, tension, rho = 2e-4, 0.7, 0.02
    delta = capstan_lift_off(bend, tension, rho)
    assert bend / (2 * rho ** 2) == pytest.approx(tension * (1 - math.cos(delta)), rel=1e-12)
    with pytest.raises(ValueError, match="does not wrap"):
        capstan_lift_off(bend, bend / (2 * rho) ** 2, rho)
    with pytest.raises(ValueError, match="no arc in contact"):
        capstan_ratio(math.pi / 4, 0.3, rho, 0.2, bend)
    with pytest.raises(ValueError, match="mu >= 0"):
        capstan_ratio(math.pi, -0.1, rho, 0.5)
