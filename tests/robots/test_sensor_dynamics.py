"""Wrist sensors while the grippers turn fast, and with contacts on the hand (issue 27).

The sensor's transmitted wrench comes from Newton-Euler of the tool side (its links' rates of
momentum, their weights, every load on them), not from Bullet's joint reaction, which counts the
links' velocity-product terms twice while they turn (see :mod:`bullet_dlo.robots.sensors`). A
Panda hand turned 90 degrees about the cable in 0.7 s read 1.71 N off the cable's load with the
joint reaction (0.43 N in 1.4 s: the square of the rate), six cable weights.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.config.robot import load_robot_spec
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene
from bullet_dlo.robots.sensors import WristSensor
from bullet_dlo.robots.transforms import quat_from_axes, rotation

CABLE = CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=126e6, n_masses=16, damping=0.01)


@pytest.mark.parametrize("robot, dt, axis, seconds", [("panda", 1e-3, 0, 0.7), ("panda", 1 / 240, 1, 0.7),
                                                      ("kuka", 1 / 240, 0, 0.5)])
def test_fast_turn_reads_the_cable_load_at_every_step(robot, dt, axis, seconds):
    """The right gripper turns 90 degrees (about the cable, or 22.5 about y) in ``seconds``: every sample
    against the load the cable applied in that step, within 0.5 % of the cable's weight plus 1 mN."""
    rot = np.zeros(3)
    rot[axis] = np.pi / 2 if axis == 0 else -np.pi / 8
    with DualArmScene(DualArmConfig(robot=robot, cable=CABLE, dt=dt, integrator="bdf2")) as scene:
        scene.grasp()
        scene.follow_motion([Move("last", (0.0, 0.0, 0.0), 0.2, seconds, rotation=tuple(rot))])
        scene.run(seconds + 0.4)
        check = scene.observation.check
        weight = CABLE.mass * float(np.linalg.norm(scene.world.gravity))
        assert scene.cable.stable
        assert check.samples == scene.world.steps  # every step sampled
        assert check.worst[:, 0].max() <= 0.005 * weight + 1e-3, check.summary()
        assert check.worst[:, 1].max() <= 0.005 * weight * CABLE.length + 1e-4, check.summary()
        # and the turn was fast: the hand's own inertial load was many cable weights
        assert scene.sensors[1].payload_mass * (np.pi / 2 / seconds) ** 2 * 0.05 > 0.3 * weight


def mirrored(c: tuple) -> tuple:
    """A contact point described from its other body: A and B swapped, the normal and the friction directions
    turned (the force on the new A is the force on the old B)."""
    neg = lambda v: tuple(-x for x in v)  # noqa: E731
    return (c[0], c[2], c[1], c[4], c[3], c[6], c[5], neg(c[7]), c[8], c[9], c[10], neg(c[11]), c[12], neg(c[13]))


@pytest.mark.parametrize("name, hand_second", [("panda", False), ("kuka", False), ("panda", True)])
def test_contact_on_the_hand_reads_as_bullets_reaction_at_rest(name, hand_second):
    """A gripper pressed down and sideways onto a fixed block: at rest (where Bullet's joint reaction is
    right) the sensor, which adds the contacts itself, reads the block's push and its moment as the joint
    reaction does, within 1 % plus 2 mN (0.2 mN m); the push is several newtons, with friction (a friction
    force of the wrong sign fails this). Bullet lists the hand as body A here; the same contacts described with the
    hand as body B (``mirrored``) read the same."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        pb.setTimeStep(1e-3, physicsClientId=client)
        pb.setPhysicsEngineParameter(solverResidualThreshold=1e-9, numSolverIterations=200, physicsClientId=client)
        half = 0.05
        robot = Robot.load(load_robot_spec(name), client, (0.0, 0.0, 0.0), visuals=False)
        block = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[half] * 3,
                                                                physicsClientId=client),
                                   basePosition=(5.0, 5.0, -5.0), physicsClientId=client)
        quat = quat_from_axes((1.0, 0.0, 0.0), (0.3, 0.0, -1.0))  # tilted: the block pushes up and sideways
        q = robot.solve_ik((0.5, 0.0, 0.35), quat, seed=np.array(robot.spec.home))
        robot.reset_joints(q)
        robot.set_targets(q)
        for _ in range(300):
            pb.stepSimulation(physicsClientId=client)
        contacts = (lambda: [mirrored(c) for c in pb.getContactPoints(physicsClientId=client)]) if hand_second else None
        sensor = WristSensor(robot, (0.0, 0.0, -9.81), contacts=contacts)
        sensor.tare()
        tool = robot.subtree_links(sensor.joint)
        low = min(pb.getAABB(robot.body, j, physicsClientId=client)[0][2] for j in tool
                  if pb.getCollisionShapeData(robot.body, j, physicsClientId=client))  # links that can touch
        pb.resetBasePositionAndOrientation(block, (0.5, 0.0, low - half + 0.002), (0, 0, 0, 1), physicsClientId=client)
        pb.changeDynamics(block, -1, lateralFriction=1.0, physicsClientId=client)
        robot.set_targets(robot.solve_ik((0.505, 0.0, 0.34), quat, seed=q))  # 1 cm into the block, 5 mm aside
        for _ in range(1500):
            pb.stepSimulation(physicsClientId=client)
            sensor.update(0.0, 1e-3)
        reading = sensor.update(1.0, 1e-3).world()
        # the same from Bullet's joint reaction: at rest the arm carries the tool's weight and the block's push
        row = sensor.rows[0]
        mass = sensor.payload_mass
        g = np.array([0.0, 0.0, -9.81])
        turn = rotation(row[3:7])
        push = -turn @ sensor.raw()[:3] - mass * g
        weight_moment = sum(m * np.cross(r[:3] - row[:3], g) for m, r in zip(sensor.payload.mass, sensor.rows))
        moment = -turn @ sensor.raw()[3:] - weight_moment  # about the sensor frame's origin
        assert {(c[1], c[2]) for c in pb.getContactPoints(physicsClientId=client)} == {(robot.body, block)}
        assert np.linalg.norm(push) > 2.0 and abs(push[0]) > 0.1, push
        assert np.allclose(reading[:3], push, rtol=0.01, atol=2e-3), (reading[:3], push)
        assert np.allclose(reading[3:], moment, rtol=0.01, atol=2e-4), (reading[3:], moment)
    finally:
        pb.disconnect(client)
