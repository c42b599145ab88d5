"""The model side of a coupled Bullet step, in one call: :class:`CableSolver`.

Shaped like Newton's ``solver.step(state_in, state_out, control, contacts, dt)``: the solver holds what a
cable's steps share (the integrator step, scratch memory, the held ends' plan, the instability detector and
the buffers of the Bullet step, :class:`~bullet_dlo.bullet.kernels.Coupling`), and :meth:`CableSolver.step`
takes the rest: the kernels' view of model, control and state (:class:`~bullet_dlo.core.model.KernelArrays`),
the control (the holders' measured poses), the contacts detected for the coming step and what Bullet's step
changed (:class:`~bullet_dlo.bullet.kernels.StepInput`). The state in is ``coupling.x, v``, the state out
``coupling.x_new, v_new`` with the sphere forces that make Bullet land there; one step is one Numba call
(:func:`~bullet_dlo.bullet.kernels.sync_and_advance`): take over the step Bullet made, check it, plan the next. Its
per-cable arguments go in packed (:mod:`bullet_dlo.bullet.solver_call`), so Numba unboxes two of them, not ~150 arrays.

A contact step whose Newton solve coasts (ends far from convergence with the momentum where it started: the
cable would move as if no force acted) is taken again from its start as 2, then 4 sub-steps
(:class:`~bullet_dlo.bullet.kernels.StallGuard`); if even those coast, the cable stops as unstable (status
STALLED) with a RuntimeWarning that says when and how far the solve was from convergence. Steps whose solve
ends unconverged otherwise are kept and counted; a RuntimeWarning says so once when they exceed
:data:`~bullet_dlo.core.engine.NEWTON_WARN_SHARE` of the steps (docs/concepts/integrators.md, "A stalled contact
step").
"""
from __future__ import annotations

import warnings
from operator import is_not

import numba
import numpy as np

from bullet_dlo.bullet.kernels import (COASTED, FINAL_RATIO, FIRST_ITER, FIRST_MOVED, FIRST_RATIO, RETRY_SUBSTEPS,
                                       WILD_RATIO, Coupling, StallGuard, StepInput, bind, make_record_rows,
                                       sync_and_advance)
from bullet_dlo.bullet.solver_call import _get_wrapper_address, pack_step_args, step_with
from bullet_dlo.core.engine import NEWTON_WARN_SHARE, DetectorOptions, start_detector
from bullet_dlo.core.integrators import Integrator, NewtonOptions, make_stepper
from bullet_dlo.core.kernels.contact import Bodies, Contacts, contact_step
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.kernels.monitor import REASONS, STABLE, STALLED
from bullet_dlo.core.kernels.steppers import Workspace, advance, make_workspace
from bullet_dlo.core.kernels.twist import TwistState
from bullet_dlo.core.model import CableControl, CableModel, CableState, KernelArrays

STALL_RETRIES = 4  # a coasting contact step is taken again as 2, 4, 8, then 16 sub-steps (a wild one as 2, then 4:
# kernels.WILD_LEVELS); 0: stop at a coast; -1: no guard
STALL_FAR = 0.1  # [-] far from convergence: momentum residual above this share of gravity's impulse in a step
STALL_WILD = WILD_RATIO  # [-] wildly far: with a free body in the solve, taken again as sub-steps even when it moved
# the momentum (and if the retry stays that far, the bodies get the reaction the cable felt: Bodies.felt_ratio)
NEWTON_WARN_MIN_STEPS = 100  # the share of unconverged steps is judged from this many planned steps on
_new_tuple = tuple.__new__  # makes a StepInput without the NamedTuple's constructor, a Python function
PACK_ARGS = True  # call the step kernel on packed arguments (solver_call.py; False: the plain call, for A/B and tests)


# What a contact step (core/kernels/contact.py, contact_step) reads that it also writes, by field: the retry restores
# these. Every other array of the Contacts, its Grip and the Bodies is either left alone by the step (the detector's
# geometry and parameters) or written before the step reads it (forces, scratch, the grippers' pose from the
# samples, the bodies' iterates), so a step taken again from these is the same step
# (tests/bullet/test_newton_stall.py, test_a_contact_step_taken_again_from_the_guard_is_the_same_step). A field
# added to the step's state must be named here. (Copying every array, 56 of them, cost 4.6 us a contact step.)
CONTACT_ROWS = ("point", "anchor", "state", "cap", "normal")  # by contact row (the first count rows)
CONTACT_WHOLE = ("body_work", "impact")
GRIP_WHOLE = ("active", "offset", "state")
BODY_ROWS = ("arm",)
BODY_WHOLE = ("vel", "impulse", "travel")


def step_state(contacts: Contacts, bodies: Bodies) -> tuple[list, list]:
    """The arrays a contact step reads and writes (see :data:`CONTACT_ROWS`): (row arrays, whole arrays)."""
    rows = [getattr(contacts, f) for f in CONTACT_ROWS] + [getattr(bodies, f) for f in BODY_ROWS]
    whole = ([getattr(contacts, f) for f in CONTACT_WHOLE] + [getattr(contacts.grip, f) for f in GRIP_WHOLE]
             + [getattr(bodies, f) for f in BODY_WHOLE])
    return rows, whole


def make_stall_guard(arrays: KernelArrays, workspace: Workspace, contacts: Contacts, bodies: Bodies, levels: int,
                     far: float, wild: float = STALL_WILD) -> StallGuard:
    """The :class:`~bullet_dlo.bullet.kernels.StallGuard` of a cable: copies of the arrays a contact step reads
    and writes (:func:`step_state` of ``contacts`` and ``bodies``), the twist state in ``arrays`` (and the clamps'
    current axes) and BDF2's history in ``workspace``."""
    n = arrays.mass.shape[0]
    live_rows, live_whole = step_state(contacts, bodies)
    rows = [(a, a.copy()) for a in live_rows]
    whole = [(a, a.copy()) for a in live_whole]
    # every twist array, empty ones too: one tuple type for every cable, so the step kernels compile once
    whole += [(a, a.copy()) for a in (getattr(arrays, f"tw_{f}") for f in (*TwistState._fields, "clamp"))]
    whole += [(workspace.x_prev, workspace.x_prev.copy()), (workspace.v_prev, workspace.v_prev.copy())]
    return StallGuard(levels=int(levels), far=float(far), wild=float(wild), x0=np.zeros((n, 3)), v0=np.zeros((n, 3)),
                      vs=np.zeros((n, 3)), rows=tuple(rows), whole=tuple(whole), info=np.zeros(6))


class CableSolver:
    """Plans each coming Bullet step of one cable with the core integrator and takes over the step Bullet made.

    stepper: the integrator's step (h = dt / substeps [s]); coupling: state in and out, sphere forces, held-end
    samples, planned end loads (:class:`~bullet_dlo.bullet.kernels.Coupling`); workspace: the step kernels'
    scratch; plan: the held ends' move tables (:class:`~bullet_dlo.core.kernels.holders.HolderPlan`);
    detector: the instability detector; status: STABLE or why it stopped (:mod:`bullet_dlo.core.kernels.monitor`);
    time_to_instability [s] (None: stable); newton_iterations, newton_failures: counts over all steps (a failure:
    a step whose solves did not all converge, after its retry); near_misses: of those, the steps whose contact
    solve ended near convergence (within ``stall_far``) and was kept; far_kept: those whose solve ended beyond
    it but had moved the momentum (kept); coasts: kept solves that coasted (only with the guard off);
    stall_retries: contact steps taken again as sub-steps after a coast or a solve beyond ``STALL_WILD`` with a free body in it; worst_kept_ratio: the largest residual ratio of a
    kept contact solve (:func:`~bullet_dlo.core.kernels.contact.stall_ratio`); last_ratio: the last step's (0 when
    its solve converged); stop_report: why the run stopped as STALLED or BODY_ENERGY (:meth:`stop`; None
    otherwise). stall_levels, stall_far: the retry's settings (:class:`StallGuard`; taken from :data:`STALL_RETRIES`, :data:`STALL_FAR` when the solver is made; a change takes effect with the next
    contact set, or at once after ``solver._guard = None``).
    """

    def __init__(self, model: CableModel, arrays: KernelArrays, control: CableControl, state: CableState, *,
                 method: Integrator, newton: NewtonOptions, detector: DetectorOptions, dt: float, substeps: int,
                 gravity: np.ndarray):
        n = model.n
        self.stepper = make_stepper(method, dt / substeps, newton)
        self.coupling = Coupling(dt=float(dt), substeps=substeps, gravity=np.array(gravity, dtype=float),  # writable: one type
                                 x=state.x.copy(), v=state.v.copy(), v_bullet=state.v.copy(), x_new=np.zeros((n, 3)),
                                 v_new=np.zeros((n, 3)), force=np.zeros((n, 3)), samples=empty_samples(),
                                 end_force=np.zeros((2, 3)), end_torque=np.zeros((2, 3)), energy=np.zeros(1),
                                 rows=make_record_rows(n))
        self.workspace = make_workspace(n)
        # the samplers write a twisting cable's clamp axes into the control (not the model)
        self.plan = model.holder_plan(control)
        sample_holders(self.plan, float(state.t), float(dt), self.coupling.samples)
        self.detector_options = detector
        self.detector = start_detector(detector, model, arrays, self.coupling.x, self.coupling.v,
                                       self.coupling.samples)
        self.status = STABLE
        self.time_to_instability: float | None = None
        self.newton_iterations = 0
        self.newton_failures = 0
        self.near_misses = 0
        self.far_kept = 0
        self.coasts = 0
        self.stall_retries = 0
        self.worst_kept_ratio = 0.0
        self.last_ratio = 0.0
        self.stop_report: str | None = None
        self.steps_planned = 0
        self.stall_levels = STALL_RETRIES
        self.stall_far = STALL_FAR
        self._warned_share = False
        self._guard: StallGuard | None = None
        self._guard_contacts: Contacts | None = None  # the contact set the guard's copies are of
        self._kernel = None  # step_with's machine code (sync_and_advance on packed arguments), bound on first use
        self._packed: tuple = ()  # the objects packed into self._args (solver_call.StepArgs)
        self._args = None
        self._addresses: tuple = ()  # the first-class functions packed into self._args (kept alive with them)
        self._plain = None  # sync_and_advance's machine code (PACK_ARGS off)

    def restart_detector(self, model: CableModel, arrays: KernelArrays) -> None:
        """Start the detector again from the current state (after a set-up change of the model)."""
        cp = self.coupling
        self.detector = start_detector(self.detector_options, model, arrays, cp.x, cp.v, cp.samples)

    def forget_factors(self) -> None:
        """Drop the Newton factors an earlier step kept for later ones (``Workspace.matrices``): a step planned again
        from the same state then starts as a step after a contact solve does, whatever plans came between."""
        self.workspace.matrices[1] = 0.0

    def step_input(self, t: float, steps: int, sync: bool, record: bool, contacts: Contacts, index: np.ndarray,
                   pos: np.ndarray, vel: np.ndarray) -> StepInput:
        """What a step needs from the caller: the time t [s] of the state the next step is planned from, the
        steps taken so far, whether to take over Bullet's step and record it, the touched spheres' read-back
        state (index (k,), pos [m], vel [m/s] (k, 3))."""
        det = self.detector
        has_prev = steps > 0 and contacts.impact.item(0) == 0  # BDF2 restarts after an impact
        return _new_tuple(StepInput, (t, has_prev, sync, sync and steps % det.check_every == 0,
                                      sync and steps % det.energy_every == 0, record, index, pos, vel))

    def kernel_args(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, bodies: Bodies,
                    inp: StepInput) -> tuple:
        """Arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` but the two kernels it calls (the same
        objects every step)."""
        return (self.stepper, arrays, self.plan, control.holders, self.coupling, self.workspace, self.detector, inp,
                contacts, bodies, self.stall_guard(arrays, contacts, bodies))

    def stall_guard(self, arrays: KernelArrays, contacts: Contacts, bodies: Bodies) -> StallGuard:
        """The retry's copies for this contact set and its bodies (made anew when the set was rebuilt)."""
        if self._guard is None or self._guard_contacts is not contacts:
            old = self._guard
            self._guard = make_stall_guard(arrays, self.workspace, contacts, bodies, self.stall_levels,
                                           self.stall_far)
            self._guard_contacts = contacts
            if old is not None and numba.typeof(old) != numba.typeof(self._guard):
                self._kernel = self._plain = None  # another structure (a row array sized like the rows by chance)
        return self._guard

    def step(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, bodies: Bodies,
             inp: StepInput) -> int:
        """Take over Bullet's step (if ``inp.sync``), check it, plan the next with the contacts and the free bodies
        solved with them; returns the status (STABLE or the reason's code: then nothing is planned)."""
        guard = self.stall_guard(arrays, contacts, bodies)
        held = self._held(arrays, control, contacts, bodies, guard)
        if not PACK_ARGS or not hasattr(sync_and_advance, "compile") or _get_wrapper_address is None:
            # (JIT disabled, or a Numba without first-class functions: a plain call)
            calls = (contact_step, advance)
            if self._plain is None:
                self._plain = bind(sync_and_advance, *held[:7], inp, *held[7:], *calls)
            status, its, ok = self._plain(*held[:7], inp, *held[7:], *calls)
        else:
            if self._kernel is None or any(map(is_not, held, self._packed)):
                self._pack(held, inp)  # one of the objects was replaced: pack the ones a plain call would pass now
            status, its, ok = self._kernel(self._args, inp)
        return self.account(status, its, ok, inp.t)

    def packed_args(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, bodies: Bodies):
        """The packed kernel arguments the last step ran on (:func:`~bullet_dlo.bullet.solver_call.step_with`'s
        first), or None when they are not the ones a step with these objects would pass now (not packed yet, one of
        the objects replaced since, or the plain call in use): :mod:`bullet_dlo.bullet.plain_steps` then leaves the
        step to :meth:`step`."""
        if self._kernel is None or self._guard is None or self._guard_contacts is not contacts:
            return None
        held = self._held(arrays, control, contacts, bodies, self._guard)
        return None if any(map(is_not, held, self._packed)) else self._args

    def _held(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, bodies: Bodies,
              guard: StallGuard) -> tuple:
        """The kernel's per-cable arguments in :data:`~bullet_dlo.bullet.solver_call.FIELDS` order."""
        return (self.stepper, arrays, self.plan, control.holders, self.coupling, self.workspace, self.detector,
                contacts, bodies, guard)

    def account(self, status: int, its: int, ok: bool, t: float) -> int:
        """Count a planned step (its status, Newton iterations, convergence, and the stall guard's ``info`` it
        left) planned from time t [s]; an unstable status stops the solver with its report. Returns the status."""
        info = self._guard.info
        self.steps_planned += 1
        self.newton_iterations += its
        if not ok:
            self.newton_failures += 1
        if info.item(RETRY_SUBSTEPS) > 0:
            self.stall_retries += 1
        ratio = self.last_ratio = info.item(FINAL_RATIO)
        if status == STABLE and ratio > 0.0:
            if ratio <= self.stall_far:
                self.near_misses += 1
            else:
                self.far_kept += 1
            self.coasts += int(info[COASTED])
            self.worst_kept_ratio = max(self.worst_kept_ratio, ratio)
        if status != STABLE:
            self.status = status
            self.time_to_instability = t
            if status == STALLED:
                retried = (f"taken again as {' then '.join(str(2 ** k) for k in range(1, self.stall_levels + 1))} "
                           f"sub-steps it still ended at {info[FINAL_RATIO]:.3g}" if self.stall_levels > 0
                           else "not taken again (no retries allowed)")
                self.stop_report = (
                    f"t = {t:.6g} s: the contact Newton solve of the step ended after {int(info[FIRST_ITER])} "
                    f"iteration(s) with its momentum residual at {info[FIRST_RATIO]:.3g} times gravity's impulse in "
                    f"a step, having moved the momentum by {info[FIRST_MOVED]:.3g} of it: the cable would coast "
                    f"through the step as if no force acted; {retried}. The cable is stopped as unstable "
                    f"({REASONS[STALLED]}); try a smaller dt or softer contact")
                warnings.warn(self.stop_report, RuntimeWarning, stacklevel=4)
        else:
            self.judge_share()
        return status

    def judge_share(self) -> None:
        """Warn once when more than NEWTON_WARN_SHARE of the steps planned so far ended unconverged (judged from
        NEWTON_WARN_MIN_STEPS steps on; after every stable step, and after a batch of plain steps, whose converged
        steps only lower the share)."""
        if not self._warned_share and self.steps_planned >= NEWTON_WARN_MIN_STEPS:
            share = self.newton_failures / self.steps_planned
            if share > NEWTON_WARN_SHARE:
                self._warned_share = True
                warnings.warn(self.failure_message(), RuntimeWarning, stacklevel=5)

    def stop(self, status: int, t: float, report: str) -> None:
        """Stop the cable as unstable for a reason found outside the step kernel (``status``, a code of
        :data:`~bullet_dlo.core.kernels.monitor.REASONS`) at time t [s], with a RuntimeWarning of ``report``."""
        self.status = status
        self.time_to_instability = t
        self.stop_report = report
        warnings.warn(report, RuntimeWarning, stacklevel=4)

    def _pack(self, held: tuple, inp: StepInput) -> None:
        """Pack ``held`` (the kernel's per-cable arguments, :data:`~bullet_dlo.bullet.solver_call.FIELDS`) into one
        StructRef and bind the kernel to its type (Numba unboxes one pointer a step instead of ~150 arrays)."""
        old = numba.typeof(self._args) if self._args is not None else None
        self._args, self._addresses = pack_step_args(held)
        self._packed = held
        if self._kernel is None or numba.typeof(self._args) != old:
            self._kernel = bind(step_with, self._args, inp)

    def failure_message(self) -> str:
        """What the counters say about the Newton solves so far, in one line (a warning's text)."""
        share = self.newton_failures / max(self.steps_planned, 1)
        return (f"Newton did not converge in {self.newton_failures} of {self.steps_planned} steps so far "
                f"({100 * share:.1f} %): {self.near_misses} contact steps ended near convergence (within "
                f"{self.stall_far:g} of gravity's impulse in a step) and {self.far_kept} far from it (the worst at "
                f"{self.worst_kept_ratio:.3g}) and were kept; {self.stall_retries} coasted (no momentum moved) and "
                "were taken again as sub-steps. The implicit "
                "equations were solved only approximately; use a smaller dt or more substeps")
