"""A position-controlled arm's links in the cable's contact model (issue 23): links a motor holds at force limits
far above the cable's loads (``BulletWorld.drive_body``; the dual-arm scene drives its arms' links but the
fingers) are kinematic obstacles in the cable's step, moving with the link's velocity; the reactions still go to
the link in Bullet.

Physics checked, at 60 Hz (where the condensed contact a dynamic link has otherwise is softest):
- non-penetration: the cable's surface stays outside the link's collision shape (Bullet's getClosestPoints of a
  sphere of the cable's radius at each node: overlap below 0.1 radius). Closed form of the condensed contact the
  links had before: the penalty in series with the link's inertia lets a load F sink by about F h^2 / M, for the
  30 g cable on a 0.1 kg finger 0.3 g h^2 = 0.82 mm (measured 0.78 mm; driven: 0.10 mm); a 6 m/s swing against
  the 3 kg forearm went 0.83 mm in (driven: 0.02 mm);
- balance: the cable resting on the finger (nothing else touching it) pushes the finger by its weight.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.config.robot import load_robot_spec
from bullet_dlo.core.model import CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.arm import Robot

HZ = 60.0
G = 9.81
FINGERS_LEVEL = (0.0, -0.2, 0.0, -2.2, 0.0, 0.43, 0.785 + np.pi / 2)  # the hand level, one finger above the other


def overlap(cid: int, body: int, x: np.ndarray, probe: int) -> float:
    """Deepest overlap [m] of a sphere of the cable's radius at each node with any link of ``body`` (0: none)."""
    worst = 0.0
    for link in range(-1, pb.getNumJoints(body, physicsClientId=cid)):
        for p in x.tolist():
            for hit in pb.getClosestPoints(-1, body, 0.005, -1, link, probe, -1, p, physicsClientId=cid):
                worst = max(worst, -hit[8])
    return worst


def panda(world: BulletWorld, q=None) -> Robot:
    robot = Robot.load(load_robot_spec("panda"), world.client, (0.0, 0.0, 0.0), visuals=False)
    if q is not None:
        robot.reset_joints(np.array(q))  # and holds them (position control at the joints' force limits)
    world.drive_body(robot.body)
    return robot


def test_a_cable_resting_on_a_driven_finger_stays_on_it_and_loads_it():
    """An Lv cable (n = 20) laid across the upper finger of a level hand, settled 1.5 s: its surface on the
    finger's (overlap < 0.1 radius over the last 0.5 s) and the finger carries the cable's weight (within 3 %,
    the mean over the last 0.5 s; it is the only support). Before (condensed contact): 0.78 mm = 0.39 radius."""
    with BulletWorld(dt=1.0 / HZ) as world:
        robot = panda(world, FINGERS_LEVEL)
        cid, finger = world.client, robot.link_index["panda_leftfinger"]
        spec = CableSpec.lv2017(n_masses=20, damping=0.02)
        r = spec.diameter / 2
        lo, hi = pb.getAABB(robot.body, finger, physicsClientId=cid)
        y = 0.5 * (lo[1] + hi[1])
        hit = pb.rayTest([0.2, y, hi[2] + 0.05], [0.2, y, lo[2]], physicsClientId=cid)[0]
        assert hit[0] == robot.body and hit[1] == finger
        cable = world.add_cable(spec, start=(0.2, y - spec.length / 2, hit[3][2] + r + 1e-3), direction=(0, 1, 0))
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=r, physicsClientId=cid)
        worst, load = 0.0, []
        for k in range(int(1.5 * HZ)):
            world.step()
            assert cable.stable, cable.reason
            if k >= HZ:
                worst = max(worst, overlap(cid, robot.body, cable.x, probe))
                pc = cable.contact_forces()
                assert set(pc["body"].tolist()) == {robot.body} and set(pc["link"].tolist()) == {finger}
                load.append(-pc["force"].sum(axis=0))
        assert worst < 0.1 * r, worst
        assert np.mean(load, axis=0)[2] == pytest.approx(-spec.mass * G, rel=0.03)


def test_a_cable_swung_against_a_driven_forearm_stays_outside_it():
    """An Lv cable pinned above the forearm, hanging, swung at it (6 m/s at the free end, 10 cm a step): it meets
    the forearm and stays outside it (overlap < 0.1 radius). Before (condensed contact): 0.83 mm = 0.42 radius."""
    n = 20
    with BulletWorld(dt=1.0 / HZ) as world:
        robot = panda(world)
        cid = world.client
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        r = spec.diameter / 2
        s = np.arange(n) * spec.rest_length
        pin = (0.3, -0.09, 0.75)
        x0 = np.stack([pin[0] + 0 * s, pin[1] + 0 * s, pin[2] - s], axis=1)
        v0 = np.stack([0 * s, 6.0 / spec.length * s, 0 * s], axis=1)  # turning about the pin
        cable = world.add_cable(spec, start=pin, direction=(0, 0, -1), ends=("pinned", "free"),
                                state=CableState(x0, v0))
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=r, physicsClientId=cid)
        worst, links = 0.0, set()
        for _ in range(int(0.5 * HZ)):
            world.step()
            assert cable.stable, cable.reason
            links |= set(cable.contact_forces()["link"].tolist())
            worst = max(worst, overlap(cid, robot.body, cable.x, probe))
        assert robot.link_index["panda_link5"] in links, links
        assert worst < 0.1 * r, worst
