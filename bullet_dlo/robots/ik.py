"""Forward and inverse kinematics of an arm's URDF chain in compiled code (Numba), without PyBullet.

PyBullet's IK needs a body whose joints are the seed: :meth:`~bullet_dlo.robots.arm.Robot.track`
used to set a kinematic twin's joints and call ``calculateInverseKinematics`` (about 135 us per arm
per control step, mostly Python wrapping). Here the chain from the world to the grasp frame is read
once from a PyBullet body (:func:`chain_of`): per movable joint, the fixed transform from the
previous movable joint's frame (the world for the first) to its own frame at zero angle, and its
axis in its own frame (URDF: the child link's frame is the joint frame, the joint turns about the
axis through its origin); then a fixed tail to the grasp link. Fixed joints in between fold into
those transforms. :func:`forward` gives the grasp frame and the geometric Jacobian,
:func:`solve_dls` the damped least-squares IK, clipped to the joint limits at every iteration.

Checked against PyBullet (``tests/robots/test_ik.py``): the forward kinematics against the body's
``getLinkState`` at random joint angles (to rounding, 1e-12 m), the IK's reached pose against
``calculateInverseKinematics`` on the twin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.kernels import bind
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.validate import ParameterError


@dataclass(frozen=True)
class Chain:
    """A serial chain of revolute joints, world to grasp frame (all lengths [m], angles [rad]).

    origin_pos (k, 3), origin_rot (k, 3, 3): joint i's frame at zero angle in joint i-1's frame (the
    world for i = 0); axis (k, 3): joint i's unit axis in its own frame; tail_pos (3,), tail_rot (3, 3):
    the grasp frame in the last joint's frame; lower, upper (k,): joint limits.
    """

    origin_pos: np.ndarray
    origin_rot: np.ndarray
    axis: np.ndarray
    tail_pos: np.ndarray
    tail_rot: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def _frame(state) -> tuple[np.ndarray, np.ndarray]:
    """World position [m] and rotation matrix of a link frame from a getLinkState answer."""
    return np.array(state[4]), np.array(pb.getMatrixFromQuaternion(state[5])).reshape(3, 3)


def chain_of(client: int, body: int, joints, tip_link: int, lower, upper) -> Chain:
    """The chain of ``body`` (a fixed-base PyBullet body in ``client``) through the revolute ``joints``
    (indices, base to tip) to link ``tip_link``, read at zero joint angles (the body's joints are put
    back afterwards). ParameterError if a joint is not revolute or the joints are not one chain to the tip."""
    joints = [int(j) for j in joints]
    saved = [s[0] for s in pb.getJointStates(body, joints, physicsClientId=client)]
    parents = {j: pb.getJointInfo(body, j, physicsClientId=client)[16]
               for j in range(pb.getNumJoints(body, physicsClientId=client))}
    # every movable joint must be an ancestor of the next one (and the last of the tip): one serial chain
    for a, b in zip(joints, joints[1:] + [tip_link]):
        up = b
        while up != -1 and up != a:
            up = parents[up]
        if up != a:
            raise ParameterError(f"joints {joints} and link {tip_link} are not one serial chain")
    axes = []
    for j in joints:
        info = pb.getJointInfo(body, j, physicsClientId=client)
        if info[2] != pb.JOINT_REVOLUTE:
            raise ParameterError(f"joint {info[1].decode()!r} is not revolute; the compiled IK handles revolute chains")
        axis = np.array(info[13], dtype=float)
        axes.append(axis / np.linalg.norm(axis))
    try:
        for j in joints:
            pb.resetJointState(body, j, 0.0, physicsClientId=client)
        frames = [_frame(pb.getLinkState(body, j, computeForwardKinematics=True, physicsClientId=client))
                  for j in joints + [tip_link]]
    finally:
        for j, q in zip(joints, saved):
            pb.resetJointState(body, j, q, physicsClientId=client)
    pos, rot = [], []
    prev_p, prev_r = np.zeros(3), np.eye(3)
    for p, r in frames:
        pos.append(prev_r.T @ (p - prev_p))
        rot.append(prev_r.T @ r)
        prev_p, prev_r = p, r
    return Chain(np.array(pos[:-1]), np.array(rot[:-1]), np.array(axes), pos[-1], rot[-1],
                 np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))


@njit(cache=True)
def _axis_rotation(axis, angle, out):
    """Rotation matrix of ``angle`` [rad] about unit ``axis`` (Rodrigues) into ``out`` (3, 3)."""
    x, y, z = axis[0], axis[1], axis[2]
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    out[0, 0] = c + x * x * t
    out[0, 1] = x * y * t - z * s
    out[0, 2] = x * z * t + y * s
    out[1, 0] = y * x * t + z * s
    out[1, 1] = c + y * y * t
    out[1, 2] = y * z * t - x * s
    out[2, 0] = z * x * t - y * s
    out[2, 1] = z * y * t + x * s
    out[2, 2] = c + z * z * t


@njit(cache=True)
def forward(origin_pos, origin_rot, axis, tail_pos, tail_rot, q, pos, rot, jac):
    """Grasp frame at joint angles q (k,): position [m] into ``pos`` (3,), rotation into ``rot`` (3, 3);
    the geometric Jacobian into ``jac`` (6, k): rows 0:3 d(position)/dq [m/rad], rows 3:6 the angular
    velocity per joint rate [-], world frame. No allocation but two 3x3 scratch matrices."""
    k = q.shape[0]
    turn = np.empty((3, 3))
    tmp = np.empty((3, 3))
    for a in range(3):  # pos, rot: the world frame
        pos[a] = 0.0
        for b in range(3):
            rot[a, b] = 1.0 if a == b else 0.0
    for i in range(k):
        for a in range(3):
            pos[a] += rot[a, 0] * origin_pos[i, 0] + rot[a, 1] * origin_pos[i, 1] + rot[a, 2] * origin_pos[i, 2]
        _mul(rot, origin_rot[i], tmp)
        for a in range(3):
            jac[a, i] = pos[a]  # the joint's origin, for the Jacobian below
            jac[3 + a, i] = tmp[a, 0] * axis[i, 0] + tmp[a, 1] * axis[i, 1] + tmp[a, 2] * axis[i, 2]
        _axis_rotation(axis[i], q[i], turn)
        _mul(tmp, turn, rot)
    for a in range(3):
        pos[a] += rot[a, 0] * tail_pos[0] + rot[a, 1] * tail_pos[1] + rot[a, 2] * tail_pos[2]
    _mul(rot, tail_rot, tmp)
    rot[:, :] = tmp
    for i in range(k):
        ax, ay, az = jac[3, i], jac[4, i], jac[5, i]
        dx, dy, dz = pos[0] - jac[0, i], pos[1] - jac[1, i], pos[2] - jac[2, i]
        jac[0, i] = ay * dz - az * dy
        jac[1, i] = az * dx - ax * dz
        jac[2, i] = ax * dy - ay * dx


@njit(cache=True)
def _mul(a, b, out):
    """out = a @ b for 3x3 matrices (out distinct from both)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@njit(cache=True)
def rotation_error(target, rot, out):
    """Rotation vector [rad] (3,) that turns ``rot`` into ``target`` (both (3, 3)), world frame, into ``out``."""
    e = target @ rot.T
    vx, vy, vz = e[2, 1] - e[1, 2], e[0, 2] - e[2, 0], e[1, 0] - e[0, 1]  # 2 sin(angle) * axis
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    c = e[0, 0] + e[1, 1] + e[2, 2] - 1.0  # 2 cos(angle)
    angle = math.atan2(s, c)  # accurate at small angles too (acos of c / 2 is not)
    if c < 0.0 and s < 1e-6:  # near pi the antisymmetric part vanishes: the axis from the symmetric one
        bx = math.sqrt(max(0.0, 0.5 * (e[0, 0] + 1.0)))
        by = math.copysign(math.sqrt(max(0.0, 0.5 * (e[1, 1] + 1.0))), e[0, 1] + e[1, 0])
        bz = math.copysign(math.sqrt(max(0.0, 0.5 * (e[2, 2] + 1.0))), e[0, 2] + e[2, 0])
        out[0], out[1], out[2] = angle * bx, angle * by, angle * bz
        return
    scale = angle / s if s > 0.0 else 0.5
    out[0], out[1], out[2] = scale * vx, scale * vy, scale * vz


@njit(cache=True)
def solve_dls(origin_pos, origin_rot, axis, tail_pos, tail_rot, lower, upper, target_pos, target_rot, q0,
              damping, iterations, tol_pos, tol_rot, q_out):
    """Damped least-squares IK from joint angles ``q0`` (k,) to the grasp pose ``target_pos`` [m] (3,),
    ``target_rot`` (3, 3): ``q += J^T (J J^T + damping^2 I)^-1 e`` with e = (position error [m], rotation
    vector [rad]), clipped to [lower, upper] after every iteration, until |e_pos| < ``tol_pos`` [m] and
    |e_rot| < ``tol_rot`` [rad] or ``iterations`` iterations. Writes the angles into ``q_out`` (k,);
    returns the final position error [m] (its rotation error is left in the last 3 of the error)."""
    k = q0.shape[0]
    q = q0.copy()
    for i in range(k):
        q[i] = min(upper[i], max(lower[i], q[i]))
    pos = np.empty(3)
    rot = np.empty((3, 3))
    jac = np.empty((6, k))
    err = np.empty(6)
    rv = np.empty(3)
    chol = np.empty((6, 6))
    y = np.empty(6)
    err_p = 0.0
    for _ in range(iterations + 1):
        forward(origin_pos, origin_rot, axis, tail_pos, tail_rot, q, pos, rot, jac)
        for a in range(3):
            err[a] = target_pos[a] - pos[a]
        rotation_error(target_rot, rot, rv)
        err[3:] = rv
        err_p = math.sqrt(err[0] ** 2 + err[1] ** 2 + err[2] ** 2)
        err_r = math.sqrt(err[3] ** 2 + err[4] ** 2 + err[5] ** 2)
        if err_p < tol_pos and err_r < tol_rot:
            break
        # (J J^T + damping^2 I) y = e by Cholesky (symmetric positive definite, 6x6), then dq = J^T y
        for a in range(6):
            for b in range(a + 1):
                acc = 0.0
                for i in range(k):
                    acc += jac[a, i] * jac[b, i]
                chol[a, b] = acc + (damping * damping if a == b else 0.0)
        for a in range(6):
            for b in range(a + 1):
                acc = chol[a, b]
                for c in range(b):
                    acc -= chol[a, c] * chol[b, c]
                chol[a, b] = math.sqrt(acc) if a == b else acc / chol[b, b]
        for a in range(6):  # forward substitution L z = e
            acc = err[a]
            for c in range(a):
                acc -= chol[a, c] * y[c]
            y[a] = acc / chol[a, a]
        for a in range(5, -1, -1):  # back substitution L^T y = z
            acc = y[a]
            for c in range(a + 1, 6):
                acc -= chol[c, a] * y[c]
            y[a] = acc / chol[a, a]
        for i in range(k):
            dq = 0.0
            for a in range(6):
                dq += jac[a, i] * y[a]
            q[i] = min(upper[i], max(lower[i], q[i] + dq))
    q_out[:] = q
    return err_p


class ChainIK:
    """The compiled IK of one arm: :func:`chain_of` once, then :meth:`solve` per call (a few microseconds).

    damping [m]: the DLS damping (small: the targets are near the current pose); tol_pos [m], tol_rot [rad]:
    when to stop; iterations: at most this many DLS steps per solve.
    """

    def __init__(self, chain: Chain, damping: float = 1e-3, iterations: int = 50, tol_pos: float = 1e-9,
                 tol_rot: float = 1e-8):
        self.chain = chain
        self.damping, self.iterations, self.tol_pos, self.tol_rot = damping, iterations, tol_pos, tol_rot
        self._rot = np.empty((3, 3))
        self._pos = np.empty(3)
        self._out = np.empty(len(chain.lower))
        self._q0 = np.empty(len(chain.lower))
        self.error = 0.0  # position error [m] of the last solve
        c = chain
        self._args = (c.origin_pos, c.origin_rot, c.axis, c.tail_pos, c.tail_rot, c.lower, c.upper, self._pos,
                      self._rot, self._q0, float(damping), int(iterations), float(tol_pos), float(tol_rot), self._out)
        self._solve = bind(solve_dls, *self._args)  # no per-call type dispatch (15 arguments: ~10 us)

    def solve(self, position, quat, q0: np.ndarray) -> np.ndarray:
        """Joint angles [rad] (k,) putting the grasp frame at ``position`` [m] with quaternion ``quat``
        [x, y, z, w], from ``q0``; within the limits. A new array."""
        self._pos[:] = position
        self._rot.flat[:] = pb.getMatrixFromQuaternion(quat)
        self._q0[:] = q0
        self.error = self._solve(*self._args)
        return self._out.copy()

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Grasp frame position [m] (3,) and rotation matrix (3, 3) at joint angles q [rad]."""
        c = self.chain
        pos, rot, jac = np.empty(3), np.empty((3, 3)), np.empty((6, len(c.lower)))
        forward(c.origin_pos, c.origin_rot, c.axis, c.tail_pos, c.tail_rot, np.asarray(q, dtype=float), pos, rot, jac)
        return pos, rot
