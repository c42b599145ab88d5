"""Cost of the twist-enabled implicit step against the round frameless step at the same n (issue 22, item 6).

The same scene with and without a material frame: a round cable (``CableSpec.lv2017``) clamped at both ends
under gravity, the last end moved 5 cm towards the first and rolled 90 degrees about the cable's axis over the
run (the twisting cable feels the roll, the frameless one does not). Each run is ``--steps`` steps of BDF2 at
dt 1 ms; twisting and frameless runs are interleaved ``--repeats`` times and timed in thread CPU time; the
script prints per-step medians, ranges, the ratio of medians and the load average, then the same ratio of the
steps alone: each ``simulate`` call also pays a fixed cost (about 21 ms, mostly the held-end speed warning's
20 000 samples, the same with and without the frame), so the second ratio takes (run - one-step run) /
(steps - 1). ``--parts`` prints instead where the coupled BDF2 step's time goes: each kernel timed alone per call
(a compiled loop of calls at the state after 0.3 s of the same scene, thread CPU time, median and range of 5
batches), the frameless step's kernels beside.

    python demos/twist_cost.py
    python demos/twist_cost.py --ns 10 20 40 80 --repeats 7 --steps 1000 --method bdf2
    python demos/twist_cost.py --parts --ns 80
    python demos/twist_cost.py --bullet --ns 10 20 40    # in a Bullet world: plain steps and Python's phases
    python demos/twist_cost.py --ns 80 --exact-from 1    # the exact Jacobian from the first Newton iteration
    python demos/twist_cost.py --section rectangle       # a flat strip (4 d x d/2) against the round frameless cable
    python demos/twist_cost.py --no-reuse                # a fresh Newton matrix every iteration (before 2026-12-06)
    python demos/twist_cost.py --reuse-gain --ns 10 20 80 320   # chord iterations on / off, frameless and twisting
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def model(n: int, twist: bool, duration: float, section: str = "round") -> CableModel:
    """The scene; a twisting ``section`` "rectangle" is 4 d wide and d/2 thick (d the round cable's diameter)."""
    spec = CableSpec.lv2017(n_masses=n, twist=twist, damping_rate=2.0)
    if twist and section == "rectangle":
        spec = CableSpec.lv2017(n_masses=n, damping_rate=2.0, section="rectangle", width=4 * spec.diameter,
                                thickness=spec.diameter / 2)
    move = Move("last", displacement=(-0.05 * spec.length, 0.0, 0.0), rotation=(math.pi / 2, 0.0, 0.0),
                duration=duration)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move])


NEWTON = NewtonOptions()


def step_cost(m: CableModel, method: str, dt: float, steps: int, newton: NewtonOptions | None = None) -> float:
    """Thread CPU time per step [s] of one run (``newton``: None takes ``NEWTON``, the command line's)."""
    t0 = time.thread_time()
    res = simulate(m, method, dt, steps * dt, record_every=steps, newton=NEWTON if newton is None else newton)
    cost = (time.thread_time() - t0) / steps
    if not res.stable:
        raise RuntimeError(f"unstable run: {res.reason}")
    return cost


def _parts(n: int, section: str = "round") -> None:
    """Per-call thread CPU time [us] of the coupled twisting step's kernels at n, the twisting cable's ``section``
    round or a rectangle (and the frameless ones)."""
    from numba import njit

    from bullet_dlo.core.integrators import NewtonOptions, make_stepper
    from bullet_dlo.core.kernels import twist_coupled as tc
    from bullet_dlo.core.kernels.forces import force_jacobian, total_forces
    from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
    from bullet_dlo.core.kernels.banded import band_solve
    from bullet_dlo.core.kernels.steppers import _implicit, _newton_matrix, _start_implicit, make_workspace
    from bullet_dlo.core.kernels.twist import set_clamp, update_frames

    def state(twist: bool):
        cm = model(n, twist, 1.0, section)
        st = simulate(cm, "bdf2", 1e-3, 0.3, record_every=300).final_state.copy()
        control = cm.control(None)
        m = cm.kernel_arrays(control, st.twist if st.twist is not None else cm.twist_state())
        samples = empty_samples()
        sample_holders(cm.holder_plan(control), st.t, 1e-3, samples)
        return m, samples, make_workspace(n), st.x.copy(), st.v.copy()

    @njit
    def residuals(reps, m, mp, imp, ws, samples, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc):
        for _ in range(reps):
            tc._residual(m, mp, imp, ws, samples, 1.0, 1e-3, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)

    @njit
    def matrices(reps, stepper, m, mp, imp, ws, band, g, sc, lower, upx, samples, exact):
        for _ in range(reps):
            tc._newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, 1.0, 1e-3)

    @njit
    def sym_solves(reps, band, r, bcopy, rcopy):
        for _ in range(reps):
            bcopy[:, :] = band
            rcopy[:] = r
            tc.band_solve_upper(bcopy, rcopy, tc.HALF_T, 4)

    @njit
    def solves(reps, band, lower, r, bcopy, lcopy, rcopy):
        for _ in range(reps):
            bcopy[:, :] = band
            lcopy[:, :] = lower
            rcopy[:] = r
            tc._band_lu_coupled(bcopy, lcopy, rcopy)

    @njit
    def plain_solves(reps, band, r, bcopy, rcopy):
        for _ in range(reps):
            bcopy[:, :] = band
            rcopy[:] = r
            band_solve(bcopy, rcopy)

    @njit
    def frames(reps, m, x, dirs):
        for _ in range(reps):
            update_frames(m, x, dirs)

    @njit
    def forces(reps, m, x, v, dirs, f):
        for _ in range(reps):
            total_forces(m, x, v, dirs, f)

    @njit
    def jacobians(reps, m, x, dirs, jac):
        for _ in range(reps):
            force_jacobian(m, x, dirs, True, jac)

    @njit
    def coupled_steps(reps, stepper, m, x, v, samples, ws):
        for _ in range(reps):
            tc.coupled_implicit(stepper, m, x, v, samples, ws, True)

    @njit
    def plain_steps(reps, stepper, m, x, v, samples, ws):
        for _ in range(reps):
            _implicit(stepper, m, x, v, samples, ws, True)

    def per_call(f, *a, reps: int = 2000) -> tuple[float, float, float]:
        f(1, *a)  # compile
        batches = []
        for _ in range(5):
            t0 = time.thread_time()
            f(reps, *a)
            batches.append((time.thread_time() - t0) / reps * 1e6)
        return float(np.median(batches)), min(batches), max(batches)

    stepper = make_stepper("bdf2", 1e-3, NewtonOptions())
    m, samples, ws, x, v = state(True)
    set_clamp(m, 2)
    imp = _start_implicit(stepper.method, m, x, v, 1e-3, samples, ws, True)
    ns = n - 1
    sc = tc.make_scratch(n)
    mp = tc._frameless(m)
    r, g, band = np.empty(4 * n), np.empty((12, 3)), np.empty((4 * n, tc.HALF_T + 1))
    lower, upx = np.empty((4 * n, tc.HALF_T + 1)), np.empty((4 * n, tc.HALF_T + 1))
    rows = {
        "twist: residual": per_call(residuals, m, mp, imp, ws, samples, m.tw_theta.copy(), np.zeros(ns),
                                    m.tw_omega.copy(), ws.v_new, m.tw_omega.copy(), np.empty(ns), np.zeros(n),
                                    np.empty(ns), r, g, sc),
        "twist: Newton matrix (Gauss-Newton)": per_call(matrices, stepper, m, mp, imp, ws, band, g, sc, lower,
                                                        upx, samples, False),
        "twist: band solve (symmetric, 4n, half-width 10)": per_call(sym_solves, band, r, band.copy(), r.copy()),
        "twist: Newton matrix (exact)": per_call(matrices, stepper, m, mp, imp, ws, band, g, sc, lower, upx,
                                                 samples, True),
        "twist: band LU solve (exact matrix)": per_call(solves, band, lower, r, band.copy(), lower.copy(), r.copy()),
        "twist: update_frames (once a step)": per_call(frames, m, ws.x_stage, imp.dirs),
        "twist: frameless forces inside the residual": per_call(forces, mp, ws.x_stage, ws.v_stage, imp.dirs,
                                                                ws.force),
        "twist: frameless Jacobian inside the matrix": per_call(jacobians, mp, ws.x_stage, imp.dirs, ws.jacobian),
        "twist: whole coupled step (held ends still)": per_call(coupled_steps, stepper, m, x, v, samples, ws, reps=300),
    }
    mf, sf, wsf, xf, vf = state(False)
    rows["frameless: forces"] = per_call(forces, mf, xf, vf, sf.dir[2], wsf.force)
    rows["frameless: Jacobian"] = per_call(jacobians, mf, xf, sf.dir[2], wsf.jacobian)
    set_clamp(mf, 2)
    _newton_matrix(stepper, mf, _start_implicit(stepper.method, mf, xf, vf, 1e-3, sf, wsf, True), wsf)
    rf = np.ones(3 * n)
    rows["frameless: band solve (3n)"] = per_call(plain_solves, wsf.band, rf, wsf.band.copy(), rf.copy())
    rows["frameless: whole implicit step (held ends still)"] = per_call(plain_steps, stepper, mf, xf, vf, sf, wsf,
                                                                       reps=300)
    for name, (med, lo, hi) in rows.items():
        print(f"n {n:3d} {name:50s} {med:8.2f} us per call ({lo:.2f}-{hi:.2f})", flush=True)


def _reuse_gain(ns: list[int], method: str, dt: float, steps: int, repeats: int, section: str) -> None:
    """Per-step thread CPU time [us] of the frameless and the twisting cable with ``reuse_matrix`` on (chord iterations,
    BDF2's extrapolated start) and off (a fresh Newton matrix every iteration): the four runs interleaved ``repeats``
    times, steps alone as in the default table; the gain is off / on."""
    options = {"on": NewtonOptions(reuse_matrix=True), "off": NewtonOptions(reuse_matrix=False)}
    for n in ns:
        runs = {(kind, k): (m, o) for kind, m in (("frameless", model(n, False, steps * dt)),
                                                  ("twist", model(n, True, steps * dt, section)))
                for k, o in options.items()}
        for m, o in runs.values():  # compile and warm up
            step_cost(m, method, dt, 20, o)
        costs: dict[tuple, list[float]] = {k: [] for k in runs}
        fixed: dict[tuple, list[float]] = {k: [] for k in runs}
        for _ in range(repeats):
            for k, (m, o) in runs.items():
                costs[k].append(step_cost(m, method, dt, steps, o))
                fixed[k].append(step_cost(m, method, dt, 1, o))
        alone = {k: 1e6 * (steps * float(np.median(costs[k])) - float(np.median(fixed[k]))) / (steps - 1)
                 for k in runs}
        spread = {k: (1e6 * min(v), 1e6 * max(v)) for k, v in costs.items()}
        for kind in ("frameless", "twist"):
            on, off = alone[kind, "on"], alone[kind, "off"]
            lo_on, hi_on = spread[kind, "on"]
            lo_off, hi_off = spread[kind, "off"]
            print(f"n {n:3d} {kind:9s}: reuse on {on:7.1f} us/step ({lo_on:.1f}-{hi_on:.1f} per step with the fixed "
                  f"cost), off {off:7.1f} ({lo_off:.1f}-{hi_off:.1f}); gain {off / on:.2f}x", flush=True)


def _bullet(ns: list[int], repeats: int, block: int = 100) -> None:
    """Per-step thread CPU time [us] of the same cables in a Bullet world (1 kHz, BDF2, the ground below), each in
    plain steps (one compiled call a step, ``bullet/plain_steps.py``) and in Python's phases: medians of ``repeats``
    interleaved blocks of ``block`` ``world.step()`` calls."""
    from bullet_dlo.bullet import plain_steps
    from bullet_dlo.bullet.world import BulletWorld

    plain_steps.PLAIN_FROM = 0  # (plain from the first steps, as a run of at least PLAIN_FROM steps)
    for n in ns:
        worlds = {}
        for twist in (False, True):
            for plain in (True, False):
                world = BulletWorld(dt=1e-3)
                world.add_cable(model(n, twist, 1.0), record_every=10**9, integrator="bdf2")
                plain_steps.PLAIN_STEPS = plain
                world.step(20)  # compile and warm up
                worlds[twist, plain] = world
        times: dict[tuple, list[float]] = {k: [] for k in worlds}
        for _ in range(repeats):
            for (twist, plain), world in worlds.items():
                plain_steps.PLAIN_STEPS = plain
                t0 = time.thread_time()
                for _ in range(block):
                    world.step()
                times[twist, plain].append((time.thread_time() - t0) / block)
        plain_steps.PLAIN_STEPS = True
        med = {k: 1e6 * float(np.median(v)) for k, v in times.items()}
        print(f"n {n:3d}, Bullet world: frameless {med[False, True]:.1f} us/step plain, {med[False, False]:.1f} in "
              f"Python's phases; twist {med[True, True]:.1f} / {med[True, False]:.1f}; ratio "
              f"{med[True, True] / med[False, True]:.2f} plain, {med[True, False] / med[False, False]:.2f} in Python's "
              f"phases", flush=True)
        for world in worlds.values():
            world.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ns", type=int, nargs="+", default=[10, 20, 40, 80])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--method", default="bdf2")
    parser.add_argument("--dt", type=float, default=1e-3)
    parser.add_argument("--parts", action="store_true", help="time the coupled step's kernels alone (BDF2)")
    parser.add_argument("--bullet", action="store_true",
                        help="instead: the same cables stepped in a Bullet world, plain and in Python's phases")
    parser.add_argument("--exact-from", type=int, default=None,
                        help="newton.exact_from: the Newton iteration from which the twisting step takes the exact "
                             "Jacobian (default: NewtonOptions')")
    parser.add_argument("--no-reuse", action="store_true",
                        help="newton.reuse_matrix False: the implicit steps build and factor their Newton matrix every "
                             "iteration (as before 2026-12-06)")
    parser.add_argument("--reuse-gain", action="store_true",
                        help="instead: the frameless and the twisting step with newton.reuse_matrix on and off, "
                             "interleaved (the gain of chord iterations and BDF2's extrapolated start)")
    parser.add_argument("--section", choices=("round", "rectangle"), default="round",
                        help="the twisting cable's section: round (as the frameless one) or a rectangle 4 d x d/2")
    args = parser.parse_args()
    global NEWTON
    NEWTON = NewtonOptions(reuse_matrix=not args.no_reuse,
                           **({} if args.exact_from is None else {"exact_from": args.exact_from}))
    if args.steps < 2:
        sys.exit(print(f"--steps must be >= 2 (got {args.steps})", file=sys.stderr) or 2)
    if args.bullet:
        print(f"load average {os.getloadavg()[0]:.2f}")
        _bullet(args.ns, args.repeats)
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
        return
    if args.reuse_gain:
        print(f"{args.method}, dt {args.dt:g} s, {args.steps} steps per run, {args.repeats} interleaved repeats; "
              f"load average {os.getloadavg()[0]:.2f}")
        _reuse_gain(args.ns, args.method, args.dt, args.steps, args.repeats, args.section)
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
        return
    if args.parts:
        print(f"load average {os.getloadavg()[0]:.2f}")
        for n in args.ns:
            _parts(n, args.section)
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
        return
    duration = args.steps * args.dt
    print(f"{args.method}, dt {args.dt:g} s, {args.steps} steps per run, {args.repeats} interleaved repeats; "
          f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    for n in args.ns:
        models = {"frameless": model(n, False, duration), "twist": model(n, True, duration, args.section)}
        for m in models.values():  # compile and warm up
            step_cost(m, args.method, args.dt, 20)
        costs: dict[str, list[float]] = {k: [] for k in models}
        fixed: dict[str, list[float]] = {k: [] for k in models}
        for _ in range(args.repeats):
            for k, m in models.items():
                costs[k].append(step_cost(m, args.method, args.dt, args.steps))
                fixed[k].append(step_cost(m, args.method, args.dt, 1))
        med = {k: float(np.median(v)) for k, v in costs.items()}
        steps_only = {k: (args.steps * med[k] - float(np.median(fixed[k]))) / (args.steps - 1) for k in models}
        rng = {k: (min(v), max(v)) for k, v in costs.items()}
        print(f"n {n:3d}: frameless {1e6 * med['frameless']:7.1f} us/step ({1e6 * rng['frameless'][0]:.1f}-"
              f"{1e6 * rng['frameless'][1]:.1f}), twist {1e6 * med['twist']:7.1f} us/step ({1e6 * rng['twist'][0]:.1f}-"
              f"{1e6 * rng['twist'][1]:.1f}), ratio {med['twist'] / med['frameless']:.2f} "
              f"({rng['twist'][0] / rng['frameless'][1]:.2f}-{rng['twist'][1] / rng['frameless'][0]:.2f}); steps alone "
              f"{1e6 * steps_only['frameless']:.1f} / {1e6 * steps_only['twist']:.1f} us, ratio "
              f"{steps_only['twist'] / steps_only['frameless']:.2f}", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
