"""A PET ribbon (0.4 m, 20 x 0.3 mm, E 2 GPa, damping_rate 5) hanging from a clamp rolled 0.7 rad, released straight,
2 s at 60 / 120 / 240 / 1000 Hz and n 21 / 41 / 81, per implicit method: stable or not (when, why), Newton failures
and iterations per step (issue 22: a flat strip at long steps; docs/concepts/model.md, "Where Gauss-Newton fails").

    python demos/ribbon_steps.py
    python demos/ribbon_steps.py --methods bdf2 implicit_midpoint --ns 21 --hz 60 240
"""
from __future__ import annotations

import argparse
import time

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def ribbon(n: int) -> CableSpec:
    return CableSpec(length=0.4, diameter=0.001, mass=0.4 * 0.02 * 0.0003 * 1400, youngs_modulus=2e9,
                     section="rectangle", width=0.02, thickness=0.0003, n_masses=n, damping_rate=5.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", default=["bdf2", "implicit_euler", "implicit_midpoint",
                                                         "gauss_legendre"])
    parser.add_argument("--ns", nargs="+", type=int, default=[21, 41, 81])
    parser.add_argument("--hz", nargs="+", type=float, default=[60, 120, 240, 1000])
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    for method in args.methods:
        for n in args.ns:
            for hz in args.hz:
                model = CableModel.straight(ribbon(n), ends=("clamped", "free"), roll=(0.7, 0.0))
                t0 = time.process_time()
                res = simulate(model, method, 1.0 / hz, args.seconds, max_records=51)
                state = "stable" if res.stable else f"stopped at {res.time_to_instability:.3g} s ({res.reason})"
                print(f"{method:17s} n {n:3d} {hz:6.0f} Hz: {state}; Newton failed {res.newton_failures} of "
                      f"{res.steps} steps, {res.newton_iterations / max(res.steps, 1):.1f} iterations a step, "
                      f"{time.process_time() - t0:.1f} s CPU", flush=True)


if __name__ == "__main__":
    main()
