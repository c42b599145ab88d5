"""Rotations in one place: quaternions [x, y, z, w] (PyBullet's order) and 3x3 matrices.

The conversions run every physics step (:func:`rotation`, four calls per dual-arm step) or
per rendered cable segment per frame (:func:`quat_from_axes`), so they avoid SciPy: building
a :class:`scipy.spatial.transform.Rotation` costs about 20 us, against about 1 us for Bullet's
own quaternion-to-matrix and a third of SciPy's cost for the written-out matrix-to-quaternion
(measured). The IK convergence check (:func:`angle_between`, set-up only) uses SciPy.
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
    """3x3 rotation matrix -> unit quaternion [x, y, z, w], shape (4,) (Shepperd: pivot on the largest component).

    On Python floats: the same operations as on NumPy's scalars (np.trace sums the diagonal in order, the norm of a
    vector is sqrt(q.dot(q))), at half their cost (Routing's gripper turns every control step); a matrix that is no
    rotation gives NaN as before."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = np.asarray(rot, float).ravel().tolist()
    tr = (m00 + m11) + m22
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * np.sqrt(1.0 + m00 - m11 - m22)
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = 2.0 * np.sqrt(1.0 + m11 - m00 - m22)
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = 2.0 * np.sqrt(1.0 + m22 - m00 - m11)
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    q = np.array([x, y, z, w])
    return q / norm(q)


def quat_from_axes(x_axis: Sequence[float], z_axis: Sequence[float]) -> np.ndarray:
    """Quaternion [x, y, z, w] of the frame with the given z axis and x axis (z kept, x orthogonalised)."""
    z = np.asarray(z_axis, float)
    z = z / norm(z)
    x = np.asarray(x_axis, float)
    x = x - x.dot(z) * z
    x /= norm(x)
    m = np.empty((3, 3))
    m[:, 0], m[:, 1], m[:, 2] = x, cross3(z, x), z
    return quat_from_matrix(m)


def angle_between(q1: Sequence[float], q2: Sequence[float]) -> float:
    """Angle [rad] of the rotation that takes orientation ``q1`` to ``q2`` (quaternions [x, y, z, w]), in [0, pi]."""
    return float((Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude())


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b for two 3-vectors: np.cross's arithmetic (same bits) at a tenth of its cost, for per-step code."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def norm(v: np.ndarray) -> float:
    """Euclidean length of a vector: np.linalg.norm's value for a 1-D float array (it computes sqrt(v.dot(v)):
    the same bits) without its Python wrapper, for per-step code."""
    return math.sqrt(v.dot(v))
