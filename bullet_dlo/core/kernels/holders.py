"""Numba kernels for held ends: minimum-jerk moves and the held-end samples a step needs.

A held end starts at a pose (position, clamp direction) and follows the sum of its moves,
each a straight-line displacement plus a rotation of the clamp direction about the held
node, both with a minimum-jerk (quintic) time profile. A step of length h needs the poses at
t, t + h/2 and t + h (RK4 and the implicit midpoint use the middle one): :func:`sample_holders`
writes them into a :class:`HeldSamples`.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

MOVE_COLUMNS = 8  # move table row: start [s], duration [s], displacement [m] (3), rotation vector [rad] (3)


class HolderPlan(NamedTuple):
    """Where the held ends start and how they move (SI units).

    start_pos: start positions of the first and last end [m], (2, 3);
    start_dir: start clamp directions, unit vectors along the cable from its first to its
    last node, (2, 3);
    moves_first, moves_last: move tables of each end, rows [start s, duration s, dx, dy, dz m,
    rx, ry, rz rad], (k, 8) (k = 0 without moves).
    """

    start_pos: np.ndarray
    start_dir: np.ndarray
    moves_first: np.ndarray
    moves_last: np.ndarray


class HeldSamples(NamedTuple):
    """Held-end poses at the three times a step needs: t, t + h/2, t + h.

    Each array has shape (3, 2, 3) = [sample, end (first, last), xyz]: pos [m], vel [m/s],
    acc [m/s^2], dir (clamp direction, unit).
    """

    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    dir: np.ndarray


def empty_samples() -> HeldSamples:
    """Zeroed held-end samples (filled by :func:`sample_holders`)."""
    return HeldSamples(*(np.zeros((3, 2, 3)) for _ in HeldSamples._fields))


@njit(cache=True, error_model="numpy")
def min_jerk(tau):
    """Quintic minimum-jerk profile s(tau) and its first two derivatives for tau in [0, 1]."""
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 1.0, 0.0, 0.0
    t2 = tau * tau
    t3 = t2 * tau
    s = t3 * (10.0 - 15.0 * tau + 6.0 * t2)
    ds = 30.0 * t2 * (1.0 - 2.0 * tau + t2)
    dds = 60.0 * tau * (1.0 - 3.0 * tau + 2.0 * t2)
    return s, ds, dds


@njit(cache=True, error_model="numpy")
def rotate(vec, rx, ry, rz):
    """Rotate the 3-vector ``vec`` in place by the rotation vector (rx, ry, rz) [rad] (Rodrigues)."""
    angle = math.sqrt(rx * rx + ry * ry + rz * rz)
    if angle < 1e-15:
        return
    kx, ky, kz = rx / angle, ry / angle, rz / angle
    ca, sa = math.cos(angle), math.sin(angle)
    v0, v1, v2 = vec[0], vec[1], vec[2]
    dot = kx * v0 + ky * v1 + kz * v2
    cx = ky * v2 - kz * v1
    cy = kz * v0 - kx * v2
    cz = kx * v1 - ky * v0
    vec[0] = v0 * ca + cx * sa + kx * dot * (1.0 - ca)
    vec[1] = v1 * ca + cy * sa + ky * dot * (1.0 - ca)
    vec[2] = v2 * ca + cz * sa + kz * dot * (1.0 - ca)


@njit(cache=True, error_model="numpy")
def held_pose(plan, end, t, samples, k):
    """Pose of held end ``end`` (0 first, 1 last) at time t [s] into sample ``k`` of ``samples``.

    Moves superpose: translations add, rotations of the clamp direction compose in table order.
    """
    moves = plan.moves_first if end == 0 else plan.moves_last
    pos, vel, acc, direction = samples.pos[k, end], samples.vel[k, end], samples.acc[k, end], samples.dir[k, end]
    pos[:] = plan.start_pos[end]
    vel[:] = 0.0
    acc[:] = 0.0
    direction[:] = plan.start_dir[end]
    for row in range(moves.shape[0]):
        start, dur = moves[row, 0], moves[row, 1]
        s, ds, dds = min_jerk((t - start) / dur)
        for j in range(3):
            pos[j] += moves[row, 2 + j] * s
            vel[j] += moves[row, 2 + j] * ds / dur
            acc[j] += moves[row, 2 + j] * dds / (dur * dur)
        if s > 0.0:
            rotate(direction, moves[row, 5] * s, moves[row, 6] * s, moves[row, 7] * s)


@njit(cache=True, error_model="numpy")
def sample_holders(plan, t, h, samples):
    """Both held ends at t, t + h/2 and t + h [s] into ``samples`` (a :class:`HeldSamples`)."""
    for k in range(3):
        tk = t + 0.5 * h * k
        held_pose(plan, 0, tk, samples, k)
        held_pose(plan, 1, tk, samples, k)
