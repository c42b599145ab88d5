"""Numba kernels for held ends: the trajectories they follow and the held-end samples a step needs.

A held end starts at a pose (position, clamp direction) and follows the superposition of
three kinds of motion, each in its own table of a :class:`HolderPlan`:

* moves: a straight-line displacement plus a rotation of the clamp direction about the held
  node, both with a minimum-jerk (quintic) time profile, rest to rest;
* a path through waypoints: piecewise quintic polynomials in position and rotation vector
  (C2: position, velocity and acceleration continuous, at rest at the first and last waypoint);
* sines: amplitude * envelope(t) * sin(2 pi f (t - start) + phase) in position and rotation
  vector, the envelope rising and falling with minimum-jerk ramps.

Translations add; the clamp direction is turned by the moves (table order), then the path,
then the sines. A step of length h needs the poses at t, t + h/2 and t + h (RK4 and the
implicit midpoint use the middle one): :func:`sample_holders` writes them into a :class:`HeldSamples`.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.jit import njit

MOVE_COLUMNS = 8  # move row: start [s], duration [s], displacement [m] (3), rotation vector [rad] (3)
PATH_COLUMNS = 38  # path row: t0 [s], t1 [s], position coefficients c0..c5 [m] (6 x 3), rotation c0..c5 [rad] (6 x 3)
SINE_COLUMNS = 11  # sine row: start [s], duration [s], ramp [s], frequency [Hz], phase [rad], amplitude [m] (3),
#                    rotation amplitude [rad] (3)


class HolderPlan(NamedTuple):
    """Where the held ends start and how they move (SI units).

    start_pos: start positions of the first and last end [m], (2, 3);
    start_dir: start clamp directions, unit vectors along the cable from its first to its
    last node, (2, 3);
    moves_first, moves_last: move tables, rows [start s, duration s, dx, dy, dz m, rx, ry, rz rad], (k, 8);
    path_first, path_last: waypoint path segments in time order, rows [t0 s, t1 s, then the
    coefficients c_0..c_5 of p(u) = sum c_i u^i, u = (t - t0)/(t1 - t0), for the displacement
    [m] (3 per coefficient) and then for the rotation vector [rad]], (k, 38);
    sines_first, sines_last: rows [start s, duration s (inf: forever), ramp s, frequency Hz,
    phase rad, amplitude m (3), rotation amplitude rad (3)], (k, 11). k = 0: none of that kind.
    start_normal: the clamps' start section axis d1 (unit, normal to start_dir), (2, 3);
    normal: where :func:`sample_holders` writes d1 turned with the clamp at the three sample times,
    (3, 2, 3) = [sample, end, xyz]; shape (0, 2, 3) when the cable has no material frame (then the
    roll about the cable axis is not tracked and nothing extra is computed). A twisting model's
    control shares this buffer (``CableControl.normal``, the kernels' ``tw_normal``): it is how the roll reaches the step kernels.
    """

    start_pos: np.ndarray
    start_dir: np.ndarray
    moves_first: np.ndarray
    moves_last: np.ndarray
    path_first: np.ndarray
    path_last: np.ndarray
    sines_first: np.ndarray
    sines_last: np.ndarray
    start_normal: np.ndarray = np.zeros((2, 3))
    normal: np.ndarray = np.zeros((0, 2, 3))


class HeldSamples(NamedTuple):
    """Held-end poses at the three times a step needs: t, t + h/2, t + h.

    Each array has shape (3, 2, 3) = [sample, end (first, last), xyz]: pos [m], vel [m/s],
    acc [m/s^2], dir (clamp direction, unit).
    """

    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    dir: np.ndarray


class ExternalHolders(NamedTuple):
    """Measured holder poses (e.g. gripper links) that ends follow instead of their move tables.

    active: which ends follow them, (2,) bool; pos [m], vel [m/s], acc [m/s^2], omega
    (angular velocity) [rad/s], alpha (angular acceleration) [rad/s^2], dir (clamp direction, unit,
    along the cable from its first to its last node): world frame, (2, 3) each, measured now and
    extrapolated over a step at constant acceleration and angular acceleration (second order: a
    constant-velocity extrapolation leaves the held end a dt^2 behind an accelerating holder and its
    velocity a dt behind, a first-order error in the cable's forces); normal: the holder's section
    axis d1 (unit, normal to dir), world frame, (2, 3), turned with dir over the step: the roll about
    the cable axis that a clamp of a cable with a material frame holds (read only by such cables).
    """

    active: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    dir: np.ndarray
    normal: np.ndarray


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
def add_moves(moves, t, pos, vel, acc, direction, normal):
    """Add the minimum-jerk moves of a move table at time t [s] to pos/vel/acc, turning ``direction``
    (and ``normal``, the section axis, unless it is empty)."""
    for row in range(moves.shape[0]):
        start, dur = moves[row, 0], moves[row, 1]
        s, ds, dds = min_jerk((t - start) / dur)
        for j in range(3):
            pos[j] += moves[row, 2 + j] * s
            vel[j] += moves[row, 2 + j] * ds / dur
            acc[j] += moves[row, 2 + j] * dds / (dur * dur)
        if s > 0.0:
            rotate(direction, moves[row, 5] * s, moves[row, 6] * s, moves[row, 7] * s)
            if normal.shape[0] == 3:
                rotate(normal, moves[row, 5] * s, moves[row, 6] * s, moves[row, 7] * s)


@njit(cache=True, error_model="numpy")
def quintic(path, row, col, u):
    """p(u) = sum_i c_i u^i with c_i = path[row, col + 3 i], and dp/du, d2p/du2 (Horner)."""
    p = dp = ddp = 0.0
    for i in range(5, -1, -1):
        ddp = ddp * u + 2.0 * dp
        dp = dp * u + p
        p = p * u + path[row, col + 3 * i]
    return p, dp, ddp


@njit(cache=True, error_model="numpy")
def add_path(path, t, pos, vel, acc, direction, normal):
    """Add the waypoint path (segment table) at time t [s]; before its first and after its last
    waypoint the end rests there."""
    k = path.shape[0]
    if k == 0:
        return
    lo, hi = 0, k - 1  # the last segment whose t0 <= t (binary search)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if path[mid, 0] <= t:
            lo = mid
        else:
            hi = mid - 1
    dur = path[lo, 1] - path[lo, 0]
    u = min(max((t - path[lo, 0]) / dur, 0.0), 1.0)
    moving = path[0, 0] <= t <= path[k - 1, 1]  # (a path at rest has zero end velocity anyway)
    for j in range(3):
        p, dp, ddp = quintic(path, lo, 2 + j, u)
        pos[j] += p
        if moving:
            vel[j] += dp / dur
            acc[j] += ddp / (dur * dur)
    # the rotation vector [rad] (np.int64 columns: a literal would compile quintic once per constant)
    rx = quintic(path, lo, np.int64(20), u)[0]
    ry = quintic(path, lo, np.int64(21), u)[0]
    rz = quintic(path, lo, np.int64(22), u)[0]
    rotate(direction, rx, ry, rz)
    if normal.shape[0] == 3:
        rotate(normal, rx, ry, rz)


@njit(cache=True, error_model="numpy")
def envelope(t, start, duration, ramp):
    """Sine envelope e(t) and its first two time derivatives [1/s, 1/s^2]: 0 outside [start, start + duration],
    rising over ``ramp`` [s] from ``start`` and falling over ``ramp`` before the end (minimum jerk)."""
    if t < start or t > start + duration:
        return 0.0, 0.0, 0.0
    if ramp <= 0.0:
        return 1.0, 0.0, 0.0
    s1, d1, dd1 = min_jerk((t - start) / ramp)
    s2, d2, dd2 = min_jerk((start + duration - t) / ramp)
    e = s1 * s2
    de = (d1 * s2 - s1 * d2) / ramp
    dde = (dd1 * s2 - 2.0 * d1 * d2 + s1 * dd2) / (ramp * ramp)
    return e, de, dde


@njit(cache=True, error_model="numpy")
def add_sines(sines, t, pos, vel, acc, direction, normal):
    """Add the sines of a sine table at time t [s] to pos/vel/acc, turning ``direction`` (and ``normal``)."""
    for row in range(sines.shape[0]):
        e, de, dde = envelope(t, sines[row, 0], sines[row, 1], sines[row, 2])
        if e == 0.0 and de == 0.0:
            continue
        w = 2.0 * math.pi * sines[row, 3]
        arg = w * (t - sines[row, 0]) + sines[row, 4]
        sn, cs = math.sin(arg), math.cos(arg)
        f = e * sn
        df = de * sn + e * w * cs
        ddf = dde * sn + 2.0 * de * w * cs - e * w * w * sn
        for j in range(3):
            pos[j] += sines[row, 5 + j] * f
            vel[j] += sines[row, 5 + j] * df
            acc[j] += sines[row, 5 + j] * ddf
        rotate(direction, sines[row, 8] * f, sines[row, 9] * f, sines[row, 10] * f)
        if normal.shape[0] == 3:
            rotate(normal, sines[row, 8] * f, sines[row, 9] * f, sines[row, 10] * f)


@njit(cache=True, error_model="numpy")
def held_pose(plan, end, t, samples, k):
    """Pose of held end ``end`` (0 first, 1 last) at time t [s] into sample ``k`` of ``samples``."""
    pos, vel, acc, direction = samples.pos[k, end], samples.vel[k, end], samples.acc[k, end], samples.dir[k, end]
    pos[:] = plan.start_pos[end]
    vel[:] = 0.0
    acc[:] = 0.0
    direction[:] = plan.start_dir[end]
    if plan.normal.shape[0] > 0:  # a material frame: turn the section axis d1 with the clamp
        normal = plan.normal[k, end]
        normal[:] = plan.start_normal[end]
    else:
        normal = plan.start_normal[end, 0:0]
    if end == 0:
        add_moves(plan.moves_first, t, pos, vel, acc, direction, normal)
        add_path(plan.path_first, t, pos, vel, acc, direction, normal)
        add_sines(plan.sines_first, t, pos, vel, acc, direction, normal)
    else:
        add_moves(plan.moves_last, t, pos, vel, acc, direction, normal)
        add_path(plan.path_last, t, pos, vel, acc, direction, normal)
        add_sines(plan.sines_last, t, pos, vel, acc, direction, normal)


@njit(cache=True, error_model="numpy")
def _end_at_rest(plan, end):
    """Whether held end ``end`` never moves: no move, path or sine rows and no section axis to turn."""
    if plan.normal.shape[0] > 0:
        return False
    if end == 0:
        return plan.moves_first.shape[0] == 0 and plan.path_first.shape[0] == 0 and plan.sines_first.shape[0] == 0
    return plan.moves_last.shape[0] == 0 and plan.path_last.shape[0] == 0 and plan.sines_last.shape[0] == 0


@njit(cache=True, error_model="numpy")
def _rest_end(plan, end, samples):
    """A held end at rest at its start pose in all three samples, written element by element: the values
    :func:`held_pose` gives with empty tables, without its array views (a fixed clamp costs ~0.1 us, not ~2.6)."""
    for k in range(3):
        for j in range(3):
            samples.pos[k, end, j] = plan.start_pos[end, j]
            samples.vel[k, end, j] = 0.0
            samples.acc[k, end, j] = 0.0
            samples.dir[k, end, j] = plan.start_dir[end, j]


@njit(cache=True, error_model="numpy")
def sample_end(plan, end, t, h, samples):
    """Held end ``end`` (0 first, 1 last) at t, t + h/2 and t + h [s] into ``samples`` (a :class:`HeldSamples`);
    an end that never moves takes the fast path :func:`_rest_end` (the same values)."""
    if _end_at_rest(plan, end):
        _rest_end(plan, end, samples)
        return
    for k in range(3):
        held_pose(plan, end, t + 0.5 * h * k, samples, k)


@njit(cache=True, error_model="numpy")
def sample_holders(plan, t, h, samples):
    """Both held ends at t, t + h/2 and t + h [s] into ``samples`` (a :class:`HeldSamples`).

    An end with no motion (a fixed clamp or pin, or a free end) takes the fast path :func:`_rest_end`
    (see :func:`sample_end`).
    """
    for end in range(2):  # (a loop, not two literal ends: sample_end and its callees compile once)
        sample_end(plan, end, t, h, samples)


@njit(cache=True, error_model="numpy")
def peak_speeds(plan, t_end, count, samples, out):
    """Largest prescribed speed [m/s] of each end over [0, t_end] [s], sampled at ``count`` evenly spaced
    times, into ``out`` (2,) (first, last); ``samples``: scratch HeldSamples."""
    out[:] = 0.0
    for k in range(count):
        t = t_end * k / max(count - 1, 1)
        sample_holders(plan, t, 0.0, samples)
        for e in range(2):
            v = samples.vel[0, e]
            out[e] = max(out[e], math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
