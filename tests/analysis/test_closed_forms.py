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
