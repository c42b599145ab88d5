"""Numba kernels of the Bullet coupling: plan a Bullet step with the core integrator, take it over.

One :func:`sync_and_advance` call per Bullet step (the step loop is overhead-bound, so the
sync, the stability check and the planning of the next step share one call). The stepping
order is written down in :mod:`bullet_dlo.bullet.cable`.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import numba
import numpy as np
from numba import njit

from bullet_dlo.core.kernels.contact import contact_energy, contact_step, grip_active
from bullet_dlo.core.kernels.forces import clamp_torque, mechanical_energy
from bullet_dlo.core.kernels.holders import ExternalHolders, HeldSamples, rotate, sample_end  # noqa: F401 (re-exported)
from bullet_dlo.core.kernels.monitor import STABLE, end_forces, monitor
from bullet_dlo.core.kernels.steppers import IMPLICIT_EULER, advance
from bullet_dlo.core.kernels.twist import set_clamp


class Coupling(NamedTuple):
    """A cable coupled to Bullet: the model's state and what the coming Bullet step needs.

    dt: Bullet step [s]; substeps: integrator steps per Bullet step; gravity: Bullet's gravity
    [m/s^2], (3,); x [m], v [m/s]: the model's state, (n, 3); v_bullet: Bullet's sphere
    velocities [m/s], (n, 3); x_new [m], v_new [m/s]: the state planned for the end of the coming
    Bullet step, (n, 3); force: sphere forces [N] that make Bullet land there, (n, 3);
    samples: held-end samples of the planned step's last substep (HeldSamples); end_force [N],
    end_torque [N m]: what the cable exerts on its held ends at the start of the planned step
    (:func:`end_loads`), (2, 3) each; energy [J] (1,): its mechanical energy then (written on
    recorded steps).
    """

    dt: float
    substeps: int
    gravity: np.ndarray
    x: np.ndarray
    v: np.ndarray
    v_bullet: np.ndarray
    x_new: np.ndarray
    v_new: np.ndarray
    force: np.ndarray
    samples: HeldSamples
    end_force: np.ndarray
    end_torque: np.ndarray
    energy: np.ndarray


class StepInput(NamedTuple):
    """What changes from one Bullet step to the next.

    t: time of the state the next step is planned from [s]; has_prev: the integrator's history
    (BDF2) is valid; sync: take over the step Bullet just made; check, energy_check: run the
    cheap / energy checks of the detector; record: this step is recorded (end loads and energy
    into the Coupling); touched_index: spheres that had contacts, (k,) int;
    touched_pos [m], touched_vel [m/s]: their state read back from Bullet, (k, 3).
    """

    t: float
    has_prev: bool
    sync: bool
    check: bool
    energy_check: bool
    record: bool
    touched_index: np.ndarray
    touched_pos: np.ndarray
    touched_vel: np.ndarray


def bind(kernel, *args) -> Callable:
    """``kernel``'s machine code for the argument types of ``args`` (compiled or loaded from cache now).

    Calling it skips Numba's per-call type dispatch, which for the ~60 arrays inside the
    NamedTuples of a Bullet step costs about 30 us, more than the step's own work at n = 10.
    The caller must keep passing arguments of exactly these types (BulletCable passes the same
    objects every step). With ``NUMBA_DISABLE_JIT=1`` the kernel is a plain Python function and
    is returned as it is.
    """
    if not hasattr(kernel, "compile"):  # JIT disabled: nothing to bind
        return kernel
    return kernel.compile(tuple(numba.typeof(a) for a in args))


@njit(cache=True, error_model="numpy")
def end_loads(m, x, v, samples, grip, out_force, out_torque):
    """What the cable exerts on each held end now (first, last): force [N] into ``out_force`` (2, 3), the
    reaction of a friction grip's force where one holds the end, and clamp torque [N m] into
    ``out_torque`` (2, 3) (zero rows for free ends). One call per coupled step: the grasp coupling
    applies both to the grippers."""
    end_forces(m, x, v, samples.dir[0], samples.acc[0], out_force)
    set_clamp(m, 0)  # a twisting cable's clamp axes at the time of dirs (no-op without a material frame)
    for e in range(2):
        if grip.active[e]:
            for j in range(3):
                out_force[e, j] = -grip.force[e, j]
        out_torque[e, :] = clamp_torque(m, x, v, samples.dir[0], e)
    set_clamp(m, 2)  # back to where the step left them (the energy check's)


@njit(cache=True, error_model="numpy")
def external_samples(ext, e, tau0, hs, samples, normal):
    """Held-end samples of end ``e`` at tau0 + (0, hs/2, hs) [s] after the measurement in ``ext``;
    ``normal``: the buffer (3, 2, 3) of the clamps' section axes (a twisting cable's ``tw_normal``,
    written like dir) or (0, 2, 3) (no material frame: nothing written)."""
    for k in range(3):
        tau = tau0 + 0.5 * hs * k
        for j in range(3):
            samples.pos[k, e, j] = ext.pos[e, j] + tau * ext.vel[e, j]
            samples.vel[k, e, j] = ext.vel[e, j]
            samples.acc[k, e, j] = ext.acc[e, j]
            samples.dir[k, e, j] = ext.dir[e, j]
        rotate(samples.dir[k, e], tau * ext.omega[e, 0], tau * ext.omega[e, 1], tau * ext.omega[e, 2])
        if normal.shape[0] > 0:
            normal[k, e, :] = ext.normal[e]
            rotate(normal[k, e], tau * ext.omega[e, 0], tau * ext.omega[e, 1], tau * ext.omega[e, 2])


@njit(cache=True, error_model="numpy")
def coupled_targets(stepper, m, plan, ext, cp, ws, t, has_prev, contacts):
    """Plan the coming Bullet step from (cp.x, cp.v) at time t [s].

    Runs ``cp.substeps`` integrator steps into cp.x_new, cp.v_new (held ends in ``ext.active``
    follow the measured poses, the others their move tables; with ``contacts`` (core
    :class:`~bullet_dlo.core.kernels.contact.Contacts`, detected for this step, and its friction
    grips) an implicit method takes them into its step; a BDF2 step after an impact restarts with implicit Euler)
    and writes the sphere forces that
    make Bullet's semi-implicit update land on x_new into cp.force:
    F = m ((x_new - x)/dt - v_bullet)/dt - m g_bullet. Returns (Newton iterations, all converged).
    """
    cp.x_new[:, :] = cp.x
    cp.v_new[:, :] = cp.v
    hs = stepper.h
    iters = 0
    ok_all = True
    for k in range(cp.substeps):
        for e in range(2):  # an end a gripper holds follows the measured pose, the others their tables
            if ext.active[e]:
                external_samples(ext, e, k * hs, hs, cp.samples, plan.normal)
            else:
                sample_end(plan, e, t + k * hs, hs, cp.samples)
        prev = has_prev or k > 0
        if (contacts.count[0] > 0 or grip_active(contacts.grip)) and stepper.method >= IMPLICIT_EULER:
            its, ok = contact_step(stepper, m, cp.x_new, cp.v_new, cp.samples, ws, prev and contacts.impact[0] == 0,
                                   contacts)
        else:
            its, ok = advance(stepper, m, cp.x_new, cp.v_new, cp.samples, ws, prev)
        iters += its
        ok_all = ok_all and ok
    h = cp.dt
    for i in range(cp.x.shape[0]):
        for j in range(3):
            v_target = (cp.x_new[i, j] - cp.x[i, j]) / h
            cp.force[i, j] = m.mass[i] * ((v_target - cp.v_bullet[i, j]) / h - cp.gravity[j])
    return iters, ok_all


@njit(cache=True, error_model="numpy")
def take_over(cp, inp):
    """Make the step Bullet just made the model's state.

    Untouched spheres are exactly where the planned forces sent them: the model takes x_new,
    v_new. Touched spheres take the read-back position, and the contact's velocity change
    (read-back minus target velocity) is added to v_new.
    """
    h = cp.dt
    for i in range(cp.x.shape[0]):
        for j in range(3):
            v_target = (cp.x_new[i, j] - cp.x[i, j]) / h
            cp.x[i, j] = cp.x_new[i, j]
            cp.v[i, j] = cp.v_new[i, j]
            cp.v_bullet[i, j] = v_target
    for k in range(inp.touched_index.shape[0]):
        i = inp.touched_index[k]
        for j in range(3):
            cp.x[i, j] = inp.touched_pos[k, j]
            cp.v[i, j] += inp.touched_vel[k, j] - cp.v_bullet[i, j]
            cp.v_bullet[i, j] = inp.touched_vel[k, j]


@njit(cache=True, error_model="numpy")
def sync_and_advance(stepper, m, plan, ext, cp, ws, det, inp, contacts):
    """One Bullet step's work on the model side: take over (if ``inp.sync``), check, plan the next.

    ``contacts``: the model's contacts for the coming step (detected from the taken-over state);
    the energy check counts the energy stored in them and the work of the bodies they touch.
    With an external holder or on a recorded step (``inp.record``), also writes cp.end_force,
    cp.end_torque (:func:`end_loads` now), and on a recorded step cp.energy (the recorder's row without
    calls of its own: they cost about a third of a step at n = 10). Returns (status, Newton iterations, converged); an unstable status plans nothing.
    """
    status = STABLE
    if inp.sync:
        take_over(cp, inp)
        if inp.check or inp.energy_check:
            extra = contact_energy(contacts, cp.x) - contacts.body_work[0] if inp.energy_check else 0.0
            status = monitor(m, cp.x, cp.v, cp.samples, det, inp.energy_check, extra)
    its, ok = 0, True
    if status == STABLE:
        its, ok = coupled_targets(stepper, m, plan, ext, cp, ws, inp.t, inp.has_prev, contacts)
    if ext.active[0] or ext.active[1] or inp.record:  # the loads on external holders (the grasp coupling
        end_loads(m, cp.x, cp.v, cp.samples, contacts.grip, cp.end_force, cp.end_torque)  # applies them)
    if inp.record:
        cp.energy[0] = mechanical_energy(m, cp.x, cp.v, cp.samples.dir[0])
    return status, its, ok
