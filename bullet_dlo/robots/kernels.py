"""Numba kernels of the robot side: grasp frames and wrist-sensor readings from link states.

Both take link states as :class:`~bullet_dlo.bullet.native.StateReader` leaves them (rows of
doubles in Bullet's b3LinkState layout: CoM position 0:3, CoM quaternion 3:7, link frame
position 14:17 and quaternion 17:21, linear velocity of the CoM 21:24, angular velocity 24:27,
world frame), so the per-step arithmetic runs compiled whether the states came through the
native reader or PyBullet's Python API.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.jit import njit

COM, COM_QUAT, FRAME, FRAME_QUAT, LIN_VEL, ANG_VEL = 0, 3, 14, 17, 21, 24  # field offsets in a link-state row


@njit(cache=True, error_model="numpy")
def grasp_frames(rows, history, rate, section, ext):
    """Both grasp frames (the first link of ``rows[arm]``, (2, k, ROW)) into the cable's external holders.

    Writes, per arm, into ``ext`` (ExternalHolders): pos [m] = link frame origin; vel [m/s], acc [m/s^2],
    omega [rad/s] and alpha [rad/s^2] from this pose and the two before it in ``history`` (2, 3, 7): the
    second-order backward difference (3 p0 - 4 p1 + p2) / 2h and the second difference (p0 - 2 p1 + p2) / h^2
    over h = 1/``rate`` [s], of the positions and of the rotation vectors between the orientations, so that the
    cable's constant-acceleration extrapolation over the coming step is the parabola through the last three
    poses. (Bullet's reported velocities are not used there: after a step they are J(q) times the joint
    velocities the step moved with, half a step behind the pose in the joint accelerations; a held end
    extrapolated from them made the cable's forces first order in dt.) Until two earlier poses are known
    (``rate`` 0 restarts the history, e.g. at a grasp) the velocities are Bullet's, v_com + omega x
    (frame - com), and the accelerations zero. dir = the frame's x axis (arm 0) or its opposite (arm 1),
    unit: the cable runs from the left gripper's x axis to the right one's; normal = the grasp frame's
    rotation times ``section[arm]`` (2, 3), the held section's axis d1 in the grasp frame (fixed at the grasp:
    the gripper's roll about the cable turns it; read only by a cable with a material frame).
    ``history[arm]`` rows: the pose one step ago, two steps ago (x, y, z, qx, qy, qz, qw), and [count, ...]
    """
    rot = np.empty(9)
    theta1 = np.empty(3)
    theta2 = np.empty(3)
    for arm in range(2):
        r = rows[arm, 0]
        h = history[arm]
        count = 0.0 if rate == 0.0 else h[2, 0]
        x, y, z, w = r[FRAME_QUAT], r[FRAME_QUAT + 1], r[FRAME_QUAT + 2], r[FRAME_QUAT + 3]
        if count >= 2.0:
            relative_rotvec(x, y, z, w, h[0, 3], h[0, 4], h[0, 5], h[0, 6], theta1)
            relative_rotvec(h[0, 3], h[0, 4], h[0, 5], h[0, 6], h[1, 3], h[1, 4], h[1, 5], h[1, 6], theta2)
            for j in range(3):
                p0, p1, p2 = r[FRAME + j], h[0, j], h[1, j]
                ext.vel[arm, j] = (3.0 * p0 - 4.0 * p1 + p2) * 0.5 * rate
                ext.acc[arm, j] = (p0 - 2.0 * p1 + p2) * rate * rate
                ext.omega[arm, j] = (3.0 * theta1[j] - theta2[j]) * 0.5 * rate
                ext.alpha[arm, j] = (theta1[j] - theta2[j]) * rate * rate
        else:
            wx, wy, wz = r[ANG_VEL], r[ANG_VEL + 1], r[ANG_VEL + 2]
            dx, dy, dz = r[FRAME] - r[COM], r[FRAME + 1] - r[COM + 1], r[FRAME + 2] - r[COM + 2]
            ext.vel[arm, 0] = r[LIN_VEL] + (wy * dz - wz * dy)
            ext.vel[arm, 1] = r[LIN_VEL + 1] + (wz * dx - wx * dz)
            ext.vel[arm, 2] = r[LIN_VEL + 2] + (wx * dy - wy * dx)
            for j in range(3):
                ext.omega[arm, j] = r[ANG_VEL + j]
                ext.acc[arm, j] = 0.0
                ext.alpha[arm, j] = 0.0
        for j in range(7):  # shift the history
            h[1, j] = h[0, j]
            h[0, j] = r[FRAME + j]  # position 14:17 then quaternion 17:21
        h[2, 0] = min(count + 1.0, 2.0)
        for j in range(3):
            ext.pos[arm, j] = r[FRAME + j]
        sign = 1.0 if arm == 0 else -1.0
        ax = sign * (1.0 - 2.0 * (y * y + z * z))  # first column of the rotation matrix
        ay = sign * 2.0 * (x * y + z * w)
        az = sign * 2.0 * (x * z - y * w)
        scale = 1.0 / math.sqrt(ax * ax + ay * ay + az * az)
        ext.dir[arm, 0], ext.dir[arm, 1], ext.dir[arm, 2] = ax * scale, ay * scale, az * scale
        sx, sy, sz = section[arm, 0], section[arm, 1], section[arm, 2]
        if sx != 0.0 or sy != 0.0 or sz != 0.0:  # (zero: no section held, nothing to turn)
            rotation_matrix(x, y, z, w, rot)
            ext.normal[arm, 0] = rot[0] * sx + rot[1] * sy + rot[2] * sz
            ext.normal[arm, 1] = rot[3] * sx + rot[4] * sy + rot[5] * sz
            ext.normal[arm, 2] = rot[6] * sx + rot[7] * sy + rot[8] * sz


@njit(cache=True, error_model="numpy")
def relative_rotvec(x0, y0, z0, w0, x1, y1, z1, w1, out):
    """Rotation vector [rad] (world frame) of the turn from unit quaternion 1 to unit quaternion 0 (both
    (x, y, z, w)): of q0 q1^-1, the shorter way round, into ``out`` (3,)."""
    # q0 * conj(q1)
    w = w0 * w1 + x0 * x1 + y0 * y1 + z0 * z1
    x = -w0 * x1 + x0 * w1 - y0 * z1 + z0 * y1
    y = -w0 * y1 + y0 * w1 - z0 * x1 + x0 * z1
    z = -w0 * z1 + z0 * w1 - x0 * y1 + y0 * x1
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    scale = 2.0 / w if s < 1e-12 else 2.0 * math.atan2(s, w) / s
    out[0], out[1], out[2] = x * scale, y * scale, z * scale


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


class Payload(NamedTuple):
    """The tool side below a wrist sensor, as the sensor removes its weight and inertia.

    k bodies, each attached to a row of the sensor's link states (row k; row 0 is the sensor's own
    link, whose CoM frame is the sensor frame): mass [kg] (k,); com [m] (k, 3): the body's centre of
    mass in its row's CoM frame (zeros for URDF links, whose rows are their own centres of mass; the
    lumped payload of a calibration: its centre of mass in the sensor frame, on row 0); inertia
    [kg m^2] (k, 3): principal moments about that centre of mass in the row's CoM frame (zeros where
    unknown, e.g. a calibrated payload); gravity [m/s^2] (3,), world frame.
    """

    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    gravity: np.ndarray


class SensorMemory(NamedTuple):
    """What a wrist sensor keeps between steps: each payload body's linear momentum m v [kg m/s] and
    spin angular momentum I omega [kg m^2/s] at the previous call, world frame, (k, 6); valid (1,): 1
    once they hold a previous call (the accelerations are their backward differences)."""

    momentum: np.ndarray
    valid: np.ndarray


@njit(cache=True, error_model="numpy")
def _body_point(row, com, r, out):
    """A payload body's centre of mass [m] and its velocity [m/s] into ``out`` (6,): the row's CoM plus
    ``com`` (row's CoM frame) turned by ``r`` (the row's rotation, row-major (9,)), v + omega x offset."""
    ox = r[0] * com[0] + r[1] * com[1] + r[2] * com[2]
    oy = r[3] * com[0] + r[4] * com[1] + r[5] * com[2]
    oz = r[6] * com[0] + r[7] * com[1] + r[8] * com[2]
    wx, wy, wz = row[ANG_VEL], row[ANG_VEL + 1], row[ANG_VEL + 2]
    out[0], out[1], out[2] = row[COM] + ox, row[COM + 1] + oy, row[COM + 2] + oz
    out[3] = row[LIN_VEL] + (wy * oz - wz * oy)
    out[4] = row[LIN_VEL + 1] + (wz * ox - wx * oz)
    out[5] = row[LIN_VEL + 2] + (wx * oy - wy * ox)


@njit(cache=True, error_model="numpy")
def payload_load(rows, payload, dt, compensate, memory, out):
    """The payload's own load to remove from a wrist reading, world frame, into ``out`` (6,):
    [F, M] = [sum dp/dt - m g, sum (c - c0) x (dp/dt - m g) + dh/dt] [N, N m], moments about the sensor
    frame's origin c0 (the CoM of ``rows[0]``); p = m v and h = I omega per body, their rates backward
    differences over ``dt`` [s] against ``memory`` (updated every call; zero at the first call or with
    ``compensate`` False, then only the weight is removed).

    The load on the tool side is what the arm applies to it minus this (Newton-Euler of the tool).
    """
    g = payload.gravity
    c0x, c0y, c0z = rows[0, COM], rows[0, COM + 1], rows[0, COM + 2]
    fx = fy = fz = mx = my = mz = 0.0
    r = np.empty(9)
    body = np.empty(6)
    for k in range(payload.mass.shape[0]):
        row, m = rows[k], payload.mass[k]
        rotation_matrix(row[COM_QUAT], row[COM_QUAT + 1], row[COM_QUAT + 2], row[COM_QUAT + 3], r)
        _body_point(row, payload.com[k], r, body)
        # spin angular momentum h = R diag(I) R^T omega
        wx, wy, wz = row[ANG_VEL], row[ANG_VEL + 1], row[ANG_VEL + 2]
        i0, i1, i2 = payload.inertia[k, 0], payload.inertia[k, 1], payload.inertia[k, 2]
        b0 = i0 * (r[0] * wx + r[3] * wy + r[6] * wz)
        b1 = i1 * (r[1] * wx + r[4] * wy + r[7] * wz)
        b2 = i2 * (r[2] * wx + r[5] * wy + r[8] * wz)
        now = (m * body[3], m * body[4], m * body[5],
               r[0] * b0 + r[1] * b1 + r[2] * b2, r[3] * b0 + r[4] * b1 + r[5] * b2,
               r[6] * b0 + r[7] * b1 + r[8] * b2)
        # net force on the body that is not the arm's: its rate of momentum minus its weight
        qx, qy, qz = -m * g[0], -m * g[1], -m * g[2]
        hx = hy = hz = 0.0
        if compensate:
            if memory.valid[0] != 0.0:
                prev = memory.momentum[k]
                qx += (now[0] - prev[0]) / dt
                qy += (now[1] - prev[1]) / dt
                qz += (now[2] - prev[2]) / dt
                hx, hy, hz = (now[3] - prev[3]) / dt, (now[4] - prev[4]) / dt, (now[5] - prev[5]) / dt
            for j in range(6):
                memory.momentum[k, j] = now[j]
        dx, dy, dz = body[0] - c0x, body[1] - c0y, body[2] - c0z
        fx, fy, fz = fx + qx, fy + qy, fz + qz
        mx += dy * qz - dz * qy + hx
        my += dz * qx - dx * qz + hy
        mz += dx * qy - dy * qx + hz
    if compensate:
        memory.valid[0] = 1.0
    out[0], out[1], out[2], out[3], out[4], out[5] = fx, fy, fz, mx, my, mz


@njit(cache=True, error_model="numpy")
def tool_reaction(rows, payload, dt, memory, applied, out):
    """What the arm applies to the tool side in the step just taken, by Newton-Euler of the tool.

    rows (k, ROW): the tool side's link states, the sensor's own link first; payload: its bodies as
    the robot description gives them (:class:`Payload`); dt [s]: the physics step; memory: their
    momenta one call ago (:class:`SensorMemory`, updated); applied (6,): every other load on the
    tool side in that step (force [N], moment about the world origin [N m], world frame: the held
    cable's, contacts). The reaction is the tool's rates of momentum minus its weight minus
    ``applied``; written into ``out`` (6,) in the sensor frame, moments about its origin (the CoM of
    ``rows[0]``), as Bullet's joint reaction is reported.
    """
    load = np.empty(6)
    payload_load(rows, payload, dt, True, memory, load)
    c0x, c0y, c0z = rows[0, COM], rows[0, COM + 1], rows[0, COM + 2]
    fx, fy, fz = applied[0], applied[1], applied[2]
    w = (load[0] - fx, load[1] - fy, load[2] - fz,  # moments of ``applied`` moved to the sensor origin
         load[3] - (applied[3] - (c0y * fz - c0z * fy)), load[4] - (applied[4] - (c0z * fx - c0x * fz)),
         load[5] - (applied[5] - (c0x * fy - c0y * fx)))
    r = np.empty(9)
    rotation_matrix(rows[0, COM_QUAT], rows[0, COM_QUAT + 1], rows[0, COM_QUAT + 2], rows[0, COM_QUAT + 3], r)
    for i in range(3):  # world -> sensor frame: R^T
        out[i] = r[i] * w[0] + r[3 + i] * w[1] + r[6 + i] * w[2]
        out[3 + i] = r[i] * w[3] + r[3 + i] * w[4] + r[6 + i] * w[5]


@njit(cache=True, error_model="numpy")
def sensor_reading(rows, payload, reaction, dt, compensate, due, tare, offset, memory, out):
    """One physics step of a wrist F/T sensor.

    rows (k, ROW): link states of the tool side, the sensor's own link first (its CoM frame is the
    sensor frame); payload: the tool side's bodies (:class:`Payload`); reaction (6,): the joint's
    reaction wrench as Bullet reports it (what the arm applies to the tool side, sensor frame, moments
    about the sensor frame's origin); dt [s]: the physics step; compensate: remove the payload's
    inertia too (:func:`payload_load`; its weight is always removed, at any orientation); memory: the
    payload's momenta one call ago (:class:`SensorMemory`, updated every call); due: a sample is taken
    now (else only the memory is updated); tare (6,): the sensor's own offset, subtracted (what it read
    unloaded at the tare); offset (6,): bias plus this sample's noise [N, N m]. When due, writes into
    ``out`` (12,) the load on the tool side: [f, m] in the sensor frame, then f and m in the world
    frame. Returns ``due``.
    """
    load = out[6:12]  # scratch until the reading is written
    payload_load(rows, payload, dt, compensate, memory, load)
    if not due:
        return False
    lfx, lfy, lfz, lmx, lmy, lmz = load[0], load[1], load[2], load[3], load[4], load[5]
    r = out[0:9]  # scratch: the rotation, sensor frame -> world, before the reading overwrites it
    rotation_matrix(rows[0, COM_QUAT], rows[0, COM_QUAT + 1], rows[0, COM_QUAT + 2], rows[0, COM_QUAT + 3], r)
    r0, r1, r2, r3, r4, r5, r6, r7, r8 = r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]
    # the load on the tool side: the payload's own (turned into the sensor frame) minus what the arm applies
    fx = r0 * lfx + r3 * lfy + r6 * lfz - reaction[0] - tare[0] + offset[0]
    fy = r1 * lfx + r4 * lfy + r7 * lfz - reaction[1] - tare[1] + offset[1]
    fz = r2 * lfx + r5 * lfy + r8 * lfz - reaction[2] - tare[2] + offset[2]
    mx = r0 * lmx + r3 * lmy + r6 * lmz - reaction[3] - tare[3] + offset[3]
    my = r1 * lmx + r4 * lmy + r7 * lmz - reaction[4] - tare[4] + offset[4]
    mz = r2 * lmx + r5 * lmy + r8 * lmz - reaction[5] - tare[5] + offset[5]
    out[0], out[1], out[2], out[3], out[4], out[5] = fx, fy, fz, mx, my, mz
    out[6] = r0 * fx + r1 * fy + r2 * fz
    out[7] = r3 * fx + r4 * fy + r5 * fz
    out[8] = r6 * fx + r7 * fy + r8 * fz
    out[9] = r0 * mx + r1 * my + r2 * mz
    out[10] = r3 * mx + r4 * my + r5 * mz
    out[11] = r6 * mx + r7 * my + r8 * mz
    return True


@njit(cache=True, error_model="numpy")
def load_mismatch(rows, reading, offset, force, torque, point, held, t, worst, worst_t, sumsq):
    """How far a wrist reading is from the load the cable applied to the gripper in the same step.

    rows (k, ROW): the sensor's link states (row 0: the sensor frame); reading (12,): the sensor's
    output (:func:`sensor_reading`); offset (6,): the bias and noise in it [N, N m], sensor frame;
    force [N], torque [N m] (3,): what the cable applied to the grasp link, world frame, the force at
    ``point`` [m] (3,), if ``held`` (else nothing was applied). The reading without its offset minus
    that load, world frame, force [N] and moment about the sensor frame's origin [N m]: its largest
    component of each raises ``worst`` (2,) (force, moment), the time ``t`` [s] going into ``worst_t`` (2,);
    the squared length of each mismatch is added to ``sumsq`` (2,).
    """
    r = np.empty(9)
    rotation_matrix(rows[0, COM_QUAT], rows[0, COM_QUAT + 1], rows[0, COM_QUAT + 2], rows[0, COM_QUAT + 3], r)
    s = 1.0 if held else 0.0
    fx, fy, fz = s * force[0], s * force[1], s * force[2]
    dx, dy, dz = point[0] - rows[0, COM], point[1] - rows[0, COM + 1], point[2] - rows[0, COM + 2]
    applied = (fx, fy, fz, s * torque[0] + dy * fz - dz * fy, s * torque[1] + dz * fx - dx * fz,
               s * torque[2] + dx * fy - dy * fx)
    for i in range(3):
        f_off = r[3 * i] * offset[0] + r[3 * i + 1] * offset[1] + r[3 * i + 2] * offset[2]
        m_off = r[3 * i] * offset[3] + r[3 * i + 1] * offset[4] + r[3 * i + 2] * offset[5]
        for kind, off in ((0, f_off), (1, m_off)):
            err = abs(reading[6 + 3 * kind + i] - off - applied[3 * kind + i])
            sumsq[kind] += err * err
            if err > worst[kind]:
                worst[kind], worst_t[kind] = err, t


@njit(cache=True, error_model="numpy")
def wrist_pair(rows, tools, tool_memories, applied, reactions, payloads, dt, compensate, due, tares, offsets,
               memories, outs, force, torque, point, held, fill, t, worst, worst_t, sumsq, sampled):
    """Both wrist sensors of a dual-arm step in one call: per arm a, :func:`tool_reaction` then
    :func:`sensor_reading` and, when it sampled, :func:`load_mismatch` against the cable's load, the same
    arithmetic as the three calls one by one (bit for bit), without Python between them.

    Per-arm arguments are tuples of two (rows, tools, tool_memories, payloads, memories) or arrays with the
    arm first (applied (2, 6), reactions (2, 6), compensate (2,), due (2,), tares, offsets (2, 6), outs
    (2, 12), force, torque, point (2, 3), held (2,), worst, worst_t, sumsq (2, 2)); ``sampled`` (2,) gets
    whether each sensor sampled. Units as in those kernels. With ``fill[a]`` the cable's load on the tool
    side is written into ``applied[a]`` first (force [N] at ``point[a]``, clamp torque, moment about the world
    origin: ``torque + point x force``, the arithmetic of ``robots.transforms.cross3``; zero if not
    ``held[a]``); else the caller wrote it (with Bullet's contacts added).
    """
    for a in range(2):
        if fill[a]:
            ld, f, p = applied[a], force[a], point[a]
            if held[a]:
                ld[0], ld[1], ld[2] = f[0], f[1], f[2]
                ld[3] = torque[a, 0] + (p[1] * f[2] - p[2] * f[1])
                ld[4] = torque[a, 1] + (p[2] * f[0] - p[0] * f[2])
                ld[5] = torque[a, 2] + (p[0] * f[1] - p[1] * f[0])
            else:
                ld[:] = 0.0
        tool_reaction(rows[a], tools[a], dt, tool_memories[a], applied[a], reactions[a])
        sampled[a] = sensor_reading(rows[a], payloads[a], reactions[a], dt, compensate[a], due[a], tares[a],
                                    offsets[a], memories[a], outs[a])
        if sampled[a]:
            load_mismatch(rows[a], outs[a], offsets[a], force[a], torque[a], point[a], held[a], t, worst[a],
                          worst_t[a], sumsq[a])
