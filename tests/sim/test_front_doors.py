"""One scene file through every front door that takes it: each honours its keys or refuses them by name.

The scene: a cable between two clamps (or two grippers) at 0.35 m, straight at the start, with a
box under its middle 3 mm below the cable. Free, the clamped cable (lv2017 made softer, E = 20 MPa)
sags by about a centimetre, stretching and bending; on the box it stops at the box's top. So where the cable's middle
ends up says whether the door built the obstacle; the Newton and detector settings are read
back from the solver each door built, and their effect (Newton failures at one iteration, a
strain bound that stops the run) is checked in the results.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from bullet_dlo.cli.main import main
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.sim import build

HOLD = 0.35  # [m] height of the held ends
LENGTH = 0.3  # [m]
RADIUS = 0.002  # [m] lv2017's
TOP = HOLD - RADIUS - 0.003  # [m] the box's top, 3 mm under the straight cable
BOX = {"type": "box", "half_extents": [0.03, 0.05, 0.05], "position": [0.0, 0.0, TOP - 0.05], "name": "support"}


def scene_dict(obstacle: bool = True, arms: bool = True, **more) -> dict:
    data = {"cable": {"preset": "lv2017", "youngs_modulus": 2.0e7, "n_masses": 13, "damping_rate": 8.0},
            "initial": "straight", "dt": 1.0 / 240.0, "duration": 1.0,
            "bullet": {"obstacles": [BOX] if obstacle else []}, **more}
    if arms:
        data["arms"] = {"hold_height": HOLD, "table_height": 0.0}
    else:
        data["layout"] = {"start": [-LENGTH / 2, 0.0, HOLD], "direction": [1, 0, 0]}
    return data


def write(tmp_path, data: dict, name: str = "scene.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def middle_height(x: np.ndarray) -> float:
    """Height [m] of the cable's middle mass, (n, 3) positions."""
    return float(x[len(x) // 2, 2])


def test_simulate_bullet_rests_the_cable_on_the_scene_obstacle(tmp_path):
    heights = {}
    for obstacle in (True, False):
        out = tmp_path / f"sim_{obstacle}.json"
        scene = write(tmp_path, scene_dict(obstacle, arms=False), f"s{obstacle}.yaml")
        assert main(["-q", "simulate", str(scene), "--engine", "bullet", "--json", str(out)]) == 0
        data = json.loads(out.read_text())
        assert data["stable"]
        heights[obstacle] = middle_height(np.array(data["final_positions"]))
    assert heights[True] == pytest.approx(TOP + RADIUS, abs=1.5e-3)  # on the box
    assert heights[False] < TOP - 3e-3  # through where the box was


def test_grasp_and_render_rest_the_cable_on_the_scene_obstacle(tmp_path):
    """grasp --scene ignored bullet.obstacles before 0.3.1; render --robot added them: the same scene, the same rest."""
    heights = {}
    for obstacle in (True, False):
        scene = write(tmp_path, scene_dict(obstacle), f"s{obstacle}.yaml")
        series = tmp_path / f"grasp_{obstacle}.npz"
        assert main(["-q", "grasp", "--robot", "kuka", "--scene", str(scene), "--series", str(series)]) == 0
        heights[obstacle] = middle_height(np.load(series)["cable_x"][-1])
    assert heights[True] == pytest.approx(TOP + RADIUS, abs=1.5e-3)
    assert heights[False] < TOP - 3e-3
    scene = write(tmp_path, scene_dict(True, duration=0.6), "render.yaml")
    series = tmp_path / "render.npz"
    assert main(["-q", "render", str(scene), "--robot", "kuka", "--out", str(tmp_path / "r"), "--fps", "5",
                 "--width", "64", "--height", "48", "--series", str(series)]) == 0
    rendered = middle_height(np.load(series)["cable_x"][-1])
    assert rendered > TOP + RADIUS - 1.5e-3  # on its way down onto the box after 0.6 s, not through it


def test_render_without_arms_rests_the_cable_on_the_scene_obstacle(tmp_path):
    scene = write(tmp_path, scene_dict(True, arms=False), "render.yaml")
    assert main(["-q", "render", str(scene), "--out", str(tmp_path / "r"), "--fps", "5", "--width", "64",
                 "--height", "48"]) == 0
    summary = json.loads((tmp_path / "r" / "render.json").read_text())
    assert middle_height(np.array(summary["final_positions"])) == pytest.approx(TOP + RADIUS, abs=1.5e-3)


@pytest.mark.parametrize("engine", ["core", "bullet", "arms"])
def test_newton_and_detector_settings_reach_the_solver_of_every_engine(engine):
    """newton: {max_iter: 1, tol: 1e-14} makes implicit Euler fail its Newton test in (nearly) every step; the
    settings are read back from the stepper each Bullet engine built."""
    data = scene_dict(False, arms=engine == "arms", duration=0.2, newton={"max_iter": 1, "tol": 1e-14})
    if engine == "core":
        del data["bullet"]
    scene = Scene.from_dict(data)
    with build(scene, engine) as sim:
        if engine != "core":
            assert (sim.cable.stepper.max_iter, sim.cable.stepper.tol) == (1, 1e-14)
        result = sim.run()
    assert result.newton_failures > 0.5 * result.steps
    data["detector"] = {"max_strain": 1e-9}  # any stretch under gravity exceeds it: the run stops at once
    with build(Scene.from_dict(data), engine) as sim:
        result = sim.run()
    assert not result.stable and "strain" in result.reason and result.time_to_instability < 0.05


def test_gravity_and_substeps_of_the_scene_reach_the_arms():
    scene = Scene.from_dict(scene_dict(False, gravity=[0.0, 0.0, -3.0], bullet={"substeps": 2}))
    with build(scene, "arms") as sim:
        assert sim.cable.substeps == 2
        assert np.allclose(sim.world.gravity, (0.0, 0.0, -3.0))
        sim.run(0.5)
        window = sim.arms.window_mean(0.2)
    weight = scene.cable.mass * 3.0
    assert window["wrench_world"][:, 2].sum() == pytest.approx(-weight, rel=0.02)  # the sensors feel 3 m/s^2


@pytest.mark.parametrize("command, data, key", [
    (["simulate", "--engine", "core"], scene_dict(True, arms=False), "bullet"),
    (["simulate", "--engine", "bullet"], scene_dict(True), "arms"),
    (["grasp", "--robot", "kuka", "--scene"], scene_dict(True, arms=False), "layout"),
    (["grasp", "--robot", "kuka", "--scene"], {**scene_dict(True), "ends": {"first": "pinned"}}, "ends"),
    (["render", "--out", "OUT"], scene_dict(True), "arms"),
])
def test_a_key_a_door_cannot_honour_is_refused_by_name(tmp_path, capsys, command, data, key):
    scene = str(write(tmp_path, data))
    args = [a.replace("OUT", str(tmp_path / "out")) for a in command]
    args = args + [scene] if args[-1] == "--scene" else args[:1] + [scene] + args[1:]
    assert main(["-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {key}: not used by") and len(err.splitlines()) == 1, err


def test_build_refuses_an_unknown_engine():
    with pytest.raises(ParameterError, match="engine must be one of core, bullet, arms"):
        build(Scene.from_dict(scene_dict(False)), "mujoco")
