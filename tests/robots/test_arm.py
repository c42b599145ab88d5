"""Robot descriptions, loading, and the one IK (checked solve and per-step tracking) against forward kinematics."""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
import yourdfpy

from bullet_dlo.assets import URDF_DIR
from bullet_dlo.config.robot import load_robot_spec, robot_names
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.compose import robot_urdf
from bullet_dlo.robots.transforms import angle_between

ROBOTS = ["kuka", "panda"]


@pytest.mark.parametrize("name", ROBOTS)
def test_robot_descriptions_are_valid_urdf(name):
    spec = load_robot_spec(name)
    urdf = yourdfpy.URDF.load(str(robot_urdf(spec)), build_scene_graph=False, load_meshes=False)
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
    paths = list(URDF_DIR.glob("*.urdf"))
    assert paths
    for path in paths:
        assert yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False).validate(), path


@pytest.fixture(params=ROBOTS)
def arm(request):
    client = pb.connect(pb.DIRECT)
    robot = Robot.load(load_robot_spec(request.param), client, (0.0, 0.0, 0.0))
    yield robot
    robot.close()
    pb.disconnect(client)


def _fk_error(robot: Robot, q: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> tuple[float, float]:
    robot.reset_joints(q)
    p, r = robot.grasp_pose()
    return float(np.linalg.norm(p - pos)), angle_between(r, quat)


def test_solve_ik_reaches_the_pose_within_limits(arm):
    home_pos, quat = arm.grasp_pose()
    target = home_pos + np.array([0.05, -0.04, -0.06])
    q = arm.solve_ik(target, quat)
    assert np.all(q >= arm.lower[arm._arm_columns]) and np.all(q <= arm.upper[arm._arm_columns])
    err_p, err_r = _fk_error(arm, q, target, quat)
    assert err_p < 1e-4 and err_r < 1e-3  # solve_ik's own tolerances, checked on the simulated arm


def test_a_solved_pose_is_solved_once(arm, monkeypatch):
    """An environment's reset solved its grasp poses again (15 ms): the same target from the same seed on the same
    twin now returns the answer kept, the same bits, and leaves the twin where the solve left it; another seed or
    another robot base is solved."""
    from bullet_dlo.robots import arm as arm_module

    monkeypatch.setattr(arm_module, "_SOLVED", {})
    calls = []
    real = arm._ik
    monkeypatch.setattr(arm, "_ik", lambda *a, **k: calls.append(1) or real(*a, **k))
    home_pos, quat = arm.grasp_pose()
    target = home_pos + np.array([0.05, -0.04, -0.06])
    home = np.array(arm.spec.home)
    q = arm.solve_ik(target, quat, seed=home)
    solves = len(calls)
    twin = arm.grasp_pose(kinematic=True)
    arm._set_twin(home)
    again = arm.solve_ik(target, quat, seed=home)
    assert solves > 0 and len(calls) == solves and np.array_equal(again, q)
    assert all(np.array_equal(a, b) for a, b in zip(arm.grasp_pose(kinematic=True), twin))
    arm.solve_ik(target, quat, seed=home + 0.01)
    assert len(calls) > solves
    client = pb.connect(pb.DIRECT)
    try:  # the same robot elsewhere: its own problem
        other = Robot.load(arm.spec, client, (0.1, 0.0, 0.0))
        before = len(calls)
        monkeypatch.setattr(other, "_ik", lambda *a, **k: calls.append(1) or Robot._ik(other, *a, **k))
        other.solve_ik(target, quat, seed=home)
        assert len(calls) > before
        other.close()
    finally:
        pb.disconnect(client)


def test_track_follows_a_nearby_target(arm):
    """One IK solve from the current joints (what runs every step of a move) lands within 0.1 mm."""
    pos, quat = arm.grasp_pose()
    for step in ([0.0, 0.0, 0.002], [0.003, -0.002, 0.0]):
        pos = pos + np.array(step)
        q = arm.track(pos, quat)
        err_p, err_r = _fk_error(arm, q, pos, quat)
        assert err_p < 1e-4 and err_r < 1e-3


def test_twin_set_in_one_call_is_the_state_set_joint_by_joint(arm):
    """The twin's joints set in one Bullet call (the IK seed every control step) hold the same angles,
    zero velocities and grasp pose as seven resetJointState calls, whatever the twin's state was."""
    q = arm.joint_positions() + np.linspace(-0.05, 0.05, len(arm.arm_joints))
    for j, val in zip(arm.arm_joints, q):
        pb.resetJointState(arm.kin_body, j, float(val), physicsClientId=arm.kin_client)
    ref_states = pb.getJointStates(arm.kin_body, arm.arm_joints, physicsClientId=arm.kin_client)
    ref_pose = arm.grasp_pose(kinematic=True)
    pb.resetJointState(arm.kin_body, arm.arm_joints[0], 0.3, targetVelocity=1.0, physicsClientId=arm.kin_client)
    arm._set_twin(q)
    states = pb.getJointStates(arm.kin_body, arm.arm_joints, physicsClientId=arm.kin_client)
    assert [s[:2] for s in states] == [s[:2] for s in ref_states]
    pose = arm.grasp_pose(kinematic=True)
    assert np.array_equal(pose[0], ref_pose[0]) and np.array_equal(pose[1], ref_pose[1])


def test_unreachable_pose_is_refused(arm):
    with pytest.raises(ParameterError, match=f"pose unreachable for robot '{arm.spec.name}'"):
        arm.solve_ik((0.0, 0.0, 3.0), (0.0, 0.0, 0.0, 1.0))


def test_wrist_joint_reports_its_reaction_after_a_step(arm):
    """Robot.load switches the F/T joint on: one step later it carries the tool's weight."""
    joint = arm.joint_index[arm.spec.sensor_joint]
    pb.setGravity(0, 0, -9.81, physicsClientId=arm.client)
    pb.stepSimulation(arm.client)
    force = np.array(pb.getJointState(arm.body, joint, physicsClientId=arm.client)[2][:3])
    assert np.linalg.norm(force) > 0.1  # [N]: a gripper weighs more than 10 g


def test_old_flat_names_still_import():
    import bullet_dlo.robots as robots

    with pytest.warns(DeprecationWarning, match="moved to bullet_dlo.robots.arm.Robot"):
        assert robots.Robot is Robot
    with pytest.warns(DeprecationWarning):
        assert robots.load_robot_spec is load_robot_spec
    with pytest.raises(AttributeError):
        robots.no_such_name


def test_a_robot_is_composed_once_while_its_files_stay_as_they_were(monkeypatch, tmp_path):
    """An environment's reset composed each arm's URDF anew (5 ms an arm). The composed file is now kept for the spec
    while the source files and the written file are unchanged; a changed written file is composed again."""
    import tempfile

    from bullet_dlo.robots import compose

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # (its own cache folder: the test changes the file)
    monkeypatch.setattr(compose, "_COMPOSED", {})
    loads = []
    real = compose._load
    monkeypatch.setattr(compose, "_load", lambda path: loads.append(path) or real(path))
    spec = load_robot_spec("panda")
    first = robot_urdf(spec)
    parsed = len(loads)
    assert first.is_relative_to(tmp_path) and parsed >= 1
    assert robot_urdf(spec) == first and len(loads) == parsed  # (kept: nothing parsed again)
    first.write_text(first.read_text() + "\n")  # the written file changed: composed and checked again
    assert robot_urdf(spec) == first and len(loads) == 2 * parsed
    assert first.read_text().endswith("</robot>\n")


def test_robot_descriptions_are_read_again_only_when_they_change(monkeypatch, tmp_path):
    """Every scene check listed the robots (and an environment's reset loaded its spec) by parsing each YAML file
    again, 15 ms a reset. A description is now parsed once while its file is unchanged; an edited one is read."""
    import shutil

    import yaml

    from bullet_dlo.config import robot as robot_config

    for path in robot_config.ROBOTS_DIR.glob("*.yaml"):
        shutil.copy(path, tmp_path / path.name)
    monkeypatch.setattr(robot_config, "ROBOTS_DIR", tmp_path)
    monkeypatch.setattr(robot_config, "_ROBOT_FILES", {})
    parsed = []
    real = yaml.safe_load
    monkeypatch.setattr(robot_config.yaml, "safe_load", lambda text: parsed.append(1) or real(text))
    assert robot_names() == sorted(ROBOTS + [n for n in robot_names() if n not in ROBOTS])
    count = len(parsed)
    assert count == len(list(tmp_path.glob("*.yaml")))
    spec = load_robot_spec("panda")
    assert len(parsed) == count and spec.source.startswith(str(tmp_path))
    panda = tmp_path / "panda.yaml"
    panda.write_text(panda.read_text().replace("name: panda", "name: panda2"))
    assert "panda2" in robot_names() and len(parsed) == count + 1
    assert load_robot_spec("panda2").name == "panda2"
    with pytest.raises(ParameterError, match="unknown robot 'panda'"):
        load_robot_spec("panda")


def test_a_closed_robots_twin_serves_the_next_robot_with_the_same_answers(monkeypatch):
    """An environment's reset disconnected both arms' kinematic twins and connected and loaded new ones (5 ms an arm).
    A closed robot now gives its twin back to the next robot of the same description and base: the same client, and
    the same IK answers (PyBullet's, without the kept answers) and compiled chain as a new twin gives; another base
    gets a twin of its own; a robot whose twin was given back has none."""
    from bullet_dlo.robots import arm as arm_module

    monkeypatch.setattr(arm_module, "_TWINS", {})
    spec = load_robot_spec("panda")
    answers = []
    for fresh in (True, False, True):
        monkeypatch.setattr(arm_module, "_SOLVED", {})
        if fresh:
            monkeypatch.setattr(arm_module, "_TWINS", {})
        client = pb.connect(pb.DIRECT)
        try:
            robot = Robot.load(spec, client, (0.0, 0.0, 0.0))
            pos, quat = robot.grasp_pose()
            q = robot.solve_ik(pos + np.array([0.04, -0.03, -0.05]), quat, seed=np.array(spec.home))
            answers.append((robot.kin_client, q, robot.chain_ik.chain))
            robot.close()
            assert robot.kin_client == -1 and len(arm_module._TWINS[robot._twin_key]) == 1
        finally:
            pb.disconnect(client)
    (c0, q0, ch0), (c1, q1, ch1), (c2, q2, ch2) = answers
    assert c1 == c0 and c2 != c1  # (the second took the first one's twin; the third a new one)
    assert np.array_equal(q0, q1) and np.array_equal(q1, q2)
    import dataclasses

    for f in dataclasses.fields(ch0):
        assert np.array_equal(getattr(ch0, f.name), getattr(ch1, f.name)), f.name
    client = pb.connect(pb.DIRECT)
    try:
        elsewhere = Robot.load(spec, client, (0.2, 0.0, 0.0))
        assert elsewhere.kin_client not in (c0, c2)
        elsewhere.close()
    finally:
        pb.disconnect(client)
