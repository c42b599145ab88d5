"""The compiled loop of :mod:`bullet_dlo.bullet.plain_steps` and its packed arguments (:class:`PlainArgs`).

The loop calls the step kernel and detection through their addresses (Numba's first-class functions, held in
:class:`PlainArgs` as ``step``, ``detect`` and ``quiet``), not as linked copies: a copy made the loop's cache entry
9.4 MB, which took about 0.6 s to load in every process. Held in the packed arguments, they are unboxed once when the
arguments are packed; passed at every call, their unboxing cost about 10 us a call."""
from __future__ import annotations

import numpy as np
from numba.experimental import structref

from bullet_dlo.bullet.contact_call import FixedFields
from bullet_dlo.bullet.kernels import FINAL_RATIO, RETRY_SUBSTEPS, StepInput
from bullet_dlo.bullet.native import read_base_states, step_simulation
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.monitor import STABLE

TAKEN, MOVED, BOOK, DETECT = 0, 1, 2, 3  # how run() ended: every step taken; Bullet's step taken and the cable's left
# to Python (MOVED: a body of the contact set moved; DETECT: the step needs detection and ``detect`` is the stand-in
# :func:`no_detect`); the last step taken and left to Python to book
FIELDS = ("api", "bodies", "bases", "last_pose", "moved", "set_args", "step_args", "every", "sizes", "last", "step",
          "detect", "quiet", "twist_now")


@structref.register
class PlainArgsType(FixedFields):
    """Numba type of :class:`PlainArgs` (fields: :data:`FIELDS`)."""


class PlainArgs(structref.StructRefProxy):
    """What :func:`run` needs that stays the same from step to step, packed (Numba unboxes one pointer a call):
    ``api`` (:func:`~bullet_dlo.bullet.native.kernel_api`); the contact set's body reads ``bodies``, ``bases``,
    ``last_pose``, ``moved`` (:func:`~bullet_dlo.bullet.native.read_base_states`); the contact set's and the step
    kernel's packed arrays ``set_args``, ``step_args``; ``every`` (3,) int64: the detector's check and energy check
    periods and the record's [steps]; ``sizes`` (3,): dt, the cable's step h [s] and its contacts' penalty per mass
    [1/s^2]; ``last`` (3,) int64: the last step's status, Newton iterations and convergence (1/0); ``step``,
    ``detect``, ``quiet``: :func:`~bullet_dlo.bullet.solver_call.step_with`,
    :func:`~bullet_dlo.bullet.contact.detect_with` and :func:`~bullet_dlo.bullet.contact.quiet_with` as first-class
    functions (called through their addresses); ``twist_now``: a twisting cable's twist state at its time t, which each
    step copies before its plan advances the cable's (``BulletCable._twist_now``; a frameless cable's own empty one)."""


structref.define_proxy(PlainArgs, PlainArgsType, list(FIELDS))


@njit(cache=True)
def make_plain_args(api, bodies, bases, last_pose, moved, set_args, step_args, every, sizes, last, step, detect, quiet,
                    twist_now):
    """Pack :class:`PlainArgs` (compiled and cached, as :func:`~bullet_dlo.bullet.solver_call.make_step_args`)."""
    return PlainArgs(api, bodies, bases, last_pose, moved, set_args, step_args, every, sizes, last, step, detect, quiet,
                     twist_now)


@njit(cache=True)
def _keep_twist(m, now):
    """The twist state of kernel arrays ``m`` copied into ``now`` (a TwistState; nothing for a frameless cable)."""
    if now.theta.shape[0]:
        now.theta[:] = m.tw_theta
        now.omega[:] = m.tw_omega
        now.ref[:] = m.tw_ref
        now.tan[:] = m.tw_tan
        now.mref[:] = m.tw_mref
        now.flag[:] = m.tw_flag
        now.prev[:] = m.tw_prev


@njit(cache=True)
def no_detect(a, x, v, mass, h, k_per_mass, h_body, h_done):
    """Stands in for :func:`~bullet_dlo.bullet.contact.detect_with` (the same signature) in :class:`PlainArgs` while
    this process has not loaded detection (a cable that has touched nothing: loading it takes about 60 ms): -1, and
    :func:`run` hands the step's cable part to Python, which detects (and loads it)."""
    return -1


@njit(cache=True)
def run(a, n, skip_quiet, t, t_world, steps, steps_world):
    """Up to ``n`` plain world steps (:class:`PlainArgs` ``a``) from the cable's time t [s] and step count and the
    world's; ``skip_quiet``: try ``a.quiet`` before detecting (``contact.SKIP_QUIET``). Returns (steps taken, how it
    ended: TAKEN, MOVED, BOOK or DETECT, the cable's time [s] and steps, the world's, the Newton iterations of the steps
    booked here, the last step's contact rows); the last step's status, iterations and convergence into ``a.last``."""
    args, set_args = a.step_args, a.set_args
    dt, h, k_per_mass = a.sizes[0], a.sizes[1], a.sizes[2]
    x = args.coupling.x_new  # the state Bullet's step took over: the planned one (parked spheres)
    v = args.coupling.v_new
    mass = args.arrays.mass
    step, detect, quiet = a.step, a.detect, a.quiet
    rows = args.coupling.rows
    contacts = args.contacts
    no_index = np.empty(0, np.int64)
    no_rows = np.empty((0, 3))
    booked, count = 0, 0
    for k in range(n):
        # phase 4
        step_simulation(a.api)
        t_world += dt
        steps_world += 1
        # phase 7
        if read_base_states(a.api, a.bodies, a.bases, a.last_pose, a.moved) != 0:
            for b in range(a.moved.shape[0]):
                if a.moved[b]:
                    a.last_pose[b, 0] = np.nan  # (Python's read then sees it move too)
            return k + 1, MOVED, t, t_world, steps, steps_world, booked, count
        if (skip_quiet and contacts.count[0] == 0 and set_args.probes.count[0] == 0
                and quiet(set_args, x, v, h, dt)):
            count = 0
        else:
            count = detect(set_args, x, v, mass, h, k_per_mass, dt, dt)
            if count < 0:  # (no_detect)
                return k + 1, DETECT, t, t_world, steps, steps_world, booked, 0
        t += dt
        steps += 1
        record = steps % a.every[2] == 0
        inp = StepInput(t, steps > 0 and contacts.impact[0] == 0, True, steps % a.every[0] == 0,
                        steps % a.every[1] == 0, record, no_index, no_rows, no_rows)
        _keep_twist(args.arrays, a.twist_now)  # (the twist state at t, before the plan advances it)
        status, its, ok = step(args, inp)
        info = args.guard.info
        if (status != STABLE or not ok or info[RETRY_SUBSTEPS] > 0 or info[FINAL_RATIO] > 0.0
                or (record and rows.count[0] >= rows.t.shape[0])):
            a.last[0] = status
            a.last[1] = its
            a.last[2] = 1 if ok else 0
            return k + 1, BOOK, t, t_world, steps, steps_world, booked, count
        booked += its
    return n, TAKEN, t, t_world, steps, steps_world, booked, count
