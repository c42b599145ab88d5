"""One vocabulary (issue 20, deliverable 5): one name per concept, old names deprecated for one release,
closed sets as enums checked once at the boundary with one line listing the allowed values."""
from __future__ import annotations

import dataclasses
import warnings

import pytest
import yaml

from bullet_dlo.config.capture import RENAMED as SPEC_RENAMED
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.robot import MIN_TABLE_CLEARANCE, ArmsOptions, DualArmSpec
from bullet_dlo.config.scene import Scene
from bullet_dlo.core import enums
from bullet_dlo.core.enums import (
    Discretisation,
    Dist,
    EndMode,
    GripKind,
    InitialShape,
    IntegratorName,
    ObstacleType,
    Payload,
    Section,
    SelfCollision,
    Sync,
    ToleranceTarget,
    UnstablePolicy,
)
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

CABLE = {"length": 0.3, "diameter": 0.004, "mass": 0.03, "youngs_modulus": 126e6, "n_masses": 5}


def scene(**top) -> dict:
    return {"cable": dict(CABLE), "dt": 1e-3, "duration": 0.01, **top}


def deprecated(fn, *args, **kwargs):
    """``fn(...)`` and the messages of the DeprecationWarnings it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args, **kwargs)
    return out, [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]


def quiet(fn, *args, **kwargs):
    """``fn(...)``, failing on any DeprecationWarning (new names must not warn)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        return fn(*args, **kwargs)


# ----- old names: a warning naming the new one, and the same values -------------------------------------
def test_cable_friction_is_dynamic_friction_in_yaml_constructor_and_with():
    new = quiet(Scene.from_dict, scene(cable={**CABLE, "dynamic_friction": 0.45, "static_friction": 0.6}))
    old, msgs = deprecated(Scene.from_dict, scene(cable={**CABLE, "friction": 0.45, "static_friction": 0.6}))
    assert old == new and new.cable.dynamic_friction == 0.45
    assert msgs == ["cable.friction is deprecated; use cable.dynamic_friction (the old name goes in the next release)"]
    built, msgs = deprecated(CableSpec, 0.3, 0.004, 0.03, 126e6, friction=0.25)
    assert built == CableSpec(0.3, 0.004, 0.03, 126e6, dynamic_friction=0.25) and "use dynamic_friction" in msgs[0]
    assert deprecated(CableSpec.lv2017().with_, friction=0.25)[0].dynamic_friction == 0.25
    assert deprecated(CableSpec.lv2017, friction=0.25)[0] == CableSpec.lv2017(dynamic_friction=0.25)
    alias, msgs = deprecated(lambda: CableSpec.lv2017(dynamic_friction=0.25).friction)  # read-only, one release
    assert alias == 0.25 and msgs == ["CableSpec.friction is deprecated; use CableSpec.dynamic_friction"]
    with pytest.raises(ParameterError, match="give only dynamic_friction"):
        CableSpec.from_dict({"preset": "lv2017", "friction": 0.1, "dynamic_friction": 0.2})


def test_grip_friction_pair_is_two_named_coefficients():
    new = quiet(Scene.from_dict, scene(arms={"grip": "friction", "grip_static_friction": 0.7,
                                             "grip_dynamic_friction": 0.3}))
    old, msgs = deprecated(Scene.from_dict, scene(arms={"grip": "friction", "grip_friction": [0.7, 0.3]}))
    assert old.arms == new.arms and (new.arms.grip_static_friction, new.arms.grip_dynamic_friction) == (0.7, 0.3)
    assert msgs == ["arms.grip_friction is deprecated; use arms.grip_static_friction and arms.grip_dynamic_friction "
                    "(the old name goes in the next release)"]
    spec = DualArmSpec.from_scene(new)
    pair, msgs = deprecated(lambda: spec.grip_friction)  # the read-only alias of one release warns
    assert (spec.grip_static_friction, spec.grip_dynamic_friction) == (0.7, 0.3) == pair and "deprecated" in msgs[0]
    for cls in (DualArmSpec, ArmsOptions):
        built, msgs = deprecated(cls, grip_friction=(0.7, 0.3))
        assert built == cls(grip_static_friction=0.7, grip_dynamic_friction=0.3) and len(msgs) == 1
    with pytest.raises(ParameterError, match="give only those"):
        ArmsOptions.from_dict({"grip_friction": [0.7, 0.3], "grip_static_friction": 0.7})
    # Coulomb: the grip slips at or below what it holds, on both paths, naming each path's keys
    with pytest.raises(ParameterError, match=r"^arms.grip_dynamic_friction \(0.8\) must be at most arms.grip_static"):
        ArmsOptions(grip_static_friction=0.5, grip_dynamic_friction=0.8)
    with pytest.raises(ParameterError, match=r"^grip_dynamic_friction \(0.8\) must be at most grip_static_friction"):
        DualArmSpec(grip_static_friction=0.5, grip_dynamic_friction=0.8)


def test_capture_spec_old_keys_warn_and_keep_values_draws_and_digest():
    u = {"dist": "uniform"}
    sample_new = {"dynamic_friction": {**u, "low": 0.1, "high": 0.3}, "grip": "friction",
                  "grip_static_friction": {**u, "low": 0.5, "high": 0.7},
                  "grip_dynamic_friction": {**u, "low": 0.2, "high": 0.4}}
    old_names = {v: k for k, v in SPEC_RENAMED.items()}
    sample_old = {old_names.get(k, k): v for k, v in sample_new.items()}
    new = quiet(CaptureSpec.from_dict, {"seed": 3, "sample": sample_new})
    old, msgs = deprecated(CaptureSpec.from_dict, {"seed": 3, "sample": sample_old})
    assert old == new and old.digest() == new.digest()
    assert sorted(msgs) == sorted(f"sample.{o} is deprecated; use sample.{n} (the old name goes in the next release)"
                                  for o, n in SPEC_RENAMED.items())
    for i in range(4):
        d = new.draw(i)
        assert d == old.draw(i) and 0.1 <= d["dynamic_friction"] <= 0.3
        assert d["grip_dynamic_friction"] <= d["grip_static_friction"]


# ----- new names round-trip through YAML -----------------------------------------------------------------
def test_new_names_round_trip_through_yaml_without_warnings():
    cable = CableSpec.lv2017(dynamic_friction=0.35, static_friction=0.5, section="tube", inner_diameter=0.002)
    text = yaml.safe_dump(cable.to_dict())
    assert "dynamic_friction: 0.35" in text and "friction: 0.35" not in text.replace("dynamic_friction", "")
    assert quiet(CableSpec.from_dict, yaml.safe_load(text)) == cable
    arms = ArmsOptions(grip="friction", grip_static_friction=0.6, grip_dynamic_friction=0.25, payload="calibrated")
    assert quiet(ArmsOptions.from_dict, yaml.safe_load(yaml.safe_dump(dataclasses.asdict(arms)))) == arms
    spec = quiet(CaptureSpec.from_dict, {"sample": {"dynamic_friction": 0.3, "grip_static_friction": 0.6,
                                                     "grip_dynamic_friction": 0.2, "section": "round"}})
    assert quiet(CaptureSpec.from_dict, yaml.safe_load(yaml.safe_dump(spec.to_dict()))) == spec


# ----- closed sets: enums, one check, one line ------------------------------------------------------------
def test_enums_are_the_runtime_sets_and_equal_their_strings():
    assert IntegratorName.names() == tuple(INTEGRATORS)  # the core's table and the enum name the same set
    assert Section.TUBE == "tube" and {"tube": 1}[Section.TUBE] == 1 and f"{Section.TUBE}" == "tube"
    spec = CableSpec.lv2017(section=Section.TUBE, inner_diameter=0.001, discretisation=Discretisation.PAPER)
    assert type(spec.section) is str and spec.section == Section.TUBE  # fields hold plain names (YAML, HDF5)
    assert yaml.safe_load(yaml.safe_dump(spec.to_dict()))["section"] == "tube"
    assert all(issubclass(e, str) for e in enums.ENUMS)


def test_fit_sets_are_enums_checked_in_one_line():
    """The module-local sets of fit and recordings are the enums' names, refused in one line."""
    from bullet_dlo.analysis.fit import START, FitOptions
    from bullet_dlo.analysis.fit_recording import HELD, KINDS

    assert (START, KINDS, HELD) == (enums.FitStart.names(), enums.ResidualKind.names(),
                                    enums.RecordingHold.names())
    for kwargs, key in (({"start": "bogus"}, "start"), ({"kinds": ("force", "bogus")}, "kinds"),
                        ({"sigma": {"bogus": 1.0}}, "sigma key")):
        with pytest.raises(ParameterError) as info:
            FitOptions(**kwargs)
        assert str(info.value).startswith(f"{key} must be one of ") and "got 'bogus'" in str(info.value)
    assert FitOptions(kinds=["force", enums.ResidualKind.MOMENT]).kinds == ("force", "moment")


SCENE_ENUM_KEYS = [
    ("integrator", IntegratorName, lambda v: scene(integrator=v)),
    ("ends.first", EndMode, lambda v: scene(ends={"first": v})),
    ("ends.last", EndMode, lambda v: scene(ends={"last": v})),
    ("initial", InitialShape, lambda v: scene(initial=v)),
    ("tolerance.target", ToleranceTarget, lambda v: scene(tolerance={"target": v})),
    ("cable.section", Section, lambda v: scene(cable={**CABLE, "section": v})),
    ("cable.discretisation", Discretisation, lambda v: scene(cable={**CABLE, "discretisation": v})),
    ("bullet.self_collision", SelfCollision, lambda v: scene(bullet={"self_collision": v})),
    ("bullet.sync", Sync, lambda v: scene(bullet={"sync": v})),
    ("bullet.obstacles[0].type", ObstacleType, lambda v: scene(bullet={"obstacles": [{"type": v}]})),
    ("arms.grip", GripKind, lambda v: scene(arms={"grip": v})),
    ("arms.payload", Payload, lambda v: scene(arms={"payload": v})),
]
SPEC_ENUM_KEYS = [
    ("policy", UnstablePolicy, lambda v: {"policy": v}),
    ("sample.length.dist", Dist, lambda v: {"sample": {"length": {"dist": v, "value": 0.3}}}),
]


@pytest.mark.parametrize("key, enum, data", SCENE_ENUM_KEYS + SPEC_ENUM_KEYS, ids=lambda x: getattr(x, "__name__", x))
def test_every_enum_key_refuses_a_bad_value_listing_the_allowed_ones(key, enum, data):
    parse = CaptureSpec.from_dict if (key, enum, data) in SPEC_ENUM_KEYS else Scene.from_dict
    with pytest.raises(ParameterError) as info:
        parse(data("bogus"))
    message = str(info.value)
    assert message.endswith(f"{key} must be one of {', '.join(enum.names())}, got 'bogus'") and "\n" not in message
    for name in enum.names():  # and every allowed value gets past this key's check
        try:
            parse(data(name))
        except ParameterError as err:
            assert f"{key} must be one of" not in str(err)


@pytest.mark.parametrize("key, enum", [("sample.grip", GripKind), ("sample.section", Section),
                                       ("sample.integrator", IntegratorName)])
def test_sample_names_refuse_unknown_values_listing_the_allowed_ones(key, enum):
    with pytest.raises(ParameterError) as info:
        CaptureSpec.from_dict({"sample": {key.split(".")[1]: "bogus"}})
    assert str(info.value).endswith(f"known: {', '.join(enum.names())}")


# ----- one table-clearance check, each path's key names ---------------------------------------------------
def test_table_clearance_is_one_rule_with_each_paths_key_names():
    low = 0.2 + MIN_TABLE_CLEARANCE * 0.5
    with pytest.raises(ParameterError, match=r"^arms.hold_height 0.225 m must be at least 5 cm above the table top"):
        Scene.from_dict(scene(arms={"hold_height": low, "table_height": 0.2}))
    with pytest.raises(ParameterError, match=r"^hold_height 0.225 m must be at least 5 cm above the table top"):
        DualArmSpec(hold_height=low, table_height=0.2)
    ok = 0.2 + MIN_TABLE_CLEARANCE
    assert ArmsOptions(hold_height=ok, table_height=0.2).hold_height == DualArmSpec(hold_height=ok).hold_height
    assert DualArmSpec(hold_height=0.05, table_height=0.0).table_height == 0.0  # no table: no rule
