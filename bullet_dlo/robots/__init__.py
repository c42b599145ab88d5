"""Robot arms (URDF as data), wrist force/torque sensors and the two-arm cable scene.

Modules: :mod:`.arm` (an arm in a world: FK, IK, position control), :mod:`.compose` (arm
plus gripper as one URDF), :mod:`.transforms` (rotations), :mod:`.sensors` (wrist F/T),
:mod:`.dual_arm` (the two-arm scene: physics, task, observation).
"""
from __future__ import annotations

import importlib
import warnings

# 0.1 had a flat module ``bullet_dlo.robots``; its names stay importable from here for one release
_OLD_NAMES = {
    "Robot": "bullet_dlo.robots.arm",
    "RobotSpec": "bullet_dlo.config.robot",
    "load_robot_spec": "bullet_dlo.config.robot",
    "robot_names": "bullet_dlo.config.robot",
    "compose_with_gripper": "bullet_dlo.robots.compose",
    "quat_from_axes": "bullet_dlo.robots.transforms",
    "quat_from_matrix": "bullet_dlo.robots.transforms",
    "rotation": "bullet_dlo.robots.transforms",
    "URDF_DIR": "bullet_dlo.assets",
}


def __getattr__(name: str):
    if name in _OLD_NAMES:
        home = _OLD_NAMES[name]
        warnings.warn(f"bullet_dlo.robots.{name} moved to {home}.{name}; the old path goes in the next release",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(home), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
