"""Robot descriptions and the dual-arm scene, as data.

:class:`RobotSpec`: ``robots/<name>.yaml``, naming the arm's URDF (from ``pybullet_data``), an
optional gripper from the project's ``urdf/`` with its mount, the F/T sensor joint, the grasp
link, the fingers and the home pose. :class:`DualArmSpec`: two such arms holding a cable.
Loading, composing and simulating them is the robots layer's job (:mod:`bullet_dlo.robots`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import yaml

from typing import TYPE_CHECKING, Any, Mapping

from bullet_dlo.assets import ROBOTS_DIR
from bullet_dlo.config.schema import one_of, only_keys, section
from bullet_dlo.config.world import BulletOptions
from bullet_dlo.core.engine import DetectorOptions
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import STANDARD_GRAVITY
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import (
    ParameterError,
    check_finite,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    check_vector3,
)

if TYPE_CHECKING:
    from bullet_dlo.config.scene import Scene

MIN_TABLE_CLEARANCE = 0.05  # [m] the held ends stay this far above the table top
PAYLOADS = ("urdf", "calibrated")  # how the wrist sensors know their payload (robots.sensors.COMPENSATIONS)
GRIPS = ("clamp", "friction")  # how a gripper holds its cable end
STARTS = ("settled", "straight")  # the cable's shape when the grippers take it
ARMS_LENGTHS = ("hold_height", "base_distance", "table_height")
ARMS_KEYS = ("robot",) + ARMS_LENGTHS + ("grip", "grip_force", "grip_friction", "grip_reach", "payload", "sensor_rate",
                                        "noise_std", "bias", "seed")
"""Keys of a scene's ``arms:`` section (:class:`ArmsOptions`)."""
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
class ArmsOptions:
    """The scene's ``arms:`` section: two arms facing each other across a table hold the cable's ends
    (``grasp``, ``render --robot``, dataset captures, environments). SI units.

    robot: robot description in ``robots/`` (None: the command's ``--robot``, kuka by default);
    hold_height: height of the held ends [m]; base_distance: each arm base's distance from the
    cable's midpoint along x [m]; table_height: top of the table [m] (0: none); grip: ``clamp``
    (rigid) or ``friction`` (fingers pinch with ``grip_force`` [N] each, ``grip_friction`` =
    (mu_static, mu_dynamic), letting go after slipping ``grip_reach`` [m]); payload: ``urdf`` or
    ``calibrated`` (how the wrist sensors know the tool below them); sensor_rate: wrist sensor
    rate [Hz] (None: every step); noise_std, bias: per wrench component (fx fy fz mx my mz)
    [N, N m]; seed: of the sensor noise.
    """

    robot: str | None = None
    hold_height: float = 0.35
    base_distance: float = 0.6
    table_height: float = 0.2
    grip: str = "clamp"
    grip_force: float = 5.0
    grip_friction: tuple[float, float] = (0.5, 0.4)
    grip_reach: float = 0.02
    payload: str = "urdf"
    sensor_rate: float | None = None
    noise_std: tuple[float, ...] = (0.0,) * 6
    bias: tuple[float, ...] = (0.0,) * 6
    seed: int = 0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for key in ARMS_LENGTHS:
            set_(self, key, check_in_range(f"arms.{key} [m]", getattr(self, key), 0.0, 10.0))
        set_(self, "grip_force", check_in_range("arms.grip_force [N]", self.grip_force, 0.0, 1e4))
        set_(self, "grip_reach", check_in_range("arms.grip_reach [m]", self.grip_reach, 0.0, 10.0))
        if not isinstance(self.grip_friction, (list, tuple)) or len(self.grip_friction) != 2:
            raise ParameterError(f"arms.grip_friction must be [mu_static, mu_dynamic], got {self.grip_friction!r}")
        set_(self, "grip_friction", tuple(check_in_range(f"arms.grip_friction[{k}]", v, 0.0, 10.0)
                                          for k, v in enumerate(self.grip_friction)))
        set_(self, "grip", one_of("arms.grip", str(self.grip), GRIPS))
        set_(self, "payload", one_of("arms.payload", str(self.payload), PAYLOADS))
        if self.sensor_rate is not None:
            set_(self, "sensor_rate", check_in_range("arms.sensor_rate [Hz]", self.sensor_rate, 1e-3, 1e6))
        for key in ("noise_std", "bias"):
            value = getattr(self, key)
            if not isinstance(value, (list, tuple)) or len(value) != 6:
                raise ParameterError(f"arms.{key} must be 6 numbers (fx fy fz mx my mz) [N, N m], got {value!r}")
            set_(self, key, tuple(check_finite(f"arms.{key}[{k}]", v) for k, v in enumerate(value)))
        if any(v < 0 for v in self.noise_std):
            raise ParameterError(f"arms.noise_std must be >= 0, got {list(self.noise_std)}")
        set_(self, "seed", check_int("arms.seed", self.seed, 0))
        if self.robot is not None:
            set_(self, "robot", one_of("arms.robot", str(self.robot), robot_names()))
        if self.hold_height <= 0 or self.base_distance <= 0:
            raise ParameterError(f"arms.hold_height and arms.base_distance must be > 0 [m], got "
                                 f"{self.hold_height}, {self.base_distance}")
        if self.table_height and self.hold_height - self.table_height < MIN_TABLE_CLEARANCE:
            raise ParameterError(f"arms.hold_height {self.hold_height} m must be at least "
                                 f"{MIN_TABLE_CLEARANCE * 100:.0f} cm above the table top {self.table_height} m")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> "ArmsOptions":
        """Validate a parsed ``arms:`` section; errors name the offending key."""
        data = section(data, "arms")
        only_keys(data, ARMS_KEYS, "arms")
        kwargs = dict(data)
        if kwargs.get("robot") is not None:
            kwargs["robot"] = str(kwargs["robot"])
        return cls(**kwargs)


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
    gravity: tuple[float, float, float] = STANDARD_GRAVITY
    bullet: BulletOptions = field(default_factory=BulletOptions)
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    detector: DetectorOptions = field(default_factory=DetectorOptions)

    def __post_init__(self) -> None:
        check_positive("dt", self.dt)
        object.__setattr__(self, "gravity", tuple(check_vector3("gravity", self.gravity).tolist()))
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
        if self.bullet.substeps != 1 and self.bullet.substeps != self.substeps:
            raise ParameterError(f"substeps ({self.substeps}) and bullet.substeps ({self.bullet.substeps}) differ; "
                                 f"give one")
        for name, choices in (("grip", GRIPS), ("payload", PAYLOADS)):
            if getattr(self, name) not in choices:
                raise ParameterError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")
        check_positive("grip_force", self.grip_force)
        check_positive("grip_reach", self.grip_reach)
        if len(self.grip_friction) != 2 or not 0.0 <= self.grip_friction[1] <= self.grip_friction[0]:
            raise ParameterError(f"grip_friction must be (mu_static, mu_dynamic) with 0 <= mu_dynamic <= mu_static, "
                                 f"got {self.grip_friction!r}")

    @classmethod
    def from_scene(cls, scene: "Scene", robot: str | None = None, renderer: str | None = None,
                   **overrides: Any) -> "DualArmSpec":
        """The dual-arm physics of ``scene``: its cable, step, integrator, gravity, ``arms:``, ``bullet:``,
        ``newton:`` and ``detector:`` sections (``robot``: a command's choice, before the scene's
        ``arms.robot``; kuka when neither names one); ``overrides``: fields the caller sets (a command's flags)."""
        arms = scene.arms or ArmsOptions()
        fields_ = dict(robot=robot or arms.robot or "kuka", cable=scene.cable, dt=scene.dt,
                       integrator=scene.integrator, hold_height=arms.hold_height, base_distance=arms.base_distance,
                       table_height=arms.table_height, sensor_rate=arms.sensor_rate, noise_std=arms.noise_std,
                       bias=arms.bias, seed=arms.seed, renderer=renderer, substeps=scene.bullet.substeps,
                       start=scene.arm_start, grip=arms.grip, grip_force=arms.grip_force,
                       grip_friction=arms.grip_friction, grip_reach=arms.grip_reach, payload=arms.payload,
                       gravity=scene.gravity, bullet=scene.bullet, newton=scene.newton, detector=scene.detector)
        return cls(**{**fields_, **overrides})
