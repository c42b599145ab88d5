"""Section and twist keys (issue 22) in scene files and capture specs: settable, randomisable, and refused
with one line naming the key when out of range."""
from __future__ import annotations

import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.plan import cable_spec

CABLE = {"length": 0.3, "diameter": 0.004, "mass": 0.03, "youngs_modulus": 126e6}


def test_scene_cable_takes_section_and_twist():
    tube = Scene.from_dict({"cable": {**CABLE, "section": "tube", "inner_diameter": 0.002, "twist": True,
                                      "poisson_ratio": 0.4}})
    assert tube.cable.section == "tube" and tube.cable.twist and tube.cable.poisson_ratio == 0.4
    assert tube.build_model().arrays.tw.k_twist.size == tube.cable.n_masses  # the model has a material frame
    strip = Scene.from_dict({"cable": {**CABLE, "diameter": 0.001, "section": "rectangle", "width": 0.01,
                                       "thickness": 0.001}})
    assert strip.cable.twist_enabled and strip.cable.width == 0.01
    assert not Scene.from_dict({"cable": CABLE}).cable.twist_enabled  # opt-in


@pytest.mark.parametrize("extra, needle", [
    ({"twist": "yes"}, "cable.twist must be true or false"),
    ({"twist": 1}, "cable.twist must be true or false"),
    ({"section": "hexagon"}, "cable.section must be one of round, tube, rectangle"),
    ({"section": "tube", "inner_diameter": -0.001}, "cable.inner_diameter must be in (0, diameter = 0.004) [m]"),
    ({"section": "tube", "inner_diameter": 0.005}, "cable.inner_diameter must be in (0, diameter = 0.004) [m]"),
    ({"section": "tube", "inner_diameter": 0}, "cable.inner_diameter must be in (0, diameter = 0.004) [m]"),
    ({"section": "tube"}, "cable.inner_diameter missing: a tube needs its bore, in (0, diameter) [m]"),
    ({"width": 0.01}, "cable.width is for section: rectangle only (section is round)"),
    ({"section": "rectangle", "width": 0.01}, "thickness must be a finite number > 0"),
    ({"section": "rectangle", "width": 2.0, "thickness": 0.001}, "cable.width must be in (0, 1.0] [m]"),
    ({"section": "rectangle", "width": -0.01, "thickness": 0.001}, "cable.width must be in (0, 1.0] [m]"),
    ({"section": "rectangle", "width": 0, "thickness": 0.001}, "cable.width must be in (0, 1.0] [m]"),
    ({"section": "rectangle", "width": 0.01, "thickness": "thin"}, "cable.thickness must be a number"),
    ({"poisson_ratio": 0.5}, "cable.poisson_ratio must be in [0.0, 0.4999]"),
])
def test_scene_section_errors_are_one_line_naming_the_key(extra, needle):
    with pytest.raises(ParameterError) as err:
        Scene.from_dict({"cable": {**CABLE, **extra}})
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_capture_randomises_section_and_twist():
    spec = CaptureSpec.from_dict({"sample": {
        "twist": {"dist": "choice", "values": [True, False]},
        "section": {"dist": "choice", "values": ["round", "tube", "rectangle"]},
        "inner_diameter": {"dist": "uniform", "low": 0.001, "high": 0.003},
        "width": 0.01, "thickness": 0.001, "poisson_ratio": {"dist": "uniform", "low": 0.2, "high": 0.45}}})
    cables = [cable_spec(spec.draw(i)) for i in range(30)]
    assert {c.section for c in cables} == {"round", "tube", "rectangle"}
    assert {c.twist for c in cables} == {True, False}
    assert all(0.001 <= c.inner_diameter <= 0.003 for c in cables if c.section == "tube")
    assert all(c.inner_diameter == 0.0 and c.width == 0.0 for c in cables if c.section == "round")
    assert all(0.2 <= c.poisson_ratio <= 0.45 for c in cables)
    assert CaptureSpec.from_dict(spec.to_dict()) == spec


def test_capture_without_section_keys_draws_as_before():
    """Specs that do not sample the new keys keep their draws, their episodes' keys and their digests."""
    spec = CaptureSpec.from_dict({"seed": 3, "sample": {"length": {"dist": "uniform", "low": 0.2, "high": 0.4}}})
    draw = spec.draw(5)
    assert not {"twist", "section", "inner_diameter", "width", "thickness", "poisson_ratio"} & set(draw)
    assert cable_spec(draw) == cable_spec({**draw, "twist": False, "section": "round", "poisson_ratio": 0.3})


@pytest.mark.parametrize("sample, needle", [
    ({"twist": "yes"}, "sample.twist.value must be true or false"),
    ({"twist": {"dist": "choice", "values": [1, 0]}}, "sample.twist.values must be true or false"),
    ({"twist": {"dist": "uniform", "low": 0, "high": 1}}, "sample.twist must be a choice or fixed"),
    ({"section": "hexagon"}, "sample.section: unknown section 'hexagon'"),
    ({"section": "tube", "inner_diameter": {"dist": "uniform", "low": 0.001, "high": 0.006}},
     "sample.inner_diameter can be drawn at or above sample.diameter"),
    ({"section": "rectangle", "width": 0.01}, "sample.thickness can be drawn at 0 m"),
    ({"section": "tube"}, "sample.inner_diameter can be drawn at 0 m"),
    ({"width": 0.2}, "sample.width.value = 0.2 is outside the allowed range [0.0, 0.05]"),
    ({"poisson_ratio": -0.1}, "sample.poisson_ratio.value = -0.1 is outside the allowed range [0.0, 0.49]"),
])
def test_capture_section_errors_are_one_line_naming_the_key(sample, needle):
    with pytest.raises(ParameterError) as err:
        CaptureSpec.from_dict({"sample": sample})
    assert needle in str(err.value) and "\n" not in str(err.value)
