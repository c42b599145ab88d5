"""Main demo: two Panda arms buckle, carry and swing a cable; every integrator on the study's scenario.

1. Video: two Panda arms hold a 60 cm, 12 mm cable (a thick power cord: 150 g, E = 20 MPa)
   by its ends, lift it, bring the ends 26 cm together so that it buckles into a U (the
   horizontal force on each gripper turns from tension to compression), swing it left and
   right, and pull it nearly straight again. The video shows the scene next to the wrist
   forces (tared sensors, solid; the model's end forces, dashed) with a moving time cursor.
2. The study's scenario (Lv et al. 2017 cable clamped at both ends, settled, one end moved
   5 mm up): each integrator at the step a robot simulator would use (1 kHz, 60 Hz) and, for
   the explicit ones, just inside their predicted critical step; a table of stable?, wall
   time per simulated second and end force.
3. The cantilever convergence of both discretisations.

Writes into its output folder (printed at the end): ``dual_arm/side_by_side.mp4`` (also
``scene.mp4``, ``forces.png``, ``still.png``), ``end_forces.png``, ``convergence.png`` and
``summary.json``.

Usage: ``python demos/main_demo.py [--out DIR] [--quick]`` (``--quick``: a 2 s, 160x120 clip
and shorter runs, for smoke tests).
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

INTEGRATORS = ("explicit_euler", "symplectic_euler", "rk4", "implicit_euler", "bdf2", "implicit_midpoint")
CORD = CableSpec(length=0.6, diameter=0.012, mass=0.15, youngs_modulus=20e6, n_masses=20, damping=0.03)
LIFT, INWARD, SWING = 0.15, 0.13, 0.12  # [m]
PHASES = ((0.0, 0.5, "grasp"), (0.5, 1.7, "lift"), (1.7, 3.2, "ends together"), (3.2, 4.4, "swing"), (5.6, 7.0, "pull apart"))


def choreography() -> tuple[Move, ...]:
    """Both grippers: lift, come together (the cable buckles), swing in x and back, return (1 cm slack)."""
    moves = []
    for end, inward in (("first", 1.0), ("last", -1.0)):
        moves += [Move(end, (0.0, 0.0, LIFT), 0.5, 1.2),
                  Move(end, (inward * INWARD, 0.0, 0.0), 1.7, 1.5),
                  Move(end, (SWING, 0.0, 0.0), 3.2, 0.6),
                  Move(end, (-SWING, 0.0, 0.0), 3.8, 0.6),
                  Move(end, (-inward * (INWARD - 0.01), 0.0, -LIFT), 5.6, 1.4)]
    return tuple(moves)


def film_dual_arm(out: Path, quick: bool) -> dict:
    """Render the Panda pair handling the cord into ``out`` (see the module doc)."""
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.render.pipeline import render_scene

    scene = Scene(cable=CORD, motion=choreography(), dt=1 / 240, duration=2.0 if quick else 7.5,
                  integrator="implicit_euler", name="60 cm cord held by two Pandas")
    size, fps = ((160, 120), 10.0) if quick else ((640, 480), 30.0)
    return render_scene(scene, out, robot="panda", width=size[0], height=size[1], fps=fps,
                        arm_options={"hold_height": 0.4}, phases=PHASES, still_time=3.5)


def study_model(n: int, modulus: float) -> CableModel:
    """The study's scenario: Lv cable clamped at both ends, last end moved 5 mm up at t = 0.2 s."""
    spec = CableSpec.lv2017(n_masses=n, youngs_modulus=modulus, damping=0.01)
    return CableModel.straight(spec, (0, 0, 0.5), (1, 0, 0), ("clamped", "clamped"),
                               [Move("last", (0.0, 0.0, 0.005), 0.2, 0.1)])


def compare_integrators(out: Path, duration: float) -> list[dict]:
    """Print the table, plot the moved end's vertical force, return the rows."""
    model = study_model(10, 126e6)
    start = solve_static(model).state()
    print(f"{'integrator':18s} {'dt [s]':>10s} {'crit dt [s]':>12s} {'stable':>8s} {'wall/sim-s':>11s} "
          f"{'Fz last [N]':>12s}")
    rows = []
    fig, ax = plt.subplots(figsize=(9, 4.5))
    for name in INTEGRATORS:
        crit = critical_dt(model, name)
        # robot-simulator rates for everyone; explicit methods also just inside their limit
        # (explicit Euler's limit is ~6e-8 s here: it is shown at 1 us, where it still fails)
        for dt in [1e-3, 1.0 / 60.0] if crit is None else [1e-3, max(0.9 * crit, 1e-6)]:
            simulate(model, name, dt, 10 * dt, state=start, max_records=3)  # compile / warm up
            res = simulate(model, name, dt, duration, state=start)
            fz = res.end_forces[-1, 1, 2] if res.stable else float("nan")
            per_sim_s = res.wall_time_s / (res.steps * dt)
            state = "yes" if res.stable else f"no@{res.time_to_instability:.3g}s"
            print(f"{name:18s} {dt:10.3g} {crit if crit else float('nan'):12.3g} {state:>8s} {per_sim_s:11.4f} "
                  f"{fz:12.5f}")
            rows.append(dict(integrator=name, dt=dt, critical_dt=crit, stable=res.stable,
                             time_to_instability=res.time_to_instability, wall_time_per_sim_s=per_sim_s,
                             final_end_force_last=res.end_forces[-1, 1].tolist() if res.stable else None))
            if res.stable:
                ax.plot(res.t, res.end_forces[:, 1, 2], label=f"{name}, dt = {dt:.2g} s", lw=1.2,
                        ls="-" if dt >= 1e-3 else ":")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("vertical force on the moved end [N]")
    ax.set_title("Lv cable, both ends clamped, last end moved 5 mm up at t = 0.2 s\n(unstable runs are left out)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    fig.tight_layout()
    fig.savefig(out / "end_forces.png", dpi=120)
    plt.close(fig)
    return rows


def plot_convergence(out: Path) -> list[dict]:
    """Cantilever tip-deflection error against n for both discretisations; returns the rows."""
    rows = cantilever_convergence((5, 10, 20, 40, 80))
    ns = [r["n_masses"] for r in rows]
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    ax.loglog(ns, [100 * abs(r["default"]) for r in rows], "o-", label="default (2nd order)")
    ax.loglog(ns, [100 * abs(r["paper"]) for r in rows], "s-", label="paper (1st order)")
    ax.set_xticks(ns, [str(n) for n in ns])
    ax.xaxis.set_minor_locator(plt.NullLocator())
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("tip-deflection error [%]")
    ax.set_title("Cantilever under its own weight vs w L^4 / (8 E I)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    plt.close(fig)
    print("\ncantilever tip error: " + ", ".join(f"n={r['n_masses']}: {100 * r['default']:.3f} % "
                                                 f"(paper {100 * r['paper']:.1f} %)" for r in rows))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "main_demo"), help="output folder (default out/main_demo)")
    parser.add_argument("--quick", action="store_true", help="a short low-resolution clip and shorter runs (smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    video = film_dual_arm(out / "dual_arm", args.quick)
    print(f"dual-arm video: {video['side_by_side']} ({video['renderer']} renderer, {video['frames']} frames, "
          f"{'stable' if video['stable'] else 'UNSTABLE'})\n")
    runs = compare_integrators(out, 0.4 if args.quick else 1.0)
    rows = plot_convergence(out)
    (out / "summary.json").write_text(json.dumps({"video": video, "runs": runs, "cantilever": rows}, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
