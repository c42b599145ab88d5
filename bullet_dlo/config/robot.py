"""Robot descriptions and the dual-arm scene, as data.

:class:`RobotSpec`: ``robots/<name>.yaml``, naming the arm's URDF (from ``pybullet_data``), an
optional gripper from the project's ``urdf/`` with its mount, the F/T sensor joint, the grasp
link, the fingers and the home pose. :class:`DualArmSpec`: two such arms holding a cable.
Loading, composing and simulating them is the robots layer's job (:mod:`bullet_dlo.robots`).
"""
from __future__ import annotations

import copy
import functools
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np
import yaml

from bullet_dlo.assets import ROBOTS_DIR
from bullet_dlo.config.schema import one_of, only_keys, section
from bullet_dlo.core.enums import ArmStart, GripKind, IntegratorName, Payload, Renderer
from bullet_dlo.config.world import BulletOptions
from bullet_dlo.core.engine import DetectorOptions
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import STANDARD_GRAVITY
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import (
    ParameterError,
    check_finite,
    check_friction_order,
    check_in_range,
    check_int,
    check_nonnegative,
    check_positive,
    check_vector3,
)

if TYPE_CHECKING:
    from bullet_dlo.config.scene import Scene

MIN_TABLE_CLEARANCE = 0.05  # [m] the held ends stay this far above the table top
PAYLOADS = Payload.names()  # how the wrist sensors know their payload (robots.sensors.COMPENSATIONS)
GRIPS = GripKind.names()  # how a gripper holds its cable end
STARTS = ArmStart.names()  # the cable's shape when the grippers take it
ARMS_LENGTHS = ("hold_height", "base_distance", "table_height")
ARMS_KEYS = ("robot",) + ARMS_LENGTHS + ("grip", "grip_force", "grip_static_friction", "grip_dynamic_friction",
                                        "grip_reach", "payload", "sensor_rate", "noise_std", "bias", "seed")
"""Keys of a scene's ``arms:`` section (:class:`ArmsOptions`)."""
DEPRECATED_ARMS_KEYS = {"grip_friction": ("grip_static_friction", "grip_dynamic_friction")}
"""Deprecated ``arms:`` keys (and constructor keywords) -> the keys that replace them (one release)."""


def check_table_clearance(hold_height: float, table_height: float, hold_key: str = "hold_height",
                          table_key: str = "table top") -> None:
    """The held ends stay :data:`MIN_TABLE_CLEARANCE` above the table top (no table: ``table_height`` 0);
    ParameterError naming ``hold_key`` (``arms.hold_height`` for a scene file, ``hold_height`` for the API)."""
    # a rounding margin: 0.25 - 0.2 is 0.04999... in floating point, and exactly 5 cm is allowed
    if table_height and hold_height - table_height < MIN_TABLE_CLEARANCE - 1e-12:
        raise ParameterError(f"{hold_key} {hold_height} m must be at least {MIN_TABLE_CLEARANCE * 100:.0f} cm above "
                             f"the {table_key} {table_height} m")


def check_grip_friction(static: Any, dynamic: Any, where: str = "") -> tuple[float, float]:
    """Coulomb coefficients of a friction grip [-]: each in [0, 10] and ``dynamic <= static``;
    ParameterError naming ``<where>grip_static_friction`` / ``<where>grip_dynamic_friction``."""
    s = check_in_range(f"{where}grip_static_friction", static, 0.0, 10.0)
    d = check_in_range(f"{where}grip_dynamic_friction", dynamic, 0.0, 10.0)
    check_friction_order(d, s, f"{where}grip_")
    return s, d


def renamed_grip_keys(data: Mapping[str, Any], where: str = "", stacklevel: int = 3) -> dict[str, Any]:
    """``data`` with the deprecated ``grip_friction: [static, dynamic]`` split into ``grip_static_friction`` and
    ``grip_dynamic_friction``, with a DeprecationWarning naming them (both forms at once: ParameterError)."""
    out = dict(data)
    if "grip_friction" not in out:
        return out
    pair = out.pop("grip_friction")
    new = DEPRECATED_ARMS_KEYS["grip_friction"]
    if any(k in out for k in new):
        raise ParameterError(f"{where}grip_friction is the old name of {where}{new[0]} and {where}{new[1]}; "
                             f"give only those")
    if not isinstance(pair, (list, tuple)) or len(pair) != 2:
        raise ParameterError(f"{where}grip_friction must be [static, dynamic], got {pair!r} (deprecated: give "
                             f"{where}{new[0]} and {where}{new[1]})")
    warnings.warn(f"{where}grip_friction is deprecated; use {where}{new[0]} and {where}{new[1]} (the old name "
                  f"goes in the next release)", DeprecationWarning, stacklevel=stacklevel)
    out[new[0]], out[new[1]] = pair
    return out


def _accept_grip_friction(cls: type) -> type:
    """Let ``cls(...)`` take the deprecated keyword ``grip_friction=(static, dynamic)`` for one release."""
    init: Callable[..., None] = cls.__init__

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        init(self, *args, **renamed_grip_keys(kwargs, stacklevel=3))

    cls.__init__ = __init__
    return cls
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
    (their closed position) when the robot is loaded (:func:`bullet_dlo.robots.compose.rigid_fingers`);
    inertias: (link name, (ixx, iyy, izz) [kg m^2]) pairs replacing those links' rotational inertias
    (principal, about their centres of mass, in their inertial frames; masses and centres of mass stay the
    URDF's), e.g. physical values where the URDF has placeholders;
    name: the robot's name; sensor_joint: the joint whose reaction the wrist sensor reads; mount_link: the
    arm link the gripper is mounted on; max_force_scale: factor [-] on the arm's joint force limits;
    source: the YAML file it was read from.
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
    inertias: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    source: str = ""

    def __post_init__(self) -> None:
        pairs = dict(self.inertias).items() if isinstance(self.inertias, Mapping) else self.inertias
        out = []
        for link, values in pairs:
            moments = check_vector3(f"robot {self.name!r} inertias.{link} [kg m^2]", values)
            if np.any(moments < 0) or not np.all(np.isfinite(moments)) or np.any(moments > 1e3) or (
                    moments.sum() - 2 * moments.max() < -1e-12 * moments.sum()):
                raise ParameterError(f"robot {self.name!r} inertias.{link} must be three principal moments in "
                                     f"[0, 1000] kg m^2, each at most the sum of the other two, got {list(values)}")
            out.append((str(link), tuple(float(v) for v in moments)))
        object.__setattr__(self, "inertias", tuple(out))


_ROBOT_FILES: dict = {}
"""Each ``robots/*.yaml`` as read, by path: ((size, modification time), its data). Every scene check reads the robot
names and an environment's reset the spec (15 ms of YAML a reset)."""


def _robot_files() -> list[tuple[Path, dict]]:
    """The robot descriptions in ``robots/``, sorted by path: (path, its data, read again when the file changed;
    not to be changed by the caller)."""
    out = []
    for path in sorted(ROBOTS_DIR.glob("*.yaml")):
        st = path.stat()
        stamp = (st.st_size, st.st_mtime_ns)
        hit = _ROBOT_FILES.get(str(path))
        if hit is None or hit[0] != stamp:
            hit = _ROBOT_FILES[str(path)] = (stamp, yaml.safe_load(path.read_text()))
        out.append((path, hit[1]))
    return out


def robot_names() -> list[str]:
    """Names of the robots described in ``robots/``."""
    return sorted(data["name"] for _, data in _robot_files())


def load_robot_spec(name: str) -> RobotSpec:
    """The description of robot ``name`` (e.g. ``kuka``, ``panda``); ParameterError if unknown."""
    for path, data in _robot_files():
        if data.get("name") == name:
            data = copy.deepcopy(data)
            for key in ("home", "mount_xyz", "finger_joints"):
                if key in data:
                    data[key] = tuple(data[key])
            return RobotSpec(**data, source=str(path))
    raise ParameterError(f"unknown robot {name!r}; supported robots: {', '.join(robot_names())}")


@_accept_grip_friction
@dataclass(frozen=True)
class ArmsOptions:
    """The scene's ``arms:`` section: two arms facing each other across a table hold the cable's ends
    (``grasp``, ``render --robot``, dataset captures, environments). SI units.

    robot: robot description in ``robots/`` (None: the command's ``--robot``, kuka by default);
    hold_height: height of the held ends [m]; base_distance: each arm base's distance from the
    cable's midpoint along x [m]; table_height: top of the table [m] (0: none); grip: ``clamp``
    (rigid) or ``friction`` (:class:`~bullet_dlo.core.enums.GripKind`: fingers pinch with
    ``grip_force`` [N] each, holding up to 2 grip_static_friction grip_force and sliding against
    2 grip_dynamic_friction grip_force, letting go after slipping ``grip_reach`` [m]);
    grip_static_friction, grip_dynamic_friction: the grip's Coulomb coefficients [-], 0 <= dynamic
    <= static (``grip_friction: [static, dynamic]`` before 0.4: deprecated); payload: ``urdf`` or
    ``calibrated`` (how the wrist sensors know the tool below them); sensor_rate: wrist sensor
    rate [Hz] (None: every step); noise_std, bias: per wrench component (fx fy fz mx my mz)
    [N, N m]; seed: of the sensor noise [-].
    """

    robot: str | None = None
    hold_height: float = 0.35
    base_distance: float = 0.6
    table_height: float = 0.2
    grip: str = "clamp"
    grip_force: float = 5.0
    grip_static_friction: float = 0.5
    grip_dynamic_friction: float = 0.4
    grip_reach: float = 0.02
    payload: str = "urdf"
    sensor_rate: float | None = None
    noise_std: tuple[float, ...] = (0.0,) * 6
    bias: tuple[float, ...] = (0.0,) * 6
    seed: int = 0

    @property
    def grip_friction(self) -> tuple[float, float]:
        """(grip_static_friction, grip_dynamic_friction) [-]: the deprecated pair, read-only."""
        warnings.warn(f"{type(self).__name__}.grip_friction is deprecated; use grip_static_friction and "
                      "grip_dynamic_friction", DeprecationWarning, stacklevel=2)
        return self.grip_static_friction, self.grip_dynamic_friction

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for key in ARMS_LENGTHS:
            set_(self, key, check_in_range(f"arms.{key} [m]", getattr(self, key), 0.0, 10.0))
        set_(self, "grip_force", check_in_range("arms.grip_force [N]", self.grip_force, 0.0, 1e4))
        set_(self, "grip_reach", check_in_range("arms.grip_reach [m]", self.grip_reach, 0.0, 10.0))
        static, dynamic = check_grip_friction(self.grip_static_friction, self.grip_dynamic_friction, "arms.")
        set_(self, "grip_static_friction", static)
        set_(self, "grip_dynamic_friction", dynamic)
        set_(self, "grip", one_of("arms.grip", self.grip, GripKind))
        set_(self, "payload", one_of("arms.payload", self.payload, Payload))
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
        check_table_clearance(self.hold_height, self.table_height, "arms.hold_height")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> "ArmsOptions":
        """Validate a parsed ``arms:`` section; errors name the offending key."""
        data = section(data, "arms")
        only_keys(data, ARMS_KEYS + tuple(DEPRECATED_ARMS_KEYS), "arms")
        kwargs = renamed_grip_keys(data, "arms.", stacklevel=3)
        if kwargs.get("robot") is not None:
            kwargs["robot"] = str(kwargs["robot"])
        return cls(**kwargs)


@_accept_grip_friction
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
    2 grip_static_friction grip_force and then slips against 2 grip_dynamic_friction grip_force
    (Coulomb coefficients [-], 0 <= dynamic <= static; ``grip_friction=(static, dynamic)`` before 0.4:
    deprecated); it lets go after slipping ``grip_reach`` [m]).
    gravity: [m/s^2]; bullet, newton, detector: the scene's sections (:class:`BulletOptions`,
    :class:`~bullet_dlo.core.integrators.NewtonOptions`, :class:`~bullet_dlo.core.engine.DetectorOptions`).
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
    grip_static_friction: float = 0.5
    grip_dynamic_friction: float = 0.4
    grip_reach: float = 0.02
    payload: str = "urdf"
    gravity: tuple[float, float, float] = STANDARD_GRAVITY
    bullet: BulletOptions = field(default_factory=BulletOptions)
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    detector: DetectorOptions = field(default_factory=DetectorOptions)

    @property
    def grip_friction(self) -> tuple[float, float]:
        """(grip_static_friction, grip_dynamic_friction) [-]: the deprecated pair, read-only."""
        warnings.warn(f"{type(self).__name__}.grip_friction is deprecated; use grip_static_friction and "
                      "grip_dynamic_friction", DeprecationWarning, stacklevel=2)
        return self.grip_static_friction, self.grip_dynamic_friction

    def __post_init__(self) -> None:
        # The boundary of direct Python users; a scene's values arrive here already checked by Scene.
        set_ = object.__setattr__
        set_(self, "dt", check_positive("dt", self.dt))
        set_(self, "gravity", tuple(check_vector3("gravity", self.gravity).tolist()))
        set_(self, "start", one_of("start", self.start, ArmStart))
        set_(self, "integrator", one_of("integrator", self.integrator, IntegratorName))
        if self.renderer is not None:
            set_(self, "renderer", one_of("renderer", self.renderer, Renderer))
        check_positive("hold_height", self.hold_height)
        check_positive("base_distance", self.base_distance)
        check_nonnegative("table_height", self.table_height)
        check_table_clearance(self.hold_height, self.table_height)
        if self.sensor_rate is not None:
            check_positive("sensor_rate", self.sensor_rate)
        check_int("substeps", self.substeps, 1)
        if self.bullet.substeps != 1 and self.bullet.substeps != self.substeps:
            raise ParameterError(f"substeps ({self.substeps}) and bullet.substeps ({self.bullet.substeps}) differ; "
                                 f"give one")
        set_(self, "grip", one_of("grip", self.grip, GripKind))
        set_(self, "payload", one_of("payload", self.payload, Payload))
        check_positive("grip_force", self.grip_force)
        check_positive("grip_reach", self.grip_reach)
        static, dynamic = check_grip_friction(self.grip_static_friction, self.grip_dynamic_friction)
        set_(self, "grip_static_friction", static)
        set_(self, "grip_dynamic_friction", dynamic)

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
                       grip_static_friction=arms.grip_static_friction,
                       grip_dynamic_friction=arms.grip_dynamic_friction, grip_reach=arms.grip_reach, payload=arms.payload,
                       gravity=scene.gravity, bullet=scene.bullet, newton=scene.newton, detector=scene.detector)
        return cls(**{**fields_, **overrides})
