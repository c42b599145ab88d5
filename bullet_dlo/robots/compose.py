"""The URDF a robot description stands for: the arm alone, or the arm with a gripper composed on.

The fingers are made rigid at their closed position (:func:`rigid_fingers`). The file is
written once per content (cached in a folder of the user's own in the temporary folder) and is
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
from scipy.spatial.transform import Rotation

from bullet_dlo.assets import URDF_DIR
from bullet_dlo.config.robot import RobotSpec
from bullet_dlo.core.validate import ParameterError


_COMPOSED: dict = {}
"""The URDF written for a robot spec in this process, by (spec, the temporary folder, its source files and their
sizes and modification times): the file and its (size, modification time) as written. Composing it took 5 ms an arm
at every environment reset."""


def robot_urdf(spec: RobotSpec) -> Path:
    """The URDF to load for ``spec`` (written once per content, cached): the arm, with its gripper composed on
    (if any), and the fingers rigid (:func:`rigid_fingers`). Composed once per process while its source files
    and the written file stay as they were."""
    arm_path = Path(pybullet_data.getDataPath()) / spec.urdf
    if not arm_path.is_file():
        raise ParameterError(f"robot {spec.name!r}: URDF {spec.urdf!r} not found in pybullet_data")
    sources = [arm_path] + ([URDF_DIR / spec.gripper] if spec.gripper is not None else [])
    key = (spec, tempfile.gettempdir(), *((str(p), _stamp(p)) for p in sources))
    try:
        done = _COMPOSED.get(key)
    except TypeError:  # (a spec holding lists: not hashable, composed every time)
        done = key = None
    if done is not None and _stamp(done[0]) == done[1] and not done[0].is_symlink():
        return done[0]
    arm = _load(arm_path)
    if spec.gripper is not None:
        arm = compose_with_gripper(arm, _load(URDF_DIR / spec.gripper), spec.mount_link, spec.mount_xyz,
                                   spec.sensor_joint)
    rigid_fingers(arm, spec.finger_joints, spec.finger_closed)
    set_inertias(arm, spec.inertias)
    out = _write_cached(arm)
    if key is not None:
        _COMPOSED[key] = (out, _stamp(out))
    return out


def _stamp(path: Path) -> tuple[int, int] | None:
    """A file's (size [bytes], modification time [ns]), None if it is missing."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns


def set_inertias(robot: yourdfpy.Robot, inertias: Sequence[tuple[str, Sequence[float]]]) -> None:
    """Replace the rotational inertia of each named link by the principal moments (ixx, iyy, izz) [kg m^2]
    about its centre of mass, in its inertial frame (masses and centres of mass unchanged), in place.

    pybullet_data's panda.urdf gives every link a placeholder 0.1 kg m^2 (a massless grasp target too):
    for the hand that is 40 to 100 times Franka's published values, and a wrist sensor whose payload
    is identified as on a real robot (mass and centre of mass) read its turning hand's I alpha, about
    1 N m, as a load (``robots/panda.yaml`` sets the published values).
    """
    links = {link.name: link for link in robot.links}
    for name, moments in inertias:
        link = links.get(name)
        if link is None:
            raise ParameterError(f"robot {robot.name!r} has no link {name!r} to set the inertia of")
        if link.inertial is None:
            link.inertial = yourdfpy.Inertial(mass=0.0, origin=np.eye(4), inertia=np.zeros((3, 3)))
        link.inertial.inertia = np.diag(np.asarray(moments, dtype=float))


def _load(path: Path) -> yourdfpy.Robot:
    """A URDF's robot, mesh paths made absolute so that the written copy can live anywhere."""
    urdf = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False)
    for link in urdf.robot.links:
        for geom in [v.geometry for v in link.visuals] + [c.geometry for c in link.collisions]:
            if geom is not None and geom.mesh is not None:
                name = geom.mesh.filename
                if name.startswith("package://"):  # PyBullet looks for these beside the URDF too
                    name = name[len("package://"):]
                if not os.path.isabs(name):
                    geom.mesh.filename = str((path.parent / name).resolve())
    return urdf.robot


def rigid_fingers(robot: yourdfpy.Robot, names: Sequence[str], closed: float) -> None:
    """Make the finger joints ``names`` fixed at their closed position ``closed`` [m or rad], in place.

    The cable's grip is modelled at the grasp frame (a clamp or a friction grip), so the fingers only
    have to stay closed; as motor-held prismatic joints they made Bullet's reaction at the wrist joint
    wrong whenever gravity had a component along them (up to 10 mN and 36 mN m on the Panda, 80 mN
    on the KUKA gripper, at rest, tilted about the cable), and a wrist sensor cannot be better than
    that reaction. A rigid hand carries the same mass, centre of mass and collision shapes.
    """
    joints = {j.name: j for j in robot.joints}
    for name in names:
        joint = joints.get(name)
        if joint is None:
            raise ParameterError(f"robot {robot.name!r} has no finger joint {name!r}")
        if joint.type not in ("prismatic", "revolute", "continuous", "fixed"):
            raise ParameterError(f"finger joint {name!r} is {joint.type}: only prismatic or revolute fingers "
                                 f"can be closed")
        if joint.type == "fixed":
            continue
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        axis = axis / np.linalg.norm(axis)
        move = np.eye(4)
        if joint.type == "prismatic":
            move[:3, 3] = closed * axis
        else:  # a turn by `closed` about the axis
            move[:3, :3] = Rotation.from_rotvec(closed * axis).as_matrix()
        origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
        joint.origin = origin @ move
        joint.type, joint.limit, joint.mimic, joint.dynamics = "fixed", None, None, None


def compose_with_gripper(arm: yourdfpy.Robot, grip: yourdfpy.Robot, mount_link: str | None,
                         mount_xyz: Sequence[float], sensor_joint: str) -> yourdfpy.Robot:
    """The arm with the gripper fixed to ``mount_link``: the gripper's root link is attached by a fixed
    joint named ``sensor_joint`` (the F/T sensor)."""
    names = {link.name for link in arm.links}
    if mount_link not in names:
        raise ParameterError(f"mount link {mount_link!r} not in {arm.name}; links: {', '.join(sorted(names))}")
    child_links = {j.child for j in grip.joints}
    roots = [link.name for link in grip.links if link.name not in child_links]
    root = roots[0] if roots else grip.links[0].name
    origin = np.eye(4)
    origin[:3, 3] = np.asarray(mount_xyz, dtype=float)
    mount = yourdfpy.Joint(name=sensor_joint, type="fixed", parent=mount_link, child=root, origin=origin)
    return yourdfpy.Robot(name=f"{arm.name}_with_{grip.name}", links=arm.links + grip.links,
                          joints=arm.joints + [mount] + grip.joints, materials=arm.materials + grip.materials)


def _write_cached(robot: yourdfpy.Robot) -> Path:
    """Write ``robot`` as a URDF named by its content in a private cache folder (once), return the path."""
    text = yourdfpy.URDF(robot=robot, build_scene_graph=False, load_meshes=False).write_xml_string()
    if isinstance(text, bytes):
        text = text.decode()
    # one element per line: PyBullet's parser fails on some lengths of a single long line
    text = etree.tostring(etree.fromstring(text.encode()), pretty_print=True, xml_declaration=True,
                          encoding="utf-8").decode()
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    folder = Path(tempfile.gettempdir()) / f"bullet_dlo_urdf_{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    if folder.is_symlink() or folder.stat().st_uid != os.getuid():
        raise ParameterError(f"URDF cache folder {folder} is not this user's own directory")
    out = folder / f"{robot.name}_{digest}.urdf"
    if out.is_file() and not out.is_symlink() and out.read_text() == text:
        return out
    fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")  # a fresh name: no write through a planted file
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, out)
    return out
