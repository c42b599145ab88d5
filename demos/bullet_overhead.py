"""Cost of the Bullet coupling: coupled step vs a bare ``stepSimulation`` of the same world.

For n = 10, 50, 200 the study's cable (clamped ends, 5 mm move, implicit Euler, 1 kHz) is
stepped in a world with the ground plane; the bare baseline is a twin world with the same
spheres, collision filters and ground, stepped by Bullet alone. Blocks of steps are interleaved and
the median ratio is printed (ratios, not absolute times, are what survive a noisy machine).
Also prints the wall time per simulated second for the Lv cable at 60, 240 and 1000 Hz and
the largest deviation between the Bullet and core trajectories. Writes
``bullet_overhead.json`` and ``bullet_overhead.png``.

Both worlds keep their spheres live (``bullet_spheres="live"``): this measures the coupling through
Bullet's spheres; a cable whose contacts the model owns parks them by default (docs/concepts/coupled-step.md).

The baseline matters: Bullet's step costs several times more when the spheres move than
when they rest (the broad phase re-sorts moving boxes; n = 200: ~1.1 ms vs ~0.3 ms), so
the bare twin's spheres fall freely (reset before every timed block, 0.2 s of fall never
reaches the ground) instead of resting.

Usage: ``python demos/bullet_overhead.py [--out DIR] [--masses 10 50 200] [--repeats 7] [--quick]``
(``--quick``: n = 10, implicit Euler, one block of 20 steps; for smoke tests).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pybullet as pb  # noqa: E402

from bullet_dlo.bullet.world import BulletWorld  # noqa: E402
from bullet_dlo.core.boundary import Move  # noqa: E402
from bullet_dlo.core.engine import simulate  # noqa: E402
from bullet_dlo.core.model import CableModel  # noqa: E402
from bullet_dlo.core.spec import CableSpec  # noqa: E402
from bullet_dlo.core.stability import critical_dt  # noqa: E402


def study(n: int, modulus: float = 126e6) -> CableModel:
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=0.01)
    return CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.1, 0.1)])


def timed(fn, steps: int) -> float:
    tic = time.perf_counter()
    fn(steps)
    return (time.perf_counter() - tic) / steps


def overhead(n: int, integrator: str, repeats: int, block: int) -> dict:
    """Median coupled/bare step-time ratio for an n-mass cable."""
    model = study(n)
    crit = critical_dt(model, integrator)
    substeps = 1 if crit is None else math.ceil(1e-3 / (0.9 * crit))  # explicit: stay inside the limit
    coupled = BulletWorld(dt=1e-3)
    cable = coupled.add_cable(model, integrator=integrator, substeps=substeps, record_every=10**9,
                              bullet_spheres="live")
    bare = BulletWorld(dt=1e-3)
    twin = bare.add_cable(model, record_every=10**9, bullet_spheres="live")  # same bodies; only Bullet steps them

    def bare_block(steps: int) -> None:
        bare.step_bare(steps)  # the spheres fall freely: moving bodies, as in the coupled world

    def reset_twin() -> None:
        for b, pos in zip(twin.body_ids, model.x0.tolist()):
            pb.resetBasePositionAndOrientation(b, pos, [0, 0, 0, 1], physicsClientId=bare.client)
            pb.resetBaseVelocity(b, [0, 0, 0], [0, 0, 0], physicsClientId=bare.client)

    coupled.step(50)  # warm-up (compilation, caches)
    bare_block(50)
    t_c, t_b = [], []
    for _ in range(repeats):
        t_c.append(timed(coupled.step, block))
        reset_twin()
        t_b.append(timed(bare_block, block))
    assert cable.stable
    ratios = [c / b for c, b in zip(t_c, t_b)]
    coupled.close()
    bare.close()
    return dict(n_masses=n, integrator=integrator, substeps=substeps, coupled_us=1e6 * statistics.median(t_c),
                bare_us=1e6 * statistics.median(t_b), ratio=statistics.median(ratios))


def per_sim_second(rate: float) -> dict:
    """Wall time per simulated second, Lv cable (n = 10), implicit Euler, Bullet at ``rate`` Hz."""
    model = study(10)
    with BulletWorld(dt=1.0 / rate) as world:
        world.add_cable(model, record_every=10**9)
        world.step(5)
        steps = int(round(1.0 * rate))
        wall = timed(world.step, steps) * steps
    return dict(rate_hz=rate, wall_time_per_sim_s=wall)


def deviation() -> float:
    """Largest |x_bullet - x_core| [m] after 1 s over the implicit methods (no contacts)."""
    worst = 0.0
    for name in ("implicit_euler", "bdf2", "implicit_midpoint"):
        model = study(10)
        core = simulate(model, name, 1e-3, 1.0).final_state.x
        with BulletWorld(dt=1e-3) as world:
            cable = world.add_cable(model, integrator=name, bullet_spheres="live")  # Bullet integrates the forces
            world.run(1.0)
            worst = max(worst, float(np.max(np.abs(cable.bullet_positions() - core))))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "bullet_overhead"), help="output folder")
    parser.add_argument("--masses", nargs="+", type=int, default=[10, 50, 200], help="cable sizes n")
    parser.add_argument("--integrators", nargs="+", default=["implicit_euler", "symplectic_euler"],
                        help="integrators to time (explicit ones get the substeps their stability limit needs)")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved blocks (median)")
    parser.add_argument("--block", type=int, default=200, help="steps per block")
    parser.add_argument("--quick", action="store_true", help="n = 10, implicit Euler, one 20-step block (smoke test)")
    args = parser.parse_args()
    if args.quick:
        args.masses, args.integrators, args.repeats, args.block = [10], ["implicit_euler"], 1, 20
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [overhead(n, name, args.repeats, args.block) for name in args.integrators for n in args.masses]
    print(f"{'n':>4s} {'integrator':18s} {'substeps':>8s} {'coupled [us]':>13s} {'bare [us]':>10s} {'ratio':>6s}")
    for r in rows:
        print(f"{r['n_masses']:4d} {r['integrator']:18s} {r['substeps']:8d} {r['coupled_us']:13.1f} "
              f"{r['bare_us']:10.1f} {r['ratio']:6.2f}")
    rates = [per_sim_second(rate) for rate in (60.0, 240.0, 1000.0)]
    print("\nLv cable (n = 10, implicit Euler) in Bullet: wall time per simulated second")
    for r in rates:
        print(f"  {r['rate_hz']:6.0f} Hz: {r['wall_time_per_sim_s']:.4f} s")
    dev = deviation()
    print(f"\nlargest Bullet-vs-core deviation after 1 s (implicit methods, no contacts): {dev:.2e} m")
    fig, ax = plt.subplots(figsize=(7.5, 4))
    for name in args.integrators:
        pts = [(r["n_masses"], r["ratio"]) for r in rows if r["integrator"] == name]
        ax.semilogx(*zip(*pts), "o-", label=name)
    ax.axhline(2.0, color="grey", ls="--", label="goal: 2x bare")
    ax.set_xticks(args.masses, [str(n) for n in args.masses])
    ax.xaxis.set_minor_locator(plt.NullLocator())
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("coupled step / bare stepSimulation [-]")
    ax.set_title("Cost of the Bullet coupling (study's cable, 1 kHz)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    fig.savefig(out / "bullet_overhead.png", dpi=120)
    (out / "bullet_overhead.json").write_text(json.dumps({"overhead": rows, "rates": rates, "deviation_m": dev},
                                                          indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
