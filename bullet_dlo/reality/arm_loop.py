"""The arm-strip loop's time steps in one compiled call (:func:`bullet_dlo.reality.beam_arm.predict_torques_compliant`).

Per step of h [s] (the module doc of :mod:`bullet_dlo.reality.beam_arm`): the arm's deviation delta on its compliant
joints takes a Newmark step (average acceleration) under the joint torques of the strip's clamp load at t and the
prescribed ones; the strip's held end at t, t + h/2, t + h is its reference pose moved by J(q_ref) delta (first
order in delta); the strip steps; its clamp load at t + h becomes the next step's torque. In Python this loop cost
about 4x the strip's own step (arrays of 3 to 7 numbers handled one call at a time).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.holders import sample_holders
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.monitor import clamp_moments, end_forces
from bullet_dlo.core.kernels.steppers import advance

RUNNING, STRIP_UNSTABLE, ARM_UNSTABLE = 0, 1, 2


class Arm(NamedTuple):
    """The compliant joints idx (nc,) of the 7, their joint-space inertia along the reference rows mass [kg m^2]
    (k, nc, nc), diagonal stiffness [N m/rad] and damping [N m s/rad] (nc,), the deviation's state q [rad],
    v [rad/s], a [rad/s^2] (nc,), and max_deviation [rad] (a larger |q| is an unstable loop)."""

    idx: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    max_deviation: float


class Coupling(NamedTuple):
    """How the strip and the arm meet, per reference row (every ``row_dt`` s): the flange Jacobian jac (k, 6, 7);
    drive [N m] (k, 7), the prescribed joint torques (a prescribed strong plane, a clamp payload, minus the
    substituted real strip's); the projectors of the stepped strip run (3, 3): translate and rotate (flange motion
    -> its clamp), force and moment (its clamp load -> the flange); lever [m] (3,), flange origin -> clamp; tau0
    [N m] (7,), the stepped run's torque at rest; row_dt [s]."""

    jac: np.ndarray
    drive: np.ndarray
    translate: np.ndarray
    rotate: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    lever: np.ndarray
    tau0: np.ndarray
    row_dt: float


class Law(NamedTuple):
    """The amplitude-dependent damping zeta = c A in the strip's bending dampers
    (:class:`bullet_dlo.reality.beam_law.AmplitudeDamping` builds it): par [slope c 1/m, omega_1 rad/s, tau0 s,
    amplitude A m, smoothing periods], (5,) (slope 0: no law); deflection [m], (2, 3): the tip's deflection from
    the clamp's tangent line at rest and at the last step; k_bend [N m/rad^2] (n,), the dampers' pattern."""

    par: np.ndarray
    deflection: np.ndarray
    k_bend: np.ndarray


class LoopRecords(NamedTuple):
    """Every ``every`` steps: the stepped run's flange wrench w [N, N m] (k, 6), the deviation dev [rad] and its
    acceleration acc [rad/s^2] (k, 7), the strip's tip [m] (k, 3); out [status, failed Newton steps, t at a stop
    s], (3,)."""

    w: np.ndarray
    dev: np.ndarray
    acc: np.ndarray
    tip: np.ndarray
    out: np.ndarray


@njit(cache=True, error_model="numpy")
def _turn(d, rv):
    """d (3,) turned in place by the rotation vector rv [rad] (3,) (Rodrigues' formula), then normalised."""
    angle = math.sqrt(rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2])
    dx, dy, dz = d[0], d[1], d[2]
    if angle > 0.0:
        kx, ky, kz = rv[0] / angle, rv[1] / angle, rv[2] / angle
        c, s = math.cos(angle), math.sin(angle)
        kd = (kx * dx + ky * dy + kz * dz) * (1.0 - c)
        dx, dy, dz = (dx * c + (ky * dz - kz * dy) * s + kx * kd, dy * c + (kz * dx - kx * dz) * s + ky * kd,
                      dz * c + (kx * dy - ky * dx) * s + kz * kd)
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    d[0], d[1], d[2] = dx / norm, dy / norm, dz / norm


@njit(cache=True, error_model="numpy")
def newmark_step(arm, tau, row, h):
    """The deviation from t to t + h under joint torques tau [N m] (7,) held over the step, the inertia of ``row``."""
    nc = arm.idx.shape[0]
    if nc == 0:
        return
    s = arm.mass[row].copy()
    rhs = np.empty(nc)
    for i in range(nc):
        k, d = arm.stiffness[i], arm.damping[i]
        s[i, i] += 0.5 * h * d + 0.25 * h * h * k
        rhs[i] = (tau[arm.idx[i]] - d * (arm.v[i] + 0.5 * h * arm.a[i])
                  - k * (arm.q[i] + h * arm.v[i] + 0.25 * h * h * arm.a[i]))
    a1 = np.linalg.solve(s, rhs)
    for i in range(nc):
        arm.q[i] += h * arm.v[i] + 0.25 * h * h * (arm.a[i] + a1[i])
        arm.v[i] += 0.5 * h * (arm.a[i] + a1[i])
        arm.a[i] = a1[i]


@njit(cache=True, error_model="numpy")
def law_update(law, m, x, direction, h):
    """After a step of h [s] to x [m] (n, 3), the clamp's tangent ``direction``: the amplitude estimate
    A = sqrt(|e - e_rest|^2 + |de/dt|^2 / omega_1^2) (e the tip's deflection from the tangent line; exact for the
    first mode alone), low-passed over the smoothing periods, and the bending dampers for the next step,
    c_bend = k_bend (tau0 + 2 c A / omega_1) (in ``m.c_bend``)."""
    par, e_rest, e_prev = law.par, law.deflection[0], law.deflection[1]
    omega = par[1]
    norm = math.sqrt(direction[0] ** 2 + direction[1] ** 2 + direction[2] ** 2)
    d0, d1, d2 = direction[0] / norm, direction[1] / norm, direction[2] / norm
    r0, r1, r2 = x[-1, 0] - x[0, 0], x[-1, 1] - x[0, 1], x[-1, 2] - x[0, 2]
    along = r0 * d0 + r1 * d1 + r2 * d2
    e0, e1, e2 = r0 - along * d0, r1 - along * d1, r2 - along * d2
    v0, v1, v2 = (e0 - e_prev[0]) / h, (e1 - e_prev[1]) / h, (e2 - e_prev[2]) / h
    e_prev[0], e_prev[1], e_prev[2] = e0, e1, e2
    q0, q1, q2 = e0 - e_rest[0], e1 - e_rest[1], e2 - e_rest[2]
    raw = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + (v0 * v0 + v1 * v1 + v2 * v2) / (omega * omega))
    alpha = min(1.0, h * omega / (2.0 * math.pi * par[4]))
    par[3] += alpha * (raw - par[3])
    tau = par[2] + 2.0 * par[0] * par[3] / omega
    for i in range(m.c_bend.shape[0]):
        m.c_bend[i] = law.k_bend[i] * tau


@njit(cache=True, error_model="numpy")
def _wrench(cp, force, moment, out):
    """out (6,) <- the stepped run's clamp load (its share) as a wrench about the flange origin [N, N m]."""
    p, q, arm = cp.force, cp.moment, cp.lever
    f0 = p[0, 0] * force[0] + p[0, 1] * force[1] + p[0, 2] * force[2]
    f1 = p[1, 0] * force[0] + p[1, 1] * force[1] + p[1, 2] * force[2]
    f2 = p[2, 0] * force[0] + p[2, 1] * force[1] + p[2, 2] * force[2]
    out[0], out[1], out[2] = f0, f1, f2
    out[3] = q[0, 0] * moment[0] + q[0, 1] * moment[1] + q[0, 2] * moment[2] + arm[1] * f2 - arm[2] * f1
    out[4] = q[1, 0] * moment[0] + q[1, 1] * moment[1] + q[1, 2] * moment[2] + arm[2] * f0 - arm[0] * f2
    out[5] = q[2, 0] * moment[0] + q[2, 1] * moment[1] + q[2, 2] * moment[2] + arm[0] * f1 - arm[1] * f0


@njit(cache=True, error_model="numpy")
def _project(p, y, off, out):
    """out (3,) <- p (3, 3) times y[off:off + 3]."""
    for i in range(3):
        out[i] = p[i, 0] * y[off] + p[i, 1] * y[off + 1] + p[i, 2] * y[off + 2]


@njit(cache=True, error_model="numpy")
def _flange_motion(jac, dq, out):
    """out (6,) <- jac (6, 7) times dq (7,): the flange's displacement and rotation vector [m, rad]."""
    for i in range(6):
        acc = 0.0
        for k in range(7):
            acc += jac[i, k] * dq[k]
        out[i] = acc


@njit(cache=True, error_model="numpy")
def run_arm_loop(stepper, m, plan, smp, x, v, ws, arm, cp, law, rec, n_steps, every):
    """``n_steps`` steps of the arm-strip loop (module doc) from t = 0, in place; records in ``rec`` (row 0 is the
    caller's). m, plan, smp, x, v, ws: the stepped strip run (kernel arrays, holder plan, samples, state,
    workspace); arm: :class:`Arm`; cp: :class:`Coupling`; law: :class:`Law`. Stops at a non-finite strip state or
    a deviation beyond ``arm.max_deviation`` (``rec.out``)."""
    h = stepper.h
    k_rows = cp.jac.shape[0]
    nc = arm.idx.shape[0]
    force, moment = np.empty((2, 3)), np.empty((2, 3))  # (each step's, written after its strip step)
    w = np.empty(6)
    tau_now = np.zeros(7)  # the strip's torque on the arm, deviation from rest: none before the first step
    tau = np.empty(7)
    full = np.zeros((2, 3, 7))  # the deviation before and after the step: q, v, a on all 7 joints
    dq = np.empty((3, 7))  # the deviation at a sample: q, v, a [rad, rad/s, rad/s^2]
    dx = np.empty((3, 6))  # the flange's displacement, velocity, acceleration from it [m, rad, ...]
    moved = np.empty(3)
    section = plan.normal
    failures = 0
    for step in range(n_steps):
        t = step * h
        row = min(int(t / cp.row_dt + 1e-9), k_rows - 1)
        for j in range(7):
            tau[j] = -(tau_now[j] + cp.drive[row, j])
        for i in range(nc):
            full[0, 0, arm.idx[i]], full[0, 1, arm.idx[i]], full[0, 2, arm.idx[i]] = arm.q[i], arm.v[i], arm.a[i]
        newmark_step(arm, tau, min(int((t + h) / cp.row_dt + 1e-9), k_rows - 1), h)
        for i in range(nc):
            full[1, 0, arm.idx[i]], full[1, 1, arm.idx[i]], full[1, 2, arm.idx[i]] = arm.q[i], arm.v[i], arm.a[i]
        sample_holders(plan, t, h, smp)
        r = row
        for s in range(3):  # the clamp moved by the arm's deviation (first order in it)
            r = min(int((t + 0.5 * s * h) / cp.row_dt + 1e-9), k_rows - 1)
            wgt = 0.5 * s
            for j in range(3):
                for k in range(7):
                    dq[j, k] = (1.0 - wgt) * full[0, j, k] + wgt * full[1, j, k]
                _flange_motion(cp.jac[r], dq[j], dx[j])
            _project(cp.translate, dx[0], 0, moved)
            for k in range(3):
                smp.pos[s, 0, k] += moved[k]
            _project(cp.translate, dx[1], 0, moved)
            for k in range(3):
                smp.vel[s, 0, k] += moved[k]
            _project(cp.translate, dx[2], 0, moved)
            for k in range(3):
                smp.acc[s, 0, k] += moved[k]
            _project(cp.rotate, dx[0], 3, moved)
            _turn(smp.dir[s, 0], moved)
            if section.shape[0]:  # the rectangle's section turns with its clamp
                _turn(section[s, 0], dx[0, 3:])
        its, ok = advance(stepper, m, x, v, smp, ws, step > 0)
        if not ok:
            failures += 1
        if law.par[0] > 0.0:
            law_update(law, m, x, smp.dir[2, 0], h)
        end_forces(m, x, v, smp.dir[2], smp.acc[2], force)
        clamp_moments(m, x, v, smp.dir[2], moment)
        rec.out[1] = failures
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(force))):
            rec.out[0], rec.out[2] = STRIP_UNSTABLE, t + h
            return
        _wrench(cp, force[0], moment[0], w)
        for k in range(7):  # Franka's external torque: -J^T w
            acc = 0.0
            for i in range(6):
                acc += cp.jac[r, i, k] * w[i]
            tau_now[k] = -acc - cp.tau0[k]
        for i in range(nc):
            if not abs(arm.q[i]) < arm.max_deviation:
                rec.out[0], rec.out[2] = ARM_UNSTABLE, t + h
                return
        if (step + 1) % every == 0:
            rec.w[r] = w
            rec.dev[r] = full[1, 0]
            rec.acc[r] = full[1, 2]
            rec.tip[r] = x[-1]
