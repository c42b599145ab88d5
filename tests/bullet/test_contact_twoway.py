"""Two-way contact: the touched body gets the reaction, held ends feel the contact, energy check in contact.

Closed forms: a box under a cable presses on the ground with (m_box + m_cable) g; pulled by the
cable (friction, frictionless ground) box and cable accelerate together at F / (m_box + m_cable);
a cable held at one end and lying on a table: holder force + support = weight.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81


def test_box_carries_the_cable_and_is_dragged_by_it():
    spec = CableSpec.lv2017(n_masses=20, static_friction=0.8, dynamic_friction=0.6)
    r, hz, m_box, pull = spec.diameter / 2, 240, 0.05, 0.05
    with BulletWorld(dt=1 / hz, ground_friction=0.0) as world:
        half = (0.2, 0.05, 0.02)
        box = world.add_box(half, (0, 0, half[2]), mass=m_box, friction=0.8)
        cable = world.add_cable(spec, start=(-0.15, 0, 2 * half[2] + r), direction=(1, 0, 0))
        cid = world.client
        normal = []
        for k in range(hz):
            world.step()
            if k > hz // 2:
                normal.append(sum(cp[9] for cp in pb.getContactPoints(box, world.ground_id, physicsClientId=cid)))
        assert np.mean(normal) == pytest.approx((m_box + spec.mass) * G, rel=0.01)
        on_box = cable.body_forces()[box]
        assert on_box == pytest.approx([0, 0, -spec.mass * G], abs=1e-3 * spec.mass * G)
        cable.set_external_force(0, (-pull, 0.0, 0.0))  # pull the first node along -x
        t, v_box = [], []
        for k in range(int(0.6 * hz)):
            world.step()
            t.append(k / hz)
            v_box.append(pb.getBaseVelocity(box, physicsClientId=cid)[0][0])
        t, v_box = np.array(t), np.array(v_box)
        accel = np.polyfit(t[t > 0.1], v_box[t > 0.1], 1)[0]
        assert accel == pytest.approx(-pull / (m_box + spec.mass), rel=0.05)
        assert cable.stable
        assert not cable.contact_forces()["sliding"].any()  # dragged along by static friction


def test_held_end_feels_what_the_table_does_not_carry():
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        # clamped 2 cm above the table, horizontal: the rest of the cable lies down on the table
        cable = world.add_cable(spec, start=(0, 0, 0.02 + r), direction=(1, 0, 0), ends=("clamped", "free"))
        world.run(2.0)
        assert cable.stable
        support = cable.contact_forces()["force"].sum(axis=0)
        held = cable.end_forces()[0]  # what the cable exerts on the holder (a wrist sensor reads this)
        assert support[2] > 0.5 * spec.mass * G  # the table carries most of it
        assert support[2] - held[2] == pytest.approx(spec.mass * G, rel=0.01)


def test_energy_check_catches_energy_made_in_contact():
    """A cable resting on a box that is teleported 2 cm up into it: the penalty springs fling the cable
    with energy no force did work for; the check (cable energy + contact energy - work) must stop it.
    (3 mm only pops it up at 0.7 m/s: 9 mJ, below the check's scale M g L = 88 mJ.)"""
    spec = CableSpec.lv2017(n_masses=20)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        box = world.add_box((0.2, 0.1, 0.1), (0, 0, 0.1))
        cable = world.add_cable(spec, start=(-0.15, 0, 0.2 + r), direction=(1, 0, 0))
        world.run(0.5)
        assert cable.stable  # no false alarm at rest
        pb.resetBasePositionAndOrientation(box, (0, 0, 0.12), (0, 0, 0, 1), physicsClientId=world.client)
        world.run(0.5)
        assert not cable.stable
        assert cable.reason == "energy growth beyond the work done on the cable"
