"""Rotations in one place: quaternions [x, y, z, w] (PyBullet's order) and 3x3 matrices.

Set-up code (grasp frames, IK convergence checks) uses :class:`scipy.spatial.transform.Rotation`.
The two conversions called every physics step or every rendered frame avoid it: building a
SciPy Rotation costs ~20 us a call against ~1 us for Bullet's own quaternion-to-matrix
(:func:`rotation`, four calls per dual-arm step) and a few us for :func:`quat_z_onto`.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import pybullet as pb
from scipy.spatial.transform import Rotation


def rotation(quat: Sequence[float]) -> np.ndarray:
    """Quaternion [x, y, z, w] (normalised here) -> 3x3 rotation matrix; its columns are the frame's axes in world.

    Bullet's conversion: the same arithmetic as the simulation's own, so frames read back agree to the bit.
    """
    return np.array(pb.getMatrixFromQuaternion(list(quat))).reshape(3, 3)


def quat_from_matrix(rot: np.ndarray) -> np.ndarray:
    """3x3 rotation matrix -> unit quaternion [x, y, z, w], shape (4,)."""
    return Rotation.from_matrix(np.asarray(rot, float)).as_quat()


def quat_from_axes(x_axis: Sequence[float], z_axis: Sequence[float]) -> np.ndarray:
    """Quaternion [x, y, z, w] of the frame with the given z axis and x axis (z kept, x orthogonalised)."""
    z = np.asarray(z_axis, float) / np.linalg.norm(z_axis)
    x = np.asarray(x_axis, float) - np.dot(x_axis, z) * z
    x /= np.linalg.norm(x)
    return quat_from_matrix(np.column_stack([x, np.cross(z, x), z]))


def angle_between(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Angle [rad] of the rotation that takes orientation ``q1`` to ``q2`` (quaternions [x, y, z, w]), in [0, pi]."""
    return float((Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude())


def quat_z_onto(direction: Sequence[float]) -> list[float]:
    """Quaternion [x, y, z, w] of the shortest rotation taking +z onto ``direction`` (identity for a zero vector).

    Per rendered segment per frame, hence written out (see the module docstring).
    """
    d = np.asarray(direction, float)
    n = np.linalg.norm(d)
    if n < 1e-12:
        return [0.0, 0.0, 0.0, 1.0]
    d = d / n
    axis = np.cross([0.0, 0.0, 1.0], d)
    s = np.linalg.norm(axis)
    c = float(d[2])
    if s < 1e-12:  # parallel or antiparallel: any axis normal to z
        return [0.0, 0.0, 0.0, 1.0] if c > 0 else [1.0, 0.0, 0.0, 0.0]
    angle = math.atan2(s, c)
    axis = axis / s * math.sin(angle / 2)
    return [float(axis[0]), float(axis[1]), float(axis[2]), math.cos(angle / 2)]
