"""Where the implicit methods' Newton solves fail on a cable with a material frame (issue 22, "exact Jacobians").

Two scenes, each run with every implicit method, step and Newton iteration cap asked for; one line per run with
the solves that failed, the Newton iterations per step, the run's outcome and its CPU time (thread CPU, so the
first run of a method also pays its kernels' compile unless the cache is warm):

- ``ribbon``: a PET ribbon (0.4 m, 20 x 0.3 mm, E 2 GPa, damping_rate 5, n 81) hanging from a clamp rolled 0.7 rad,
  released straight for 0.5 s (its weak axis tilted: the anisotropic bending's curvature terms matter);
- ``pushed``: the study's round cable (``CableSpec.lv2017``, n 40, damping_rate 2) clamped at both ends, its last
  end pushed 30 % in over 1 s while turned ``--turns`` times about its axis, run 1.5 s (0 turns with ``--frameless``
  compares the frameless step).

    python demos/twist_newton.py
    python demos/twist_newton.py --scenes ribbon --methods gauss_legendre bdf2 --dts 0.001 0.002 0.0041667
    python demos/twist_newton.py --scenes pushed --turns 0 0.25 3 --max-iter 8 30 --dts 0.016667
    python demos/twist_newton.py --scenes pushed --turns 0 --frameless --methods gauss_legendre
"""
from __future__ import annotations

import argparse
import math
import os
import time

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

RIBBON = CableSpec(length=0.4, diameter=0.001, mass=0.4 * 0.02 * 0.0003 * 1400, youngs_modulus=2e9,
                   section="rectangle", width=0.02, thickness=0.0003, n_masses=81, damping_rate=5.0)


def ribbon() -> tuple[CableModel, float]:
    """The hanging ribbon and its run time [s]."""
    return CableModel.straight(RIBBON, ends=("clamped", "free"), roll=(0.7, 0.0)), 0.5


def pushed(turns: float, twist: bool) -> tuple[CableModel, float]:
    """The study's cable pushed 30 % in while its last clamp turns ``turns`` times, and its run time [s]."""
    spec = CableSpec.lv2017(n_masses=40, twist=twist, damping_rate=2.0)
    move = Move("last", displacement=(-0.3 * spec.length, 0.0, 0.0), rotation=(2.0 * math.pi * turns, 0.0, 0.0),
                duration=1.0)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move]), 1.5


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="+", choices=("ribbon", "pushed"), default=["ribbon", "pushed"],
                    help="which scenes to run (default both)")
    ap.add_argument("--methods", nargs="+", default=["gauss_legendre", "bdf2"],
                    help="implicit integrators to run (default gauss_legendre bdf2)")
    ap.add_argument("--dts", nargs="+", type=float, default=[1e-3, 1 / 240],
                    help="time steps [s] (default 0.001 and 1/240)")
    ap.add_argument("--max-iter", nargs="+", type=int, default=[None],
                    help="Newton iteration caps per step (default: each method's, 8, and 32 for gauss_legendre)")
    ap.add_argument("--turns", nargs="+", type=float, default=[3.0],
                    help="turns of the pushed cable's last clamp (default 3)")
    ap.add_argument("--frameless", action="store_true",
                    help="run the pushed cable without a material frame (its turns then do nothing)")
    args = ap.parse_args()
    runs = []
    for scene in args.scenes:
        if scene == "ribbon":
            runs.append(("ribbon", *ribbon()))
        else:
            for turns in args.turns:
                runs.append((f"pushed {turns:g} turns" + (" frameless" if args.frameless else ""),
                             *pushed(turns, not args.frameless)))
    print(f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'scene':28s} {'method':16s} {'dt [s]':>9s} {'cap':>4s} {'failed':>10s} {'it/step':>8s} "
          f"{'cpu [s]':>8s}  outcome")
    for name, model, duration in runs:
        for method in args.methods:
            for dt in args.dts:
                for cap in args.max_iter:
                    t0 = time.thread_time()
                    newton = NewtonOptions(max_iter=cap)
                    res = simulate(model, method, dt, duration, max_records=3, newton=newton)
                    cpu = time.thread_time() - t0
                    cap = newton.iterations(method)
                    outcome = "stable" if res.stable else f"stopped at {res.final_state.t:.3f} s: {res.reason}"
                    print(f"{name:28s} {method:16s} {dt:9.6f} {cap:4d} {res.newton_failures:4d}/{res.steps:<5d} "
                          f"{res.newton_iterations / max(res.steps, 1):8.2f} {cpu:8.2f}  {outcome}", flush=True)


if __name__ == "__main__":
    main()
