"""Cable specification: derived quantities and validation messages."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.spec import CableSpec, preset
from bullet_dlo.core.validate import ParameterError


def test_lv2017_preset_matches_table_2():
    spec = preset("lv2017")
    assert (spec.length, spec.diameter, spec.mass, spec.youngs_modulus) == (0.3, 0.004, 0.03, 126e6)
    assert spec.poisson_ratio == 0.3 and spec.dynamic_friction == 0.2 and spec.static_friction == 0.3


def test_derived_quantities():
    spec = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=10)
    area = math.pi * 0.004**2 / 4
    inertia = math.pi * 0.004**4 / 64
    l0 = 0.3 / 9
    assert spec.area == pytest.approx(area)
    assert spec.second_moment == pytest.approx(inertia)
    assert spec.rest_length == pytest.approx(l0)
    assert spec.k_stretch == pytest.approx(126e6 * area / l0)
    assert spec.k_bend == pytest.approx(126e6 * inertia / l0)
    assert spec.k_bend_clamp == pytest.approx(2 * 126e6 * inertia / l0)
    assert spec.with_(discretisation="paper").k_bend_clamp == pytest.approx(126e6 * inertia / l0)


@pytest.mark.parametrize("disc", ["default", "paper"])
def test_point_masses_sum_to_total(disc):
    spec = CableSpec.lv2017(n_masses=7, discretisation=disc)
    m = spec.point_masses()
    assert m.shape == (7,) and m.sum() == pytest.approx(0.03)
    if disc == "paper":
        assert np.allclose(m, 0.03 / 7)
    else:
        assert m[0] == pytest.approx(m[3] / 2) and m[-1] == pytest.approx(m[3] / 2)


def test_damping_gives_uniform_decay_rate():
    spec = CableSpec.lv2017(n_masses=8, damping=0.02)
    rate = spec.damping_coefficients() / spec.point_masses()
    assert np.allclose(rate, spec.mass_damping_rate)
    paper = spec.with_(discretisation="paper")
    assert np.allclose(paper.damping_coefficients(), 0.02)  # Lv's per-mass k_d exactly


@pytest.mark.parametrize(
    "field,value,needle",
    [
        ("length", 0.0, "length must be a finite number > 0"),
        ("length", -1.0, "length"),
        ("diameter", float("nan"), "diameter"),
        ("mass", float("inf"), "mass"),
        ("youngs_modulus", -5.0, "youngs_modulus"),
        ("n_masses", 1, "n_masses must be an integer in [2,"),
        ("n_masses", 2.5, "n_masses"),
        ("damping", -0.1, "damping must be a finite number >= 0"),
        ("dynamic_friction", float("nan"), "dynamic_friction"),
        ("poisson_ratio", 0.5, "poisson_ratio must be in [0.0, 0.5)"),
        ("discretisation", "fancy", "discretisation must be one of default, paper"),
        ("length", "abc", "length must be a number"),
        ("width", 1.5, "width must be in (0, 1.0] [m] for section: rectangle"),  # scene files refuse it too
        ("thickness", 2.0, "thickness must be in (0, 1.0] [m] for section: rectangle"),
    ],
)
def test_invalid_values_name_the_parameter(field, value, needle):
    with pytest.raises(ParameterError, match=None) as err:
        section = {"section": "rectangle", "width": 0.01, "thickness": 0.001} if field in ("width", "thickness") else {}
        CableSpec.lv2017(**{**section, field: value})
    assert needle in str(err.value)


def test_unknown_preset_and_keys():
    with pytest.raises(ParameterError, match="unknown cable preset 'nope'; known presets: lv2017"):
        preset("nope")
    with pytest.raises(ParameterError, match="unknown cable parameter"):
        CableSpec.from_dict({"preset": "lv2017", "colour": "red"})
    with pytest.raises(ParameterError, match="missing"):
        CableSpec.from_dict({"length": 1.0})
    spec = CableSpec.from_dict({"preset": "lv2017", "n_masses": 20})
    assert spec.n_masses == 20 and spec.length == 0.3


def test_spec_is_immutable():
    spec = preset("lv2017")
    with pytest.raises(Exception):
        spec.length = 1.0  # type: ignore[misc]
