"""Wrist sensors at any gripper orientation (issue 27): the payload's weight is removed in the world frame.

A held cable at rest: each wrist sensor must read the cable model's end force, whatever the
gripper's tilt, and both sensors together the cable's weight. Before the fix the hand's weight
(9.9 N on the Panda) was tared in the sensor frame, so a turn of 0.3 rad about the cable read
-2.9 N sideways (10 cable weights); and the motor-held fingers made Bullet's wrist reaction
itself wrong under tilt (now rigid, :func:`bullet_dlo.robots.compose.rigid_fingers`).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene
from bullet_dlo.robots.sensors import identify_payload

CABLE = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=16, damping=0.01)
MOVE, HOLD = 0.6, 0.8  # [s]
TURNS = {("panda", 0): np.radians(67.5), ("kuka", 0): np.radians(45.0),
         ("panda", 1): np.radians(-22.5), ("kuka", 1): np.radians(-22.5)}
"""Per robot and world axis (0: x, along the cable; 1: y), the turn of each of two moves [rad]: holds at 0,
67.5 and 135 degrees about the cable (Panda), 0, 45 and 90 (KUKA), 0, -22.5 and -45 about y. At 135 degrees
about the cable the KUKA's wrist no longer follows the turn and its clamp pulls the cable to 6 N, so the
balance of the two wrists is off by 1.9 % of the weight while each sensor reads the model within 0.03 %;
a full 180 degrees is out of both arms' reach from this hold (the IK refuses it)."""


def tilted_holds(robot: str, dt: float, axis: int, payload: str = "urdf"):
    """Turn the right gripper about world axis ``axis`` in two steps (:data:`TURNS`), holding after each; per
    hold, the last 0.3 s averaged: sensors (2, 3) and model (2, 3) [N]."""
    rot = np.zeros(3)
    rot[axis] = TURNS[robot, axis]
    config = DualArmConfig(robot=robot, cable=CABLE, dt=dt, integrator="bdf2", payload=payload)
    with DualArmScene(config) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (0.0, 0.0, 0.0), 0.5 + k * (MOVE + HOLD), MOVE, rotation=tuple(rot))
                             for k in range(2)])
        holds = []
        for k in range(3):
            scene.run(MOVE + HOLD if k else 0.5)
            w = scene.window_mean(0.3)
            holds.append((w["wrench_world"][:, :3], w["end_forces"]))
        weight = CABLE.mass * float(np.linalg.norm(scene.world.gravity))
        assert scene.cable.stable
        return holds, weight, scene.observation.check


@pytest.mark.parametrize("robot", ["panda", "kuka"])
@pytest.mark.parametrize("dt", [1 / 240, 1e-3])
@pytest.mark.parametrize("axis", [0, 1])
def test_sensors_read_the_model_at_any_tilt(robot, dt, axis):
    holds, weight, _ = tilted_holds(robot, dt, axis)
    for k, (sensor, model) in enumerate(holds):
        err = np.abs(sensor - model)
        assert np.all(err <= 0.005 * weight + 1e-3), (k, sensor, model)
        balance = sensor[:, 2].sum() + weight  # the sensors carry the cable's weight
        assert abs(balance) <= 0.005 * weight, (k, balance)


@pytest.mark.parametrize("robot", ["panda", "kuka"])
def test_slow_continuous_turn_reads_the_model_at_every_step(robot):
    """90 degrees about the cable in 4 s, at 1 kHz: every sample against the load the cable applied in that
    step (the scene's own check, :class:`SensorCheck`), within 0.5 % of the weight plus 1 mN. With Bullet's
    joint reaction it was 11 mN (KUKA) and 54 mN (Panda) off; the old tare read 10 N off at 90 degrees."""
    config = DualArmConfig(robot=robot, cable=CABLE, dt=1e-3, integrator="bdf2")
    with DualArmScene(config) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (0.0, 0.0, 0.0), 0.3, 4.0, rotation=(np.pi / 2, 0.0, 0.0))])
        scene.run(4.5)
        check = scene.observation.check
        weight = CABLE.mass * float(np.linalg.norm(scene.world.gravity))
        assert check.samples == 4500
        assert check.worst[:, 0].max() <= 0.005 * weight + 1e-3, check.summary()


def test_identify_payload_recovers_a_known_payload():
    """Synthetic rest readings of a 1.2 kg payload, CoM (0.01, -0.02, 0.05) m, offsets: recovered exactly;
    orientations about one axis only cannot determine it (clear error)."""
    rng = np.random.default_rng(1)
    g = np.array([0.0, 0.0, -9.81])
    mass, com, f0, m0 = 1.2, np.array([0.01, -0.02, 0.05]), np.array([0.1, -0.2, 0.3]), np.array([0.01, 0.02, -0.03])
    rots = Rotation.random(8, random_state=rng).as_matrix()
    reactions = []
    for r in rots:
        gs = r.T @ g
        reactions.append(np.r_[-(mass * gs + f0), -(np.cross(mass * com, gs) + m0)])
    fit = identify_payload(rots, np.array(reactions), g)
    assert fit.mass == pytest.approx(mass, rel=1e-9)
    assert np.allclose(fit.com, com, atol=1e-9) and np.allclose(fit.force_offset, f0, atol=1e-9)
    assert np.allclose(fit.moment_offset, m0, atol=1e-9) and fit.rms_force < 1e-9
    about_z = Rotation.from_rotvec(np.outer(np.linspace(0, 2, 5), [0, 0, 1])).as_matrix()
    with pytest.raises(ParameterError, match="do not determine the payload"):
        identify_payload(about_z, np.zeros((5, 6)), g)


@pytest.mark.parametrize("robot", ["panda", "kuka"])
def test_calibrated_payload_matches_the_urdf_and_reads_the_model(robot):
    """The calibration over :data:`CALIBRATION_TILTS` finds the robot description's payload mass within 0.1 %
    and centre of mass within 0.5 mm, and the calibrated sensor reads the model at a tilt as the URDF one does."""
    holds, weight, _ = tilted_holds(robot, 1e-3, 0, payload="calibrated")
    with DualArmScene(DualArmConfig(robot=robot, cable=CABLE, payload="calibrated")) as scene:
        fit = scene.physics.payload_fits[0]
        assert scene.sensors[0].compensation == "calibrated"
    physics = DualArmScene(DualArmConfig(robot=robot, cable=CABLE))
    try:
        sensor = physics.sensors[0]
        sensor.reader.read()
        mass = sensor.payload.mass
        rows = sensor.rows[: len(mass)]
        com = (mass[:, None] * rows[:, :3]).sum(axis=0) / mass.sum()
        r0 = Rotation.from_quat(rows[0, 3:7]).as_matrix()
        com_sensor = r0.T @ (com - rows[0, :3])
    finally:
        physics.close()
    assert fit.mass == pytest.approx(mass.sum(), rel=1e-3)
    assert np.allclose(fit.com, com_sensor, atol=5e-4), (fit.com, com_sensor)
    for k, (sensor_f, model) in enumerate(holds):
        assert np.all(np.abs(sensor_f - model) <= 0.005 * weight + 1e-3), (k, sensor_f, model)


def test_gravity_off_the_settled_hold_starts_and_the_wrists_read_the_bar_tension():
    """Gravity off (a space scene): the settled start is taken (before, its static solve ended unconverged at
    2e-12 N, the grippers 1.7e-7 m closer than the cable's length, and the scene was refused), and after the right
    gripper pulls 0.5 mm along the cable both wrists read the model's end forces, the bar's tension
    E A (|x_n - x_1| - L) / L along the cable, equal and opposite."""
    config = DualArmConfig(robot="panda", cable=CABLE, dt=1e-3, integrator="bdf2", gravity=(0.0, 0.0, 0.0))
    with DualArmScene(config) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (5e-4, 0.0, 0.0), 0.1, 0.3)])
        scene.run(0.8)
        w = scene.window_mean(0.3)
        x = scene.cable.x
        assert scene.cable.stable
    sensor, model = w["wrench_world"][:, :3], w["end_forces"]
    stretch = np.linalg.norm(x[-1] - x[0]) - CABLE.length
    tension = CABLE.youngs_modulus * np.pi * CABLE.diameter ** 2 / 4 * stretch / CABLE.length
    assert tension > 1.0  # [N] (about 2.6 N: the pull arrived)
    assert np.abs(sensor - model).max() <= 1e-3 * tension
    assert model[1, 0] == pytest.approx(-tension, rel=2e-3) and model[0, 0] == pytest.approx(tension, rel=2e-3)
    assert np.abs(sensor.sum(axis=0)).max() <= 1e-3 * tension
