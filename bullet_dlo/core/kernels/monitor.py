"""Numba kernels of the instability detector and the end-force read-out.

Cheap checks (every ``check_every`` steps): finite state, segment strain within bound.
Energy check (every ``energy_every`` steps): E(t) - E(0) - W_holders(t) <= factor * E_scale,
with E the mechanical energy (plus, in contact, the energy stored in the contacts minus the work
of the touched bodies), W the work the held ends did on the cable (trapezoid rule on end
force times held-end displacement, and on clamp moment times the turn of the clamp direction,
between energy checks) and E_scale a floor plus sum |dW|. A turning clamp does work through its
moment alone: leaving that term out made a zero-gravity run whose clamp turns "create" energy
(issue 21). A clamp that rolls about its own axis does work on a twisting cable (material frame,
issue 22) through the torsion moment about that axis, which the turn of the direction does not
see: that work is summed at every step (:func:`roll_work`), so that a gripper rolled by half a turn
is not reported as energy created from nothing. See :mod:`bullet_dlo.core.engine` for the thresholds and the floor.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.forces import clamp_torque, max_strain, mechanical_energy, total_forces
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.twist import has_twist, transport, twist_clamp_torque

STABLE, NONFINITE, STRETCH, ENERGY = 0, 1, 2, 3
STALLED = 4  # set by the Bullet coupling (bullet.kernels.StallGuard), not by monitor()
BODY_ENERGY = 5  # set by the Bullet coupling (bullet.body_energy), not by monitor()
REASONS = {STABLE: None, NONFINITE: "non-finite state", STRETCH: "segment strain beyond bound",
           ENERGY: "energy growth beyond the work done on the cable",
           STALLED: "contact Newton stalled far from convergence, also in sub-steps",
           BODY_ENERGY: "a body gained energy from contact beyond the work the cable's step did on it"}


class Detector(NamedTuple):
    """Detector thresholds and its running energy balance (the arrays change during a run).

    max_strain: largest allowed |l/l0 - 1|; energy_factor: allowed energy created, in units of
    the energy scale; check_every, energy_every: steps between cheap checks / energy checks;
    e0: mechanical energy at the start [J]; work: work the holders did on the cable so far
    [J], (1,); scale: energy scale, floor + sum |dW| [J], (1,); end_force: end forces at the
    last energy check [N], (2, 3); hold_pos: held-end positions then [m], (2, 3);
    end_moment: clamp moments the cable exerted then [N m], (2, 3); hold_dir: clamp directions
    then (unit), (2, 3).
    """

    max_strain: float
    energy_factor: float
    check_every: int
    energy_every: int
    e0: float
    work: np.ndarray
    scale: np.ndarray
    end_force: np.ndarray
    hold_pos: np.ndarray
    end_moment: np.ndarray
    hold_dir: np.ndarray


@njit(cache=True, error_model="numpy")
def end_forces(m, x, v, dirs, acc, out):
    """Force [N] the cable exerts on each held end, (2, 3) into ``out``: F_node - m a (0 if free).

    F_node is everything acting on the held node except the holder (elastic incl. clamp spring,
    gravity, damping, external) with clamp directions ``dirs`` and held-end accelerations ``acc``
    [m/s^2] (both (2, 3)); for a static cable the two rows sum to M g.
    """
    n = x.shape[0]
    f = np.empty_like(x)
    total_forces(m, x, v, dirs, f)
    out[:, :] = 0.0
    if m.held[0]:
        out[0, :] = f[0] - m.mass[0] * acc[0]
    if m.held[n - 1]:
        out[1, :] = f[n - 1] - m.mass[n - 1] * acc[1]


@njit(cache=True, error_model="numpy")
def clamp_moments(m, x, v, dirs, out):
    """Moment [N m] the cable exerts on each clamp, (2, 3) into ``out`` (0 where the end is not clamped)."""
    for e in range(2):
        out[e, :] = clamp_torque(m, x, v, dirs, e)


@njit(cache=True, error_model="numpy")
def check_state(m, x, v, strain_bound):
    """The cheap checks: finite state, every segment strain within ``strain_bound``."""
    for i in range(x.shape[0]):
        for j in range(3):
            if not (math.isfinite(x[i, j]) and math.isfinite(v[i, j])):
                return NONFINITE
    if not max_strain(m, x) <= strain_bound:
        return STRETCH
    return STABLE


@njit(cache=True, error_model="numpy")
def roll_work(m, x, samples, det):
    """Add to ``det``'s balance the work [J] the clamps did on a twisting cable by rolling about their axis
    during the step: the roll (angle about the new direction d from the section axis at t, carried by the
    minimal rotation onto d, to the one at t + h) times the torsion moment about d at t + h."""
    carried = np.empty(3)
    for e in range(2):
        d = samples.dir[2, e]
        transport(m.tw_normal[0, e], samples.dir[0, e], d, carried)
        n1 = m.tw_normal[2, e]
        cross_d = ((carried[1] * n1[2] - carried[2] * n1[1]) * d[0] + (carried[2] * n1[0] - carried[0] * n1[2]) * d[1]
                   + (carried[0] * n1[1] - carried[1] * n1[0]) * d[2])
        roll = math.atan2(cross_d, carried[0] * n1[0] + carried[1] * n1[1] + carried[2] * n1[2])
        if roll == 0.0:
            continue
        tq = twist_clamp_torque(m, x, samples.dir[2], e)
        dw = -(tq[0] * d[0] + tq[1] * d[1] + tq[2] * d[2]) * roll
        det.work[0] += dw
        det.scale[0] += abs(dw)


@njit(cache=True, error_model="numpy")
def monitor(m, x, v, samples, det, energy_check, extra=0.0):
    """Status (STABLE, ...) of the state (x, v) at the end of a step (held-end sample 2).

    With ``energy_check`` also updates the energy balance in ``det``: end forces and clamp moments
    now, the holders' work since the last energy check (force times displacement plus moment
    times the turn d_prev x d_now of the clamp direction), then the check itself. ``extra`` [J] joins the
    cable's mechanical energy in the balance: for a cable in contact, the energy stored in the
    contact springs minus the work the touched bodies did on the cable (counting contact force
    times displacement as external work instead would hide a blow-up inside a contact).
    """
    status = check_state(m, x, v, det.max_strain)
    if has_twist(m):
        roll_work(m, x, samples, det)
    if not energy_check:
        return status
    f_now = np.empty((2, 3))
    end_forces(m, x, v, samples.dir[2], samples.acc[2], f_now)
    for e in range(2):
        for j in range(3):
            dw = -0.5 * (f_now[e, j] + det.end_force[e, j]) * (samples.pos[2, e, j] - det.hold_pos[e, j])
            det.work[0] += dw
            det.scale[0] += abs(dw)
    m_now = np.empty((2, 3))
    clamp_moments(m, x, v, samples.dir[2], m_now)
    for e in range(2):
        d0, d1 = det.hold_dir[e], samples.dir[2, e]
        turn = (d0[1] * d1[2] - d0[2] * d1[1], d0[2] * d1[0] - d0[0] * d1[2], d0[0] * d1[1] - d0[1] * d1[0])
        for j in range(3):
            dw = -0.5 * (m_now[e, j] + det.end_moment[e, j]) * turn[j]
            det.work[0] += dw
            det.scale[0] += abs(dw)
    det.hold_pos[:, :] = samples.pos[2]
    det.end_force[:, :] = f_now
    det.hold_dir[:, :] = samples.dir[2]
    det.end_moment[:, :] = m_now
    if status != STABLE:
        return status
    e = mechanical_energy(m, x, v, samples.dir[2]) + extra
    if not (e - det.e0 - det.work[0] <= det.energy_factor * det.scale[0]):
        return ENERGY
    return STABLE
