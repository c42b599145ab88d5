"""``bullet-dlo simulate | stability | paper-table | convergence``: the numerical core from the command line."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from bullet_dlo.cli.outputs import add_plot_options, plot_path, print_outputs
from bullet_dlo.cli.quiet import bar, elapsed
from bullet_dlo.core.enums import Engine

TABLES = ("base", "rates")
RATE_INTEGRATORS = ("symplectic_euler", "implicit_euler", "bdf2", "implicit_midpoint")


def write_json(path: str, data: object) -> None:
    """Write ``data`` as indented JSON, creating the folder."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=2))


def cmd_simulate(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from bullet_dlo.config.scene import Scene, result_json
    from bullet_dlo.core.integrators import get_integrator
    from bullet_dlo.core.validate import check_positive, check_steps

    from bullet_dlo.sim import resolved

    scene = resolved(Scene.from_yaml(args.scene))
    if args.integrator is not None:
        scene = replace(scene, integrator=get_integrator(args.integrator).name)
    for key in ("dt", "duration"):
        if getattr(args, key) is not None:
            scene = replace(scene, **{key: check_positive(f"--{key}", getattr(args, key))})
    substeps = scene.bullet.substeps if args.engine == "bullet" else 1
    check_steps(scene.dt, scene.duration, substeps, "--dt" if args.dt is not None else "dt",
                "--duration" if args.duration is not None else "duration")  # the caps apply to flags too
    from bullet_dlo.sim import build

    png = plot_path(args, args.json, args.npz)
    with build(scene, args.engine, command=f"simulate --engine {args.engine}") as sim:
        if args.engine == "bullet":  # a bar with an ETA, told every hundred steps (a hook told of every step would
            # keep each step out of the plain steps' compiled loop, bullet/plain_steps.py)
            with bar(sim.world.steps_in(scene.duration), f"simulate ({scene.name})", args.quiet,
                     unit="step") as progress:
                result = sim.run(progress=progress.update)
        else:  # one compiled time loop: an elapsed-time counter
            with elapsed(f"simulate ({scene.name})", args.quiet):
                result = sim.run()
    model = sim.model
    data = result_json(scene, model, result, engine=args.engine)
    if args.json:
        write_json(args.json, data)
    if args.npz:
        Path(args.npz).parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.npz, t=result.t, x=result.x, v=result.v, end_forces=result.end_forces,
                            energy=result.energy)
    if png is not None and len(result.t):
        from bullet_dlo.render.plots import plot_run

        held = tuple(bool(model.arrays.held[i]) for i in (0, -1))
        plot_run(result.t, result.x, result.end_forces, result.energy, png,
                 title=f"{scene.name}: {data['integrator']}, dt = {scene.dt:g} s, {args.engine} engine", held=held)
    status = "stable" if data["stable"] else f"UNSTABLE at t = {data['time_to_instability']:.6g} s ({data['reason']})"
    print(f"{scene.name}: {data['integrator']} dt={scene.dt:g} s, {data['steps']} steps in "
          f"{data['wall_time_s']:.3f} s: {status}")
    if scene.twist_reason:
        print(f"  {scene.twist_reason}")
    for warning in data.get("warnings", []):
        print(f"  warning: {warning}")
    if data["stable"]:
        for end in ("first", "last"):
            if data["end_forces"][end] is not None:
                print(f"  end force {end}: " + " ".join(f"{v:+.5f}" for v in data["end_forces"][end]) + " N")
    print_outputs(args.json, args.npz, png)
    return 0


def cmd_stability(args: argparse.Namespace) -> int:
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.core.integrators import INTEGRATORS
    from bullet_dlo.core.stability import critical_dt, damping_bounds

    scene = Scene.from_yaml(args.scene)
    model = scene.build_model()
    report = {"dt": scene.dt, "critical_dt": {}, "stable_at_dt": {}}
    print(f"{scene.name}: n={model.n}, E={scene.cable.youngs_modulus:.4g} Pa, dt={scene.dt:g} s")
    for name in INTEGRATORS:
        crit = critical_dt(model, name)
        report["critical_dt"][name] = crit
        report["stable_at_dt"][name] = True if crit is None else bool(scene.dt <= crit)
        txt = "unconditionally stable (linear analysis)" if crit is None else f"{crit:.4g} s"
        print(f"  {name:18s} critical dt: {txt}")
    b = damping_bounds(model, scene.dt)
    report["damping"] = b.__dict__
    print(f"  omega_max = {b.omega_max:.4g} rad/s, damping ratio of the stiffest mode = {b.damping_ratio:.3g}")
    print(f"  k_d that critically damps one segment spring: {b.k_d_critical_spring:.4g} N s/m;"
          f" explicit Euler needs k_d >= {b.k_d_min_explicit_euler:.4g}; explicit methods need k_d <= "
          f"{b.k_d_max_explicit:.4g} N s/m at this dt")
    if args.json:
        write_json(args.json, report)
    png = plot_path(args, args.json)
    if png is not None:
        from bullet_dlo.render.plots import plot_critical_dt

        plot_critical_dt(report["critical_dt"], scene.dt, png, title=scene.name)
    print_outputs(args.json, png)
    return 0


def parse_tables(text: str) -> tuple[str, ...]:
    """``base,rates`` -> ("base", "rates"); argparse reports anything else."""
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    bad = [t for t in names if t not in TABLES]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"tables must be a comma-separated subset of {','.join(TABLES)}, got {text!r}")
    return names


def cmd_paper_table(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis import study
    from bullet_dlo.core.integrators import get_integrator

    tables = ("base", "rates") if args.rates else args.tables
    check_paper_table(args)
    if args.quick:  # a subset in seconds, to see the command work: not the study's table
        args.moduli = args.moduli or QUICK_TABLE["moduli"]
        args.masses = args.masses or QUICK_TABLE["masses"]
        args.steps = args.steps or QUICK_TABLE["steps"]
        args.duration, args.rate_duration = QUICK_TABLE["duration"], QUICK_TABLE["rate_duration"]
        print("--quick: a subset with short runs, to see the command work; not the study's table", flush=True)
    moduli = [float(e) * 1e6 for e in args.moduli] if args.moduli else study.PAPER_E
    masses = args.masses or study.PAPER_N
    plans = []  # (heading, steps, integrators, duration)
    if "base" in tables:
        plans.append(("The study's time steps", args.steps or study.PAPER_DT,
                      args.integrators or study.PAPER_INTEGRATORS, args.duration))
    if "rates" in tables:
        plans.append(("At robot-simulator rates (1 kHz Gazebo, 60 Hz Isaac Sim)", tuple(study.ROBOT_RATES.values()),
                      RATE_INTEGRATORS, args.rate_duration))
    for _, _, integrators, _ in plans:
        for name in integrators:
            get_integrator(name)  # a bad name fails before any run
    print("The study's scenario: Lv cable, both ends clamped at rest length, settled, last end moved 5 mm "
          f"(k_d = {args.damping} N s/m).", flush=True)
    total = sum(len(moduli) * len(masses) * len(steps) * len(integ) for _, steps, integ, _ in plans)
    progress = bar(total, "paper-table", args.quiet)

    finished = []  # every run as it ends: what an interrupted table still writes

    def report(run) -> None:
        finished.append(run)
        progress.update(1)
        progress.set_postfix_str(f"E={run.youngs_modulus / 1e6:g} MPa n={run.n_masses} dt={run.dt:g} {run.integrator}")
        if args.verbose:
            state = "stable" if run.stable else f"unstable at {run.time_to_instability:.4g} s"
            progress.write(f"  E={run.youngs_modulus / 1e6:g} MPa n={run.n_masses} dt={run.dt:g} {run.integrator}: "
                           f"{state} ({run.wall_time_s:.1f} s)")

    text = ""
    try:
        with progress:
            for heading, steps, integrators, duration in plans:
                start = len(finished)
                study.paper_table(moduli, masses, steps, integrators, damping=args.damping, duration=duration,
                                  progress=report)
                table = study.format_table(finished[start:])
                progress.write(f"\n{heading}, {duration:g} s per run:\n{table}")
                text += f"## {heading}\n\n{table}\n\n"
    except KeyboardInterrupt:  # keep what finished: the table so far, marked partial
        if finished:
            text += f"## Interrupted: the {len(finished)} runs that finished\n\n{study.format_table(finished)}\n\n"
        write_paper_table(args, text, finished, partial=True)
        print(f"interrupted (Ctrl-C): {len(finished)} of {total} runs finished"
              + (f"; written to {', '.join(p for p in (args.markdown, args.json) if p)}" if args.markdown or args.json
                 else ""), file=sys.stderr)
        return 130
    write_paper_table(args, text, finished, partial=False)
    return 0


QUICK_TABLE = {"moduli": [12.6, 1002.6], "masses": [6], "steps": [5e-6], "duration": 0.02, "rate_duration": 0.2}
"""``paper-table --quick``: two moduli, six masses, the study's larger step, short runs (seconds in all)."""


def write_paper_table(args: argparse.Namespace, text: str, runs: list, partial: bool) -> None:
    """The table as Markdown and every run as JSON where asked; ``partial``: an interrupted table (said in both)."""
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(("**Partial: interrupted.**\n\n" if partial else "") + text)
    if args.json:
        write_json(args.json, {"partial": partial, "runs": [r.__dict__ for r in runs]} if partial
                   else [r.__dict__ for r in runs])
    png = plot_path(args, args.json, args.markdown)
    if png is not None and runs:
        from bullet_dlo.render.plots import plot_paper_table

        plot_paper_table(runs, png, title="the study's stability table" + (" (partial: interrupted)" if partial else ""))
    print_outputs(args.markdown, args.json, png)


def check_paper_table(args: argparse.Namespace) -> None:
    """Every number of ``paper-table``'s flags, against the cable bounds and the step cap (before any run)."""
    from bullet_dlo.analysis import study
    from bullet_dlo.config.schema import CABLE_BOUNDS
    from bullet_dlo.core.validate import check_in_range, check_int, check_positive, check_steps

    lo, hi = CABLE_BOUNDS["youngs_modulus"]
    for e in args.moduli or ():
        check_in_range("--moduli [MPa]", e, lo / 1e6, hi / 1e6)
    for n in args.masses or ():
        check_int("--masses", n, *(int(b) for b in CABLE_BOUNDS["n_masses"]))
    check_in_range("--damping", args.damping, *CABLE_BOUNDS["damping"])
    duration = check_positive("--duration", args.duration)
    rate_duration = check_positive("--rate-duration", args.rate_duration)
    for dt in args.steps or study.PAPER_DT:
        check_steps(check_positive("--steps", dt), duration, dt_name="--steps", duration_name="--duration")
    for dt in study.ROBOT_RATES.values():
        check_steps(dt, rate_duration, dt_name="the rates table's dt", duration_name="--rate-duration")


def cmd_convergence(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.closed_forms import cantilever_convergence
    from bullet_dlo.config.schema import CABLE_BOUNDS
    from bullet_dlo.core.validate import check_int

    for n in args.masses:
        check_int("--masses", n, 3, int(CABLE_BOUNDS["n_masses"][1]))

    rows = []
    with bar(len(args.masses), "convergence", args.quiet, unit="n") as progress:
        for n in args.masses:
            rows += cantilever_convergence([n])
            progress.update(1)
    print("Clamped cantilever under its own weight vs delta = w L^4 / (8 E I) (small deflection):")
    print("| n | default error | paper error |\n|---|---|---|")
    for r in rows:
        print(f"| {r['n_masses']} | {100 * r['default']:+.3f} % | {100 * r['paper']:+.2f} % |")
    if args.json:
        write_json(args.json, rows)
    png = plot_path(args, args.json)
    if png is not None and rows:
        from bullet_dlo.render.plots import plot_convergence

        plot_convergence(rows, png, title="clamped cantilever under its own weight vs w L^4 / (8 E I)")
    print_outputs(args.json, png)
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """The four subcommands of this group, on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("simulate", parents=[common], help="run a scene file and write JSON results",
                       description="Run SCENE.yaml (see the README for its keys) with the core engine or in "
                                   "PyBullet and print stability and end forces.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--json", metavar="OUT.json", help="write stable, time_to_instability, critical_dt, "
                   "final_positions, end_forces, steps, wall_time_s (and more) to this file")
    s.add_argument("--npz", metavar="OUT.npz", help="also save the recorded trajectory (t, x, v, end_forces, energy)")
    s.add_argument("--engine", default="core", choices=[Engine.CORE.value, Engine.BULLET.value],
                   help="core: the NumPy/Numba engine (default, no contacts); bullet: the cable as PyBullet spheres "
                        "driven by the same integrator, with contacts against the ground and the scene's "
                        "bullet.obstacles (same JSON keys)")
    s.add_argument("--integrator", help="override the scene's integrator (explicit_euler, symplectic_euler, rk4, "
                   "implicit_euler, bdf2, implicit_midpoint)")
    s.add_argument("--dt", type=float, help="override the scene's time step [s]")
    s.add_argument("--duration", type=float, help="override the scene's duration [s]")
    add_plot_options(s, "the end forces and energy over time and the first and last shapes")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("stability", parents=[common], help="predicted critical time step of every integrator",
                       description="Linear stability analysis of SCENE.yaml's cable: critical dt per integrator "
                                   "and damping bounds.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--json", metavar="OUT.json", help="write the report as JSON")
    add_plot_options(s, "each integrator's critical step against the scene's dt (log scale)")
    s.set_defaults(func=cmd_stability)

    s = sub.add_parser("paper-table", parents=[common], help="re-run the study's stability table with every integrator",
                       description="Lv cable clamped at both ends, settled, last end moved 5 mm; for each E, n and "
                                   "dt report stable/unstable and the time to instability. The full base table "
                                   "takes about 13 minutes on 2 cores (a progress bar shows the ETA); the rates "
                                   "table about a minute.")
    s.add_argument("--tables", type=parse_tables, default=("base",), metavar="base,rates",
                   help="which tables to compute: base (the study's steps 5e-6 and 1e-7 s), rates (1 kHz and "
                        "60 Hz with symplectic Euler and the implicit methods), or both (default: base)")
    s.add_argument("--rates", action="store_true", help="same as --tables base,rates (kept for old scripts)")
    s.add_argument("--moduli", nargs="+", type=float, metavar="MPA",
                   help="Young's moduli in MPa (default: 12.6 526 1002 1002.6)")
    s.add_argument("--masses", nargs="+", type=int, metavar="N", help="numbers of masses (default: 6 10)")
    s.add_argument("--steps", nargs="+", type=float, metavar="DT",
                   help="time steps [s] of the base table (default: 5e-6 1e-7)")
    s.add_argument("--integrators", nargs="+", metavar="NAME",
                   help="integrators of the base table (default: explicit_euler symplectic_euler rk4 implicit_euler)")
    s.add_argument("--damping", type=float, default=0.01, help="k_d [N s/m] (default 0.01)")
    s.add_argument("--duration", type=float, default=0.25, help="simulated seconds per base-table run (default 0.25)")
    s.add_argument("--rate-duration", type=float, default=2.0,
                   help="simulated seconds per rates-table run (default 2)")
    s.add_argument("--markdown", metavar="OUT.md", help="write the table(s) as Markdown")
    s.add_argument("--json", metavar="OUT.json", help="write every run as JSON")
    s.add_argument("-v", "--verbose", action="store_true", help="print each run as it finishes")
    add_plot_options(s, "the table as a stable/unstable grid per modulus")
    s.add_argument("--quick", action="store_true",
                   help="a subset in seconds (E 12.6 and 1002.6 MPa, n 6, dt 5e-6 s, 0.02 s runs; rates 0.2 s) to see "
                        "the command work; not the study's table. A Ctrl-C at any time writes the runs that finished "
                        "(marked partial) and exits 130")
    s.set_defaults(func=cmd_paper_table)

    s = sub.add_parser("convergence", parents=[common], help="cantilever static convergence of both discretisations",
                       description="Tip deflection of a clamped cantilever under its own weight vs beam "
                                   "theory, for the default and the paper discretisation.")
    s.add_argument("--masses", nargs="+", type=int, default=[5, 10, 20, 40], metavar="N",
                   help="numbers of masses (default: 5 10 20 40)")
    s.add_argument("--json", metavar="OUT.json", help="write the table as JSON")
    add_plot_options(s, "the error of both discretisations against n (log-log)")
    s.set_defaults(func=cmd_convergence)
