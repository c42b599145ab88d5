"""Dual-arm grasping with wrist F/T sensors: the physics the sensors must reproduce, and the scene's parts."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from bullet_dlo.config.robot import DualArmSpec, load_robot_spec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.dual_arm import DualArmObservation, DualArmPhysics, DualArmScene

ROBOTS = ["kuka", "panda"]


@pytest.fixture(params=ROBOTS)
def held(request):
    """Both ends grasped, held still for 3 s at 240 Hz."""
    scene = DualArmScene(DualArmSpec(robot=request.param))
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
    with DualArmScene(DualArmSpec(robot=robot, dt=1e-3)) as scene:
        scene.grasp()
        scene.run(1.0)
        rms, peak = _tracking(scene, displacement, duration)
        assert scene.cable.stable
        assert rms < 0.05 * peak, (rms, peak)


@pytest.mark.parametrize("robot", ROBOTS)
def test_grasp_holds_through_fast_move(robot):
    """Both grippers lift 0.3 m in 1.5 s (0.2 m/s on average): the ends stay within 1 mm."""
    with DualArmScene(DualArmSpec(robot=robot, dt=1e-3)) as scene:
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
        assert np.allclose(scene.task.target(1, scene.world.time), [0.5 * scene.cable.model.spec.length, 0, 0.65])


def test_release_lets_the_end_fall():
    with DualArmScene(DualArmSpec(robot="kuka")) as scene:
        scene.grasp()
        scene.run(0.5)
        scene.release("right")
        z0 = scene.cable.x[-1, 2]
        scene.run(0.5)
        assert scene.cable.x[-1, 2] < z0 - 0.05  # the free end swung down
        f = scene.window_mean(0.1)["wrench_world"][1, :3]
        assert np.linalg.norm(f) < 0.01  # the right sensor feels nothing any more


def test_physics_and_observation_with_a_task_of_their_own():
    """What an environment or a capture does: its own controller (joint targets), no scene record;
    the sensors still equal the model's end forces once the arm has stopped."""
    physics = DualArmPhysics(DualArmSpec(robot="panda"))
    try:
        observation = DualArmObservation(physics, record=False)
        physics.clamp(0)
        physics.clamp(1)
        right = physics.robots[1]
        pos, quat = physics.grasp_poses[1]
        lifted = right.solve_ik(pos + np.array([-0.05, 0.0, 0.03]), quat)
        physics.world.before_step.append(lambda: right.set_targets(lifted))  # a step target, not a profile
        physics.run(2.0)
        assert physics.cable.stable
        assert observation.record.t == []
        assert physics.cable.holder_positions()[1] == pytest.approx(pos + [-0.05, 0.0, 0.03], abs=1e-3)
        wrench = np.array([s.last.world()[:3] for s in observation.sensors])
        weight = physics.spec.cable.mass * 9.81
        assert np.max(np.abs(wrench - physics.cable.end_forces())) < 0.02 * weight
    finally:
        physics.close()


def test_spec_checks_name_the_field():
    with pytest.raises(ParameterError, match="hold_height 0.22 m must be at least 5 cm above the table top 0.2 m"):
        DualArmSpec(hold_height=0.22)
    assert DualArmSpec(hold_height=0.22, table_height=0.0).hold_height == 0.22  # no table, no clearance
    with pytest.raises(ParameterError, match="dt must be a finite number > 0"):
        DualArmSpec(dt=0.0)
    with pytest.raises(ParameterError, match="sensor_rate"):
        DualArmSpec(sensor_rate=0.0)
    with pytest.raises(ParameterError, match="substeps must be an integer >= 1"):
        DualArmSpec(substeps=0)


def test_clear_errors():
    with pytest.raises(ParameterError, match="unknown robot 'ur5'; supported robots: kuka, panda"):
        DualArmScene(DualArmSpec(robot="ur5"))
    with DualArmScene(DualArmSpec(robot="kuka")) as scene:
        with pytest.raises(ParameterError, match="pose unreachable for robot 'kuka'"):
            scene.move("left", (0.0, 0.0, 2.0), 1.0)
        with pytest.raises(ParameterError, match="arm must be one of left, right"):
            scene.move("middle", (0.0, 0.0, 0.01), 1.0)
        with pytest.raises(ParameterError, match="arm must be one of left, right"):
            scene.grasp(2)
        spec = load_robot_spec("panda")
        bad = type(spec)(**{**spec.__dict__, "sensor_joint": "wrist_ft"})  # the KUKA's name for it
        with pytest.raises(ParameterError, match="has no joint 'wrist_ft'"):
            Robot.load(bad, scene.world.client, (0.0, 1.0, 0.0))


def test_old_names_and_paths():
    sys.modules.pop("bullet_dlo.dual_arm", None)  # the alias warns on first import only
    with pytest.warns(DeprecationWarning, match="bullet_dlo.dual_arm moved to bullet_dlo.robots.dual_arm"):
        import bullet_dlo.dual_arm as old
    assert old.DualArmConfig is DualArmSpec and old.DualArmScene is DualArmScene
    DualArmConfig = old.DualArmConfig
    with DualArmScene(DualArmConfig(robot="kuka", hold_height=0.4)) as scene:
        assert scene.config is scene.spec and scene.config.hold_height == 0.4
        assert scene.robots[1].grasp_pose()[0][2] == pytest.approx(0.4, abs=1e-4)


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


@pytest.mark.parametrize("robot", ["panda", "kuka"])
def test_arms_without_visual_meshes_move_and_sense_the_same(robot):
    """A scene built without a renderer loads its arms without visual meshes (faster resets); the physics
    must not notice: the same grasp and move give the same cable and wrist readings to the bit."""
    runs = []
    for renderer in (None, "tiny"):
        with DualArmScene(DualArmSpec(robot=robot, renderer=renderer)) as sc:
            sc.grasp()
            sc.move("right", (0.0, 0.0, 0.01), 0.2)
            sc.run(0.25)
            runs.append((sc.cable.x.copy(), np.array([s.last.world() for s in sc.sensors])))
    (x0, w0), (x1, w1) = runs
    assert np.array_equal(x0, x1) and np.array_equal(w0, w1)
    assert np.abs(w0[:, 2]).max() > 0.05  # the wrists carry the cable


def test_a_move_scheduled_after_idle_steps_is_driven():
    """The task's drive does nothing while nothing is scheduled (an environment drives the arms itself), and a
    move added later, after idle steps, is tracked from its start: the gripper ends on the moved pose within
    1 mm (a position-controlled arm under the cable's load) and the other arm stays where it was."""
    with DualArmScene(DualArmSpec(robot="panda")) as scene:
        scene.grasp()
        scene.run(0.1)  # idle: nothing scheduled
        before = [r.grasp_pose()[0] for r in scene.robots]
        scene.task.move("right", (0.0, 0.0, 0.02), 0.3)
        scene.run(0.6)
        after = [r.grasp_pose()[0] for r in scene.robots]
        goal = scene.physics.grasp_poses[1][0] + np.array([0.0, 0.0, 0.02])  # moves start from the built pose
        assert np.abs(after[1] - goal).max() < 1e-3 and after[1][2] - before[1][2] > 0.015
        assert np.abs(after[0] - before[0]).max() < 1e-3
