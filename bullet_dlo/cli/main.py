"""``bullet-dlo``: the command-line entry point (one subcommand per task).

Every invalid input ends with a one-line ``error: ...`` naming the bad key or option and
exit code 2.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from bullet_dlo.core.validate import ParameterError


def _write_json(path: str, data: object) -> None:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=2))


def cmd_simulate(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from bullet_dlo.config.scene import Scene, result_json
    from bullet_dlo.core.integrators import get_integrator
    from bullet_dlo.core.validate import check_positive

    scene = Scene.from_yaml(args.scene).resolved()
    if args.integrator is not None:
        scene = replace(scene, integrator=get_integrator(args.integrator).name)
    for key in ("dt", "duration"):
        if getattr(args, key) is not None:
            scene = replace(scene, **{key: check_positive(f"--{key}", getattr(args, key))})
    if args.engine == "bullet":
        from bullet_dlo.bullet.world import run_scene_bullet

        model, result = run_scene_bullet(scene)
    else:
        model, result = scene.run()
    data = result_json(scene, model, result, engine=args.engine)
    if args.json:
        _write_json(args.json, data)
    if args.npz:
        Path(args.npz).parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.npz, t=result.t, x=result.x, v=result.v, end_forces=result.end_forces,
                            energy=result.energy)
    status = "stable" if data["stable"] else f"UNSTABLE at t = {data['time_to_instability']:.6g} s ({data['reason']})"
    print(f"{scene.name}: {data['integrator']} dt={scene.dt:g} s, {data['steps']} steps in "
          f"{data['wall_time_s']:.3f} s: {status}")
    if data["stable"]:
        for end in ("first", "last"):
            if data["end_forces"][end] is not None:
                print(f"  end force {end}: " + " ".join(f"{v:+.5f}" for v in data["end_forces"][end]) + " N")
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
        _write_json(args.json, report)
    return 0


def cmd_paper_table(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis import study as paper

    moduli = [float(e) * 1e6 for e in args.moduli] if args.moduli else paper.PAPER_E
    masses = args.masses or paper.PAPER_N
    steps = args.steps or paper.PAPER_DT
    integrators = args.integrators or paper.PAPER_INTEGRATORS
    for name in integrators:
        from bullet_dlo.core.integrators import get_integrator
        get_integrator(name)
    print("The study's scenario: Lv cable, both ends clamped at rest length, settled, last end moved 5 mm "
          f"(k_d = {args.damping} N s/m, {args.duration} s per run).", flush=True)
    done = []

    def progress(run: paper.PaperRun) -> None:
        done.append(run)
        if args.verbose:
            state = "stable" if run.stable else f"unstable at {run.time_to_instability:.4g} s"
            print(f"  E={run.youngs_modulus / 1e6:g} MPa n={run.n_masses} dt={run.dt:g} {run.integrator}: {state}"
                  f" ({run.wall_time_s:.1f} s)", flush=True)

    runs = paper.paper_table(moduli, masses, steps, integrators, damping=args.damping, duration=args.duration,
                             progress=progress)
    table = paper.format_table(runs)
    print(table)
    text = "## The study's time steps\n\n" + table + "\n"
    if args.rates:
        rate_runs = paper.robot_rate_table(moduli, masses, damping=args.damping, duration=args.rate_duration)
        rate_table = paper.format_table(rate_runs)
        print("\nAt the robot simulators' rates (1 kHz Gazebo, 60 Hz Isaac Sim):")
        print(rate_table)
        text += "\n## At robot-simulator rates\n\n" + rate_table + "\n"
        runs = runs + rate_runs
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(text)
    if args.json:
        _write_json(args.json, [r.__dict__ for r in runs])
    return 0


def cmd_convergence(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.closed_forms import cantilever_convergence

    rows = cantilever_convergence(args.masses)
    print("Clamped cantilever under its own weight vs delta = w L^4 / (8 E I) (small deflection):")
    print("| n | default error | paper error |\n|---|---|---|")
    for r in rows:
        print(f"| {r['n_masses']} | {100 * r['default']:+.3f} % | {100 * r['paper']:+.2f} % |")
    if args.json:
        _write_json(args.json, rows)
    return 0


def cmd_grasp(args: argparse.Namespace) -> int:
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.core.spec import CableSpec
    from bullet_dlo.core.validate import check_positive
    from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

    if args.scene:
        scene = Scene.from_yaml(args.scene).resolved()
        cable, dt, integrator, duration = scene.cable, scene.dt, scene.integrator, scene.duration
        moves = [("left" if m.end == "first" else "right", m.displacement, m.start, m.duration, m.rotation)
                 for m in scene.motion]
    else:
        cable = CableSpec.lv2017(n_masses=10, damping=0.02)
        dt, integrator, duration = 1.0 / 240.0, "implicit_euler", 3.0
        moves = [("right", (0.0, 0.0, 0.005), 1.5, 0.1, (0.0, 0.0, 0.0))]  # the study's 5 mm move
    dt = check_positive("--dt", args.dt) if args.dt is not None else dt
    duration = check_positive("--duration", args.duration) if args.duration is not None else duration
    if any(np.any(np.asarray(m[4]) != 0.0) for m in moves):
        raise ParameterError("motion: gripper rotations are not supported by grasp yet; use displacements")
    config = DualArmConfig(robot=args.robot, cable=cable, dt=dt, integrator=integrator,
                           sensor_rate=args.sensor_rate, noise_std=(args.noise,) * 3 + (0.0,) * 3)
    with DualArmScene(config) as sc:
        sc.grasp()
        for arm, disp, start, dur, _ in moves:
            sc.move(arm, disp, dur, start=start)
        wall = sc.run(duration)
        window = sc.window_mean(0.5)
        weight = cable.mass * float(np.linalg.norm(sc.world.gravity))
        w, f = window["wrench_world"], window["end_forces"]
        data = {
            "robot": args.robot, "dt": dt, "duration": duration, "integrator": integrator,
            "stable": bool(sc.cable.stable), "time_to_instability": sc.cable.time_to_instability,
            "cable_weight": weight,
            "wrench_world": {"left": w[0].tolist(), "right": w[1].tolist()},
            "ground_truth_end_forces": {"left": f[0].tolist(), "right": f[1].tolist()},
            "force_balance_error": float((w[0, 2] + w[1, 2] + weight) / weight),
            "sensor_vs_model_error": float(np.max(np.abs(w[:, :3] - f)) / weight),
            "wall_time_s": wall, "steps": sc.world.steps,
        }
    if args.json:
        _write_json(args.json, data)
    print(f"{args.robot}: {'stable' if data['stable'] else 'UNSTABLE'}, {data['steps']} steps in {wall:.2f} s; "
          f"cable weight {weight:.4f} N")
    for arm in ("left", "right"):
        print(f"  {arm:5s} sensor (world) " + " ".join(f"{v:+.4f}" for v in data["wrench_world"][arm][:3])
              + " N   model " + " ".join(f"{v:+.4f}" for v in data["ground_truth_end_forces"][arm]) + " N")
    print(f"  vertical balance error {100 * data['force_balance_error']:+.3f} % of the weight")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.render.pipeline import render_scene

    scene = Scene.from_yaml(args.scene).resolved()
    summary = render_scene(scene, args.out, robot=args.robot, fps=args.fps, width=args.width, height=args.height,
                           renderer=args.renderer, fmt=args.format, progress=not args.quiet)
    print(f"renderer: {summary['renderer']} ({summary['renderer_note']}); {summary['frames']} frames, "
          f"{summary['format']} ({summary['codec']}) in {summary['wall_time_s']:.1f} s")
    print(f"outputs written to {Path(args.out).resolve()}")
    return 0


def cmd_capture(args: argparse.Namespace) -> int:
    from bullet_dlo.config.capture import CaptureSpec
    from bullet_dlo.data.capture import capture

    spec = CaptureSpec.from_yaml(args.spec)
    res = capture(spec, args.out, args.episodes, workers=args.workers, backend=args.backend, resume=args.resume,
                  progress=not args.quiet)
    print(f"{res.done} episodes in {res.out} ({res.flagged} flagged unstable, {res.failed} failed); ran {res.ran} "
          f"in {res.wall_time_s:.1f} s = {res.episodes_per_second:.2f} episodes/s with {args.workers} worker(s)")
    return 0


def cmd_dataset_summary(args: argparse.Namespace) -> int:
    from bullet_dlo.data.capture import Dataset

    ds = Dataset(args.dir)
    png = Path(args.dir) / "quality.png"
    summary = ds.summary(png)
    print(f"{summary['episodes']} episodes: {summary['ok']} ok, {summary['flagged']} flagged unstable, "
          f"{summary['failed']} failed; stability decisions: {summary['decisions']}")
    for run in summary["flagged_runs"]:
        print(f"  flagged: episode {run['episode']} unstable at t = {run['time_to_instability']} s")
    for key, (lo, hi) in sorted(summary["coverage"].items()):
        print(f"  {key:16s} {lo:.4g} .. {hi:.4g}")
    print(f"quality histogram: {png}")
    if args.json:
        _write_json(args.json, summary)
    return 0


def cmd_resolve(args: argparse.Namespace) -> int:
    from bullet_dlo.analysis.resolve import resolve
    from bullet_dlo.config.scene import Scene

    scene = Scene.from_yaml(args.scene)
    r = resolve(scene, args.tol, args.target, args.rollout)
    print(f"{scene.name}: n_masses = {r.n_masses}, integrator = {r.integrator}, dt = {r.dt:.4g} s; predicted error "
          f"{r.predicted_error:.4f} (spatial {r.spatial_error:.4f} + temporal {r.temporal_error:.4f}) <= "
          f"{r.tolerance} on {r.target}; {r.wall_time_per_sim_s:.4f} s wall per simulated second")
    if args.json:
        _write_json(args.json, r.to_dict())
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from bullet_dlo.cli import bench as bench_cli

    return bench_cli.run(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="bullet-dlo",
        description="Mass-spring-damper cables with stable integrators (PyBullet-free core). "
                    "All quantities in SI units.",
    )
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("simulate", help="run a scene file and write JSON results",
                       description="Run SCENE.yaml (see README for the schema) and write results.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--json", metavar="OUT.json", help="write stable, time_to_instability, critical_dt, "
                   "final_positions, end_forces, steps, wall_time_s (and more) to this file")
    s.add_argument("--npz", metavar="OUT.npz", help="also save the recorded trajectory (t, x, v, end_forces, energy)")
    s.add_argument("--engine", default="core", choices=["core", "bullet"],
                   help="core: the NumPy/Numba engine (default, no contacts); bullet: the cable as PyBullet spheres "
                        "driven by the same integrator, with contacts against the ground and the scene's "
                        "bullet.obstacles (same JSON keys)")
    s.add_argument("--integrator", help="override the scene's integrator")
    s.add_argument("--dt", type=float, help="override the scene's time step [s]")
    s.add_argument("--duration", type=float, help="override the scene's duration [s]")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("stability", help="predicted critical time step of every integrator for a scene",
                       description="Linear stability analysis of SCENE.yaml's cable: critical dt per integrator "
                                   "and damping bounds.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--json", metavar="OUT.json", help="write the report as JSON")
    s.set_defaults(func=cmd_stability)

    s = sub.add_parser("paper-table", help="re-run the study's stability table with every integrator",
                       description="Lv cable clamped at both ends, settled, last end moved 5 mm; for each "
                                   "E, n and dt report stable/unstable and time to instability.")
    s.add_argument("--moduli", nargs="+", type=float, metavar="MPA",
                   help="Young's moduli in MPa (default: 12.6 526 1002 1002.6)")
    s.add_argument("--masses", nargs="+", type=int, metavar="N", help="numbers of masses (default: 6 10)")
    s.add_argument("--steps", nargs="+", type=float, metavar="DT", help="time steps [s] (default: 5e-6 1e-7)")
    s.add_argument("--integrators", nargs="+", metavar="NAME",
                   help="integrators (default: explicit_euler symplectic_euler rk4 implicit_euler)")
    s.add_argument("--damping", type=float, default=0.01, help="k_d [N s/m] (default 0.01)")
    s.add_argument("--duration", type=float, default=0.25, help="simulated seconds per run (default 0.25)")
    s.add_argument("--rates", action="store_true",
                   help="also run the scenario at 1 kHz and 60 Hz with symplectic Euler and the implicit methods")
    s.add_argument("--rate-duration", type=float, default=2.0, help="seconds per run for --rates (default 2)")
    s.add_argument("--markdown", metavar="OUT.md", help="write the table(s) as Markdown")
    s.add_argument("--json", metavar="OUT.json", help="write every run as JSON")
    s.add_argument("-v", "--verbose", action="store_true", help="print each run as it finishes")
    s.set_defaults(func=cmd_paper_table)

    s = sub.add_parser("grasp", help="two arms grasp the cable ends and read their wrist F/T sensors",
                       description="Build the dual-arm scene (arms facing each other, cable between the grippers), "
                                   "grasp both ends, hold, run the motion (scene file's motion: first end = left "
                                   "arm, last end = right arm; default: the study's 5 mm lift of the right end at "
                                   "1.5 s) and report the tared wrist wrenches in world frame, averaged over the "
                                   "last 0.5 s, next to the model's end forces.")
    s.add_argument("--robot", default="kuka", help="robot description in robots/ (kuka, panda)")
    s.add_argument("--scene", metavar="SCENE.yaml", help="take cable, dt, integrator, duration and motion from a "
                   "scene file (its layout and ends are replaced by the grasp)")
    s.add_argument("--json", metavar="OUT.json", help="write cable_weight, wrench_world, ground_truth_end_forces, "
                   "stable and more")
    s.add_argument("--dt", type=float, help="Bullet step [s] (default 1/240 or the scene's)")
    s.add_argument("--duration", type=float, help="simulated time [s] (default 3 or the scene's)")
    s.add_argument("--sensor-rate", type=float, default=None, help="F/T sensor rate [Hz] (default: every step)")
    s.add_argument("--noise", type=float, default=0.0, help="F/T force noise std [N] (default 0)")
    s.set_defaults(func=cmd_grasp)

    s = sub.add_parser("render", help="headless video and force plots of a scene",
                       description="Run SCENE.yaml in PyBullet (DIRECT mode, no display) and write scene.mp4 "
                                   "(H.264; WebM or PNG frames as fallbacks), forces.png, side_by_side.mp4 (scene "
                                   "left, force plot with a moving cursor right), still.png and render.json.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder")
    s.add_argument("--robot", help="hold the cable with two arms (kuka, panda); plots show the wrist sensors")
    s.add_argument("--fps", type=float, default=30.0, help="video frame rate, independent of the physics (30)")
    s.add_argument("--width", type=int, default=640, help="frame width [px] (640)")
    s.add_argument("--height", type=int, default=480, help="frame height [px] (480)")
    s.add_argument("--renderer", default="auto", choices=["auto", "tiny", "egl"],
                   help="auto: EGL when its plugin loads, else TinyRenderer (reported); tiny; egl (error if absent)")
    s.add_argument("--format", default="auto", choices=["auto", "mp4", "webm", "png"],
                   help="video format: auto tries H.264 MP4, then VP9 WebM, then a PNG sequence")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_render)

    s = sub.add_parser("capture", help="capture a domain-randomised dual-arm force dataset",
                       description="Run episodes 0..N-1 of SPEC.yaml (see demos/specs/dr_small.yaml) into DIR: one "
                                   "HDF5 file per episode, manifest.jsonl, capture.json.")
    s.add_argument("spec", help="randomisation spec (YAML)")
    s.add_argument("--out", required=True, metavar="DIR", help="capture directory")
    s.add_argument("--episodes", type=int, required=True, help="number of episodes N")
    s.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    s.add_argument("--backend", default="local", choices=["local", "ray"],
                   help="local process pool (default) or a Ray cluster (RAY_ADDRESS, else a local Ray instance)")
    s.add_argument("--resume", action="store_true", help="continue an interrupted capture in DIR")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_capture)

    s = sub.add_parser("dataset", help="inspect a captured dataset")
    dsub = s.add_subparsers(dest="dataset_command", required=True, metavar="ACTION")
    d = dsub.add_parser("summary", help="counts, flagged runs, parameter coverage, quality histogram (PNG)")
    d.add_argument("dir", help="capture directory")
    d.add_argument("--json", metavar="OUT.json", help="write the summary as JSON")
    d.set_defaults(func=cmd_dataset_summary)

    s = sub.add_parser("resolve", help="fewest masses, integrator and largest step meeting a tolerance",
                       description="Convergence tests on a short rollout of SCENE.yaml pick the fewest masses, then "
                                   "the cheapest integrator and largest step, that keep the error on what the scene "
                                   "needs within --tol. Scenes may also say n_masses: auto / dt: auto.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--tol", type=float, default=0.01, help="relative tolerance (default 0.01)")
    s.add_argument("--target", default="both", choices=["forces", "shape", "both"],
                   help="what must be accurate: end forces (0.2 s means), final shape, or both")
    s.add_argument("--rollout", type=float, default=None, help="seconds per trial (default: duration, at most 2)")
    s.add_argument("--json", metavar="OUT.json", help="write n_masses, dt, integrator, predicted_error, "
                   "wall_time_per_sim_s and the trials")
    s.set_defaults(func=cmd_resolve)

    s = sub.add_parser("bench", help="speed against accuracy: work-precision, stability map, peers, scaling")
    bsub = s.add_subparsers(dest="bench_command", required=True, metavar="BENCH")
    for name, text in (("work-precision", "error vs wall time per simulated second for every integrator, dt, n, "
                        "scenario S1-S4 and engine; PNG + CSV"),
                       ("stability", "largest stable dt vs E and n per method, measured by bisection, with the "
                        "predicted limit"),
                       ("peers", "PyElastica and MuJoCo on S1 and S2 next to ours (pip install '.[peers]')"),
                       ("scaling", "cost of the implicit solve vs n up to 1000 and its fitted exponent"),
                       ("resolve", "resolve's choices on S1-S4 checked against their references")):
        b = bsub.add_parser(name, help=text, description=text)
        b.add_argument("--out", default=os.path.join("out", "bench"), help="output folder (default out/bench)")
        b.add_argument("--quick", action="store_true", help="a few points only (seconds; for CI)")
        b.set_defaults(func=cmd_bench)

    s = sub.add_parser("convergence", help="cantilever static convergence of both discretisations",
                       description="Tip deflection of a clamped cantilever under its own weight vs beam "
                                   "theory, for the default and the paper discretisation.")
    s.add_argument("--masses", nargs="+", type=int, default=[5, 10, 20, 40], metavar="N",
                   help="numbers of masses (default: 5 10 20 40)")
    s.add_argument("--json", metavar="OUT.json", help="write the table as JSON")
    s.set_defaults(func=cmd_convergence)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ParameterError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
