"""Bullet's collision groups of cables whose contacts are the model's.

PyBullet collides a pair when either body's group is in the other's mask, and a static body's mask
holds every bit but 0x2: a world's second and third model-contact cables met the ground in Bullet
on top of the model (their spheres were read back from Bullet's contacts)."""
from __future__ import annotations

import pybullet as pb

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec


def test_every_model_contact_cable_leaves_static_bodies_to_the_model():
    spec = CableSpec.lv2017(n_masses=12, damping=0.02)
    with BulletWorld(dt=1 / 240) as world:
        cables = [world.add_cable(spec, name=f"c{k}", start=(0.0, 0.05 * k, spec.diameter / 2), direction=(1.0, 0, 0))
                  for k in range(3)]
        world.step(30)
        for cable in cables:
            touching = [b for b in cable.body_ids if pb.getContactPoints(bodyA=b, physicsClientId=world.client)]
            assert touching == [], (cable.name, len(touching))
            assert abs(cable.x[:, 2].mean() - spec.diameter / 2) < 2e-4  # the model holds it on the ground
