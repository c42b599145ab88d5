"""Robot descriptions and the dual-arm scene, as data.

:class:`RobotSpec`: ``robots/<name>.yaml``, naming the arm's URDF (from ``pybullet_data``), an
optional gripper from the project's ``urdf/`` with its mount, the F/T sensor joint, the grasp
link, the fingers and the home pose. :class:`DualArmSpec`: two such arms holding a cable.
Loading, composing and simulating them is the robots layer's job (:mod:`bullet_dlo.robots`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import yaml

from bullet_dlo.assets import ROBOTS_DIR
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_int, check_nonnegative, check_positive

MIN_TABLE_CLEARANCE = 0.05  # [m] the held ends stay this far above the table top
PAYLOADS = ("urdf", "calibrated")  # how the wrist sensors know their payload (robots.sensors.COMPENSATIONS)
CALIBRATION_TILTS = ((0.0, 0.0, 0.0), (0.6, 0.0, 0.0), (-0.6, 0.0, 0.0), (0.0, 0.6, 0.0), (0.0, -0.6, 0.0),
                     (1.2, 0.0, 0.0), (0.0, 1.2, 0.0), (0.5, 0.5, 0.0), (0.0, 0.0, 1.0))
"""Rotation vectors [rad] (world frame) that turn the grasp orientation for a payload calibration."""


@dataclass(frozen=True)
class RobotSpec:
    """A supported arm (see ``robots/<name>.yaml``).

    urdf: arm URDF relative to pybullet_data; gripper: optional gripper URDF in ``urdf/``
    mounted on ``mount_link`` at ``mount_xyz`` [m] through the fixed joint ``sensor_joint``;
    grasp_link: link whose frame is the grasp frame (z approach, x along the held cable);
    home: arm joint angles [rad]; finger_joints: the fingers, made rigid at finger_closed [m or rad]
    (their closed position) when the robot is loaded (:func:`bullet_dlo.robots.compose.rigid_fingers`).
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


@dataclass(frozen=True)
class DualArmSpec:
    """Two arms facing each other across a table, holding the two ends of a cable (SI units).

    robot: robot name in ``robots/``; cable: the cable; dt: Bullet step [s]; integrator: the
    cable's; substeps: cable steps per Bullet step; hold_height: height of the held cable ends
    above the floor [m]; base_distance: distance of each arm base from the cable's midpoint
    along x [m]; table_height: top of the table [m] (0: no table); renderer: Bullet renderer
    (None: none). Wrist sensors: sensor_rate [Hz] (None: every step); noise_std, bias: per
    component (fx fy fz mx my mz) [N, N m], checked where the sensors are built; seed: for the noise.
    start: the cable's shape when it is attached: ``settled`` (static equilibrium with both ends
    clamped in the grippers' hold: the first sample reads the static load) or ``straight`` (at
    full length between the grippers, released into a start transient; the behaviour before 0.3).
    grip: how a grasp holds its end: ``clamp`` (rigid: position and tangent) or ``friction`` (the
    fingers pinch it with ``grip_force`` [N] each; along the gripper it holds up to
    2 mu_s grip_force and then slips against 2 mu_d grip_force, ``grip_friction`` = (mu_s, mu_d);
    it lets go after slipping ``grip_reach`` [m]).
    payload: how the wrist sensors know the tool below them, whose weight and inertia they remove:
    ``urdf`` (every link's mass, centre of mass and inertia from the robot description) or
    ``calibrated`` (mass and centre of mass identified from the unloaded arms at
    :data:`CALIBRATION_TILTS`, before the cable is attached).
    """

    robot: str = "kuka"
    cable: CableSpec = field(default_factory=lambda: CableSpec.lv2017(n_masses=10, damping=0.02))
    dt: float = 1.0 / 240.0
    integrator: str = "implicit_euler"
    hold_height: float = 0.35
    base_distance: float = 0.6
    table_height: float = 0.2
    sensor_rate: float | None = None
    noise_std: tuple[float, ...] = (0.0,) * 6
    bias: tuple[float, ...] = (0.0,) * 6
    seed: int = 0
    renderer: str | None = None
    substeps: int = 1
    start: str = "settled"
    grip: str = "clamp"
    grip_force: float = 5.0
    grip_friction: tuple[float, float] = (0.5, 0.4)
    grip_reach: float = 0.02
    payload: str = "urdf"

    def __post_init__(self) -> None:
        check_positive("dt", self.dt)
        if self.start not in ("settled", "straight"):
            raise ParameterError(f"start must be one of settled, straight, got {self.start!r}")
        check_positive("hold_height", self.hold_height)
        check_positive("base_distance", self.base_distance)
        check_nonnegative("table_height", self.table_height)
        if self.table_height and self.hold_height - self.table_height < MIN_TABLE_CLEARANCE:
            raise ParameterError(f"hold_height {self.hold_height} m must be at least "
                                 f"{MIN_TABLE_CLEARANCE * 100:.0f} cm above the table top {self.table_height} m")
        if self.sensor_rate is not None:
            check_positive("sensor_rate", self.sensor_rate)
        check_int("substeps", self.substeps, 1)
        if self.grip not in ("clamp", "friction"):
            raise ParameterError(f"grip must be one of clamp, friction, got {self.grip!r}")
        if self.payload not in PAYLOADS:
            raise ParameterError(f"payload must be one of {', '.join(PAYLOADS)}, got {self.payload!r}")
        check_positive("grip_force", self.grip_force)
        check_positive("grip_reach", self.grip_reach)
        if len(self.grip_friction) != 2 or not 0.0 <= self.grip_friction[1] <= self.grip_friction[0]:
            raise ParameterError(f"grip_friction must be (mu_static, mu_dynamic) with 0 <= mu_dynamic <= mu_static, "
                                 f"got {self.grip_friction!r}")
