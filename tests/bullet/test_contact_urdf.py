"""URDF obstacles in the cable's contact model (issue 23): a URDF ``<cylinder>`` is a cylinder the cable
rests on (it loaded as a mesh and was ignored before); shapes on child links are in the model too
(Bullet's narrow phase, tests/bullet/test_contact_mesh.py), so nothing is warned about."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

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
