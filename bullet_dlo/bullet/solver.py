"""The model side of a coupled Bullet step, in one call: :class:`CableSolver`.

Shaped like Newton's ``solver.step(state_in, state_out, control, contacts, dt)``: the solver holds what a
cable's steps share (the integrator step, scratch memory, the held ends' plan, the instability detector and
the buffers of the Bullet step, :class:`~bullet_dlo.bullet.kernels.Coupling`), and :meth:`CableSolver.step`
takes the rest: the kernels' view of model, control and state (:class:`~bullet_dlo.core.model.KernelArrays`),
the control (the holders' measured poses), the contacts detected for the coming step and what Bullet's step
changed (:class:`~bullet_dlo.bullet.kernels.StepInput`). The state in is ``coupling.x, v``, the state out
``coupling.x_new, v_new`` with the sphere forces that make Bullet land there; one step is one Numba call
(:func:`~bullet_dlo.bullet.kernels.sync_and_advance`): take over the step Bullet made, check it, plan the next.
"""
from __future__ import annotations

import numpy as np

from bullet_dlo.bullet.kernels import Coupling, StepInput, bind, sync_and_advance
from bullet_dlo.core.engine import DetectorOptions, start_detector
from bullet_dlo.core.integrators import Integrator, NewtonOptions, make_stepper
from bullet_dlo.core.kernels.contact import Contacts
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.kernels.monitor import STABLE
from bullet_dlo.core.kernels.steppers import make_workspace
from bullet_dlo.core.model import CableControl, CableModel, CableState, KernelArrays


class CableSolver:
    """Plans each coming Bullet step of one cable with the core integrator and takes over the step Bullet made.

    stepper: the integrator's step (h = dt / substeps [s]); coupling: state in and out, sphere forces, held-end
    samples, planned end loads (:class:`~bullet_dlo.bullet.kernels.Coupling`); workspace: the step kernels'
    scratch; plan: the held ends' move tables (:class:`~bullet_dlo.core.kernels.holders.HolderPlan`);
    detector: the instability detector; status: STABLE or why it stopped (:mod:`bullet_dlo.core.kernels.monitor`);
    time_to_instability [s] (None: stable); newton_iterations, newton_failures: counts over all steps.
    """

    def __init__(self, model: CableModel, arrays: KernelArrays, control: CableControl, state: CableState, *,
                 method: Integrator, newton: NewtonOptions, detector: DetectorOptions, dt: float, substeps: int,
                 gravity: np.ndarray):
        n = model.n
        self.stepper = make_stepper(method, dt / substeps, newton)
        self.coupling = Coupling(dt=float(dt), substeps=substeps, gravity=np.asarray(gravity, dtype=float),
                                 x=state.x.copy(), v=state.v.copy(), v_bullet=state.v.copy(), x_new=np.zeros((n, 3)),
                                 v_new=np.zeros((n, 3)), force=np.zeros((n, 3)), samples=empty_samples(),
                                 end_force=np.zeros((2, 3)), end_torque=np.zeros((2, 3)), energy=np.zeros(1))
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
        self._kernel = None  # sync_and_advance's machine code, bound on first use

    def restart_detector(self, model: CableModel, arrays: KernelArrays) -> None:
        """Start the detector again from the current state (after a set-up change of the model)."""
        cp = self.coupling
        self.detector = start_detector(self.detector_options, model, arrays, cp.x, cp.v, cp.samples)

    def step_input(self, t: float, steps: int, sync: bool, record: bool, contacts: Contacts, index: np.ndarray,
                   pos: np.ndarray, vel: np.ndarray) -> StepInput:
        """What a step needs from the caller: the time t [s] of the state the next step is planned from, the
        steps taken so far, whether to take over Bullet's step and record it, the touched spheres' read-back
        state (index (k,), pos [m], vel [m/s] (k, 3))."""
        det = self.detector
        has_prev = steps > 0 and contacts.impact[0] == 0  # BDF2 restarts after an impact
        return StepInput(t, has_prev, sync, sync and steps % det.check_every == 0,
                         sync and steps % det.energy_every == 0, record, index, pos, vel)

    def kernel_args(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, inp: StepInput) -> tuple:
        """Arguments of :func:`~bullet_dlo.bullet.kernels.sync_and_advance` (the same objects every step)."""
        return (self.stepper, arrays, self.plan, control.holders, self.coupling, self.workspace, self.detector, inp,
                contacts)

    def step(self, arrays: KernelArrays, control: CableControl, contacts: Contacts, inp: StepInput) -> int:
        """Take over Bullet's step (if ``inp.sync``), check it, plan the next; returns the status (STABLE or the
        reason's code: then nothing is planned)."""
        args = self.kernel_args(arrays, control, contacts, inp)
        if self._kernel is None:
            self._kernel = bind(sync_and_advance, *args)
        status, its, ok = self._kernel(*args)
        self.newton_iterations += its
        self.newton_failures += 0 if ok else 1
        if status != STABLE:
            self.status = status
            self.time_to_instability = inp.t
        return status
