"""Heightfields in the cable's contact model (issue 23 item 1: "heightfields ... enter the cable's implicit solve").

PyBullet's ``getCollisionShapeData`` lists no shape for a heightfield (it prints "Unexpected collision shape
type"), and the contact set skipped such a link as shapeless: the cable fell through terrain that Bullet's own
bodies rest on. A link PyBullet does not describe but whose broad-phase box is wider than an empty link's now
goes to Bullet's narrow phase like any other mesh. Closed forms: a cable at rest on flat terrain puts its weight on
it with no strain; on a slope of angle theta a straight cable holds when mu > tan(theta) (the terrain carries the
weight, normal and friction together) and slides with acceleration g (sin(theta) - mu cos(theta)) when not.
"""
from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest
from test_contact_rest import strain

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
CELLS = 41  # heightfield samples per side
SPACING = 0.04  # [m] between samples: a 1.6 m square
LIFT = 0.1  # [m] the terrain's centre height (above Bullet's ground plane)


def terrain(world: BulletWorld, slope: float, friction: float) -> int:
    """A static heightfield z = LIFT + tan(slope) x (Bullet centres the samples between their extremes)."""
    xs = (np.arange(CELLS) - (CELLS - 1) / 2) * SPACING
    heights = [math.tan(slope) * xs[c] for _ in range(CELLS) for c in range(CELLS)]
    cid = world.client
    col = pb.createCollisionShape(pb.GEOM_HEIGHTFIELD, meshScale=[SPACING, SPACING, 1.0], heightfieldData=heights,
                                  numHeightfieldRows=CELLS, numHeightfieldColumns=CELLS, physicsClientId=cid)
    body = pb.createMultiBody(0, col, -1, [0.0, 0.0, LIFT], physicsClientId=cid)
    pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=cid)
    return body


def run(world: BulletWorld, cable, seconds: float) -> None:
    for _ in range(int(round(seconds / world.dt))):
        world.step()
        assert cable.stable, cable.reason


@pytest.mark.parametrize("integrator,hz,n", [("implicit_euler", 240, 20), ("bdf2", 60, 10)])
def test_cable_rests_on_a_flat_heightfield(integrator, hz, n):
    """The terrain carries the weight within 1 %, no node below its surface, no strain (before: fell through)."""
    with BulletWorld(dt=1.0 / hz) as world:
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        body = terrain(world, 0.0, spec.static_friction)
        r = spec.diameter / 2
        cable = world.add_cable(spec, start=(-0.15, 0.05, LIFT + r + 1e-3), direction=(1, 0, 0), integrator=integrator)
        run(world, cable, 1.0)
        assert np.all(cable.x[:, 2] > LIFT + r - 1e-4)
        assert np.max(np.abs(strain(cable))) < 1e-4
        assert cable.body_forces().get(body, np.zeros(3))[2] == pytest.approx(-spec.mass * G, rel=0.01)


@pytest.mark.parametrize("mu", [0.3, 0.08])
def test_cable_on_a_heightfield_slope_holds_or_slides_by_coulomb(mu):
    """A straight cable laid down a 10 degree slope: mu = 0.3 > tan = 0.176 holds (moves < 1 mm in 1 s; the
    terrain carries the weight as a vertical force within 1 %); mu = 0.08 slides as a block, s = g (sin - mu cos)
    t^2 / 2 within 5 % (no internal force: every node feels the same slope)."""
    slope = math.radians(10.0)
    hz, seconds = 240.0, 0.8
    spec = CableSpec.lv2017(n_masses=20, damping=0.0).with_(static_friction=mu, dynamic_friction=mu)
    with BulletWorld(dt=1.0 / hz) as world:
        body = terrain(world, slope, mu)  # combined coefficient sqrt(mu_cable mu_body) = mu
        r = spec.diameter / 2
        x0 = 0.35
        normal = np.array([-math.sin(slope), 0.0, math.cos(slope)])
        start = np.array([x0, 0.05, LIFT + math.tan(slope) * x0]) + r * normal
        down = (-math.cos(slope), 0.0, -math.sin(slope))
        cable = world.add_cable(spec, start=tuple(start), direction=down)
        first = cable.x[0].copy()
        run(world, cable, seconds)
        travel = float(np.dot(cable.x[0] - first, down))
        height = cable.x[:, 2] - (LIFT + math.tan(slope) * cable.x[:, 0])
        assert np.all(height > r / math.cos(slope) - 1e-4)  # on the surface, not through it
        if mu > math.tan(slope):
            assert abs(travel) < 1e-3
            force = cable.body_forces().get(body, np.zeros(3))
            assert force[2] == pytest.approx(-spec.mass * G, rel=0.01)
            assert np.hypot(force[0], force[1]) < 0.01 * spec.mass * G
        else:
            expected = 0.5 * G * (math.sin(slope) - mu * math.cos(slope)) * seconds ** 2
            assert travel == pytest.approx(expected, rel=0.05)
