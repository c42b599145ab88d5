"""Where our cheapest 1 % run of the peer benchmark spends its time, part by part (issue 24, item 2).

S1's cheapest run within 1 % is implicit Euler at n = 20 and 1/60 s (one Newton iteration per
step); S2's is the implicit midpoint at n = 20 and 1 ms. Each part of one step is timed in a
compiled loop of ``--block`` calls on the benchmark's own model, in interleaved rounds, in
``time.thread_time``; medians and ranges, the machine's load beside them:

* the whole step (``sample_holders`` + ``advance``, as ``run_loop`` calls them, without the monitor);
* ``sample_holders``: the held ends' poses at t, t + h/2, t + h (6 poses, also for a fixed clamp);
* ``_start_implicit``: the method's affine map and Newton's first iterate;
* ``_residual``: forces at the Newton iterate (called twice per step: before the solve and at the trial);
* ``_newton_matrix``: force Jacobian, damping Jacobian, banded assembly;
* ``band_solve``: the block-banded LU solve;
* the rest (Newton's per-step set-up and line-search bookkeeping) is the step minus its parts.

Then the cost per step against n (the fixed part and the part per node, from ``simulate`` runs of
100 s and 10 s, their difference per step), which says how much of the step does not grow with n.

``--per-step``: instead, only ``simulate``'s cost per step on S1 (n = 20, 1/60 s) and the study's cable (n = 10,
1 kHz), with the public API only, so that ``PYTHONPATH=OLD_TREE python demos/solver_cost.py --per-step`` measures
an older source tree the same way (interleave trees for an A/B).
``--accuracy``: instead, the error and CPU cost of our candidates at 1 % and 0.1 % on S1 and S2 (implicit Euler,
implicit midpoint, Gauss-Legendre; :data:`ACCURACY_CASES`), written to ``solver_accuracy.json``.

Writes ``solver_cost.json`` into ``--out``. Usage:
``python demos/solver_cost.py [--n 20] [--rounds 5] [--block 20000] [--out DIR] [--quick] [--accuracy] [--per-step]``
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

from numba import njit

from bullet_dlo.analysis.closed_forms import cantilever_model
from bullet_dlo.bench.scenarios import s1_spec
from bullet_dlo.core.engine import DetectorOptions, simulate
from bullet_dlo.core.integrators import NewtonOptions, get_integrator, make_stepper
from bullet_dlo.core.kernels.banded import band_solve
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
# private step kernels, timed one by one (names as in core/kernels/steppers.py when this was written); --per-step
# uses only the public API, so that it also runs with PYTHONPATH on older source trees that lack some of them
try:
    from bullet_dlo.core.kernels.steppers import _newton_matrix, _residual, _start_implicit, advance, make_workspace
except ImportError:  # an older tree: only --per-step works
    pass


@njit
def _steps(stepper, m, plan, x, v, samples, ws, k):
    total = 0
    for i in range(k):
        sample_holders(plan, i * stepper.h, stepper.h, samples)
        its, _ = advance(stepper, m, x, v, samples, ws, i > 0)
        total += its
    return total


@njit
def _sample(stepper, m, plan, x, v, samples, ws, k):
    for i in range(k):
        sample_holders(plan, i * stepper.h, stepper.h, samples)


@njit
def _start(stepper, m, plan, x, v, samples, ws, k):
    for _ in range(k):
        _start_implicit(stepper.method, m, x, v, stepper.h, samples, ws, True)


@njit
def _residuals(stepper, m, plan, x, v, samples, ws, k):
    imp = _start_implicit(stepper.method, m, x, v, stepper.h, samples, ws, True)
    for _ in range(k):
        _residual(m, imp, ws, ws.v_new, ws.residual)


@njit
def _matrix(stepper, m, plan, x, v, samples, ws, k):
    imp = _start_implicit(stepper.method, m, x, v, stepper.h, samples, ws, True)
    _residual(m, imp, ws, ws.v_new, ws.residual)
    for _ in range(k):
        _newton_matrix(stepper, m, imp, ws)


@njit
def _solve(stepper, m, plan, x, v, samples, ws, k):
    imp = _start_implicit(stepper.method, m, x, v, stepper.h, samples, ws, True)
    _residual(m, imp, ws, ws.v_new, ws.residual)
    _newton_matrix(stepper, m, imp, ws)
    band, rhs = ws.band.copy(), ws.residual.copy()
    for _ in range(k):
        ws.band[:] = band  # the copies cost < 10 % of the solve (n = 20: 0.17 of 1.6 us)
        ws.residual[:] = rhs
        band_solve(ws.band, ws.residual)


PARTS = {"whole step": _steps, "sample_holders": _sample, "_start_implicit": _start, "_residual": _residuals,
         "_newton_matrix": _matrix, "band_solve": _solve}


def part_costs(integrator: str, n: int, dt: float, rounds: int, block: int) -> tuple[dict[str, list[float]], float]:
    """Per part, the cost of one call [us] in each of ``rounds`` interleaved rounds of ``block`` calls, and
    the Newton iterations per step of the timed steps (from rest under gravity, as S1 starts)."""
    model = cantilever_model(s1_spec(n))
    m, plan = model.kernel_arrays(), model.holder_plan()
    stepper = make_stepper(get_integrator(integrator), dt, NewtonOptions())
    samples = empty_samples()
    sample_holders(plan, 0.0, dt, samples)
    out: dict[str, list[float]] = {name: [] for name in PARTS}
    its = 0
    for r in range(rounds + 1):
        for name, f in PARTS.items():
            st = model.initial_state().copy()  # every part starts from the same state
            args = (stepper, m, plan, st.x, st.v, samples, make_workspace(n))
            c0 = time.thread_time()
            total = f(*args, block if r else 2)  # round 0 compiles
            if r:
                out[name].append((time.thread_time() - c0) / block * 1e6)
                if name == "whole step":
                    its = total / block
    return out, its


def per_step_vs_n(n_masses, rounds: int, long: float = 100.0) -> dict[int, list[float]]:
    """Cost per step [us] of ``simulate`` (S1, implicit Euler, 1/60 s, monitor as default) at each n:
    the difference of a ``long`` and a ``long / 10`` run per extra step, in interleaved rounds."""
    out: dict[int, list[float]] = {n: [] for n in n_masses}
    models = {n: cantilever_model(s1_spec(n)) for n in n_masses}
    for n in n_masses:
        simulate(models[n], "implicit_euler", 1 / 60, 1.0, max_records=3)  # compile / load
    for _ in range(rounds):
        for n in n_masses:
            c0 = time.thread_time()
            a = simulate(models[n], "implicit_euler", 1 / 60, long, max_records=3, detector=DetectorOptions())
            c1 = time.thread_time()
            b = simulate(models[n], "implicit_euler", 1 / 60, long / 10, max_records=3)
            c2 = time.thread_time()
            out[n].append(((c1 - c0) - (c2 - c1)) / (a.steps - b.steps) * 1e6)
    return out


ACCURACY_CASES = (("S1", "implicit_euler", 20, 1 / 60), ("S1", "implicit_euler", 40, 1 / 60),
                  ("S1", "implicit_euler", 40, 0.05),
                  ("S2", "implicit_midpoint", 20, 1e-3), ("S2", "gauss_legendre", 20, 1 / 160),
                  ("S2", "gauss_legendre", 20, 5e-3), ("S2", "implicit_midpoint", 40, 2e-4),
                  ("S2", "gauss_legendre", 40, 5e-3), ("S2", "gauss_legendre", 40, 3e-3),
                  ("S2", "gauss_legendre", 40, 2e-3))
"""Our candidates at 1 % and 0.1 % on S1 and S2 (scenario, integrator, n, dt [s])."""


def accuracy(repeats: int = 3) -> list[dict]:
    """Error and cost of :data:`ACCURACY_CASES`: thread CPU time of the whole scenario call (1 s simulated, with
    the start's static solve), median and range of ``repeats`` interleaved runs after a short warm-up run."""
    from bullet_dlo.bench.scenarios import RUNNERS

    for sc, name, n, dt in ACCURACY_CASES:
        RUNNERS[sc](n, name, dt, "core", 0.05)  # compile / load
    cpu: dict[int, list[float]] = {k: [] for k in range(len(ACCURACY_CASES))}
    points = {}
    for _ in range(repeats):
        for k, (sc, name, n, dt) in enumerate(ACCURACY_CASES):
            c0 = time.thread_time()
            points[k] = RUNNERS[sc](n, name, dt)
            cpu[k].append(time.thread_time() - c0)
    rows = []
    for k, (sc, name, n, dt) in enumerate(ACCURACY_CASES):
        p, v = points[k], cpu[k]
        rows.append(dict(scenario=sc, integrator=name, n=n, dt=dt, error=p.error, amplitude_kept=p.extra,
                         cpu_per_sim_s=statistics.median(v), cpu_min=min(v), cpu_max=max(v)))
        print(f"  {sc} {name:18s} n={n:3d} dt={dt:.4g} s: error {100 * p.error:+.3f} %, "
              f"{statistics.median(v):.4g} CPU s per simulated s ({min(v):.4g}-{max(v):.4g})")
    return rows


def per_step(rounds: int = 3) -> dict[str, list[float]]:
    """Cost per step [us] of ``simulate`` (implicit Euler; thread CPU time of a long minus a short run per extra
    step) on S1 (n = 20, 1/60 s, fixed clamp) and the study's cable (n = 10, 1 kHz, one end moving 5 mm), in
    ``rounds`` interleaved rounds; public API only (for A/B runs against older trees)."""
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.model import CableModel
    from bullet_dlo.core.spec import CableSpec

    study = CableModel.straight(CableSpec.lv2017(n_masses=10, youngs_modulus=126e6, damping=0.01),
                                ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])
    cases = {"S1 n=20 1/60 s": (cantilever_model(s1_spec(20)), 1 / 60, 200.0),
             "study n=10 1 kHz": (study, 1e-3, 4.0)}
    for model, dt, _ in cases.values():
        simulate(model, "implicit_euler", dt, 10 * dt, max_records=3)  # compile / load
    out: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(rounds):
        for k, (model, dt, long) in cases.items():
            c0 = time.thread_time()
            a = simulate(model, "implicit_euler", dt, long, max_records=3)
            c1 = time.thread_time()
            b = simulate(model, "implicit_euler", dt, long / 10, max_records=3)
            c2 = time.thread_time()
            out[k].append(((c1 - c0) - (c2 - c1)) / (a.steps - b.steps) * 1e6)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=20)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--block", type=int, default=20000)
    p.add_argument("--out", default="out/bench")
    p.add_argument("--quick", action="store_true", help="one round of 200 calls, n = 5 and 10 only (smoke test)")
    p.add_argument("--accuracy", action="store_true",
                   help="only the error and cost of our candidates at 1 %% and 0.1 %% on S1 and S2 (ACCURACY_CASES)")
    p.add_argument("--per-step", action="store_true",
                   help="only simulate's cost per step on S1 and the study's cable (public API: runs on older trees)")
    a = p.parse_args(argv)
    rounds, block = (1, 200) if a.quick else (a.rounds, a.block)
    load0 = os.getloadavg()
    if a.per_step:
        res = per_step(1 if a.quick else 3)
        load1 = os.getloadavg()
        print(f"simulate, implicit Euler, us per step, median (range); load {load0[0]:.2f} -> {load1[0]:.2f}")
        for k, v in res.items():
            print(f"  {k}: {statistics.median(v):.2f} ({min(v):.2f}-{max(v):.2f})")
        return 0
    if a.accuracy:
        print(f"S1 / S2, core engine, thread CPU time per simulated second; load {load0[0]:.2f} / {load0[1]:.2f} / "
              f"{load0[2]:.2f}")
        rows = accuracy(1 if a.quick else 3)
        load1 = os.getloadavg()
        print(f"load at the end {load1[0]:.2f} / {load1[1]:.2f} / {load1[2]:.2f}")
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "solver_accuracy.json").write_text(json.dumps({"load_start": load0, "load_end": load1, "rows": rows},
                                                             indent=2))
        return 0
    report: dict = {"load_start": load0, "n": a.n, "rounds": rounds, "block": block, "parts": {}}
    for integrator, dt in (("implicit_euler", 1 / 60), ("implicit_midpoint", 1e-3)):
        costs, its = part_costs(integrator, a.n, dt, rounds, block)
        med = {k: statistics.median(v) for k, v in costs.items()}
        rest = med["whole step"] - med["sample_holders"] - med["_start_implicit"] \
            - its * (med["_newton_matrix"] + med["band_solve"] + med["_residual"]) - med["_residual"]
        print(f"{integrator}, n = {a.n}, dt = {dt:.3g} s ({its:.2f} Newton iterations per timed step): "
              f"us per call, median (range of {rounds})")
        for k, v in costs.items():
            times = {"_residual": f" x {its + 1:.2f} per step", "_newton_matrix": f" x {its:.2f}",
                     "band_solve": f" x {its:.2f}"}.get(k, "")
            print(f"  {k:16s} {med[k]:7.2f} ({min(v):.2f}-{max(v):.2f}){times}")
        print(f"  {'rest (Newton set-up, line search)':16s} {rest:7.2f}  (whole step minus its parts)")
        report["parts"][integrator] = dict(dt=dt, rounds=costs, median=med, rest=rest, newton_iterations=its)
    ns = (5, 10) if a.quick else (5, 10, 20, 40, 80)
    per_n = per_step_vs_n(ns, 1 if a.quick else 3, 10.0 if a.quick else 100.0)
    meds = {n: statistics.median(v) for n, v in per_n.items()}
    slope = (meds[ns[-1]] - meds[ns[0]]) / (ns[-1] - ns[0])
    print("simulate, S1, implicit Euler at 1/60 s: us per step " +
          ", ".join(f"n = {n}: {meds[n]:.1f}" for n in ns) +
          f"; fixed {meds[ns[0]] - slope * ns[0]:.1f} us + {slope:.2f} us per node")
    report["per_step_vs_n"] = {str(n): v for n, v in per_n.items()}
    report["load_end"] = os.getloadavg()
    print(f"load average at start {', '.join(f'{x:.2f}' for x in load0)}, at end "
          f"{', '.join(f'{x:.2f}' for x in report['load_end'])}; {os.cpu_count()} CPUs")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "solver_cost.json").write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
