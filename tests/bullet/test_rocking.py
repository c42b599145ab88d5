"""A box lying across a cable on the ground rocks about the cable's axis: a two-way contact dynamics check.

Closed form (a rigid body rolling without slip on a fixed cylinder of radius R, its centre of mass h above the
contact, radius of gyration rho about the parallel axis through it): the potential m g ((R + h) cos(theta) +
R theta sin(theta)) has stiffness m g (R - h) at theta = 0 and the inertia about the contact line is
m (rho^2 + h^2), so

- h < R: it rocks at omega = sqrt(g (R - h) / (rho^2 + h^2));
- h > R: it is balanced unstably and tips at the growth rate lambda = sqrt(g (h - R) / (rho^2 + h^2)).

The cable's contact carries the box's weight, its moment and the friction that keeps it rolling; the rate and
frequency check all three inside the coupled step (its penalty, the body's condensed inertia, the anchored
friction). An earlier sweep read a box dropped centred on the cable coming to rest only after 2.1-2.4 s: it is
this unstable balance, tipped by round-off growing at lambda (a real box tips at once).
"""
from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81


def rocking(hz: int, n: int, half: tuple[float, float, float], diameter: float, duration: float,
            yaw: float = math.radians(30), spin: float = 1e-4) -> tuple[np.ndarray, np.ndarray, float]:
    """Times [s], roll angles [rad] about the cable's axis of a 30 g box (half extents ``half`` [m], turned ``yaw``
    about the vertical) laid across a cable lying on the ground along x and started rolling at ``spin`` [rad/s];
    and the closed form's g (R - h) / (rho^2 + h^2) [1/s^2] (negative: it rocks)."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02).with_(diameter=diameter)
    r = diameter / 2
    axis = np.array([1.0, 0.0, 0.0])
    with BulletWorld(dt=1.0 / hz) as world:
        cid = world.client
        world.add_cable(spec, start=(-spec.length / 2, 0, r), direction=tuple(axis))
        world.run(0.1)
        q0 = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        box = world.add_box(half, (0, 0, 2 * r + half[2]), q0, mass=0.03, friction=0.5)
        pb.resetBaseVelocity(box, [0, 0, 0], list(spin * axis), physicsClientId=cid)
        t, roll = [], []
        for _ in range(world.steps_in(duration)):
            world.step()
            q = pb.getBasePositionAndOrientation(box, physicsClientId=cid)[1]
            t.append(world.time)
            roll.append(float((Rotation.from_quat(q) * Rotation.from_quat(q0).inv()).as_rotvec() @ axis))
            if abs(roll[-1]) > 0.02:
                break  # tipped well past the linear range
    # a square box: the same radius of gyration about any horizontal axis through its centre
    rho2 = ((2 * half[0]) ** 2 + (2 * half[2]) ** 2) / 12
    h = half[2]
    return np.array(t), np.array(roll), G * (h - r) / (rho2 + h * h)


@pytest.mark.parametrize("hz,n,half,diameter", [(60, 20, (0.02, 0.02, 0.01), 0.004),
                                                (240, 20, (0.02, 0.02, 0.01), 0.004),
                                                (240, 30, (0.03, 0.03, 0.02), 0.006)])
def test_a_box_balanced_on_the_cable_tips_at_the_rocking_instabilitys_rate(hz, n, half, diameter):
    t, roll, lam2 = rocking(hz, n, half, diameter, duration=1.5)
    assert lam2 > 0 and abs(roll[-1]) > 0.02  # it tips
    grown = (np.abs(roll) > 1e-4) & (np.abs(roll) < 1e-2)  # the growing exponential alone: lambda t > 3.5
    assert grown.sum() >= 8
    rate = np.polyfit(t[grown], np.log(np.abs(roll[grown])), 1)[0]
    assert rate == pytest.approx(math.sqrt(lam2), rel=0.01)  # measured -0.1 to -0.4 % (60-1000 Hz)


@pytest.mark.parametrize("hz,n", [(60, 20), (240, 20), (1000, 40)])
def test_a_plank_across_a_thicker_cable_rocks_at_the_closed_forms_frequency(hz, n):
    t, roll, lam2 = rocking(hz, n, (0.03, 0.03, 0.001), 0.008, duration=1.5)
    assert lam2 < 0 and np.abs(roll).max() < 1e-4  # it stays balanced
    swing = roll - roll.mean()
    crossings = t[1:][np.sign(swing[1:]) != np.sign(swing[:-1])]
    assert len(crossings) >= 4
    omega = math.pi / np.mean(np.diff(crossings))
    assert omega == pytest.approx(math.sqrt(-lam2), rel=0.02)  # measured -1.3 % at 60 Hz, +0.06 % at 240 Hz
