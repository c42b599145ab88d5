"""Dual-arm grasping with wrist F/T sensors: the physics the sensors must reproduce."""
from __future__ import annotations

import numpy as np
import pytest
import yourdfpy

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.arm import Robot, load_robot_spec, robot_names
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene
from bullet_dlo.robots.sensors import WristSensor

ROBOTS = ["kuka", "panda"]


@pytest.mark.parametrize("name", ROBOTS)
def test_robot_descriptions_are_valid_urdf(name):
    spec = load_robot_spec(name)
    urdf = yourdfpy.URDF.load(str(spec.urdf_path()), build_scene_graph=False, load_meshes=False)
    assert urdf.validate()
    joints = {j.name: j for j in urdf.robot.joints}
    assert joints[spec.sensor_joint].type == "fixed"  # reports all six wrench components
    assert spec.grasp_link in {link.name for link in urdf.robot.links}
    arm = [j for j in urdf.robot.joints if j.type == "revolute"]
    assert len(arm) == len(spec.home) == 7
    for j, q in zip(arm, spec.home):
        assert j.limit.lower <= q <= j.limit.upper
    assert set(ROBOTS) <= set(robot_names())


def test_project_urdfs_validate():
    from bullet_dlo.robots.arm import URDF_DIR

    for path in URDF_DIR.glob("*.urdf"):
        assert yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False).validate(), path


@pytest.fixture(params=ROBOTS)
def held(request):
    """Both ends grasped, held still for 3 s at 240 Hz."""
    scene = DualArmScene(DualArmConfig(robot=request.param))
    scene.grasp()
    scene.run(3.0)
    yield scene
    scene.close()


def test_static_hold_force_balance(held):
    weight = held.cable.model.spec.mass * 9.81
    mean = held.window_mean(0.5)
    f = mean["wrench_world"][:, :3]
    assert held.cable.stable
    assert f[0, 2] + f[1, 2] == pytest.approx(-weight, rel=0.01)  # the cable pulls both arms down by its weight
    assert abs(f[0, 0] + f[1, 0]) < 0.01 * weight  # horizontal pulls equal and opposite
    assert abs(f[0, 1] + f[1, 1]) < 0.01 * weight
    assert f[0, 0] > 0.5  # held at rest length, the sagging cable pulls the grippers together (N)
    assert np.max(np.abs(f - mean["end_forces"])) < 0.02 * weight  # each sensor = the model's end force


def _tracking(scene, displacement, duration, arm="right"):
    t0 = scene.world.time
    scene.move(arm, displacement, duration)
    scene.run(duration + 0.5)
    rec = scene.record.arrays()
    sel = rec["t"] >= t0
    err = rec["wrench_world"][sel][:, :, :3] - rec["end_forces"][sel]
    rms = float(np.sqrt(np.mean(np.sum(err**2, axis=2))))
    peak = float(np.max(np.linalg.norm(rec["end_forces"][sel], axis=2)))
    return rms, peak


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("displacement,duration", [((0.0, 0.0, 0.005), 0.1), ((-0.1, 0.0, 0.0), 1.0)])
def test_sensor_tracks_model_force_during_moves(robot, displacement, duration):
    """The study's 5 mm lift, and bringing the ends 10 cm closer: RMS error below 5 % of the peak force."""
    with DualArmScene(DualArmConfig(robot=robot, dt=1e-3)) as scene:
        scene.grasp()
        scene.run(1.0)
        rms, peak = _tracking(scene, displacement, duration)
        assert scene.cable.stable
        assert rms < 0.05 * peak, (rms, peak)


@pytest.mark.parametrize("robot", ROBOTS)
def test_grasp_holds_through_fast_move(robot):
    """Both grippers lift 0.3 m in 1.5 s (0.2 m/s on average): the ends stay within 1 mm."""
    with DualArmScene(DualArmConfig(robot=robot, dt=1e-3)) as scene:
        scene.grasp()
        scene.run(0.3)
        start = scene.world.time
        for arm in ("left", "right"):
            scene.move(arm, (0.0, 0.0, 0.3), 1.5, start=start)
        scene.run(1.8)
        rec = scene.record.arrays()
        gap = np.linalg.norm(rec["grasp_pos"] - rec["cable_end_pos"], axis=2)
        assert scene.cable.stable
        assert gap.max() < 1e-3
        assert rec["grasp_pos"][-1, :, 2] == pytest.approx([0.65, 0.65], abs=5e-3)  # the arms got there


def test_release_lets_the_end_fall():
    with DualArmScene(DualArmConfig(robot="kuka")) as scene:
        scene.grasp()
        scene.run(0.5)
        scene.release("right")
        z0 = scene.cable.x[-1, 2]
        scene.run(0.5)
        assert scene.cable.x[-1, 2] < z0 - 0.05  # the free end swung down
        f = scene.window_mean(0.1)["wrench_world"][1, :3]
        assert np.linalg.norm(f) < 0.01  # the right sensor feels nothing any more


def test_sensor_rate_noise_and_bias():
    config = DualArmConfig(robot="panda", dt=1e-3, sensor_rate=100.0, noise_std=(0.05, 0.05, 0.05, 0, 0, 0),
                           bias=(0.0, 0.0, 0.2, 0, 0, 0), seed=3)
    with DualArmScene(config) as scene:
        scene.grasp()
        scene.run(2.0)
        rec = scene.record.arrays()
        fz = rec["wrench_world"][-1000:, 0, 2]
        changes = np.count_nonzero(np.diff(fz))
        assert 95 <= changes <= 101  # 100 Hz samples held between 1 kHz physics steps
        samples = fz[np.r_[True, np.diff(fz) != 0]]
        clean = rec["end_forces"][-1000:, 0, 2].mean()
        assert np.std(samples) == pytest.approx(0.05, rel=0.25)
        # the bias is in the sensor frame, whose z axis (the approach direction) points down in world
        assert np.mean(samples) - clean == pytest.approx(-0.2, abs=0.02)


def test_clear_errors():
    with pytest.raises(ParameterError, match="unknown robot 'ur5'; supported robots: kuka, panda"):
        DualArmScene(DualArmConfig(robot="ur5"))
    with DualArmScene(DualArmConfig(robot="kuka")) as scene:
        with pytest.raises(ParameterError, match="pose unreachable for robot 'kuka'"):
            scene.move("left", (0.0, 0.0, 2.0), 1.0)
        spec = load_robot_spec("panda")
        bad = type(spec)(**{**spec.__dict__, "sensor_joint": "wrist_ft"})
        with pytest.raises(ParameterError, match="has no joint 'wrist_ft'"):
            Robot.load(bad, scene.world.client, (0.0, 1.0, 0.0))
        robot = scene.robots[0]
        robot.spec = bad
        with pytest.raises(ParameterError, match="no joint 'wrist_ft' for the F/T sensor"):
            WristSensor(robot)


def test_cli_grasp_json(tmp_path):
    import json

    from bullet_dlo.cli.main import main

    out = tmp_path / "g.json"
    assert main(["grasp", "--robot", "panda", "--duration", "2.5", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    for key in ("cable_weight", "wrench_world", "ground_truth_end_forces", "stable"):
        assert key in data
    assert data["stable"] is True
    w = {arm: np.array(data["wrench_world"][arm]) for arm in ("left", "right")}
    assert len(w["left"]) == 6
    assert w["left"][2] + w["right"][2] == pytest.approx(-data["cable_weight"], rel=0.01)
    assert main(["grasp", "--robot", "abb"]) == 2
