"""Main demo: the study's scenario with every integrator, and what each costs.

The Lv et al. 2017 cable is clamped at both ends, settled, and one end is moved 5 mm up.
Each integrator runs at the step a robot simulator would use (1 kHz, 60 Hz) and, for the
explicit ones, at 0.9x their predicted critical step. The demo prints a table (stable?,
wall time per simulated second, end force) and writes into its output folder:

* ``end_forces.png``: vertical force at the moved end over time, every integrator
* ``convergence.png``: cantilever tip-deflection error vs n for both discretisations
* ``summary.json``: the numbers behind the table
* ``dual_arm/``: two Panda arms holding the cable through the same 5 mm lift, as an H.264
  video (scene and wrist forces side by side) with its force plot (skipped with ``--quick``)

Usage: ``python demos/main_demo.py [--out DIR] [--quick]``
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from bullet_dlo.analysis.closed_forms import cantilever_convergence  # noqa: E402
from bullet_dlo.core.boundary import Move  # noqa: E402
from bullet_dlo.core.engine import simulate  # noqa: E402
from bullet_dlo.core.model import CableModel  # noqa: E402
from bullet_dlo.core.spec import CableSpec  # noqa: E402
from bullet_dlo.core.stability import critical_dt  # noqa: E402
from bullet_dlo.core.statics import solve_static  # noqa: E402


def study_model(n: int, modulus: float) -> CableModel:
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=0.01)
    return CableModel.straight(spec, (0, 0, 0.5), (1, 0, 0), ("clamped", "clamped"),
                               [Move("last", (0.0, 0.0, 0.005), 0.2, 0.1)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "main_demo"), help="output folder (default out/main_demo)")
    parser.add_argument("--quick", action="store_true", help="shorter runs (for smoke tests)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    duration = 0.4 if args.quick else 1.0
    model = study_model(10, 126e6)
    start = solve_static(model).state()

    runs = []
    for name in ("explicit_euler", "symplectic_euler", "rk4", "implicit_euler", "bdf2", "implicit_midpoint"):
        crit = critical_dt(model, name)
        # robot-simulator rates for everyone; explicit methods also just inside their limit
        # (explicit Euler's limit is ~6e-8 s here: it is shown at 1 us, where it still fails)
        steps = [1e-3, 1.0 / 60.0] if crit is None else [1e-3, max(0.9 * crit, 1e-6)]
        for dt in steps:
            simulate(model, name, dt, 10 * dt, state=start, max_records=3)  # compile / warm up
            res = simulate(model, name, dt, duration, state=start)
            runs.append((name, dt, crit, res))

    print(f"{'integrator':18s} {'dt [s]':>10s} {'crit dt [s]':>12s} {'stable':>8s} {'wall/sim-s':>11s} {'Fz last [N]':>12s}")
    summary = []
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for name, dt, crit, res in runs:
        fz = res.end_forces[-1, 1, 2] if res.stable else float("nan")
        per_sim_s = res.wall_time_s / (res.steps * dt)
        state = "yes" if res.stable else f"no@{res.time_to_instability:.3g}s"
        print(f"{name:18s} {dt:10.3g} {crit if crit else float('nan'):12.3g} {state:>8s} {per_sim_s:11.4f} {fz:12.5f}")
        summary.append(dict(integrator=name, dt=dt, critical_dt=crit, stable=res.stable,
                            time_to_instability=res.time_to_instability, wall_time_per_sim_s=per_sim_s,
                            final_end_force_last=res.end_forces[-1, 1].tolist() if res.stable else None))
        if res.stable:
            ax.plot(res.t, res.end_forces[:, 1, 2], label=f"{name} dt={dt:.2g}s", lw=1)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("vertical force on the moved gripper [N]")
    ax.set_title("Lv cable, clamped-clamped, last end moved 5 mm at t = 0.2 s")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "end_forces.png", dpi=120)

    rows = cantilever_convergence((5, 10, 20, 40, 80))
    fig, ax = plt.subplots(figsize=(5, 4))
    ns = [r["n_masses"] for r in rows]
    ax.loglog(ns, [abs(r["default"]) for r in rows], "o-", label="default (2nd order)")
    ax.loglog(ns, [abs(r["paper"]) for r in rows], "s-", label="paper (1st order)")
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("relative tip-deflection error")
    ax.set_title("Cantilever under its own weight")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    print("\ncantilever tip error: " + ", ".join(f"n={r['n_masses']}: {100 * r['default']:.3f} % "
                                                 f"(paper {100 * r['paper']:.1f} %)" for r in rows))
    (out / "summary.json").write_text(json.dumps({"runs": summary, "cantilever": rows}, indent=2))
    if not args.quick:
        from bullet_dlo.config.scene import Scene
        from bullet_dlo.render.pipeline import render_scene

        scene = Scene(cable=CableSpec.lv2017(n_masses=15, damping=0.02), motion=(Move("last", (0, 0, 0.005), 1.0, 0.1),),
                      dt=1 / 240, duration=2.5, name="Lv cable held by two Pandas")
        video = render_scene(scene, out / "dual_arm", robot="panda", progress=False)
        print(f"\ndual-arm video: {video['side_by_side']} ({video['renderer']} renderer, {video['frames']} frames)")
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
