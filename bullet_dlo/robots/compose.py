"""The URDF a robot description stands for: the arm alone, or the arm with a gripper composed on.

The composed file is written once per content (cached in the temporary folder) and is
pretty-printed: PyBullet's URDF parser rejects some lengths of a single very long line, so
a one-line file made the KUKA load or not depending on the install path.
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np
import pybullet_data
import yourdfpy
from lxml import etree

from bullet_dlo.assets import URDF_DIR
from bullet_dlo.config.robot import RobotSpec
from bullet_dlo.core.validate import ParameterError


def robot_urdf(spec: RobotSpec) -> Path:
    """The URDF to load for ``spec``: the arm itself, or the arm composed with its gripper (cached)."""
    arm = Path(pybullet_data.getDataPath()) / spec.urdf
    if not arm.is_file():
        raise ParameterError(f"robot {spec.name!r}: URDF {spec.urdf!r} not found in pybullet_data")
    if spec.gripper is None:
        return arm
    return compose_with_gripper(arm, URDF_DIR / spec.gripper, spec.mount_link, spec.mount_xyz, spec.sensor_joint)


def compose_with_gripper(arm_urdf: Path, gripper_urdf: Path, mount_link: str | None,
                         mount_xyz: Sequence[float], sensor_joint: str) -> Path:
    """Write (once, cached by content) the arm with the gripper fixed to ``mount_link``.

    The gripper's root link is attached by a fixed joint named ``sensor_joint`` (the F/T
    sensor). Mesh paths of the arm are made absolute so the composed file can live anywhere.
    """
    arm = yourdfpy.URDF.load(str(arm_urdf), build_scene_graph=False, load_meshes=False)
    grip = yourdfpy.URDF.load(str(gripper_urdf), build_scene_graph=False, load_meshes=False)
    names = {link.name for link in arm.robot.links}
    if mount_link not in names:
        raise ParameterError(f"mount link {mount_link!r} not in {arm_urdf.name}; links: {', '.join(sorted(names))}")
    for link in arm.robot.links:
        for geom in [v.geometry for v in link.visuals] + [c.geometry for c in link.collisions]:
            if geom is not None and geom.mesh is not None and not os.path.isabs(geom.mesh.filename):
                geom.mesh.filename = str((arm_urdf.parent / geom.mesh.filename).resolve())
    root = grip.robot.links[0].name
    child_links = {j.child for j in grip.robot.joints}
    roots = [link.name for link in grip.robot.links if link.name not in child_links]
    root = roots[0] if roots else root
    origin = np.eye(4)
    origin[:3, 3] = np.asarray(mount_xyz, dtype=float)
    mount = yourdfpy.Joint(name=sensor_joint, type="fixed", parent=mount_link, child=root, origin=origin)
    robot = yourdfpy.Robot(name=f"{arm.robot.name}_with_{grip.robot.name}",
                           links=arm.robot.links + grip.robot.links,
                           joints=arm.robot.joints + [mount] + grip.robot.joints,
                           materials=arm.robot.materials + grip.robot.materials)
    text = yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False).write_xml_string()
    if isinstance(text, bytes):
        text = text.decode()
    # one element per line: PyBullet's parser fails on some lengths of a single long line
    text = etree.tostring(etree.fromstring(text.encode()), pretty_print=True, xml_declaration=True,
                          encoding="utf-8").decode()
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    out = Path(tempfile.gettempdir()) / "bullet_dlo_urdf" / f"{robot.name}_{digest}.urdf"
    if not out.is_file():
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".tmp")
        tmp.write_text(text)
        tmp.replace(out)
    return out
