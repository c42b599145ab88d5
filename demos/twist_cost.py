"""Cost of the twist-enabled implicit step against the round frameless step at the same n (issue 22, item 6).

The same scene with and without a material frame: a round cable (``CableSpec.lv2017``) clamped at both ends
under gravity, the last end moved 5 cm towards the first and rolled 90 degrees about the cable's axis over the
run (the twisting cable feels the roll, the frameless one does not). Each run is ``--steps`` steps of BDF2 at
dt 1 ms; twisting and frameless runs are interleaved ``--repeats`` times and timed in thread CPU time; the
script prints per-step medians, ranges, the ratio of medians and the load average.

    python demos/twist_cost.py
    python demos/twist_cost.py --ns 10 20 40 80 --repeats 7 --steps 1000 --method bdf2
"""
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def model(n: int, twist: bool, duration: float) -> CableModel:
    spec = CableSpec.lv2017(n_masses=n, twist=twist, damping_rate=2.0)
    move = Move("last", displacement=(-0.05 * spec.length, 0.0, 0.0), rotation=(math.pi / 2, 0.0, 0.0),
                duration=duration)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move])


def step_cost(m: CableModel, method: str, dt: float, steps: int) -> float:
    """Thread CPU time per step [s] of one run."""
    t0 = time.thread_time()
    res = simulate(m, method, dt, steps * dt, record_every=steps)
    cost = (time.thread_time() - t0) / steps
    if not res.stable:
        raise RuntimeError(f"unstable run: {res.reason}")
    return cost


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ns", type=int, nargs="+", default=[10, 20, 40, 80])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--method", default="bdf2")
    parser.add_argument("--dt", type=float, default=1e-3)
    args = parser.parse_args()
    duration = args.steps * args.dt
    print(f"{args.method}, dt {args.dt:g} s, {args.steps} steps per run, {args.repeats} interleaved repeats; "
          f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    for n in args.ns:
        models = {"frameless": model(n, False, duration), "twist": model(n, True, duration)}
        for m in models.values():  # compile and warm up
            step_cost(m, args.method, args.dt, 20)
        costs: dict[str, list[float]] = {k: [] for k in models}
        for _ in range(args.repeats):
            for k, m in models.items():
                costs[k].append(step_cost(m, args.method, args.dt, args.steps))
        med = {k: float(np.median(v)) for k, v in costs.items()}
        rng = {k: (min(v), max(v)) for k, v in costs.items()}
        print(f"n {n:3d}: frameless {1e6 * med['frameless']:7.1f} us/step ({1e6 * rng['frameless'][0]:.1f}-"
              f"{1e6 * rng['frameless'][1]:.1f}), twist {1e6 * med['twist']:7.1f} us/step ({1e6 * rng['twist'][0]:.1f}-"
              f"{1e6 * rng['twist'][1]:.1f}), ratio {med['twist'] / med['frameless']:.2f} "
              f"({rng['twist'][0] / rng['frameless'][1]:.2f}-{rng['twist'][1] / rng['frameless'][0]:.2f})", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
