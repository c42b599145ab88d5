"""Torsion the wrist can feel (issue 22): a gripper's roll about the cable is the twist boundary condition of a
cable with a material frame, and the torsion torque reaches the gripper and its wrist sensor.

Closed form: a straight clamped-clamped rod whose clamps differ in roll by theta carries the torque
T = G J theta / L about its axis [N m] (G = E / (2 (1 + nu)), J = pi d^4 / 32 for a round section).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

CABLE = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=16, damping=0.01)
TURN = math.pi / 2  # [rad] about the cable axis (world x)
START, DURATION, HOLD = 0.2, 1.0, 0.4  # [s]; a faster quarter turn loses the Panda's per-step IK tracking


def held_turn(robot: str, twist: bool, grip: str = "clamp"):
    """Grasp, turn the right gripper by :data:`TURN` about the cable, hold; the last 0.3 s averaged. Returns the
    sensors' moments [N m] (2, 3) about the held end masses (the reading is about the sensor frame's origin:
    the cable's end force has a lever arm there once the wrist is rolled) and the model's clamp moments (2, 3)."""
    cable = CABLE.with_(twist=twist)
    with DualArmScene(DualArmConfig(robot=robot, cable=cable, dt=1e-3, integrator="bdf2", grip=grip)) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (0.0, 0.0, 0.0), START, DURATION, rotation=(TURN, 0.0, 0.0))])
        scene.run(START + DURATION + HOLD)
        assert scene.cable.stable and scene.cable.newton_failures == 0
        w = scene.window_mean(0.3)["wrench_world"]
        moments = np.array([w[a, 3:] + np.cross(scene.sensors[a].rows[0, :3] - scene.physics.load_points[a],
                                                  w[a, :3]) for a in (0, 1)])
        return moments, scene.cable.end_moments()


@pytest.mark.parametrize("robot, grip", [("panda", "clamp"), ("kuka", "clamp"), ("kuka", "friction")])
def test_wrist_sensors_read_the_torsion_of_a_turned_gripper(robot, grip):
    """Measured (python -m pytest tests/robots/test_twist_grip.py): both robots read 0.99986 G J theta / L about
    the cable axis, left +, right - (the cable resists the turn); the model's clamp moments the same. A friction
    grip holds the roll as a clamp does (its fingers pinch the cable)."""
    moments, model = held_turn(robot, twist=True, grip=grip)
    torque = CABLE.torsional_rigidity * TURN / CABLE.length
    assert moments[0, 0] == pytest.approx(torque, rel=0.01)
    assert moments[1, 0] == pytest.approx(-torque, rel=0.01)
    assert model[:, 0] == pytest.approx([torque, -torque], rel=0.01)


def test_a_cable_without_twist_reads_no_torsion():
    """The opt-in: a round cable without ``twist`` has no material frame, and a rolled gripper feels nothing about
    the cable axis (the clamp holds only the tangent)."""
    with pytest.warns(UserWarning, match="rolls the right gripper 90 deg about the cable axis, but the cable has no "
                                         "material frame"):
        moments, model = held_turn("panda", twist=False)
    torque = CABLE.torsional_rigidity * TURN / CABLE.length
    assert np.abs(moments[:, 0]).max() < 1e-4 * torque
    assert np.abs(model[:, 0]).max() < 1e-4 * torque


@pytest.mark.parametrize("mode", ["clamped", "pinned"])
def test_external_holder_roll_twists_a_clamped_end_not_a_pinned_one(mode):
    """BulletCable's external holders without arms: the last holder's section axis (``set_external_pose``'s
    normal) turned by a quarter turn about the cable; a clamp there carries G J theta / L, a pin nothing."""
    spec = CABLE.with_(twist=True, damping_rate=5.0)
    with BulletWorld(dt=1e-3, gravity=(0.0, 0.0, 0.0)) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.5), integrator="bdf2")
        x0 = cable.x.copy()
        for end, node in ((0, 0), (1, -1)):
            cable.set_external_pose(end, x0[node], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0))
            cable.hold_externally(end, "clamped" if end == 0 else mode)
        for k in range(400):
            angle = TURN * min(1.0, k / 200)  # (a step change would ring the twist modes)
            normal = (0.0, math.cos(angle), math.sin(angle))
            cable.set_external_pose(1, x0[-1], np.zeros(3), np.zeros(3), np.zeros(3), (1.0, 0.0, 0.0), normal)
            world.step()
        assert cable.stable
        moments = cable.end_moments()
    torque = spec.torsional_rigidity * TURN / spec.length if mode == "clamped" else 0.0
    assert moments[:, 0] == pytest.approx([torque, -torque], rel=1e-3, abs=1e-9)


def test_roll_warning_names_the_rolled_gripper_only():
    """The warning of a frameless cable's rolled gripper: a roll about the cable axis (a move, a sine) is named with
    its angle; a swing or yaw of the gripper (the cable turns, it does not twist) and a cable with a frame are not."""
    from bullet_dlo.core.boundary import Sine
    from bullet_dlo.robots.dual_arm.scene import roll_warning

    x = np.array([[0.0, 0.0, 0.5], [0.15, 0.0, 0.5], [0.3, 0.0, 0.5]])
    roll = Move("last", (0.0, 0.0, 0.0), START, DURATION, rotation=(TURN, 0.0, 0.0))
    assert "the right gripper 90 deg" in roll_warning(False, x, [roll])
    assert "the left gripper 22.9 deg" in roll_warning(False, x, [Sine("first", frequency=2.0, rotation=(0.4, 0, 0))])
    assert roll_warning(True, x, [roll]) == ""
    swing = Move("last", (0.0, 0.0, 0.01), START, DURATION, rotation=(0.0, 0.3, 0.2))
    assert roll_warning(False, x, [swing, Sine("first", frequency=2.0, rotation=(0.0, 0.0, 0.4))]) == ""


def test_a_roll_the_arm_cannot_follow_warns_when_the_gripper_leaves_its_target():
    """A KUKA gripper rolled 170 degrees about the cable over 1.9 s: its joints reach the path's end kinematically,
    but on the way the arm falls behind (a wrist joint near its limit) and the per-step tracking loses the pose: the
    gripper ends 16 cm away and the sensors read 300 N on a 0.29 N cable, where the run used to report nothing.
    Now a warning names the arm and the time (about 1.4 s; tracking lags 0.1 mm before), and the task notes it."""
    with DualArmScene(DualArmConfig(robot="kuka", cable=CABLE.with_(twist=True), dt=1e-3)) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (0.0, 0.0, 0.0), START, 1.9, rotation=(math.radians(170.0), 0.0, 0.0))])
        with pytest.warns(UserWarning, match=r"the right arm's grasp frame is \d+\.\d mm from its target at t = 1\."):
            scene.run(1.5)
        (t, arm, miss), = scene.task.pose_misses
        assert arm == 1 and 1.2 < t < 1.5 and miss >= 0.02


def test_an_arm_that_comes_to_rest_off_its_final_pose_warns():
    """A KUKA gripper rolled 120 degrees about the cable in 1 s: the arm follows the roll (tracking within 0.2 mm)
    but, its wrist joints near their limits, comes to rest 11 mm from the final pose, under the 2 cm a moving arm
    may lag; the run used to report nothing while the clamps read G J theta / L 1.1 % off. Checked once the targets
    have stopped for :data:`~bullet_dlo.robots.dual_arm.task.SETTLE` s against 2 mm; a 90-degree roll is not named."""
    from bullet_dlo.robots.dual_arm.task import SETTLE, SETTLED_MISS

    for degrees, warned in ((90.0, False), (120.0, True)):
        with DualArmScene(DualArmConfig(robot="kuka", cable=CABLE.with_(twist=True), dt=1e-3)) as scene:
            scene.grasp()
            scene.follow_motion([Move("last", (0.0, 0.0, 0.0), START, DURATION,
                                      rotation=(math.radians(degrees), 0.0, 0.0))])
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                scene.run(START + DURATION + SETTLE + 0.01)
            misses = scene.task.pose_misses
        named = [str(w.message) for w in caught if "grasp frame" in str(w.message)]
        if warned:
            (t, arm, miss), = misses
            assert arm == 1 and t == pytest.approx(START + DURATION + SETTLE, abs=2e-3) and miss >= SETTLED_MISS
            assert len(named) == 1 and "the right arm's grasp frame" in named[0]
        else:
            assert misses == [] and named == []
