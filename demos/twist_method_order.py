"""Order in dt of Gauss-Legendre and the explicit methods on a twisting cable (issue 22), core only.

These methods used to advance the positions with the twist held, then the twist by an implicit-Euler sub-step
(staggered: first order in the twist). Now Gauss-Legendre solves the stage twist rates in its collocation system
(``coupled_gauss_legendre``) and the explicit methods carry the twist angles and rates through their stages
(``explicit_twist``, both in ``bullet_dlo/core/kernels/twist_coupled.py``). The scene is the one of
``tests/core/test_twist_coupled.py``: a soft strip (rectangle 10 x 1 mm, E 2 GPa, 0.3 m, n = 9) clamped-free, its
clamp rolled 90 degrees and moved 5 cm sideways, 2 cm up over 0.5 s. Errors at T against the same method at
T / ref: node positions x [m], material axes m1 (max over segments) and the torque about the clamp's axis [N m].

    python demos/twist_method_order.py                          # Gauss-Legendre, T 0.5 s, dt 5 -> 0.625 ms (~10 s)
    python demos/twist_method_order.py --method rk4 --duration 0.05 --steps 500,1000,2000,4000 --ref 16000 \\
        --internal-damping 0                                    # RK4 (explicit: no internal damping, ~3 s)
    python demos/twist_method_order.py --cost 0.001             # CPU per step: Gauss-Legendre against BDF2 (~15 s)

``--cost DT`` times instead whole runs of T at step DT with each method's default Newton settings (Gauss-Legendre,
BDF2, and Gauss-Legendre with the Gauss-Newton stage matrices, ``exact_from`` 1000), interleaved in 5 rounds, in
thread CPU time: median and range in us per step, Newton iterations per step, the load average.
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
from bullet_dlo.core.integrators import INTEGRATORS, NewtonOptions
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def model(internal_damping: float) -> CableModel:
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                     thickness=0.001, n_masses=9, damping_rate=2.0, internal_damping=internal_damping)
    return CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), roll=(0.3, 0.0),
                               motion=[Move("first", rotation=(math.pi / 2, 0, 0), displacement=(0, 0.05, 0.02),
                                            duration=0.5)])


def final(cable: CableModel, method: str, duration: float, steps: int):
    """Positions [m], material axes m1 and the axial clamp torque [N m] at ``duration``, Newton iterations/step."""
    res = simulate(cable, method, duration / steps, duration, newton=NewtonOptions(tol=1e-11, max_iter=50))
    if not res.stable:
        raise SystemExit(f"{method} at dt {duration / steps:.3g} s is unstable ({res.reason})")
    tw = res.final_state.twist
    m1 = np.cos(tw.theta)[:, None] * tw.ref + np.sin(tw.theta)[:, None] * np.cross(tw.tan, tw.ref)
    return res.x[-1], m1, res.end_moments[0, 0], res.newton_iterations / res.steps


def cost(cable: CableModel, duration: float, dt: float, rounds: int = 5) -> None:
    """Print each method's CPU time per step [us] (median, range over interleaved rounds) and iterations per step."""
    runs = {"gauss_legendre": ("gauss_legendre", NewtonOptions()), "bdf2": ("bdf2", NewtonOptions()),
            "gauss_legendre, Gauss-Newton stage matrices": ("gauss_legendre", NewtonOptions(exact_from=1000))}
    times = {name: [] for name in runs}
    its = {}
    for _ in range(rounds):
        for name, (method, newton) in runs.items():
            t0 = time.thread_time()
            res = simulate(cable, method, dt, duration, max_records=3, newton=newton)
            times[name].append((time.thread_time() - t0) / res.steps * 1e6)
            its[name] = res.newton_iterations / res.steps
    print(f"T {duration} s at dt {dt * 1e3:.4g} ms, {rounds} interleaved rounds, load {os.getloadavg()[0]:.1f}")
    print("| method | us per step (range) | Newton its/step |")
    print("|---|---|---|")
    for name, ts in times.items():
        print(f"| {name} | {np.median(ts):.0f} ({min(ts):.0f}-{max(ts):.0f}) | {its[name]:.1f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="gauss_legendre")
    ap.add_argument("--duration", type=float, default=0.5)
    ap.add_argument("--steps", default="100,200,400,800")
    ap.add_argument("--ref", type=int, default=3200)
    ap.add_argument("--internal-damping", type=float, default=1e-3)
    ap.add_argument("--cost", type=float, metavar="DT",
                    help="time Gauss-Legendre against BDF2 at step DT [s] instead (see above)")
    a = ap.parse_args(argv)
    if a.cost is not None:
        if not 0 < a.cost <= a.duration:
            print(f"--cost: a step in (0, {a.duration}] s", file=sys.stderr)
            raise SystemExit(2)
        cost(model(a.internal_damping), a.duration, a.cost)
        return
    try:
        steps = [int(s) for s in a.steps.split(",")]
    except ValueError:
        steps = []
    if a.method not in INTEGRATORS:
        print(f"--method must be one of {', '.join(INTEGRATORS)}", file=sys.stderr)
        raise SystemExit(2)
    if not steps or min(steps) < 1 or a.ref < 1 or not a.duration > 0 or not a.internal_damping >= 0:
        print("--steps: comma-separated integers >= 1; --ref >= 1; --duration > 0; --internal-damping >= 0",
              file=sys.stderr)
        raise SystemExit(2)
    cable = model(a.internal_damping)
    xr, mr, tr, _ = final(cable, a.method, a.duration, a.ref)
    print(f"{a.method}, T {a.duration} s, against dt {a.duration / a.ref * 1e3:.4g} ms")
    print("| dt [ms] | x [m] | m1 | torque about the axis [N m] | Newton its/step |")
    print("|---|---|---|---|---|")
    prev = None
    for s in steps:
        x, m1, tq, its = final(cable, a.method, a.duration, s)
        err = (np.abs(x - xr).max(), np.abs(m1 - mr).max(), abs(tq - tr))
        cells = [f"{e:.2g}" + ("" if prev is None else f" ({math.log2(p / e):.2f})") for e, p in
                 zip(err, prev or err)]
        print(f"| {a.duration / s * 1e3:.4g} | " + " | ".join(cells) + f" | {its:.1f} |")
        prev = err


if __name__ == "__main__":
    main()
