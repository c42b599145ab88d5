"""The Bullet world a scene sets: ground, obstacles, how the cable meets Bullet (the ``bullet:`` section).

Validated here once, at the boundary; :func:`bullet_dlo.sim.build` hands the typed options to the
world, the cable and the dual-arm physics, so every entry point builds the same world from them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from bullet_dlo.config.schema import LIMITS, one_of, only_keys, section
from bullet_dlo.core.enums import ObstacleType, SelfCollision, Sync
from bullet_dlo.core.validate import (ParameterError, check_bool, check_finite, check_int, check_nonnegative,
                                      check_positive, check_vector3)

MAX_OBSTACLES = 1000
"""Most ``bullet.obstacles`` entries in one scene: 5000 took 26 s to build on a 2-core machine before a step."""
BULLET_KEYS = ("ground", "ground_height", "ground_friction", "substeps", "self_collision", "sync", "obstacles")
OBSTACLE_KEYS = {"box": ("half_extents", "position", "orientation", "mass", "friction", "name", "contact"),
                 "cylinder": ("radius", "height", "position", "orientation", "mass", "friction", "name", "contact"),
                 "urdf": ("path", "position", "orientation", "fixed", "name", "contact")}
SELF_COLLISION = SelfCollision.names()
SYNC = Sync.names()


@dataclass(frozen=True)
class BulletOptions:
    """The scene's ``bullet:`` section, validated on construction; every Bullet path honours it
    (``simulate --engine bullet``, ``grasp``, ``render``, captures, environments).

    ground: add a ground plane at ground_height [m]; ground_friction: its Coulomb coefficient [-] (>= 0; a
    Bullet body's single coefficient, combined with the cable's static_friction and dynamic_friction);
    substeps: integrator steps per Bullet step (>= 1); self_collision: neighbours | none | all;
    sync: contacts | always; obstacles: {type: box|cylinder|urdf, ...} entries whose keys and numbers
    (masses and friction >= 0, sizes > 0) are checked here; a URDF's file is found when
    :func:`bullet_dlo.bullet.world.add_obstacles` adds it (relative paths from the working directory then).
    """

    ground: bool = True
    ground_height: float = 0.0
    ground_friction: float = 0.5
    substeps: int = 1
    self_collision: str = "neighbours"
    sync: str = "contacts"
    obstacles: tuple[dict, ...] = ()

    def __post_init__(self) -> None:
        # the same check_* helpers BulletWorld and BulletCable apply to these values
        set_ = object.__setattr__
        set_(self, "ground", check_bool("bullet.ground", self.ground))
        set_(self, "ground_height", check_finite("bullet.ground_height", self.ground_height))
        set_(self, "ground_friction", check_nonnegative("bullet.ground_friction", self.ground_friction))
        set_(self, "substeps", check_int("bullet.substeps", self.substeps, 1, int(LIMITS["substeps"])))
        set_(self, "self_collision", one_of("bullet.self_collision", self.self_collision, SelfCollision))
        set_(self, "sync", one_of("bullet.sync", self.sync, Sync))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None) -> "BulletOptions":
        """Validate a parsed ``bullet:`` section; errors name the offending key."""
        data = section(data, "bullet")
        only_keys(data, BULLET_KEYS, "bullet")
        obstacles = data.get("obstacles") or []
        if not isinstance(obstacles, list):
            raise ParameterError("bullet.obstacles must be a list")
        if len(obstacles) > MAX_OBSTACLES:
            raise ParameterError(f"bullet.obstacles has {len(obstacles)} entries; at most {MAX_OBSTACLES} "
                                 f"(each is a Bullet body the cable's contact model searches every step)")
        kwargs = {k: data[k] for k in BULLET_KEYS if k in data and k != "obstacles"}
        return cls(**kwargs, obstacles=tuple(_obstacle(k, ob) for k, ob in enumerate(obstacles)))


def _obstacle(k: int, data: Any) -> dict:
    """One ``bullet.obstacles`` entry with its type and keys checked."""
    ob = dict(section(data, f"bullet.obstacles[{k}]"))
    kind = one_of(f"bullet.obstacles[{k}].type", ob.pop("type", None), ObstacleType)
    only_keys(ob, OBSTACLE_KEYS[kind], f"bullet.obstacles[{k}] ({kind})")
    where = f"bullet.obstacles[{k}]"
    for key in ("mass", "friction"):  # (the checks BulletWorld.add_box / add_cylinder apply again)
        if key in ob:
            ob[key] = check_nonnegative(f"{where}.{key}", ob[key])
    for key in ("radius", "height"):
        if key in ob:
            ob[key] = check_positive(f"{where}.{key}", ob[key])
    if "half_extents" in ob:
        extents = check_vector3(f"{where}.half_extents", ob["half_extents"])
        if not np.all(extents > 0.0):
            raise ParameterError(f"{where}.half_extents must be three lengths > 0 [m], "
                                 f"got {[float(e) for e in extents]}")
    if kind == "urdf" and not (isinstance(ob.get("path"), str) and ob["path"].strip()):
        raise ParameterError(f"{where}.path must name a URDF file, got {ob.get('path')!r}")
    return {"type": kind, **ob}
