"""Rotations in one place: quaternions [x, y, z, w] (PyBullet's order) and 3x3 matrices.

The conversions run every physics step (:func:`rotation`, four calls per dual-arm step) or
per rendered cable segment per frame (:func:`quat_from_axes`), so they avoid SciPy: building
a :class:`scipy.spatial.transform.Rotation` costs about 20 us, against about 1 us for Bullet's
own quaternion-to-matrix and a third of SciPy's cost for the written-out matrix-to-quaternion
(measured). The IK convergence check (:func:`angle_between`, set-up only) uses SciPy.
"""
from __future__ import annotations

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
    """3x3 rotation matrix -> unit quaternion [x, y, z, w], shape (4,) (Shepperd: pivot on the largest component)."""
    m = np.asarray(rot, float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        w, x, y, z = (m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s
    q = np.array([x, y, z, w])
    return q / np.linalg.norm(q)


def quat_from_axes(x_axis: Sequence[float], z_axis: Sequence[float]) -> np.ndarray:
    """Quaternion [x, y, z, w] of the frame with the given z axis and x axis (z kept, x orthogonalised)."""
    z = np.asarray(z_axis, float) / np.linalg.norm(z_axis)
    x = np.asarray(x_axis, float) - np.dot(x_axis, z) * z
    x /= np.linalg.norm(x)
    return quat_from_matrix(np.column_stack([x, cross3(z, x), z]))


def angle_between(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Angle [rad] of the rotation that takes orientation ``q1`` to ``q2`` (quaternions [x, y, z, w]), in [0, pi]."""
    return float((Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude())


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors: np.cross's arithmetic (same bits) at a tenth of its cost, for per-step code."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
