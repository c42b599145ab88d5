"""Parked proxy spheres (``bullet_spheres="auto"``): a model-contact cable's spheres sleep in Bullet and are written
there only when read. The model's trajectory is the live one's, bit for bit; every read the library makes
(``bullet_positions``, rendered frames, a new cable's spawn check) sees the cable where the model has it; a body
dropped onto the cable still meets it; a ``contact="bullet"`` cable wakes the spheres where the model is."""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError

G = 9.81


def _dropped(mode: str, steps: int = 120):
    """A 20-mass cable dropped 2 cm onto the ground, slanted, at 240 Hz: positions and velocities of every step."""
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    xs, vs = [], []
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, spec.diameter / 2 + 0.02), direction=(1.0, 0.3, 0.0),
                                bullet_spheres=mode)
        proxy = cable.proxy
        for _ in range(steps):
            world.step()
            xs.append(cable.x.copy())
            vs.append(cable.v.copy())
    return proxy, np.array(xs), np.array(vs)


def test_proxy_spheres_keep_the_live_trajectory_bit_for_bit():
    """Untouched spheres are never read back, so parking them cannot change the model: the cable landing on the
    ground (contacts the model's) runs exactly as with live spheres."""
    proxy, x_p, v_p = _dropped("auto")
    live, x_l, v_l = _dropped("live")
    assert proxy and not live
    assert np.array_equal(x_p, x_l) and np.array_equal(v_p, v_l)
    assert np.ptp(x_p[:, :, 2]) > 0.015  # it did fall the 2 cm


def test_reads_of_proxy_spheres_see_the_model():
    spec = CableSpec.lv2017(n_masses=12, damping=0.02)
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.3))  # free: falls ~8 cm in 0.15 s (damped)
        assert cable.proxy
        cid = world.client
        spawn = np.array(pb.getBasePositionAndOrientation(cable.body_ids[3], physicsClientId=cid)[0])
        world.run(0.15)
        # a direct PyBullet read is as of the last sync (documented), and the velocity of a sleeping body is 0
        stale = np.array(pb.getBasePositionAndOrientation(cable.body_ids[3], physicsClientId=cid)[0])
        assert np.max(np.abs(stale - spawn)) <= 1e-12 and cable.x[3, 2] < spawn[2] - 0.05
        assert pb.getBaseVelocity(cable.body_ids[3], physicsClientId=cid)[0] == (0.0, 0.0, 0.0)
        assert np.array_equal(cable.bullet_positions(), cable.x)  # synced first
        world.step()
        world.sync_bullet_spheres()
        now = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in cable.body_ids])
        assert np.array_equal(now, cable.x)
        world.run(0.05)  # still parked: Bullet did not move them (not even the step it takes to fall asleep)
        parked = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in cable.body_ids])
        assert np.max(np.abs(parked - now)) <= 1e-12


def test_rendered_frame_draws_proxy_spheres_where_the_cable_is():
    from bullet_dlo.render.camera import Camera, render_frame

    camera = Camera(eye=(0.15, -0.6, 0.45), target=(0.15, 0.0, 0.3), width=320, height=240, fov=50)
    with BulletWorld(dt=1 / 240, renderer="tiny") as world:
        cable = world.add_cable(CableSpec.lv2017(n_masses=12, diameter=0.01), start=(0.0, 0.0, 0.45))
        world.run(0.2)  # fallen ~0.2 m from where Bullet last had the spheres
        assert cable.proxy
        frame = render_frame(world.client, camera, world.renderer, {b: i for i, b in enumerate(cable.body_ids)})
        uv, _ = camera.project(cable.x, world.client)
        for i, (u, v) in enumerate(uv):
            r, c = int(round(v)), int(round(u))
            assert np.any(frame.cable_mass[r - 1:r + 2, c - 1:c + 2] == i), f"mass {i} not drawn at ({c}, {r})"


def test_body_dropped_onto_a_proxy_cable_rests_on_it():
    """A 50 g box dropped 2 cm onto two parallel cables lying on the ground comes to rest flat on them (the model's
    contact, two-way): its bottom one diameter above the ground, the two cables carrying its weight."""
    spec = CableSpec.lv2017(n_masses=20, damping=0.02)
    d, half, mass = spec.diameter, 0.02, 0.05
    with BulletWorld(dt=1 / 240) as world:
        cables = [world.add_cable(spec, start=(-0.15, y, d / 2), name=f"c{k}") for k, y in enumerate((-0.012, 0.012))]
        assert all(c.proxy for c in cables)
        box = world.add_box((half, half, half), (0.0, 0.0, d + half + 0.02), mass=mass, name="box")
        world.run(1.0)
        assert all(c.stable and c.proxy for c in cables)
        z = pb.getBasePositionAndOrientation(box, physicsClientId=world.client)[0][2]
        assert z - half == pytest.approx(d, abs=5e-4)  # on the cables, not through them
        assert sum(c.body_forces()[box][2] for c in cables) == pytest.approx(mass * G, rel=0.05)  # (on the box, up)


def test_a_bullet_contact_cable_wakes_the_proxies_where_the_model_is():
    spec = CableSpec.lv2017(n_masses=12, damping=0.02)
    with BulletWorld(dt=1 / 240) as world:
        first = world.add_cable(spec, start=(0.0, 0.0, 0.3), name="first")
        second = world.add_cable(spec, start=(0.0, 0.2, 0.3), name="second", ends=("clamped", "free"))
        assert first.proxy and second.proxy  # both leave their mutual contacts to the model
        world.run(0.1)
        third = world.add_cable(spec, start=(0.0, 0.4, 0.3), name="third", contact="bullet",
                                integrator="symplectic_euler", substeps=5)
        assert not (first.proxy or second.proxy or third.proxy)
        assert np.array_equal(first.bullet_positions(), first.x)
        world.run(0.1)  # live again: Bullet's semi-implicit step lands on the model's positions
        for c in (first, second):
            assert np.max(np.abs(c.bullet_positions() - c.x)) <= 1e-9
        assert first.x[0, 2] < 0.3 - 0.08  # and it kept falling


def test_bullet_spheres_option_is_checked():
    with BulletWorld(dt=1 / 240) as world:
        with pytest.raises(ParameterError, match="bullet_spheres must be one of auto, live"):
            world.add_cable(CableSpec.lv2017(n_masses=5), bullet_spheres="asleep")
        live = world.add_cable(CableSpec.lv2017(n_masses=5), bullet_spheres="live", name="live")
        always = world.add_cable(CableSpec.lv2017(n_masses=5), start=(0, 0.2, 0.5), sync="always", name="always")
        assert not live.proxy and not always.proxy


def test_set_up_calls_on_the_spheres_keep_them_parked():
    """Pair filters (a grasp's), colours (the tube renderer's), exclusions and a point mass do not wake parked
    spheres: Bullet leaves them where they were parked (a woken sphere would fall freely: no forces)."""
    with BulletWorld(dt=1 / 240) as world:
        c = world.add_cable(CableSpec.lv2017(n_masses=6), start=(0, 0, 0.3), ends=("clamped", "clamped"))
        box = world.add_box((0.02,) * 3, (0.5, 0.5, 0.02), mass=0.1)
        world.step(2)
        cid = world.client
        pb.setCollisionFilterPair(box, c.body_ids[0], -1, -1, 0, physicsClientId=cid)
        pb.changeVisualShape(c.body_ids[1], -1, rgbaColor=[1, 0, 0, 1], physicsClientId=cid)
        c.exclude_contact(box, nodes=[0, 1])
        c.add_point_mass(2, 0.01)
        before = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in c.body_ids])
        world.step(10)
        after = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in c.body_ids])
        assert c.proxy and np.max(np.abs(after - before)) <= 1e-12


def test_every_model_contact_cable_leaves_static_bodies_to_the_model():
    """With live spheres, a world's second and third model-contact cables had Bullet contacts with the
    ground on top of the model's (PyBullet collides a pair when either group is in the other's mask, and
    a static body's mask holds every cable group but the first's); all three lie on the ground here."""
    spec = CableSpec.lv2017(n_masses=12, damping=0.02)
    with BulletWorld(dt=1 / 240) as world:
        cables = [world.add_cable(spec, name=f"c{k}", start=(0.0, 0.05 * k, spec.diameter / 2), direction=(1.0, 0, 0),
                                  bullet_spheres="live") for k in range(3)]
        world.step(30)
        for cable in cables:
            touching = [b for b in cable.body_ids if pb.getContactPoints(bodyA=b, physicsClientId=world.client)]
            assert touching == [], (cable.name, len(touching))
            assert abs(cable.x[:, 2].mean() - spec.diameter / 2) < 2e-4  # the model holds it on the ground
