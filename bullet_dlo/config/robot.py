"""Robot descriptions as data: ``robots/<name>.yaml`` read into :class:`RobotSpec`.

A description names the arm's URDF (from ``pybullet_data``), an optional gripper from the
project's ``urdf/`` with its mount, the F/T sensor joint, the grasp link, the fingers and
the home pose. Loading and composing the URDF is the robots layer's job
(:func:`bullet_dlo.robots.compose.robot_urdf`).
"""
from __future__ import annotations

from dataclasses import dataclass

import yaml

from bullet_dlo.assets import ROBOTS_DIR
from bullet_dlo.core.validate import ParameterError


@dataclass(frozen=True)
class RobotSpec:
    """A supported arm (see ``robots/<name>.yaml``).

    urdf: arm URDF relative to pybullet_data; gripper: optional gripper URDF in ``urdf/``
    mounted on ``mount_link`` at ``mount_xyz`` [m] through the fixed joint ``sensor_joint``;
    grasp_link: link whose frame is the grasp frame (z approach, x along the held cable);
    home: arm joint angles [rad]; finger_joints / finger_closed [m]: finger position targets.
    """

    name: str
    urdf: str
    sensor_joint: str
    grasp_link: str
    home: tuple[float, ...]
    gripper: str | None = None
    mount_link: str | None = None
    mount_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    finger_joints: tuple[str, ...] = ()
    finger_closed: float = 0.0
    max_force_scale: float = 1.0
    source: str = ""


def robot_names() -> list[str]:
    """Names of the robots described in ``robots/``."""
    return sorted(yaml.safe_load(p.read_text())["name"] for p in ROBOTS_DIR.glob("*.yaml"))


def load_robot_spec(name: str) -> RobotSpec:
    """The description of robot ``name`` (e.g. ``kuka``, ``panda``); ParameterError if unknown."""
    for path in sorted(ROBOTS_DIR.glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        if data.get("name") == name:
            data = dict(data)
            for key in ("home", "mount_xyz", "finger_joints"):
                if key in data:
                    data[key] = tuple(data[key])
            return RobotSpec(**data, source=str(path))
    raise ParameterError(f"unknown robot {name!r}; supported robots: {', '.join(robot_names())}")
