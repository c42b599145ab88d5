"""URDF obstacles in the cable's contact model (issue 23): a URDF ``<cylinder>`` is a cylinder the cable
rests on (it loaded as a mesh and was ignored before); shapes on child links are in the model too
(Bullet's narrow phase, tests/bullet/test_contact_mesh.py), so nothing is warned about."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pybullet as pb
import pytest
from test_contact_friction import G, R_CAPSTAN, capstan_onset, capstan_references, capstan_world

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

PEG = """<?xml version="1.0"?>
<robot name="peg">
  <link name="base">
    <inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <collision><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.02" length="0.3"/></geometry></collision>
  </link>
{child}
</robot>
"""
CHILD = """  <link name="shelf">
    <inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <collision><geometry><box size="0.1 0.1 0.01"/></geometry></collision>
  </link>
  <joint name="fix" type="fixed"><parent link="base"/><child link="shelf"/><origin xyz="0.3 0 0"/></joint>"""


def drape(tmp_path, child: str):
    """A light cable dropped across the peg's axis from 1 cm above it, 1 s at 240 Hz: (final positions, warnings)."""
    urdf = tmp_path / "peg.urdf"
    urdf.write_text(PEG.format(child=child))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with BulletWorld(dt=1 / 240, ground=False) as world:
            world.add_urdf(urdf, (0.0, 0.0, 0.5))
            cable = world.add_cable(CableSpec.lv2017(n_masses=21, damping_rate=10.0), (-0.15, 0.0, 0.532),
                                    ends=("free", "free"), integrator="implicit_euler")
            world.run(1.0)
            return cable.x.copy(), [str(w.message) for w in caught]


def test_a_urdf_cylinder_holds_the_cable(tmp_path):
    x, messages = drape(tmp_path, "")
    middle = x[len(x) // 2]
    assert middle[2] == pytest.approx(0.5 + 0.02 + 0.002, abs=1.5e-3)  # on the peg's top: its radius + the cable's
    assert np.all(x[:, 2] > 0.5 - 0.02)  # draped over it, not fallen through
    assert not any("not handled" in m for m in messages)


def test_shapes_on_child_links_are_no_longer_left_out(tmp_path):
    x, messages = drape(tmp_path, CHILD)
    assert not any("not handled" in m for m in messages), messages
    assert np.all(x[:, 2] > 0.5 - 0.02)


CHILD_PEG = """<?xml version="1.0"?>
<robot name="fixture">
  <link name="plate">
    <inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <collision><origin xyz="0 0 -0.3"/><geometry><box size="0.1 0.1 0.02"/></geometry></collision>
  </link>
  <link name="peg">
    <inertial><mass value="0.2"/><inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>
    <collision><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.02" length="0.3"/></geometry></collision>
  </link>
  <joint name="fix" type="fixed"><parent link="plate"/><child link="peg"/><origin xyz="0 0 0"/></joint>
</robot>
"""
"""A fixture: a plate 0.3 m below and the peg (radius R_CAPSTAN, axis along y, 0.2 kg as real links have) on a child
link fixed to it."""


def urdf_peg(tmp_path, child: bool = False):
    """A peg maker for capstan_onset: PEG's cylinder (a URDF ``<cylinder>``, radius R_CAPSTAN, axis along y) at the
    origin, with the given friction; ``child``: CHILD_PEG's peg, a fixed child link with a mass."""
    urdf = tmp_path / "peg.urdf"
    urdf.write_text(CHILD_PEG if child else PEG.format(child=""))

    def make(world: BulletWorld, radius: float, friction: float) -> int:
        assert radius == R_CAPSTAN == 0.02  # (the file's radius)
        body = world.add_urdf(urdf, (0.0, 0.0, 0.0))
        pb.changeDynamics(body, 0 if child else -1, lateralFriction=friction, physicsClientId=world.client)
        return body

    return make


@pytest.mark.parametrize("child", [False, True], ids=["base", "child_link"])
@pytest.mark.parametrize("hz", [240.0, 60.0, 1000.0])
def test_capstan_on_a_urdf_cylinder(hz, child, tmp_path):
    """Slip onset of the capstan tests' cable wrapped half round a URDF cylinder: exp(mu pi) within 10 %; also on a
    fixture's peg, a child link with a mass fixed to a fixed base (before 2026-12-08 its rows were the condensed
    contact of a movable 0.2 kg link, 170 times softer: the cable sank 5 mm into the peg at 60 Hz and held twice the
    ratio)."""
    mu = 0.3
    onset, cable = capstan_onset(math.pi, mu, hz=hz, peg=urdf_peg(tmp_path, child))
    assert onset is not None, "never slipped"
    assert onset == pytest.approx(math.exp(mu * math.pi), rel=0.10)


@pytest.mark.parametrize("hz", [60.0, 240.0])
def test_a_fixture_pegs_joint_sensor_reads_the_cable_it_carries(hz, tmp_path):
    """The fixture's peg, static in the cable's step, still gets the cable's reactions in Bullet: the force-torque
    sensor on its fixed joint reads the peg's own weight and the hanging cable's (its end weights included) within
    1 %."""
    world, cable, _ = capstan_world(math.pi, 0.3, hz, "implicit_euler", urdf_peg(tmp_path, child=True))
    try:
        cid = world.client
        body = next(b for b, name in world.bodies.items() if name == "peg")
        pb.enableJointForceTorqueSensor(body, 0, True, physicsClientId=cid)
        world.run(1.5)
        assert cable.stable, cable.reason
        force = np.array(pb.getJointState(body, 0, physicsClientId=cid)[2][:3])
        carried = (0.2 + float(cable.model.arrays.mass.sum())) * G
        assert np.linalg.norm(force) == pytest.approx(carried, rel=0.01)
    finally:
        world.close()


def test_a_stiff_cable_on_a_urdf_cylinder_slips_at_the_elastica_ratio(tmp_path):
    """The same with the cable 15x stiffer (bend length 1.2 x the wrap radius): the elastica's ratio within 5 %, the
    string's 30 % above it (analysis.closed_forms.capstan_ratio; test_contact_friction for the Bullet cylinder)."""
    mu, theta = 0.4, math.pi
    onset, cable = capstan_onset(theta, mu, peg=urdf_peg(tmp_path), youngs_modulus=3e7, ramp=24.0)
    stiff, string, _ = capstan_references(cable, theta, mu)
    assert onset == pytest.approx(stiff, rel=0.05)
    assert onset < 0.8 * string
