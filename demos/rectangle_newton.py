"""Rectangle sections: the exact Jacobian from the first Newton iteration (the default) against the Gauss-Newton
matrix until an iteration contracts poorly (issue 22; docs/concepts/model.md, "A Gauss-Newton matrix that is one").

Each case runs in the core engine (no Bullet) with BDF2, once per Newton setting per round, the settings
interleaved; it prints whether the run stayed stable, its failed Newton solves, Newton iterations per step, the
thread CPU time's median and range over the rounds (the first round includes any kernel compile: read the range's
top with that in mind) and how far the two settings' end states lie apart [m].

Cases: a 10 x 1 mm strip (0.3 m, n 40, E 2 GPa) clamped at both ends, its last end turned 90 degrees and moved 5-7 cm
in 0.5 s at 1 kHz; a PET ribbon (0.4 m, 20 x 0.3 mm, n 81) falling from a clamp rolled 0.7 rad, at 1 kHz and 240 Hz.

    python demos/rectangle_newton.py
    python demos/rectangle_newton.py --rounds 5 --duration 2
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

STRIP = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                  thickness=0.001, n_masses=40, damping_rate=2.0)
RIBBON = CableSpec(length=0.4, diameter=0.001, mass=0.4 * 0.02 * 0.0003 * 1400, youngs_modulus=2e9,
                   section="rectangle", width=0.02, thickness=0.0003, n_masses=81, damping_rate=5.0)
GAUSS_NEWTON_FIRST = 1000  # newton.exact_from past every iteration a step takes: Gauss-Newton until a poor contraction


def cases() -> dict[str, tuple[CableModel, float]]:
    """name -> (model, dt [s])."""
    turned = Move("last", rotation=(math.pi / 2, 0.0, 0.0), displacement=(-0.05, 0.05, 0.02), duration=0.5)
    strip = CableModel.straight(STRIP, ends=("clamped", "clamped"), motion=[turned])
    ribbon = CableModel.straight(RIBBON, ends=("clamped", "free"), roll=(0.7, 0.0))
    return {"strip, end turned and moved, 1 kHz": (strip, 1e-3), "ribbon falling, 1 kHz": (ribbon, 1e-3),
            "ribbon falling, 240 Hz": (ribbon, 1.0 / 240.0)}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=3, help="interleaved rounds per case (default 3)")
    p.add_argument("--duration", type=float, default=1.0, help="simulated time per run [s] (default 1)")
    args = p.parse_args(argv)
    if args.rounds < 1:
        p.error("--rounds must be >= 1")
    if not args.duration > 0.0:
        p.error("--duration must be > 0 s")
    settings = {"exact from iteration 1": 1, "Gauss-Newton first": GAUSS_NEWTON_FIRST}
    print(f"{'case':38s} {'Newton':24s} stable  failed  iterations/step  CPU median [s] (range)")
    for name, (model, dt) in cases().items():
        cpu = {k: [] for k in settings}
        last = {}
        for _ in range(args.rounds):
            for label, first in settings.items():
                t0 = time.thread_time()
                res = simulate(model, "bdf2", dt, args.duration, max_records=3,
                               newton=NewtonOptions(exact_from=first))
                cpu[label].append(time.thread_time() - t0)
                last[label] = res
        for label in settings:
            res = last[label]
            print(f"{name:38s} {label:24s} {str(res.stable):6s}  {res.newton_failures:6d}  "
                  f"{res.newton_iterations / res.steps:15.2f}  {np.median(cpu[label]):.2f} "
                  f"({min(cpu[label]):.2f}-{max(cpu[label]):.2f})")
        a, b = (last[label].final_state.x for label in settings)
        print(f"{name:38s} end states apart by {np.abs(a - b).max():.1e} m")


if __name__ == "__main__":
    main()
