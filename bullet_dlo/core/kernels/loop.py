"""The core's fixed-step time loop in Numba (so that even 1e-7 s steps are affordable), callable in pieces:
the engine runs it in stretches of about 0.1 s so that a Ctrl-C stops a run promptly."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.kernels.holders import HeldSamples, sample_holders
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.monitor import STABLE, clamp_moments, end_forces, monitor
from bullet_dlo.core.kernels.steppers import advance


class Records(NamedTuple):
    """Rows recorded every ``every`` steps (first row: the start; also the last and an unstable step).

    t: times [s], (rows,); x: positions [m], (rows, n, 3); v: velocities [m/s], (rows, n, 3);
    end_force: force the cable exerts on each holder [N], (rows, 2, 3); end_moment: moment it exerts
    on each clamp [N m], (rows, 2, 3) (taken in the loop: a twisting cable's clamp moment depends on
    its twist state, which is not recorded); energy: mechanical energy [J], (rows,).
    """

    every: int
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    end_force: np.ndarray
    end_moment: np.ndarray
    energy: np.ndarray


def make_records(rows: int, n: int, every: int) -> Records:
    """Zeroed records with room for ``rows`` rows of an n-node cable."""
    return Records(int(every), np.zeros(rows), np.zeros((rows, n, 3)), np.zeros((rows, n, 3)),
                   np.zeros((rows, 2, 3)), np.zeros((rows, 2, 3)), np.zeros(rows))


class LoopState(NamedTuple):
    """Where a run of :func:`run_loop` stands between its calls (with x, v, the model, detector, workspace and
    records, the whole state of the loop): a run taken in pieces equals the run in one call bit for bit.

    counts: steps done, rows recorded, Newton failures, Newton iterations, status (STABLE, ...), int64 (5,);
    end_force: end forces of the latest state [N], (2, 3); t_bad: time of instability [s] or -1, (1,).
    """

    counts: np.ndarray
    end_force: np.ndarray
    t_bad: np.ndarray


STEPS, ROWS, FAILURES, ITERS, STATUS = 0, 1, 2, 3, 4


def start_loop(det) -> LoopState:
    """The state of a run that has not started, watched by ``det`` (a Detector at its start)."""
    return LoopState(np.zeros(5, np.int64), det.end_force.copy(), np.full(1, -1.0))


@njit(cache=True, error_model="numpy")
def run_loop(stepper, m, plan, x, v, t0, n_steps, stop, det, ws, rec, loop):
    """Steps of ``stepper`` up to step ``stop`` (<= n_steps) of an ``n_steps`` run from (x, v) at t0 [s], in place,
    watched by ``det``, from where ``loop`` (a :class:`LoopState`) stands; its first call records the start row.

    m: KernelArrays (the model under its control, with the twist state); plan: HolderPlan; det: Detector started
    at (x, v); ws: Workspace; rec: Records. Stops at the first unstable check. Step k starts at t0 + k h whatever
    the calls, so any split of the run gives the same result. Returns the status (also in ``loop.counts``).
    """
    h = stepper.h
    samples = HeldSamples(np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)))
    ef = loop.end_force  # end forces of the latest state [N]
    counts = loop.counts
    if counts[ROWS] == 0:
        rec.t[0] = t0
        rec.x[0] = x
        rec.v[0] = v
        rec.end_force[0] = ef
        rec.end_moment[0] = det.end_moment
        rec.energy[0] = det.e0
        counts[ROWS] = 1
    rows = counts[ROWS]
    status = counts[STATUS]
    failures = counts[FAILURES]
    total_iters = counts[ITERS]
    steps = counts[STEPS]
    if status != STABLE:
        return status
    for k in range(counts[STEPS], min(stop, n_steps)):
        sample_holders(plan, t0 + k * h, h, samples)
        its, ok = advance(stepper, m, x, v, samples, ws, k > 0)
        total_iters += its
        if not ok:
            failures += 1
        steps = k + 1
        t_new = t0 + steps * h
        do_rec = steps % rec.every == 0 or steps == n_steps
        energy_check = steps % det.energy_every == 0 or steps == n_steps
        if steps % det.check_every == 0 or energy_check:
            status = monitor(m, x, v, samples, det, energy_check)
        if energy_check:
            ef[:, :] = det.end_force
        elif do_rec:
            end_forces(m, x, v, samples.dir[2], samples.acc[2], ef)
        if (do_rec or status != STABLE) and rows < rec.t.shape[0]:
            rec.t[rows] = t_new
            rec.x[rows] = x
            rec.v[rows] = v
            rec.end_force[rows] = ef
            clamp_moments(m, x, v, samples.dir[2], rec.end_moment[rows])
            rec.energy[rows] = mechanical_energy(m, x, v, samples.dir[2])
            rows += 1
        if status != STABLE:
            loop.t_bad[0] = t_new
            break
    counts[STEPS] = steps
    counts[ROWS] = rows
    counts[FAILURES] = failures
    counts[ITERS] = total_iters
    counts[STATUS] = status
    return status
