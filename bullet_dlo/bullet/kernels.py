"""Numba kernels of the Bullet coupling: plan a Bullet step with the core integrator, take it over.

One :func:`sync_and_advance` call per Bullet step (the step loop is overhead-bound, so the
sync, the stability check and the planning of the next step share one call). The stepping
order is written down in :mod:`bullet_dlo.bullet.cable`.
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numba
import numpy as np
from numba import literal_unroll

from bullet_dlo.core.kernels.contact import (WILD_RATIO, contact_energy, contact_step, grip_active,  # noqa: F401
                                             body_stall_ratio, impulse_scale, stall_ratio)  # (re-exported)
from bullet_dlo.core.kernels.forces import clamp_torque, mechanical_energy
from bullet_dlo.core.kernels.holders import ExternalHolders, HeldSamples, rotate, sample_end  # noqa: F401 (re-exported)
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.monitor import STABLE, STALLED, end_forces, monitor
from bullet_dlo.core.kernels.steppers import BDF2, IMPLICIT_EULER, Stepper
from bullet_dlo.core.kernels.twist import has_twist, set_clamp, twist_ready


ROW_FLOATS = 1 << 16  # floats of x and v per block (a block holds min(256, this / (6 n)) rows, at least one)


class RecordRows(NamedTuple):
    """A block of recorded rows: t [s], (k,); x [m], v [m/s], (k, n, 3); end_force [N], (k, 2, 3); energy [J], (k,);
    count (1,) int64: the rows written so far (the next row's index)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    end_force: np.ndarray
    energy: np.ndarray
    count: np.ndarray


def make_record_rows(n: int, rows: int | None = None) -> RecordRows:
    """An empty block for an n-node cable (``rows``: its size; default as :data:`ROW_FLOATS` allows)."""
    k = rows if rows is not None else max(1, min(256, ROW_FLOATS // (6 * max(n, 1))))
    return RecordRows(np.zeros(k), np.zeros((k, n, 3)), np.zeros((k, n, 3)), np.zeros((k, 2, 3)), np.zeros(k),
                      np.zeros(1, np.int64))


class Coupling(NamedTuple):
    """A cable coupled to Bullet: the model's state and what the coming Bullet step needs.

    dt: Bullet step [s]; substeps: integrator steps per Bullet step; gravity: Bullet's gravity
    [m/s^2], (3,); x [m], v [m/s]: the model's state, (n, 3); v_bullet: Bullet's sphere
    velocities [m/s], (n, 3); x_new [m], v_new [m/s]: the state planned for the end of the coming
    Bullet step, (n, 3); force: sphere forces [N] that make Bullet land there, (n, 3);
    samples: held-end samples of the planned step's last substep (HeldSamples); end_force [N],
    end_torque [N m]: what the cable exerts on its held ends at the start of the planned step
    (:func:`end_loads`), (2, 3) each; energy [J] (1,): its mechanical energy then (written on
    recorded steps); rows: the record's block (:class:`RecordRows`) that a recorded step writes its row into
    (t, x, v, end_force, energy: the row :class:`~bullet_dlo.bullet.recorder.CableRecord` keeps).
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
    rows: RecordRows


class StepInput(NamedTuple):
    """What changes from one Bullet step to the next.

    t: time of the state the next step is planned from [s]; has_prev: the integrator's history
    (BDF2) is valid; sync: take over the step Bullet just made; check, energy_check: run the
    cheap / energy checks of the detector; record: this step is recorded (end loads and energy
    into the Coupling, its row into coupling.rows); touched_index: spheres that had contacts, (k,) int;
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
    """Held-end samples of end ``e`` at tau0 + (0, hs/2, hs) [s] after the measurement in ``ext``, at constant
    acceleration and angular acceleration; ``normal``: the buffer (3, 2, 3) of the clamps' section axes (a
    twisting cable's ``tw_normal``, written like dir) or (0, 2, 3) (no material frame: nothing written)."""
    for k in range(3):
        tau = tau0 + 0.5 * hs * k
        for j in range(3):
            samples.pos[k, e, j] = ext.pos[e, j] + tau * (ext.vel[e, j] + 0.5 * tau * ext.acc[e, j])
            samples.vel[k, e, j] = ext.vel[e, j] + tau * ext.acc[e, j]
            samples.acc[k, e, j] = ext.acc[e, j]
            samples.dir[k, e, j] = ext.dir[e, j]
        # the turn over tau: tau times the mean angular velocity over it (exact for a fixed axis)
        rx = tau * (ext.omega[e, 0] + 0.5 * tau * ext.alpha[e, 0])
        ry = tau * (ext.omega[e, 1] + 0.5 * tau * ext.alpha[e, 1])
        rz = tau * (ext.omega[e, 2] + 0.5 * tau * ext.alpha[e, 2])
        rotate(samples.dir[k, e], rx, ry, rz)
        if normal.shape[0] > 0:
            normal[k, e, :] = ext.normal[e]
            rotate(normal[k, e], rx, ry, rz)


# StallGuard.info: what the last planned step's contact solves left (written by coupled_targets)
FIRST_RATIO, FIRST_ITER, FINAL_RATIO, RETRY_SUBSTEPS, COASTED, FIRST_MOVED = range(6)
COAST_MOVE = 1e-3  # [-] a far solve that moved no node's momentum by this share of gravity's impulse coasted
# (implicit Euler's tolerance; far solves of a cable resting on a table edge moved at least 0.011)
WILD_LEVELS = 2  # a solve taken again for ending wildly far (it moved the momentum) is kept from 2 or 4 sub-steps
# (8 and 16 let a duck thrown at the cable at 60 Hz 0.19 mm into it, tests/bullet/test_contact_compound.py) unless
# they coast; a coast, which would stop the run, goes on to all of StallGuard.levels (a 1 g box rolling off the cable
# at 1 kHz needs 8 or 16)


class StallGuard(NamedTuple):
    """What a contact step needs to be taken again when its Newton solve coasts far from convergence.

    levels: retries at most, with 2, 4, ..., 2**levels sub-steps of the same integrator (0: none, a coast stops
    the run at once; -1: no guard, nothing stops the run, the behaviour before it, with ``info`` still written); a
    wild solve that moved the momentum is kept from at most :data:`WILD_LEVELS` of them unless their sub-steps coast;
    far [-]: a solve ends far from
    convergence when its largest momentum residual exceeds ``far`` times the scale newton's tolerance
    multiplies (gravity's and the external forces' impulse on the heaviest node in a step, plus the step's
    largest momentum change; :func:`stall_ratio`); wild [-]: a solve that ends beyond ``wild`` times that scale
    is taken again like a coast, even though it moved the momentum, when a free body is in the solve (such a
    step hands the body an impulse of that many times its weight's) or the cable's section is flat; x0 [m], v0 [m/s]: the state a contact sub-step starts from,
    (n, 3); vs [m/s]: the velocities a retry's sub-step starts from, (n, 3); rows, whole: (live, saved) array pairs of everything else a contact step writes (every array of the
    Contacts and of its grips, the twist state, BDF2's history): ``rows`` indexed by contact row (only the rows
    in use are saved), ``whole`` copied whole; info (5,): the last planned step's worst residual ratio of a
    first attempt that did not converge (0: all converged), the Newton iterations that solve took, the worst
    ratio of the solves kept, the sub-steps of the retry kept (0: no retry), 1.0 when a kept solve coasted
    (ended far from convergence without moving the momentum from its start, :func:`_coasted`: with ``levels``
    >= 0 the run stops, status STALLED), and how far the first of those solves moved the momentum (in units of
    gravity's impulse, :func:`momentum_moved` over :func:`impulse_scale`).
    """

    levels: int
    far: float
    wild: float
    x0: np.ndarray
    v0: np.ndarray
    vs: np.ndarray
    rows: tuple
    whole: tuple
    info: np.ndarray


@njit(cache=True, error_model="numpy")
def _copy_rows(pairs, k, save):
    """The first k rows of each (live, saved) pair: live into saved (``save``) or back."""
    for p in literal_unroll(pairs):
        if save:
            p[1][:k] = p[0][:k]
        else:
            p[0][:k] = p[1][:k]


@njit(cache=True, error_model="numpy")
def _copy_whole(pairs, save):
    """Each (live, saved) pair whole: live into saved (``save``) or back."""
    for p in literal_unroll(pairs):
        if save:
            p[1][:] = p[0]
        else:
            p[0][:] = p[1]


@njit(cache=True, error_model="numpy")
def momentum_moved(m, v0, v1):
    """max over free nodes of m_i |v1_i - v0_i| [N s]: how far a solve moved the momentum from its start v0."""
    worst = 0.0
    for i in range(v0.shape[0]):
        if not m.held[i]:
            for j in range(3):
                worst = max(worst, m.mass[i] * abs(v1[i, j] - v0[i, j]))
    return worst


@njit(cache=True, error_model="numpy")
def _coasted(m, far, v0, v, hf, ratio):
    """A solve that ended far from convergence (``ratio`` above ``far``) without moving any free node's momentum
    from its start v0 by COAST_MOVE of gravity's impulse: the cable would move as if no force acted."""
    return ratio > far and momentum_moved(m, v0, v) <= COAST_MOVE * impulse_scale(m, hf)


@njit(cache=True, error_model="numpy")
def _moves_a_body(bodies):
    """Whether the last contact step solved a free body's motion with the cable's (a row touched one)."""
    for s in range(bodies.active.shape[0]):
        if bodies.active[s]:
            return True
    return False


@njit(cache=True, error_model="numpy")
def _sample(plan, ext, cp, t, tau0, hs):
    """Held-end samples of the (sub-)step [t + tau0, t + tau0 + hs] [s] into cp.samples: an end a gripper
    holds follows the measured pose, the others their tables."""
    for e in range(2):
        if ext.active[e]:
            external_samples(ext, e, tau0, hs, cp.samples, plan.normal)
        else:
            sample_end(plan, e, t + tau0, hs, cp.samples)


@njit(cache=True, error_model="numpy")
def _force_weight(stepper, use_prev):
    """hf [s] of contact_step's momentum balance: 2h/3 for BDF2 with history, else h (implicit Euler)."""
    return 2.0 * stepper.h / 3.0 if use_prev and stepper.method == BDF2 else stepper.h


@njit(cache=True, error_model="numpy", inline="always")
def _add_row_forces(c, nc, w, out):
    """out[k] += w times row k's force on the cable [N] (its clipped normal force along its normal and its friction),
    for the first nc rows of ``c``."""
    for k in range(nc):
        fn = max(c.f_n[k], 0.0)
        for j in range(3):
            out[k, j] += w * (fn * c.normal[k, j] + c.f_t[k, j])


@njit(cache=True, error_model="numpy", inline="always")
def _set_row_forces(c, nc, force):
    """Rows' f_n, f_t such that each row's force (as :func:`_add_row_forces` reads it) is ``force[k]`` [N]: the
    normal part along its current normal (at least 0), the rest as friction."""
    for k in range(nc):
        fn = max(force[k, 0] * c.normal[k, 0] + force[k, 1] * c.normal[k, 1] + force[k, 2] * c.normal[k, 2], 0.0)
        c.f_n[k] = fn
        for j in range(3):
            c.f_t[k, j] = force[k, j] - fn * c.normal[k, j]


@njit(cache=True, error_model="numpy", inline="always")
def spread_held(bodies, s, sub, part):
    """Before step s of ``sub`` equal steps that share ``part`` of the Bullet step: the held load's velocity
    (``Bodies.held_dv``, folded whole into ``bodies.vel`` for the step) spread over them, 1/sub of ``part`` in each.
    Folded whole, a body the table holds got its support in the first step alone and fell in the others: a 10 kg box
    leaning on the cable and the ground, retried as 2 sub-steps at 240 Hz, was planned to tip at 0.77 rad/s where
    Bullet held it, and crept back up the cable at 1 mm/s (2026-12-05)."""
    f = part / sub - (part if s == 0 else 0.0)
    for o in range(bodies.vel.shape[0]):
        for j in range(6):
            bodies.vel[o, j] += f * bodies.held_dv[o, j]


@njit(cache=True, error_model="numpy", inline="always")
def _guarded_contact_step(stepper, m, plan, ext, cp, ws, t, k, prev, contacts, bodies, guard, contact_call):
    """Contact sub-step k of the coming Bullet step on (cp.x_new, cp.v_new), taken again from its start as 2,
    4, ... sub-steps when its Newton solve coasts (:func:`_coasted`: far from convergence with the momentum where
    it started), or ends beyond ``guard.wild`` with a free body in it or a flat section (:class:`StallGuard`): the
    first attempt whose solves all end within ``guard.far`` is kept, else
    the last. Returns (Newton iterations, converged,
    the worst residual ratio of the solves kept (0: all converged), whether one of them coasted)."""
    save = guard.levels > 0
    nc = contacts.count[0]
    guard.x0[:, :] = cp.x_new
    guard.v0[:, :] = cp.v_new
    if save:  # (a few hundred numbers: the cost of the guard when Newton converges)
        _copy_rows(guard.rows, nc, save)  # (save: a runtime True; literals compiled each copy twice)
        _copy_whole(guard.whole, save)
    has_prev = prev and contacts.impact[0] == 0
    its, ok = contact_call(stepper, m, cp.x_new, cp.v_new, cp.samples, ws, has_prev, contacts, bodies)
    if ok:
        return its, ok, 0.0, False
    hf = _force_weight(stepper, has_prev)
    ratio = stall_ratio(m, ws, hf)
    body = body_stall_ratio(bodies, hf)  # (a body off its balance with the cable balanced: wild, not a coast)
    info = guard.info
    if max(ratio, body) > info[FIRST_RATIO]:
        info[FIRST_RATIO] = max(ratio, body)
        info[FIRST_ITER] = its
        info[FIRST_MOVED] = momentum_moved(m, guard.v0, cp.v_new) / impulse_scale(m, hf)
    coast = _coasted(m, guard.far, guard.v0, cp.v_new, hf, ratio)
    # wildly far with a free body in the solve, or for a flat section (its impact at 60-120 Hz: sub-steps land it)
    wild = max(ratio, body) > guard.wild and (_moves_a_body(bodies) or contacts.section[0] > 0.0)
    if not save or not (coast or wild):
        # a near miss, or far after moving the momentum: kept (sub-steps do not help those: on a cable sliding
        # over a box edge 918 of 921 retried steps, and 67 of 67 that stalled after some iterations, stayed
        # far, at 1.6 to 9 times the CPU time; docs/concepts/integrators.md, "A stalled contact step"), unless
        # wildly far with a free body in the solve: a 20 g part on a cord at 120 Hz got 8x its weight from a kept
        # solve at 69 and was launched (without a body, e.g. on an edge, the retry changes the slide, not the fault),
        # or with a flat section: a tilted ribbon landing at 60 or 120 Hz (its exact matrix indefinite) was stopped,
        # and lands in 2 or 4 sub-steps
        return its, ok, max(ratio, body), coast
    hs = stepper.h
    worst = max(ratio, body)
    top = guard.levels if coast else min(guard.levels, WILD_LEVELS)  # the attempt kept however it ends
    for level in range(1, guard.levels + 1):
        last = level >= top
        sub = 2 ** level
        hsub = hs / sub
        sstep = Stepper(stepper.method, hsub, stepper.max_iter, stepper.tol, stepper.definite,
                        stepper.exact_from, stepper.reuse)
        cp.x_new[:, :] = guard.x0
        cp.v_new[:, :] = guard.v0
        _copy_rows(guard.rows, nc, not save)  # back (save is True here)
        _copy_whole(guard.whole, not save)
        worst = 0.0
        coast = False
        impact = 0
        mean = np.zeros((nc, 3))  # each row's force on the cable [N], averaged over the sub-steps
        for s in range(sub):
            _sample(plan, ext, cp, t, k * hs + s * hsub, hsub)
            spread_held(bodies, s, sub, 1.0 / cp.substeps)  # (the share of this cable step: its own)
            use_prev = s > 0 and contacts.impact[0] == 0  # BDF2: history only within the sub-steps
            guard.vs[:, :] = cp.v_new
            its_s, ok_s = contact_call(sstep, m, cp.x_new, cp.v_new, cp.samples, ws, use_prev, contacts, bodies)
            _add_row_forces(contacts, nc, 1.0 / sub, mean)
            its += its_s
            impact = max(impact, contacts.impact[0])
            if not ok_s:
                hf_s = _force_weight(sstep, use_prev)
                r_s = stall_ratio(m, ws, hf_s)
                worst = max(worst, r_s, body_stall_ratio(bodies, hf_s))
                coast = coast or _coasted(m, guard.far, guard.vs, cp.v_new, hf_s, r_s)
                if worst > guard.far and not last:
                    break  # this attempt failed: on to the next
        contacts.impact[0] = impact
        if coast and worst > guard.far and last and level < guard.levels:
            top = guard.levels  # kept, a coast would stop the run (a wild first attempt's sub-steps may coast): on as
            continue  # for a coast (kept at 8 sub-steps far, such a retry handed a 1 g box energy: the run stopped)
        if worst <= guard.far or last:
            info[RETRY_SUBSTEPS] = sub
            # the rows report the step's mean force, as the cable's momentum change over the step felt it (the last
            # sub-step's alone handed a table 4 % of the cable's weight more than the sliding cable felt)
            _set_row_forces(contacts, nc, mean)
            # as after one step of hs: BDF2's history is the sub-step's start, the samples those of step hs
            ws.x_prev[:, :] = guard.x0
            ws.v_prev[:, :] = guard.v0
            _sample(plan, ext, cp, t, k * hs, hs)
            break
    return its, worst == 0.0, worst, coast


@njit(cache=True, error_model="numpy", inline="always")
def coupled_targets(stepper, m, plan, ext, cp, ws, t, has_prev, contacts, bodies, guard, contact_call, advance_call):
    """Plan the coming Bullet step from (cp.x, cp.v) at time t [s].

    Runs ``cp.substeps`` integrator steps into cp.x_new, cp.v_new (held ends in ``ext.active``
    follow the measured poses, the others their move tables; with ``contacts`` (core
    :class:`~bullet_dlo.core.kernels.contact.Contacts`, detected for this step, and its friction
    grips, and ``bodies``, the free bodies solved with it, :class:`~bullet_dlo.core.kernels.contact.Bodies`) an
    implicit method takes them into its step; a BDF2 step after an impact restarts with implicit Euler;
    a contact step whose Newton solve coasts far from convergence is taken again as 2, 4, ... sub-steps,
    :class:`StallGuard` ``guard``, which receives what the solves left in ``guard.info``)
    and writes the sphere forces that
    make Bullet's semi-implicit update land on x_new into cp.force:
    F = m ((x_new - x)/dt - v_bullet)/dt - m g_bullet. Returns (Newton iterations, all converged, a contact
    solve coasted far from convergence even in the retry's sub-steps: the planned step is not to be taken).
    ``contact_call``, ``advance_call``: the contact step and the step without contact (:func:`sync_and_advance`).
    """
    cp.x_new[:, :] = cp.x
    cp.v_new[:, :] = cp.v
    bodies.impulse[:, :] = 0.0  # the reactions on the free bodies over this Bullet step (Bullet gets their mean)
    bodies.travel[:, :] = 0.0  # and their planned displacement over it
    hs = stepper.h
    iters = 0
    ok_all = True
    stalled = False
    guard.info[:] = 0.0
    for k in range(cp.substeps):
        _sample(plan, ext, cp, t, k * hs, hs)
        if cp.substeps > 1:
            spread_held(bodies, k, cp.substeps, 1.0)
        prev = has_prev or k > 0
        if (contacts.count[0] > 0 or grip_active(contacts.grip)) and stepper.method >= IMPLICIT_EULER:
            its, ok, ratio, coast = _guarded_contact_step(stepper, m, plan, ext, cp, ws, t, k, prev, contacts, bodies,
                                                          guard, contact_call)
            guard.info[FINAL_RATIO] = max(guard.info[FINAL_RATIO], ratio)
            if coast:
                guard.info[COASTED] = 1.0
                stalled = guard.levels >= 0
        else:
            its, ok = advance_call(stepper, m, cp.x_new, cp.v_new, cp.samples, ws, prev)
        iters += its
        ok_all = ok_all and ok
        if stalled:
            break  # nothing to plan: the run stops here
    h = cp.dt
    if not stalled:
        for i in range(cp.x.shape[0]):
            for j in range(3):
                v_target = (cp.x_new[i, j] - cp.x[i, j]) / h
                cp.force[i, j] = m.mass[i] * ((v_target - cp.v_bullet[i, j]) / h - cp.gravity[j])
    # a last use after the branches (tests/llvm_loops.py)
    _last_use = stepper, m, plan, ext, cp, ws, contacts, bodies, guard
    return iters, ok_all, stalled


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


@njit(cache=True, error_model="numpy", inline="always")
def sync_and_advance(stepper, m, plan, ext, cp, ws, det, inp, contacts, bodies, guard, contact_call, advance_call):
    """One Bullet step's work on the model side: take over (if ``inp.sync``), check, plan the next.

    ``contacts``: the model's contacts for the coming step (detected from the taken-over state), ``bodies``: the
    free bodies solved with them (:class:`~bullet_dlo.core.kernels.contact.Bodies`);
    the energy check counts the energy stored in them and the work of the bodies they touch.
    With an external holder, a material frame or on a recorded step (``inp.record``), also writes cp.end_force,
    cp.end_torque (:func:`end_loads` of the state at t, before the plan advances the twist; a friction grip's
    force row: the reaction of the planned step's grip force, as :func:`end_loads` gives it after the plan), and
    on a recorded step cp.energy (the recorder's row without calls of its own: they cost about a third of a step
    at n = 10).
    ``guard``: the stalled contact step's retry (:class:`StallGuard`); a contact solve that coasts far from
    convergence even so makes the status STALLED. ``contact_call``, ``advance_call``: the core's
    :func:`~bullet_dlo.core.kernels.contact.contact_step` and :func:`~bullet_dlo.core.kernels.steppers.advance`, or
    their machine code as first-class functions (:func:`~bullet_dlo.bullet.solver_call.step_with`, whose compile
    then does not link and optimise their code again). Returns (status, Newton iterations, converged); an unstable
    status plans nothing (its planned forces are not to be applied).
    """
    status = STABLE
    if inp.sync:
        take_over(cp, inp)
        if inp.check or inp.energy_check:
            extra = contact_energy(contacts, cp.x) - contacts.body_work[0] if inp.energy_check else 0.0
            status = monitor(m, cp.x, cp.v, cp.samples, det, inp.energy_check, extra)
    # the loads on external holders (the grasp coupling applies them over the coming Bullet step) and the
    # recorded energy: of the state at t, before coupled_targets advances the twist state (m.tw_*) to t + dt
    # (x, v stay at t); a twisting cable's every step (BulletCable.end_loads reads them), the held ends sampled
    # at t (dir[0] of the first sub-step)
    if ext.active[0] or ext.active[1] or inp.record or has_twist(m):
        _sample(plan, ext, cp, inp.t, 0.0, stepper.h)
        if has_twist(m):  # a new twist state: built as the plan would build it
            twist_ready(m, cp.x, cp.samples.dir[0])
        end_loads(m, cp.x, cp.v, cp.samples, contacts.grip, cp.end_force, cp.end_torque)
        if inp.record:
            cp.energy[0] = mechanical_energy(m, cp.x, cp.v, cp.samples.dir[0])
    its, ok = 0, True
    if status == STABLE:
        its, ok, stalled = coupled_targets(stepper, m, plan, ext, cp, ws, inp.t, inp.has_prev, contacts, bodies,
                                           guard, contact_call, advance_call)
        if stalled:
            status = STALLED
    grip = contacts.grip
    for e in range(2):  # a friction grip's reaction: the force of the planned step, which acts over the coming
        if grip.active[e]:  # Bullet step (the momentum the grip gives the end node is taken from the gripper)
            for j in range(3):
                cp.end_force[e, j] = -grip.force[e, j]
    if inp.record:
        write_row(cp.rows, inp.t, cp.x, cp.v, cp.end_force, cp.energy[0])
    # a last use after the branches (tests/llvm_loops.py)
    _last_use = stepper, m, plan, ext, cp, ws, det, inp, contacts, bodies, guard
    return status, its, ok


@njit(cache=True, error_model="numpy", inline="always")
def write_row(rows, t, x, v, end_force, energy):
    """The row of time t [s] into the next free row of ``rows`` (:class:`RecordRows`; none free: nothing written,
    which the record's flushing after every row rules out)."""
    k = rows.count[0]
    if k >= rows.t.shape[0]:
        return
    rows.t[k] = t
    for i in range(x.shape[0]):
        for j in range(3):
            rows.x[k, i, j] = x[i, j]
            rows.v[k, i, j] = v[i, j]
    for e in range(2):
        for j in range(3):
            rows.end_force[k, e, j] = end_force[e, j]
    rows.energy[k] = energy
    rows.count[0] = k + 1
