"""Scene and capture specs: validated once, on construction, with errors that name the key."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.scene import BulletOptions, Scene
from bullet_dlo.core.validate import ParameterError

ROOT = Path(__file__).resolve().parents[2]
CABLE = {"preset": "lv2017", "n_masses": 8}


@pytest.mark.parametrize(
    "section,needle",
    [
        ({"substeps": 0}, "bullet.substeps must be an integer in [1, 10000], got 0"),
        ({"substeps": 1.5}, "bullet.substeps must be an integer in [1, 10000]"),
        ({"self_collision": "some"}, "bullet.self_collision must be one of neighbours, none, all, got 'some'"),
        ({"sync": "never"}, "bullet.sync must be one of contacts, always, got 'never'"),
        ({"ground_friction": -0.1}, "bullet.ground_friction must be a finite number >= 0"),
        ({"gravity": 1}, "unknown key(s) gravity in bullet; allowed: ground,"),
        ({"obstacles": {"type": "box"}}, "bullet.obstacles must be a list"),
        ({"obstacles": [{"type": "cone"}]}, "bullet.obstacles[0].type must be one of box, cylinder, urdf, got 'cone'"),
        ({"obstacles": [{"type": "box", "radius": 1}]}, "unknown key(s) radius in bullet.obstacles[0] (box)"),
        ({"obstacles": [[1, 2]]}, "bullet.obstacles[0] must be a mapping, got list"),
        # values checked when the file is read, not only when a world is built from it
        ({"obstacles": [{"type": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0, 0, 0], "friction": -1}]},
         "bullet.obstacles[0].friction must be a finite number >= 0, got -1"),
        ({"obstacles": [{"type": "cylinder", "radius": 0.1, "height": 0.2, "mass": -2}]},
         "bullet.obstacles[0].mass must be a finite number >= 0"),
        ({"obstacles": [{"type": "cylinder", "radius": 0.0, "height": 0.2}]},
         "bullet.obstacles[0].radius must be a finite number > 0"),
        ({"obstacles": [{"type": "box", "half_extents": [0.1, -0.1, 0.1]}]},
         "bullet.obstacles[0].half_extents must be three lengths > 0 [m], got [0.1, -0.1, 0.1]"),
        ({"obstacles": [{"type": "urdf"}]}, "bullet.obstacles[0].path must name a URDF file, got None"),
    ],
)
def test_bullet_section_errors_name_the_key(section, needle):
    with pytest.raises(ParameterError) as info:
        Scene.from_dict({"cable": CABLE, "bullet": section})
    assert needle in str(info.value)


def test_bullet_options_are_checked_on_construction_too():
    """The same checks whether the options come from a file or from code."""
    with pytest.raises(ParameterError, match="bullet.substeps"):
        BulletOptions(substeps=0)
    with pytest.raises(ParameterError, match="bullet.sync"):
        BulletOptions(sync="sometimes")
    opts = BulletOptions.from_dict({"substeps": 3.0, "ground_friction": 1, "obstacles": [
        {"type": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0, 0, 0.1]}]})
    assert opts.substeps == 3 and isinstance(opts.substeps, int) and opts.ground_friction == 1.0
    assert opts.obstacles == ({"type": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0, 0, 0.1]},)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.substeps = 2  # type: ignore[misc]
    assert BulletOptions.from_dict(None) == BulletOptions()


@pytest.mark.parametrize(
    "edit,needle",
    [
        ({"tolerance": {"target": "speed"}}, "tolerance.target must be one of forces, shape, both, got 'speed'"),
        ({"initial": "bent"}, "initial must be one of straight, static, got 'bent'"),
        ({"layout": [0, 0, 1]}, "layout must be a mapping, got list"),
        ({"detector": {"max_strain": 0.5, "every": 2}}, "unknown key(s) every in detector"),
    ],
)
def test_scene_errors_name_the_key(edit, needle):
    with pytest.raises(ParameterError) as info:
        Scene.from_dict({"cable": CABLE, **edit})
    assert needle in str(info.value)


@pytest.mark.parametrize(
    "data,needle",
    [
        ({"seed": -1}, "seed must be an integer in [0, 4611686018427387904], got -1"),
        ({"seed": 2**70}, "seed must be an integer in [0, 4611686018427387904]"),
        ({"seed": True}, "seed must be an integer in [0,"),
        ({"policy": "retry"}, "policy must be one of reject, implicit, substeps, got 'retry'"),
        ({"episode": [2.0]}, "episode must be a mapping, got list"),
        ({"episode": {"length": 2.0}}, "unknown key(s) length in episode; allowed: duration, record_rate"),
        ({"episode": {"duration": 0}}, "episode.duration must be in [0.001, 3600.0]"),
        ({"camera": {"fps": -1}}, "camera.fps must be in [0.0, 1000.0]"),
        ({"camera": {"width": "wide"}}, "camera.width must be an integer in [1, 8192], got 'wide'"),
        ({"max_resamples": 0}, "max_resamples must be an integer in [1, 10000]"),
        ({"sample": ["dt"]}, "sample must be a mapping, got list"),
        ({"sample": {"integrator": {"dist": "uniform", "low": 0, "high": 1}}}, "sample.integrator"),
        ({"seeds": 1}, "unknown key(s) seeds in capture spec"),
    ],
)
def test_capture_spec_errors_name_the_key(data, needle):
    with pytest.raises(ParameterError) as info:
        CaptureSpec.from_dict(data)
    assert needle in str(info.value)


def test_capture_spec_round_trips_and_keeps_its_digest():
    """The digest ties a capture directory to its spec: it must not change across releases,
    or ``--resume`` would refuse directories captured before."""
    spec = CaptureSpec.from_yaml(ROOT / "demos" / "specs" / "dr_small.yaml")
    assert CaptureSpec.from_dict(spec.to_dict()) == spec
    assert spec.digest() == "75beb7e332dbafc6"  # (8b3a7c464c6f30fa until its dynamic_friction range met static's)
    assert CaptureSpec().digest() == "e883660e79932801"
    assert spec.draw(3) == CaptureSpec.from_dict(spec.to_dict()).draw(3) != spec.draw(4)
    assert spec.camera_width == 160 and isinstance(spec.camera_width, int) and spec.seed == 7


def test_dual_arm_start_follows_the_scene_file():
    """A scene's ``initial`` decides how grasp/render attach the cable: settled unless it says straight."""
    from bullet_dlo.config.scene import Scene

    base = {"cable": {"preset": "lv2017", "n_masses": 8}}
    assert Scene.from_dict(base).arm_start == "settled"
    assert Scene.from_dict({**base, "initial": "static"}).arm_start == "settled"
    assert Scene.from_dict({**base, "initial": "straight"}).arm_start == "straight"
    # the core engine still starts straight when the file does not say otherwise
    scene = Scene.from_dict(base)
    model = scene.build_model()
    assert np.array_equal(scene.initial_state(model).x, model.initial_state().x)


def test_a_static_start_that_does_not_converge_is_refused():
    """``initial: static`` for a cable free at both ends has no equilibrium under gravity: the solve's last
    iterate used to start the run as if it were one; now a ParameterError names the setting. A cantilever's
    static start is its equilibrium."""
    from bullet_dlo.config.scene import Scene

    free = Scene.from_dict({"cable": {"preset": "lv2017", "n_masses": 8}, "ends": {"first": "free", "last": "free"},
                            "initial": "static"})
    with pytest.raises(ParameterError, match="initial: static did not converge"):
        free.initial_state(free.build_model())
    held = Scene.from_dict({"cable": {"preset": "lv2017", "n_masses": 8}, "ends": {"first": "clamped", "last": "free"},
                            "initial": "static"})
    model = held.build_model()
    state = held.initial_state(model)
    assert state.x[-1, 2] < model.x0[-1, 2] - 0.1  # it droops


def test_cable_friction_must_slip_at_or_below_what_it_holds():
    """Coulomb friction: dynamic <= static, for a cable spec, a scene file and every draw of a capture spec (the
    capture spec drew dynamic_friction up to 0.4 against the fixed static 0.3 before; the cable spec took it)."""
    from bullet_dlo.core.spec import CableSpec

    with pytest.raises(ParameterError, match=r"^dynamic_friction \(0.5\) must be at most static_friction \(0.3\)"):
        CableSpec.lv2017(dynamic_friction=0.5)
    assert CableSpec.lv2017(dynamic_friction=0.5, static_friction=0.5).dynamic_friction == 0.5
    with pytest.raises(ParameterError, match=r"^cable.dynamic_friction \(0.4\) must be at most cable.static_friction"):
        Scene.from_dict({"cable": {**CABLE, "dynamic_friction": 0.4}, "dt": 1e-3, "duration": 0.1})
    u = {"dist": "uniform"}
    with pytest.raises(ParameterError, match=r"^sample.dynamic_friction can be drawn above sample.static_friction"):
        CaptureSpec.from_dict({"seed": 1, "sample": {"dynamic_friction": {**u, "low": 0.1, "high": 0.4}}})
    spec = CaptureSpec.from_dict({"seed": 1, "sample": {"dynamic_friction": {**u, "low": 0.3, "high": 0.5},
                                                        "static_friction": {**u, "low": 0.5, "high": 0.8}}})
    for i in range(5):
        params = spec.draw(i)
        assert params["dynamic_friction"] <= 0.5 <= params["static_friction"] <= 0.8
    # a spec that does not sample it keeps its draws and its episodes' parameters (no static_friction key)
    assert "static_friction" not in CaptureSpec.from_dict({"seed": 1}).draw(0)
