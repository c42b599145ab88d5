"""Contact with what the exact geometry does not cover (issue 23): convex hulls, concave triangle meshes,
mesh pegs and the shapes of URDF child links, all through Bullet's narrow phase with the same contact law.

Closed forms as in test_contact_rest (the supports carry the weight, the segments the strain of the
contact-free static solution, |strain| < 1e-4) and test_contact_friction (the capstan law at the slip
onset). Before, these shapes were ignored with a warning and the cable fell through them.

A mesh in Bullet carries a collision margin: its surface is the mesh grown by 1 mm (measured:
getClosestPoints answers from 1 mm above a hull's or a triangle mesh's face), and the cable rests on that
surface, as Bullet's own bodies do.
"""
from __future__ import annotations

import math

import numpy as np
import pybullet as pb
import pytest
from test_contact_friction import capstan_onset
from probes import deepest
from test_contact_rest import settle, strain

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81
HULL_MARGIN = 1e-3  # [m] Bullet's collision margin of a mesh made by createCollisionShape or a URDF
BOX = (0.1, 0.1, 0.1)  # [m] half extents of the support: the 0.3 m cable hangs 0.05 m over each edge
TWO_LINKS = """<?xml version="1.0"?>
<robot name="stand">
  <link name="foot">
    <inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <collision><origin xyz="0.5 0 0"/><geometry><box size="0.05 0.05 0.05"/></geometry></collision>
  </link>
  <link name="top">
    <inertial><mass value="{mass}"/><inertia ixx="{inertia}" ixy="0" ixz="0" iyy="{inertia}" iyz="0" izz="{inertia}"/>
    </inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <joint name="fix" type="{joint}"><parent link="foot"/><child link="top"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
</robot>
"""


def box_corners(he) -> list[list[float]]:
    return [[sx * he[0], sy * he[1], sz * he[2]] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]


def box_triangles() -> list[int]:
    """The 12 triangles of box_corners (index = 4 ix + 2 iy + iz), outward."""
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [i for a, b, c, d in quads for i in (a, b, c, a, c, d)]


def add_support(world: BulletWorld, kind: str, tmp_path) -> tuple[int, int, float]:
    """A 0.2 m cube on the ground, as ``kind``: (body, link, top z [m] of the surface the cable meets)."""
    cid = world.client
    if kind in ("hull", "trimesh"):
        # vertices only: a convex hull; with triangles: a triangle mesh (concave, static)
        mesh = {"indices": box_triangles(), "flags": pb.GEOM_FORCE_CONCAVE_TRIMESH} if kind == "trimesh" else {}
        col = pb.createCollisionShape(pb.GEOM_MESH, vertices=box_corners(BOX), physicsClientId=cid, **mesh)
        body = pb.createMultiBody(0, col, -1, [0, 0, BOX[2]], physicsClientId=cid)
        return body, -1, 2 * BOX[2] + HULL_MARGIN
    urdf = tmp_path / "stand.urdf"
    # heavy_child: the fixed child link has a mass, as real fixtures' links do (it cannot move all the same)
    mass = 2.0 if kind == "heavy_child" else 0.0
    urdf.write_text(TWO_LINKS.format(joint="revolute" if kind == "revolute_child" else "fixed", mass=mass,
                                     inertia=mass * 0.2 ** 2 / 6))
    body = world.add_urdf(urdf, (0.0, 0.0, 0.0))
    return body, 0, 2 * BOX[2]


@pytest.mark.parametrize("kind", ["hull", "trimesh", "child_link", "heavy_child", "revolute_child"])
@pytest.mark.parametrize("integrator,hz,n", [("implicit_euler", 240, 20), ("bdf2", 60, 10)])
def test_cable_rests_on_a_mesh_or_child_link(kind, integrator, hz, n, tmp_path):
    """An Lv cable laid across the cube's top (over two edges): the body carries its weight, no strain; also on a
    fixed child link with a mass (2 kg), as static as one without (test_contact_urdf: the capstan on such a peg)."""
    with BulletWorld(dt=1.0 / hz) as world:
        body, link, top = add_support(world, kind, tmp_path)
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        r = spec.diameter / 2
        cable = world.add_cable(spec, start=(-0.15, 0.0, top + r), direction=(1, 0, 0), integrator=integrator)
        settle(world, cable, 1.5)
        weight = spec.mass * G
        on_top = np.abs(cable.x[:, 0]) < BOX[0]
        assert np.all(cable.x[:, 2] > 2 * BOX[2] - 0.06)  # hanging over the edges, not fallen down
        assert np.all(cable.x[on_top, 2] > top + r - 1e-4)  # not through the top
        assert np.max(np.abs(strain(cable))) < 1e-4
        assert cable.body_forces().get(body, np.zeros(3))[2] == pytest.approx(-weight, rel=0.01)  # the reaction
        assert set(cable.contact_forces()["link"].tolist()) == {link}


def hull_peg(world: BulletWorld, radius: float, friction: float, sides: int = 48) -> int:
    """A cylinder of ``radius`` [m] as a convex hull of a ``sides``-gon prism, axis along y: its faces
    (grown by the hull margin) at ``radius``, its rounded corners 0.2 % beyond."""
    rv = (radius - HULL_MARGIN) / math.cos(math.pi / sides)
    a = 2 * math.pi * (np.arange(sides) + 0.5) / sides
    ring = [[rv * math.cos(t), y, rv * math.sin(t)] for t in a for y in (-0.1, 0.1)]
    col = pb.createCollisionShape(pb.GEOM_MESH, vertices=ring, physicsClientId=world.client)
    body = pb.createMultiBody(0, col, -1, [0, 0, 0], physicsClientId=world.client)
    pb.changeDynamics(body, -1, lateralFriction=friction, physicsClientId=world.client)
    return body


@pytest.mark.parametrize("hz", [240.0, 60.0])
def test_capstan_on_a_hull_peg(hz):
    """Slip onset of a light cable wrapped half round a 48-gon hull peg: T_long/T_short = exp(mu pi) within 10 %
    (the 50 g end weights dwarf the wrapped part's weight, 0.1 g)."""
    mu = 0.3
    onset, cable = capstan_onset(math.pi, mu, hz=hz, peg=hull_peg)
    assert onset is not None, "never slipped"
    assert onset == pytest.approx(math.exp(mu * math.pi), rel=0.10)
    # a faceted peg's corners are stick/slide kinks: a step may end at Newton's iteration limit (kept; measured on
    # this peg with Bullet's narrow phase too: 0-3 of about 1000 steps at 240 Hz, 8-17 at 1 kHz), rarely
    assert cable.newton_failures <= 0.01 * cable.steps


@pytest.mark.parametrize("hz", [240.0, 60.0])
def test_a_cable_swung_against_a_panda_stays_outside_it(hz):
    """An Lv cable pinned 9 cm beside a Panda's column (pybullet_data's URDF: meshes on child links), hanging,
    swung at it (6 m/s at the free end): it meets the arm's links and its centre line stays outside their
    meshes (Bullet's surface is 1 mm beyond them; measured: the spheres overlap the arm's surface by at most 0.3 mm at 240 Hz, 2.4 mm at 60 Hz where the
    end moves 10 cm a step). Before, it swung through (12.5 mm deep at 240 Hz)."""
    from bullet_dlo.core.model import CableState

    n = 20
    with BulletWorld(dt=1.0 / hz) as world:
        arm = world.add_urdf("franka_panda/panda.urdf", (0.0, 0.0, 0.0))
        spec = CableSpec.lv2017(n_masses=n, damping=0.02)
        s = np.arange(n) * spec.rest_length
        x0 = np.stack([0 * s, -0.09 + 0 * s, 0.75 - s], axis=1)
        v0 = np.stack([0 * s, 6.0 / spec.length * s, 0 * s], axis=1)  # turning about the pin
        cable = world.add_cable(spec, start=(0.0, -0.09, 0.75), direction=(0, 0, -1), ends=("pinned", "free"),
                                state=CableState(x0, v0))
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=spec.diameter / 2, physicsClientId=world.client)
        worst, touched = np.inf, False
        for _ in range(int(0.5 * hz)):
            world.step()
            assert cable.stable, cable.reason
            pc = cable.contact_forces()
            touched |= bool(np.any(pc["body"] == arm))
            worst = min(worst, deepest(world.client, arm, cable.x, probe, search=0.01))
        assert touched, "never touched the arm"
        assert worst > -(spec.diameter / 2 + HULL_MARGIN), worst  # the centre line outside the links' meshes


def test_a_mesh_out_of_reach_changes_nothing(tmp_path):
    """A falling cable with a hull and a child link far below it: bit for bit the run without them (the
    broad phase finds nothing, no closest-point query is made)."""
    runs = []
    for with_meshes in (False, True):
        with BulletWorld(dt=1 / 240, ground=False) as world:
            if with_meshes:
                for kind in ("hull", "child_link"):
                    body, _, _ = add_support(world, kind, tmp_path)
                    pb.resetBasePositionAndOrientation(body, [0, 0, -5.0], [0, 0, 0, 1], physicsClientId=world.client)
            cable = world.add_cable(CableSpec.lv2017(n_masses=10), start=(-0.15, 0, 1.0), direction=(1, 0, 0.2))
            world.run(0.3)
            assert cable.contacts_last_step == 0
            runs.append(cable.x.copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_excluded_bodies_are_passed_through(tmp_path):
    """``contact: false`` on a scene obstacle, and BulletCable.exclude_contact on one link, leave them out of the
    contact model: the cable falls through onto the ground; the other link still holds it."""
    from bullet_dlo.bullet.world import add_obstacles

    spec = CableSpec.lv2017(n_masses=10, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        add_obstacles(world, [{"type": "box", "half_extents": list(BOX), "position": [0, 0, BOX[2]], "contact": False}])
        cable = world.add_cable(spec, start=(-0.15, 0.0, 2 * BOX[2] + r + 0.01), direction=(1, 0, 0))
        world.run(0.5)
        assert cable.x[:, 2].max() < 0.01  # on the ground
    with BulletWorld(dt=1 / 240) as world:
        body, link, top = add_support(world, "child_link", tmp_path)
        cable = world.add_cable(spec, start=(-0.15, 0.0, top + r + 0.001), direction=(1, 0, 0))
        world.run(0.2)
        assert cable.x[:, 2].min() > top  # held by the child link
        cable.exclude_contact(body, link)
        world.run(0.5)
        assert cable.x[:, 2].max() < 0.01


def test_a_link_that_collides_with_nothing_in_bullet_is_passed_through(tmp_path):
    """BulletWorld.set_collision_filter with group and mask 0 (Bullet collides that link with nothing) leaves it
    out of the cable's contact model too, set after the cable or before it (a box): the cable falls onto the ground
    (before: set with PyBullet directly, a ghost sphere carried 0.179 N of a 0.196 N cable)."""
    spec = CableSpec.lv2017(n_masses=10, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1 / 240) as world:
        body, link, top = add_support(world, "child_link", tmp_path)
        cable = world.add_cable(spec, start=(-0.15, 0.0, top + r + 0.001), direction=(1, 0, 0))
        world.run(0.2)
        assert cable.x[:, 2].min() > top  # held by the child link
        world.set_collision_filter(body, link, 0, 0)
        world.run(0.5)
        assert cable.x[:, 2].max() < 0.01
    with BulletWorld(dt=1 / 240) as world:
        box = world.add_box(BOX, (0, 0, BOX[2]))
        world.set_collision_filter(box, -1, 0, 0)
        cable = world.add_cable(spec, start=(-0.15, 0.0, 2 * BOX[2] + r + 0.01), direction=(1, 0, 0))
        world.run(0.5)
        assert cable.x[:, 2].max() < 0.01 and box not in cable.body_forces()


def test_a_mesh_added_after_the_cable_holds_it(tmp_path):
    """A hull created (by PyBullet directly, not through the world) after the cable: the cable lands on it."""
    spec = CableSpec.lv2017(n_masses=10, damping=0.02)
    with BulletWorld(dt=1 / 240) as world:
        cable = world.add_cable(spec, start=(-0.15, 0.0, 2 * BOX[2] + 0.02), direction=(1, 0, 0))
        world.step()
        body, _, top = add_support(world, "hull", tmp_path)
        world.run(0.5)
        assert cable.x[:, 2].min() > top
        assert cable.body_forces().get(body, np.zeros(3))[2] == pytest.approx(-spec.mass * G, rel=0.01)


def test_worlds_of_the_same_meshes_share_the_packed_hulls_and_the_grasp_rebuilds_once(monkeypatch):
    """A dual-arm scene (an environment's reset builds one) packed the Panda links' hulls anew in each contact set it
    built, and built three (the cable, then one per gripper's exclusion): 27 of a reset's 125 ms. The hulls' arrays
    are now packed once per list of hulls (equal to a fresh pack, shared by the sets; each set keeps its own row,
    near and hint), and both grippers' exclusions rebuild the set once."""
    from bullet_dlo.bullet import cable_contacts, contact
    from bullet_dlo.config.robot import DualArmSpec
    from bullet_dlo.robots.dual_arm import DualArmScene

    built = []

    class Counted(contact.ContactSet):
        def __init__(self, *args, **kwargs):
            built.append(1)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(cable_contacts, "ContactSet", Counted)
    sets = []
    for _ in range(2):
        built.clear()
        with DualArmScene(DualArmSpec(robot="panda")) as scene:
            sets.append(scene.cable.contact.set)
            assert len(built) == 2  # (the cable's own, then one for both grippers' exclusions)
    a, b = (s.hulls for s in sets)
    assert len(a.margin) > 0  # (the Panda's links as hulls)
    shared = [f for f in a._fields if f not in ("row", "near", "hint")]
    assert all(getattr(a, f) is getattr(b, f) for f in shared)
    assert a.hint is not b.hint and a.near is not b.near and a.row is not b.row
    (hulls,) = [h for h, fields in contact._PACKED_HULLS.values() if fields["tri"] is b.tri]
    monkeypatch.setattr(contact, "_PACKED_HULLS", {})  # a fresh pack of the same hulls: the same arrays
    fresh = contact._packed_geometry(list(hulls))
    for f in shared:
        np.testing.assert_array_equal(getattr(b, f), fresh[f])
