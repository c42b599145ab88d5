"""The core's fixed-step time loop in one Numba call (so that even 1e-7 s steps are affordable)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from bullet_dlo.core.kernels.forces import mechanical_energy
from bullet_dlo.core.kernels.holders import HeldSamples, sample_holders
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


@njit(cache=True, error_model="numpy")
def run_loop(stepper, m, plan, x, v, t0, n_steps, det, ws, rec):
    """``n_steps`` steps of ``stepper`` from (x, v) at t0 [s], in place, watched by ``det``.

    m: KernelArrays (the model under its control, with the twist state); plan: HolderPlan; det: Detector started at (x, v); ws: Workspace;
    rec: Records. Stops at the first unstable check. Returns (steps done, status, time of
    instability [s] or -1, rows recorded, Newton failures, Newton iterations).
    """
    h = stepper.h
    samples = HeldSamples(np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)))
    ef = det.end_force.copy()  # end forces of the latest state [N]
    rec.t[0] = t0
    rec.x[0] = x
    rec.v[0] = v
    rec.end_force[0] = ef
    rec.end_moment[0] = det.end_moment
    rec.energy[0] = det.e0
    rows = 1
    status = STABLE
    t_bad = -1.0
    failures = 0
    total_iters = 0
    steps = 0
    for k in range(n_steps):
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
            t_bad = t_new
            break
    return steps, status, t_bad, rows, failures, total_iters
