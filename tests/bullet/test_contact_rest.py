"""A cable at rest in contact: on a table, across a box's edges, over a peg.

Closed forms: the support forces sum to the weight; the segments carry the strain of the
contact-free static solution (zero tension along a cable lying on supports: |strain| ~ 1e-6
from bending); the kinetic energy decays. Before the contact model, a cable lying still on the
box carried 1-9 % strain and one over a peg stretched beyond 50 %.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
Q_AXIS_Y = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))


def strain(cable) -> np.ndarray:
    seg = np.linalg.norm(np.diff(cable.x, axis=0), axis=1)
    return seg / cable.model.spec.rest_length - 1.0


def kinetic(cable) -> float:
    return 0.5 * float(np.sum(cable.arrays.mass[:, None] * cable.v ** 2))


def settle(world, cable, seconds: float) -> list[float]:
    """Run, returning the kinetic energy [J] after each step."""
    ke = []
    for _ in range(int(round(seconds / world.dt))):
        world.step()
        assert cable.stable, cable.reason
        ke.append(kinetic(cable))
    return ke


SCENES = ["table", "box_edges", "peg"]


def build(scene: str, world: BulletWorld, n: int, integrator: str):
    """Lv cable (0.3 m, 30 g) laid at rest on its support: the ground, a 0.2 m-wide box (0.05 m
    over each edge) or a peg of radius 8 mm (two diameters), centred."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r = spec.diameter / 2
    if scene == "table":
        body, top = world.ground_id, 0.0
    elif scene == "box_edges":
        body, top = world.add_box((0.1, 0.1, 0.1), (0, 0, 0.1)), 0.2
    else:
        body, top = world.add_cylinder(0.008, 0.2, (0, 0, 0.292), Q_AXIS_Y), 0.3
    cable = world.add_cable(spec, start=(-0.15, 0.0, top + r), direction=(1, 0, 0), integrator=integrator)
    return cable, body


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("integrator,hz,n", [("implicit_euler", 240, 20), ("bdf2", 60, 40),
                                             ("implicit_midpoint", 1000, 10)])
def test_rest_support_equals_weight_and_strain_stays_static(scene, integrator, hz, n):
    with BulletWorld(dt=1.0 / hz) as world:
        cable, body = build(scene, world, n, integrator)
        ke = settle(world, cable, 1.5)
        weight = cable.model.spec.mass * G
        support = cable.contact_forces()["force"].sum(axis=0)
        assert support[2] == pytest.approx(weight, rel=0.01)
        assert np.hypot(support[0], support[1]) < 1e-3 * weight
        assert cable.body_forces()[body][2] == pytest.approx(-weight, rel=0.01)  # the reaction, on the support
        assert np.max(np.abs(strain(cable))) < 1e-4
        late = np.array(ke[-int(0.3 * hz):])
        assert late[-1] < 1e-6 * weight * cable.model.spec.length  # at rest (max speed ~ 2 mm/s)
        assert late[-1] <= late[0] + 1e-15  # and not gaining
        assert cable.contact_forces()["gap"].min() > -1e-4  # penetration below 0.1 mm


def test_bodies_added_together_between_steps_join_the_contact_model():
    """Five boxes added at once between steps (a table under the falling cable among them): the cable lands on
    the table top, not on the ground under it. (The contact set's rebuild check compared Bullet's body count,
    spheres included, with the world's named bodies: with five boxes on a five-mass cable the two matched and
    the boxes stayed out of the contact model; the cable fell through the table.)"""
    with BulletWorld(dt=1.0 / 240.0) as world:
        spec = CableSpec.lv2017(n_masses=5)
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.2))
        world.step()
        half = 0.5 * spec.length
        top = 0.1
        table = world.add_box((half + 0.1, 0.2, 0.5 * top), (half, 0.0, 0.5 * top))
        for k in range(4):
            world.add_box((0.05, 0.05, 0.05), (3.0 + k, 3.0, 0.05))
        for _ in range(72):  # 0.3 s: the cable falls 0.1 m onto the table in 0.14 s and settles
            world.step()
        assert cable.stable, cable.reason
        assert float(cable.x[:, 2].min()) > top, "the cable went through the table"
        assert table in cable.body_forces()
