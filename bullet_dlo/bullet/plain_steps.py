"""A world's plain steps in one compiled call: Bullet's step and the cable's, with no Python between them.

:meth:`BulletWorld.step <bullet_dlo.bullet.world.BulletWorld.step>` takes a step in eight phases, each a Python call
into PyBullet or into a compiled kernel. For one cable at n = 10 that Python costs about as much as the cable's kernel
and more than Bullet's step (``demos/step_breakdown.py``). A step in which Python has nothing to decide is *plain*: the
world holds one cable, its spheres are parked proxies (Bullet does not move them, so no forces go to them and none are
read back), its contacts are the model's with static bodies only (no free body, no other cable, no probed link), its
ends are not in friction grips, and the world has no couplings and no hooks (:func:`take` checks each; a material
frame is fine after the cable's first step). Plain steps run here, phase by phase in the order of
``BulletWorld.step`` and on the same arrays, so their results are the ones of the Python phases to the bit
(``tests/bullet/test_plain_steps.py``):

1.-3. nothing to do: no forces for parked spheres, no coupling, no hook;
4. Bullet's step (:func:`~bullet_dlo.bullet.native.step_simulation`);
5.-6. nothing to do: no coupling, no hook;
7. the cable's step: its contact set's body poses (a body that moved hands the rest of the step to Python, which
   updates the shapes), the contacts (:func:`~bullet_dlo.bullet.contact.quiet`, else
   :func:`~bullet_dlo.bullet.contact.detect`; until this process has loaded detection a stand-in hands that step's
   cable part to Python, which loads it), then the step kernel
   (:func:`~bullet_dlo.bullet.kernels.sync_and_advance`: take over, check, plan, the record's row), a twisting
   cable's twist state at t kept before the plan (``BulletCable._twist_now``);
8. nothing to do: no hook.

The loop stops after a step whose outcome Python books (Newton not converged, a retry, an unstable status, a full
block of recorded rows): :meth:`CableSolver.account <bullet_dlo.bullet.solver.CableSolver.account>` and
``BulletCable._after_plan`` then do what they do after every step of the Python phases. Needs the native Bullet calls
(:mod:`bullet_dlo.bullet.native`); without them, or with :data:`PLAIN_STEPS` off, every step takes the Python phases.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
from numba import typeof

from bullet_dlo.bullet import contact
from bullet_dlo.bullet.contact import detect_with, quiet_with
from bullet_dlo.bullet.kernels import StepInput, bind
from bullet_dlo.bullet.native import kernel_api
from bullet_dlo.bullet.plain_call import BOOK, DETECT, MOVED, TAKEN, make_plain_args, no_detect, run
from bullet_dlo.bullet.solver import NEWTON_WARN_MIN_STEPS
from bullet_dlo.bullet.solver_call import _get_wrapper_address, first_class, step_with
from bullet_dlo.core.kernels.monitor import STABLE


PLAIN_STEPS = True  # take plain steps in one compiled call (False: every step in Python's phases; for A/B and tests)
PLAIN_FROM = 2000
"""World steps a run must reach before it takes plain steps. Readying the loop (loading its code and its packed
arguments' constructor, about 1.8 MB of cache, and looking up the kernels it calls by address) takes about 16 ms per
process (detection, which takes another 60 ms to load, is loaded when a step first needs it, by the Python phases as
without plain steps), which the 8-9 us it saves a step at n = 10 pays back after about 1800 steps: a shorter run keeps
Python's phases, a longer one (its length known from ``step(n)`` or ``run_while_stable``, or the world's steps so
far) takes plain steps from its start."""


def _plain_cable(world):
    """The world's one cable when its next step is plain (module doc), else None."""
    if (not PLAIN_STEPS or _get_wrapper_address is None or world.couplings or world.before_step
            or world.after_physics or world.after_step or world.bodies_added or world.model_touches
            or world._model_touches_now or len(world.cables) != 1):
        return None
    (cable,) = world.cables.values()
    if not (cable.proxy and cable.model_contact) or cable._waking or cable._fresh or cable.sync == "always":
        return None
    if cable.solver.status != STABLE or True in cable.grip.active.tolist():
        return None
    if cable.twist.theta.shape[0] and cable._twist_now is None:  # (a twisting cable's first step keeps Python's phases)
        return None
    cs = cable.contact.set
    if (cs is None or cs.free_bodies or cs._dynamic_rows or cs.other_cables or cs._probe_rows
            or cs._read_bases is None or cs._set_args is None or cable.record.rows is not cable._cp.rows):
        return None
    if cable.contact.partners_seen or pb.getNumBodies(world.client) != cable.contact.bodies_seen:
        return None  # (contact.refresh() would rebuild the set)
    return cable


def _first_class(kernel, *args) -> tuple:
    """``kernel``'s machine code for the argument types of ``args`` as a first-class function (:func:`first_class`)."""
    return first_class(kernel, tuple(map(typeof, args)))


def _detection_loaded(detect_args: tuple) -> bool:
    """Whether this process has detection for these arguments ready (loaded or compiled)."""
    return tuple(map(typeof, detect_args)) in detect_with.overloads


def _functions(cable, args) -> tuple:
    """The step kernel, detection and the quiet test for the cable's packed arguments as first-class functions:
    (their types, their addresses). Detection not loaded in this process yet (a cable that has touched nothing; it
    takes about 60 ms) is :func:`no_detect` until the loop needs it."""
    set_args, x, v = cable.contact.set._set_args, cable.solver.coupling.x_new, cable.solver.coupling.v_new
    no_index, no_rows = np.empty(0, np.int64), np.empty((0, 3))
    detect_args = (set_args, x, v, cable.arrays.mass, 0.0, 0.0, 0.0, 0.0)
    made = (_first_class(step_with, args, StepInput(0.0, True, True, True, True, True, no_index, no_rows, no_rows)),
            _first_class(detect_with if _detection_loaded(detect_args) else no_detect, *detect_args),
            _first_class(quiet_with, set_args, x, v, 0.0, 0.0))
    return tuple(m[0] for m in made), tuple(m[1] for m in made)


def _packed(world, cable, args):
    """The cable's :class:`PlainArgs`, :func:`run` bound to them and their ``last`` (made anew when what they hold
    changed)."""
    cs, det = cable.contact.set, cable.solver.detector
    held = cable._plain_args
    if (held is None or held[0] is not args or held[1] is not cs._set_args or held[2] is not cs._base_args
            or held[3] is not det or held[4] != cable.record_every
            or (cable._twist_now is not None and held[9] is not cable._twist_now)):
        h = cable.solver.stepper.h
        every = np.array([det.check_every, det.energy_every, cable.record_every], dtype=np.int64)
        sizes = np.array([world.dt, h, cs.alpha / (h * h)])  # (as ContactSet.update computes them)
        last = np.zeros(3, dtype=np.int64)
        values = (kernel_api(world.native_handle()), *cs._base_args[1:], cs._set_args, args, every, sizes, last)
        function_types, addresses = _functions(cable, args)
        now = cable._twist_now if cable._twist_now is not None else cable.twist  # (frameless: its empty state)
        # (compiled for the functions' types and called as compiled: the dispatcher cannot type an address)
        pack = make_plain_args.compile(tuple(map(typeof, values)) + function_types + (typeof(now),))
        packed = pack(*values, *addresses, now)
        # (the addresses' objects kept with them: the packed functions refer to them)
        held = cable._plain_args = (args, cs._set_args, cs._base_args, det, cable.record_every, packed,
                                    bind(run, packed, 1, True, 0.0, 0.0, 0, 0), last, addresses, now)
    return held[5:]


def take(world, n: int, horizon: int = 0) -> int:
    """Take up to ``n`` (>= 1) of ``world``'s next steps here while they are plain; returns how many (0: the next one
    is not plain, take it in Python's phases). ``horizon``: the steps the run still asks for, if more than ``n``
    (:data:`PLAIN_FROM`)."""
    if world.steps + max(n, horizon) < PLAIN_FROM:
        return 0
    cable = _plain_cable(world)
    if cable is None:
        return 0
    solver, cs = cable.solver, cable.contact.set
    args = solver.packed_args(cable.arrays, cable.control, cs.contacts, cs.bodies)
    if args is None:
        return 0
    if not solver._warned_share and solver.newton_failures and solver.steps_planned < NEWTON_WARN_MIN_STEPS:
        n = min(n, NEWTON_WARN_MIN_STEPS - solver.steps_planned)  # (its share is judged at that step: book it there)
    packed, kernel, last = _packed(world, cable, args)[:3]
    taken, how, cable.t, world.time, cable.steps, world.steps, booked, count = kernel(
        packed, n, contact.SKIP_QUIET, cable.t, world.time, cable.steps, world.steps)
    plain = taken - (how != TAKEN)
    solver.steps_planned += plain
    solver.newton_iterations += booked
    if cable._twist_now is not None and (plain or how == BOOK):
        cable._twist_planned = True  # (each step the loop planned advanced the twist state on from _twist_now)
    if plain:
        solver.last_ratio = 0.0
        solver.judge_share()  # (the batch ends where the share is first judged: as after that step)
    if how not in (MOVED, DETECT):
        cable.contacts_last_step = count
    world._supported = world._supported_in(())  # phase 7's books of Bullet's contacts: none read (parked spheres)
    world._supported_due = False
    if how in (MOVED, DETECT):  # the cable's step of the last world step, in Python
        world.take_cable_steps()
        if how == DETECT:
            cable._plain_args = None  # (packed anew at the next call, with the detection Python has just loaded)
    elif how == BOOK:
        status = solver.account(int(last[0]), int(last[1]), bool(last[2]), cable.t)
        cable._after_plan(status, cable.steps % cable.record_every == 0, True)
    return taken
