"""Numba kernels of the robot side: grasp frames and wrist-sensor readings from link states.

Both take link states as :class:`~bullet_dlo.bullet.native.StateReader` leaves them (rows of
doubles in Bullet's b3LinkState layout: CoM position 0:3, CoM quaternion 3:7, link frame
position 14:17 and quaternion 17:21, linear velocity of the CoM 21:24, angular velocity 24:27,
world frame), so the per-step arithmetic runs compiled whether the states came through the
native reader or PyBullet's Python API.
"""
from __future__ import annotations

import math

from numba import njit

COM, COM_QUAT, FRAME, FRAME_QUAT, LIN_VEL, ANG_VEL = 0, 3, 14, 17, 21, 24  # field offsets in a link-state row


@njit(cache=True, error_model="numpy")
def grasp_frames(rows, prev_vel, rate, ext):
    """Both grasp frames (the first link of ``rows[arm]``, (2, k, ROW)) into the cable's external holders.

    Writes, per arm, into ``ext`` (ExternalHolders): pos [m] = link frame origin, vel [m/s] = the
    frame origin's velocity v_com + omega x (frame - com), acc [m/s^2] = its backward difference
    against ``prev_vel`` (2, 3) over 1/``rate`` [1/s] (0 at the first call: rate 0), omega [rad/s],
    dir = the frame's x axis (arm 0) or its opposite (arm 1), unit: the cable runs from the left
    gripper's x axis to the right one's. ``prev_vel`` becomes the velocities now.
    """
    for arm in range(2):
        r = rows[arm, 0]
        wx, wy, wz = r[ANG_VEL], r[ANG_VEL + 1], r[ANG_VEL + 2]
        dx, dy, dz = r[FRAME] - r[COM], r[FRAME + 1] - r[COM + 1], r[FRAME + 2] - r[COM + 2]
        vx = r[LIN_VEL] + (wy * dz - wz * dy)
        vy = r[LIN_VEL + 1] + (wz * dx - wx * dz)
        vz = r[LIN_VEL + 2] + (wx * dy - wy * dx)
        ext.acc[arm, 0] = (vx - prev_vel[arm, 0]) * rate
        ext.acc[arm, 1] = (vy - prev_vel[arm, 1]) * rate
        ext.acc[arm, 2] = (vz - prev_vel[arm, 2]) * rate
        prev_vel[arm, 0], prev_vel[arm, 1], prev_vel[arm, 2] = vx, vy, vz
        x, y, z, w = r[FRAME_QUAT], r[FRAME_QUAT + 1], r[FRAME_QUAT + 2], r[FRAME_QUAT + 3]
        sign = 1.0 if arm == 0 else -1.0
        ax = sign * (1.0 - 2.0 * (y * y + z * z))  # first column of the rotation matrix
        ay = sign * 2.0 * (x * y + z * w)
        az = sign * 2.0 * (x * z - y * w)
        scale = 1.0 / math.sqrt(ax * ax + ay * ay + az * az)
        for j in range(3):
            ext.pos[arm, j] = r[FRAME + j]
            ext.omega[arm, j] = r[ANG_VEL + j]
        ext.vel[arm, 0], ext.vel[arm, 1], ext.vel[arm, 2] = vx, vy, vz
        ext.dir[arm, 0], ext.dir[arm, 1], ext.dir[arm, 2] = ax * scale, ay * scale, az * scale


@njit(cache=True, error_model="numpy")
def momentum(rows, mass, out):
    """Sum of m v [kg m/s] over links (rows (k, ROW), masses [kg] (k,)) into ``out`` (3,)."""
    px = py = pz = 0.0
    for k in range(mass.shape[0]):
        px += mass[k] * rows[k, LIN_VEL]
        py += mass[k] * rows[k, LIN_VEL + 1]
        pz += mass[k] * rows[k, LIN_VEL + 2]
    out[0], out[1], out[2] = px, py, pz


@njit(cache=True, error_model="numpy")
def rotation_matrix(x, y, z, w, r):
    """Row-major 3x3 rotation of the quaternion (x, y, z, w) into ``r`` (9,), as Bullet's btMatrix3x3."""
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    r[0], r[1], r[2] = 1.0 - (yy + zz), xy - wz, xz + wy
    r[3], r[4], r[5] = xy + wz, 1.0 - (xx + zz), yz - wx
    r[6], r[7], r[8] = xz - wy, yz + wx, 1.0 - (xx + yy)


@njit(cache=True, error_model="numpy")
def sensor_reading(rows, mass, reaction, dt, compensate, due, tare, offset, prev, out):
    """One physics step of a wrist F/T sensor.

    rows (k, ROW): link states of the tool side, the sensor's own link first (its CoM frame is the
    sensor frame); mass [kg] (k,); reaction (6,): the joint's reaction wrench as Bullet reports it
    (what the arm applies to the tool side, sensor frame); dt [s]: the physics step; compensate:
    subtract the payload's inertial force m a, from its momentum change since the previous call
    (``prev`` (4,): that momentum [kg m/s] and whether it is valid, updated every call); due: a sample
    is taken now (else only the momentum is tracked); tare (6,): the reading zeroed at the tare;
    offset (6,): bias plus this sample's noise [N, N m]. When due, writes into ``out`` (12,) the load
    on the tool side: [f, m] in the sensor frame, then f and m in the world frame. Returns ``due``.
    """
    ax = ay = az = 0.0
    if compensate:
        p = out[9:12]  # scratch until the reading is written
        momentum(rows, mass, p)
        if prev[3] != 0.0:
            ax, ay, az = (p[0] - prev[0]) / dt, (p[1] - prev[1]) / dt, (p[2] - prev[2]) / dt
        prev[0], prev[1], prev[2], prev[3] = p[0], p[1], p[2], 1.0
    if not due:
        return False
    r = out[0:9]  # scratch: the rotation, sensor frame -> world, before the reading overwrites it
    rotation_matrix(rows[0, COM_QUAT], rows[0, COM_QUAT + 1], rows[0, COM_QUAT + 2], rows[0, COM_QUAT + 3], r)
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]
    # the load on the tool side is minus what the arm applies (statics of the tool); inertia in the sensor frame
    fx = tare[0] - reaction[0] + (r0 * ax + r3 * ay + r6 * az) + offset[0]
    fy = tare[1] - reaction[1] + (r1 * ax + r4 * ay + r7 * az) + offset[1]
    fz = tare[2] - reaction[2] + (r2 * ax + r5 * ay + r8 * az) + offset[2]
    mx = tare[3] - reaction[3] + offset[3]
    my = tare[4] - reaction[4] + offset[4]
    mz = tare[5] - reaction[5] + offset[5]
    out[0], out[1], out[2], out[3], out[4], out[5] = fx, fy, fz, mx, my, mz
    out[6] = r0 * fx + r1 * fy + r2 * fz
    out[7] = r3 * fx + r4 * fy + r5 * fz
    out[8] = r6 * fx + r7 * fy + r8 * fz
    out[9] = r0 * mx + r1 * my + r2 * mz
    out[10] = r3 * mx + r4 * my + r5 * mz
    out[11] = r6 * mx + r7 * my + r8 * mz
    return True
