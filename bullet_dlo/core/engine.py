"""The core engine: run a cable model with one integrator, watch for instability, record.

``simulate(model, "implicit_euler", dt=1e-3, duration=2.0)`` runs the whole time loop in
Numba (so even 1e-7 s steps are affordable) and returns a :class:`SimulationResult`.
An unstable run is data, not an exception: the result says when it went unstable and why.

Instability detector (cheap checks every ``check_every`` steps, energy every ``energy_every``):

* non-finite positions or velocities;
* a segment stretched or compressed beyond ``max_strain`` (default 50 %);
* energy created from nothing: E(t) - E(0) - W_holders(t) > ``energy_factor`` * E_scale, with
  E the kinetic + elastic + gravitational energy, W the work done by the held ends, and
  E_scale = M |g| L + |E(0) elastic and kinetic| + sum |dW| (so a dissipative or energy-
  conserving method never trips it, while exponential growth trips it within a few steps).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from bullet_dlo.core.boundary import sample_holders
from bullet_dlo.core.integrators import BDF2, WORK_SLOTS, NewtonOptions, get_integrator, step_kernel
from bullet_dlo.core.kernels.forces import clamp_torque, internal_energy, max_strain, total_forces
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.validate import ParameterError, check_int, check_positive

STABLE, NONFINITE, STRETCH, ENERGY = 0, 1, 2, 3
REASONS = {STABLE: None, NONFINITE: "non-finite state", STRETCH: "segment strain beyond bound",
           ENERGY: "energy growth beyond the work done on the cable"}


@dataclass(frozen=True)
class DetectorOptions:
    """Instability detector thresholds.

    max_strain: largest allowed |l/l0 - 1| of any segment; energy_factor: allowed energy
    created, as a multiple of the energy scale (see module doc); check_every: steps between
    the cheap checks (finite, strain); energy_every: steps between energy-balance checks
    (an energy evaluation costs about a force evaluation).
    """

    max_strain: float = 0.5
    energy_factor: float = 1.0
    check_every: int = 1
    energy_every: int = 10


@dataclass
class SimulationResult:
    """Outcome of a run. Arrays are recorded every ``record_every`` steps (plus the final state).

    t: times [s], (k,); x, v: positions [m] / velocities [m/s], (k, n, 3);
    end_forces: force the cable exerts on each holder [N], (k, 2, 3) (first, last);
    energy: total mechanical energy [J], (k,).
    """

    integrator: str
    dt: float
    stable: bool
    time_to_instability: float | None
    reason: str | None
    steps: int
    wall_time_s: float
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    end_forces: np.ndarray
    energy: np.ndarray
    final_state: CableState
    end_moments: np.ndarray = field(default_factory=lambda: np.zeros((2, 3)))
    newton_failures: int = 0
    newton_iterations: int = 0

    def summary(self) -> dict[str, Any]:
        """Small JSON-ready dict."""
        return {
            "integrator": self.integrator, "dt": self.dt, "stable": self.stable,
            "time_to_instability": self.time_to_instability, "reason": self.reason,
            "steps": self.steps, "wall_time_s": self.wall_time_s,
        }


@njit(cache=True, error_model="numpy")
def end_forces_kernel(x, v, m, dirs, acc, f_ext, out):
    """Force [N] the cable exerts on each held end, (2, 3): F_node - m a (zero for free ends).

    F_node is everything acting on the held node except the holder (elastic incl. clamp
    spring, gravity, damping, external), so for a static cable the two rows sum to M g.
    """
    n = x.shape[0]
    f = np.empty_like(x)
    total_forces(x, v, m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity, dirs[0], dirs[1], f_ext, f)
    out[:, :] = 0.0
    if m.held[0]:
        out[0, :] = f[0] - m.mass[0] * acc[0]
    if m.held[n - 1]:
        out[1, :] = f[n - 1] - m.mass[n - 1] * acc[1]


@njit(cache=True, error_model="numpy")
def energy_kernel(x, v, m, dirs):
    """Kinetic + elastic + gravitational energy [J]."""
    e = internal_energy(x, m.k_stretch, m.rest_length, m.k_bend, dirs[0], dirs[1])
    for i in range(x.shape[0]):
        for j in range(3):
            e += 0.5 * m.mass[i] * v[i, j] * v[i, j] - m.mass[i] * m.gravity[j] * x[i, j]
    return e


@njit(cache=True, error_model="numpy")
def _check_state(x, v, m, max_strain_bound):
    """The cheap checks: finite state, strain within bound."""
    for i in range(x.shape[0]):
        for j in range(3):
            if not (math.isfinite(x[i, j]) and math.isfinite(v[i, j])):
                return NONFINITE
    if not max_strain(x, m.rest_length) <= max_strain_bound:
        return STRETCH
    return STABLE


@njit(cache=True, error_model="numpy")
def _check(x, v, m, dirs, max_strain_bound, e0, work, e_scale, energy_factor):
    status = _check_state(x, v, m, max_strain_bound)
    if status != STABLE:
        return status
    e = energy_kernel(x, v, m, dirs)
    if not (e - e0 - work <= energy_factor * e_scale):
        return ENERGY
    return STABLE


HIST_SLOTS = 4 + WORK_SLOTS


def history(n: int) -> np.ndarray:
    """Multistep history plus integrator workspace for :func:`advance`, shape (HIST_SLOTS, n, 3)."""
    return np.zeros((HIST_SLOTS, n, 3))


@njit(cache=True, error_model="numpy")
def advance(code, x, v, hist, has_prev, h, m, hp, hv, hd, f_ext, max_iter, tol, definite):
    """One step of method ``code`` in place, keeping BDF2's history in ``hist``.

    hist: (HIST_SLOTS, n, 3) from :func:`history`: hist[0], hist[1] are the previous x, v
    (valid when ``has_prev``), hist[2:4] scratch, hist[4:] the integrator workspace.
    Returns (Newton iterations, converged).
    """
    if code == BDF2:
        hist[2] = x
        hist[3] = v
    its, ok = step_kernel(code, x, v, hist[0], hist[1], has_prev, h, m, hp, hv, hd, f_ext, max_iter, tol, definite,
                          hist[4:])
    if code == BDF2:
        hist[0] = hist[2]
        hist[1] = hist[3]
    return its, ok


@njit(cache=True, error_model="numpy")
def monitor(x, v, m, hp2, ha2, hd2, f_ext, ef, last_hold, last_force, acc, e0, max_strain_bound, energy_factor,
            energy_check):
    """Instability check after a step (held ends at hp2/ha2/hd2, each (2, 3)).

    Without ``energy_check`` only the cheap checks run (finite, strain). With it, also writes
    the end forces into ``ef``; accumulates the work the holders did on the cable since the
    last energy check (trapezoid of force times held-end displacement) into acc[0] and its
    absolute value into the energy scale acc[1]; and checks the energy balance.
    Returns a status code (STABLE, ...).
    """
    if not energy_check:
        return _check_state(x, v, m, max_strain_bound)
    end_forces_kernel(x, v, m, hd2, ha2, f_ext, ef)
    for e in range(2):
        for j in range(3):
            dw = -0.5 * (ef[e, j] + last_force[e, j]) * (hp2[e, j] - last_hold[e, j])
            acc[0] += dw
            acc[1] += abs(dw)
    last_hold[:, :] = hp2
    last_force[:, :] = ef
    return _check(x, v, m, hd2, max_strain_bound, e0, acc[0], acc[1], energy_factor)


@njit(cache=True, error_model="numpy")
def run_loop(code, x, v, t0, h, n_steps, m, p0s, d0s, moves_first, moves_last, f_ext,
             record_every, rec_t, rec_x, rec_v, rec_f, rec_e,
             max_iter, tol, definite, max_strain_bound, energy_factor, check_every, energy_every, e_scale0):
    """Fixed-step loop; records every ``record_every`` steps into rec_* (first row = start).

    Returns (steps done, status, time of instability, rows recorded, Newton failures,
    Newton iterations).
    """
    n = x.shape[0]
    hp = np.empty((3, 2, 3))
    hv = np.empty((3, 2, 3))
    ha = np.empty((3, 2, 3))
    hd = np.empty((3, 2, 3))
    ef = np.empty((2, 3))
    hist = np.zeros((4 + WORK_SLOTS, n, 3))
    sample_holders(t0, h, p0s, d0s, moves_first, moves_last, hp, hv, ha, hd)
    e0 = energy_kernel(x, v, m, hd[0])
    end_forces_kernel(x, v, m, hd[0], ha[0], f_ext, ef)
    acc = np.array([0.0, e_scale0])  # holder work, energy scale
    last_hold = hp[0].copy()
    last_force = ef.copy()
    rec_t[0] = t0
    rec_x[0] = x
    rec_v[0] = v
    rec_f[0] = ef
    rec_e[0] = e0
    rows = 1
    status = STABLE
    t_bad = -1.0
    failures = 0
    total_iters = 0
    steps = 0
    for k in range(n_steps):
        sample_holders(t0 + k * h, h, p0s, d0s, moves_first, moves_last, hp, hv, ha, hd)
        its, ok = advance(code, x, v, hist, k > 0, h, m, hp, hv, hd, f_ext, max_iter, tol, definite)
        total_iters += its
        if not ok:
            failures += 1
        steps = k + 1
        t_new = t0 + steps * h
        do_rec = steps % record_every == 0 or steps == n_steps
        energy_check = steps % energy_every == 0 or steps == n_steps
        if steps % check_every == 0 or energy_check:
            status = monitor(x, v, m, hp[2], ha[2], hd[2], f_ext, ef, last_hold, last_force, acc, e0,
                             max_strain_bound, energy_factor, energy_check)
        if do_rec and not energy_check:
            end_forces_kernel(x, v, m, hd[2], ha[2], f_ext, ef)
        if (do_rec or status != STABLE) and rows < rec_t.shape[0]:
            rec_t[rows] = t_new
            rec_x[rows] = x
            rec_v[rows] = v
            rec_f[rows] = ef
            rec_e[rows] = energy_kernel(x, v, m, hd[2])
            rows += 1
        if status != STABLE:
            t_bad = t_new
            break
    return steps, status, t_bad, rows, failures, total_iters


def energy_scale(model: CableModel, state: CableState) -> float:
    """M |g| L + kinetic and elastic energy of the start state [J] (floor of the energy check)."""
    a = model.arrays
    ke = 0.5 * float(np.sum(a.mass[:, None] * state.v**2))
    ee = internal_energy(state.x, a.k_stretch, a.rest_length, a.k_bend, model.first.direction, model.last.direction)
    return model.spec.mass * float(np.linalg.norm(a.gravity)) * model.spec.length + ke + ee + 1e-12


def simulate(
    model: CableModel,
    integrator: str = "implicit_euler",
    dt: float = 1e-3,
    duration: float = 1.0,
    *,
    state: CableState | None = None,
    record_every: int | None = None,
    max_records: int = 2001,
    newton: NewtonOptions = NewtonOptions(),
    detector: DetectorOptions = DetectorOptions(),
    f_ext: np.ndarray | None = None,
) -> SimulationResult:
    """Run ``model`` for ``duration`` seconds with fixed steps ``dt``.

    Args:
        model: the cable and its end conditions.
        integrator: name from :data:`bullet_dlo.integrators.INTEGRATORS`.
        dt: time step [s], > 0.
        duration: simulated time [s], > 0 (rounded to a whole number of steps).
        state: start state (default: the model's initial state at rest).
        record_every: steps between recorded rows (default: so that about ``max_records`` rows are kept).
        newton: Newton options for implicit methods.
        detector: instability thresholds.
        f_ext: constant external forces [N], (n, 3).
    """
    method = get_integrator(integrator)
    dt = check_positive("dt", dt)
    duration = check_positive("duration", duration)
    n_steps = max(1, int(round(duration / dt)))
    if record_every is None:
        record_every = max(1, math.ceil(n_steps / max(1, max_records - 1)))
    record_every = check_int("record_every", record_every, 1)
    check_int("newton max_iter", newton.max_iter, 1)
    tol = check_positive("newton tol", newton.tolerance(method.name))
    check_positive("max_strain", detector.max_strain)
    check_positive("energy_factor", detector.energy_factor)
    check_int("check_every", detector.check_every, 1)
    check_int("energy_every", detector.energy_every, 1)
    st = (state or model.initial_state()).copy()
    n = model.n
    if st.x.shape != (n, 3) or st.v.shape != (n, 3):
        raise ParameterError(f"state arrays must have shape ({n}, 3)")
    if f_ext is None:
        f_ext = np.zeros((n, 3))
    f_ext = np.ascontiguousarray(f_ext, dtype=float)
    if f_ext.shape != (n, 3) or not np.all(np.isfinite(f_ext)):
        raise ParameterError(f"f_ext must be a finite array of shape ({n}, 3)")
    rows_max = n_steps // record_every + 3
    rec_t = np.zeros(rows_max)
    rec_x = np.zeros((rows_max, n, 3))
    rec_v = np.zeros((rows_max, n, 3))
    rec_f = np.zeros((rows_max, 2, 3))
    rec_e = np.zeros(rows_max)
    p0s, d0s, mf, ml = model.holder_tables()
    x, v = st.x, st.v
    tic = time.perf_counter()
    steps, status, t_bad, rows, failures, iters = run_loop(
        method.code, x, v, st.t, dt, n_steps, model.arrays, p0s, d0s, mf, ml, f_ext,
        record_every, rec_t, rec_x, rec_v, rec_f, rec_e,
        newton.max_iter, tol, newton.definite,
        detector.max_strain, detector.energy_factor, detector.check_every, detector.energy_every,
        energy_scale(model, st),
    )
    wall = time.perf_counter() - tic
    t_final = st.t + steps * dt
    final = CableState(x, v, t_final)
    a = model.arrays
    moments = np.zeros((2, 3))
    if status == STABLE:
        from bullet_dlo.core.boundary import held_pose

        dirs = np.zeros((2, 3))
        for e, (p0, d0, mv) in enumerate(((p0s[0], d0s[0], mf), (p0s[1], d0s[1], ml))):
            held_pose(t_final, p0, d0, mv, np.zeros(3), np.zeros(3), np.zeros(3), dirs[e])
        moments = np.stack([clamp_torque(x, a.k_bend, dirs[0], dirs[1], e) for e in (0, 1)])
    return SimulationResult(
        integrator=method.name, dt=dt, stable=status == STABLE,
        time_to_instability=None if status == STABLE else float(t_bad), reason=REASONS[status],
        steps=int(steps), wall_time_s=wall,
        t=rec_t[:rows].copy(), x=rec_x[:rows].copy(), v=rec_v[:rows].copy(),
        end_forces=rec_f[:rows].copy(), energy=rec_e[:rows].copy(), final_state=final,
        end_moments=moments, newton_failures=int(failures), newton_iterations=int(iters),
    )
