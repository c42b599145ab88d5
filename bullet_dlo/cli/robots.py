"""``bullet-dlo grasp | render``: two arms holding the cable, and headless video."""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bullet_dlo.cli.outputs import add_plot_options, plot_path, print_outputs
from bullet_dlo.cli.quiet import bar
from bullet_dlo.cli.simulate import write_json


def grasp_scene(args: argparse.Namespace):
    """The scene ``grasp`` runs: the ``--scene`` file (or the study's: lv2017 cable, 1/240 s, a 5 mm lift of
    the right end at 1.5 s, 3 s) with the command's flags applied, validated as a capture spec bounds them."""
    from dataclasses import replace

    from bullet_dlo.config.capture import PARAMETERS
    from bullet_dlo.config.robot import ArmsOptions, robot_names
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.config.schema import one_of
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.spec import CableSpec
    from bullet_dlo.core.validate import check_in_range, check_positive, check_steps

    if args.robot is not None:
        one_of("--robot", args.robot, robot_names())
    # the ranges a capture spec allows for the same quantities (config.capture.PARAMETERS)
    check_in_range("--noise [N]", args.noise, *PARAMETERS["noise_std"][2])
    if args.sensor_rate is not None:
        check_in_range("--sensor-rate [Hz]", args.sensor_rate, 1e-3, PARAMETERS["sensor_rate"][2][1])
    if args.scene:
        from bullet_dlo.sim import resolved

        scene = resolved(Scene.from_yaml(args.scene))  # dt: auto becomes a step before it is checked
    else:
        scene = Scene(cable=CableSpec.lv2017(n_masses=10, damping=0.02), dt=1.0 / 240.0, duration=3.0,
                      motion=(Move("last", (0.0, 0.0, 0.005), 1.5, 0.1),))  # the study's 5 mm move
    dt_lo, dt_hi = PARAMETERS["dt"][2]  # a robot controller's step
    dt = check_in_range("--dt [s]" if args.dt is not None else "dt [s] (robot scenes)",
                        scene.dt if args.dt is None else args.dt, dt_lo, dt_hi)
    duration = check_positive("--duration", args.duration) if args.duration is not None else scene.duration
    check_steps(dt, duration, dt_name="--dt" if args.dt is not None else "dt",
                duration_name="--duration" if args.duration is not None else "duration")
    arms = scene.arms or ArmsOptions()
    if args.sensor_rate is not None:
        arms = replace(arms, sensor_rate=args.sensor_rate)
    if args.noise:
        arms = replace(arms, noise_std=(args.noise,) * 3 + (0.0,) * 3)
    return replace(scene, dt=dt, duration=duration, arms=arms)


def cmd_grasp(args: argparse.Namespace) -> int:
    from bullet_dlo.sim import build

    scene = grasp_scene(args)
    with build(scene, "arms", robot=args.robot, command="grasp") as sim:
        sc = sim.arms
        spec, dt, duration = sc.spec, scene.dt, scene.duration
        robot, cable, integrator = spec.robot, spec.cable, spec.integrator
        recorder = None
        png = plot_path(args, args.json, args.series)
        if args.series:
            from bullet_dlo.data.recording import series_format

            series_format(args.series)  # a bad suffix fails before the run, not after
        if args.series or png is not None:
            recorder = _attach_series(sc)
        with bar(sc.world.steps_in(duration), f"grasp ({robot})", args.quiet, unit="step") as progress:
            sc.world.after_step.append(lambda: progress.update(1))
            first_step, wall = sc.run_timed(duration)
        window = sc.window_mean(0.5)
        weight = cable.mass * float(np.linalg.norm(sc.world.gravity))
        w, f = window["wrench_world"], window["end_forces"]
        data = {
            "robot": robot, "dt": dt, "duration": duration, "integrator": integrator,
            "stable": bool(sc.cable.stable), "time_to_instability": sc.cable.time_to_instability,
            "cable_weight": weight,
            "wrench_world": {"left": w[0].tolist(), "right": w[1].tolist()},
            "ground_truth_end_forces": {"left": f[0].tolist(), "right": f[1].tolist()},
            "force_balance_error": float((w[0, 2] + w[1, 2] + weight) / weight),
            "sensor_vs_model_error": float(np.max(np.abs(w[:, :3] - f)) / weight),
            "sensor_check": sc.observation.check.summary(),
            "sensor_compensation": sc.sensors[0].compensation,
            "wall_time_s": wall, "first_step_s": first_step, "steps": sc.world.steps,
            "twist_reason": sim.scene.twist_reason,
            "pose_misses": [{"t": t, "arm": ("left", "right")[a], "distance_m": d} for t, a, d in sc.task.pose_misses],
        }
        if args.series:
            from bullet_dlo.data.recording import write_series

            write_series(args.series, recorder.arrays(), {k: v for k, v in data.items() if not isinstance(v, dict)}
                         | {"cable": cable.to_dict()})
        if png is not None:
            from bullet_dlo.render.plots import plot_wrenches

            rows = recorder.arrays()
            plot_wrenches(rows["t"], rows["wrench_world"], rows["end_forces"], png,
                          title=f"grasp: {robot}, dt = {dt:g} s, {integrator}")
    if args.json:
        write_json(args.json, data)
    print(f"{robot}: {'stable' if data['stable'] else 'UNSTABLE'}, {data['steps'] - 1} steps in {wall:.2f} s "
          f"after a first step of {first_step:.2f} s (loading or compiling kernels); cable weight {weight:.4f} N")
    for arm in ("left", "right"):
        print(f"  {arm:5s} sensor (world) " + " ".join(f"{v:+.4f}" for v in data["wrench_world"][arm][:3])
              + " N   model " + " ".join(f"{v:+.4f}" for v in data["ground_truth_end_forces"][arm]) + " N")
    print(f"  vertical balance error {100 * data['force_balance_error']:+.3f} % of the weight")
    if data["twist_reason"]:
        print(f"  {data['twist_reason']}")
    for miss in data["pose_misses"]:
        print(f"  GRIPPER OFF ITS MOTION: the {miss['arm']} grasp frame {1000 * miss['distance_m']:.1f} mm from its "
              f"target at t = {miss['t']:.3f} s (the arm does not follow it: the wrists read the pose it reached)")
    failures = data["sensor_check"]["failures"]
    for line in failures:
        print(f"  SENSOR CHECK FAILED: {line}")
    print_outputs(args.json, args.series, png)
    return 1 if failures or data["pose_misses"] else 0


def _attach_series(scene):
    """A per-step series recorder on ``scene``'s world (see bullet_dlo.data.recording)."""
    from bullet_dlo.data.recording import SeriesRecorder

    recorder = SeriesRecorder(scene)
    scene.world.after_step.append(recorder)
    return recorder


def cmd_render(args: argparse.Namespace) -> int:
    from bullet_dlo.config.robot import robot_names
    from bullet_dlo.config.scene import Scene
    from bullet_dlo.config.schema import LIMITS, one_of
    from bullet_dlo.core.validate import check_in_range, check_int
    from bullet_dlo.render.pipeline import render_scene

    check_in_range("--fps [Hz]", args.fps, 0.1, 1000.0)
    check_int("--width [px]", args.width, 16, int(LIMITS["pixels"]))
    check_int("--height [px]", args.height, 16, int(LIMITS["pixels"]))
    if args.robot is not None:
        one_of("--robot", args.robot, robot_names())
    scene = Scene.from_yaml(args.scene)
    robot = args.robot or (scene.arms.robot if scene.arms is not None else None)
    recorders = []
    if args.series:
        from bullet_dlo.core.validate import ParameterError
        from bullet_dlo.data.recording import series_format

        if robot is None:
            raise ParameterError("--series needs --robot or the scene's arms.robot (the series are the dual-arm "
                                 "scene's: wrist wrenches, grasp poses, joint states)")
        series_format(args.series)  # a bad suffix fails before the run, not after
    summary = render_scene(scene, args.out, robot=args.robot, fps=args.fps, width=args.width, height=args.height,
                           renderer=args.renderer, fmt=args.format, progress=not args.quiet,
                           on_arm_scene=(lambda sc: recorders.append(_attach_series(sc))) if args.series else None)
    if recorders:
        from bullet_dlo.data.recording import write_series

        write_series(args.series, recorders[0].arrays(), {"robot": robot, "dt": scene.dt,
                                                           "integrator": scene.integrator,
                                                           "cable": scene.cable.to_dict()})
    print(f"renderer: {summary['renderer']} ({summary['renderer_note']}); {summary['frames']} frames, "
          f"{summary['format']} ({summary['codec']}) in {summary['wall_time_s']:.1f} s")
    print(f"outputs written to {Path(args.out).resolve()}")
    return 0


def add_parsers(sub, common: argparse.ArgumentParser) -> None:
    """``grasp`` and ``render`` on ``sub`` (argparse subparsers); ``common``: shared options."""
    s = sub.add_parser("grasp", parents=[common], help="two arms grasp the cable ends and read their wrist F/T sensors",
                       description="Build the dual-arm scene (arms facing each other, cable between the grippers), "
                                   "grasp both ends, hold, run the motion (scene file's motion: first end = left "
                                   "arm, last end = right arm; default: the study's 5 mm lift of the right end at "
                                   "1.5 s) and report the wrist wrenches (payload weight and inertia removed) in "
                                   "world frame, averaged over the last 0.5 s, next to the model's end forces. "
                                   "Every sample is checked against the load the cable applied in the same step; "
                                   "exit 1 if one differs by more than 10 % of the cable's weight + 5 mN.")
    s.add_argument("--robot", help="robot description in robots/: kuka or panda (default: the scene's arms.robot, "
                   "else kuka)")
    s.add_argument("--scene", metavar="SCENE.yaml", help="take the cable, dt, integrator, duration, motion, gravity, "
                   "initial, newton, detector, bullet (ground, obstacles, substeps, ...) and arms sections from a scene "
                   "file; layout and ends are refused (the grippers place and hold the cable)")
    s.add_argument("--json", metavar="OUT.json", help="write cable_weight, wrench_world, ground_truth_end_forces, "
                   "stable and more")
    s.add_argument("--dt", type=float, help="Bullet step [s] (default 1/240 or the scene's)")
    s.add_argument("--duration", type=float, help="simulated time [s] (default 3 or the scene's)")
    s.add_argument("--sensor-rate", type=float, default=None, help="F/T sensor rate [Hz] (default: every step)")
    s.add_argument("--noise", type=float, default=0.0, help="F/T force noise standard deviation [N] (default 0)")
    s.add_argument("--series", metavar="OUT.npz|OUT.h5|OUT.csv", help="write the per-step time series (wrist "
                   "wrenches in world and sensor frame, model end forces and moments, grasp poses, joint states, "
                   "cable positions; names as in dataset episodes, see bullet_dlo.data.recording); .csv holds what "
                   "bullet-dlo fit needs")
    add_plot_options(s, "both wrists' forces over time beside the model's end forces")
    s.set_defaults(func=cmd_grasp)

    s = sub.add_parser("render", parents=[common], help="headless video and force plots of a scene",
                       description="Run SCENE.yaml in PyBullet (DIRECT mode, no display) and write scene.mp4 "
                                   "(H.264; WebM or PNG frames as fallbacks), forces.png, side_by_side.mp4 (scene "
                                   "left, force plot with a moving cursor right), still.png and render.json. The "
                                   "camera frames the cable's whole motion; shadows are on.")
    s.add_argument("scene", help="scene YAML file")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder")
    s.add_argument("--robot", help="hold the cable with two arms (kuka, panda; default: the scene's arms.robot, else "
                   "no arms); the plot shows their wrist sensors")
    s.add_argument("--fps", type=float, default=30.0, help="video frame rate [Hz], independent of the physics (30)")
    s.add_argument("--width", type=int, default=640, help="frame width [px] (640)")
    s.add_argument("--height", type=int, default=480, help="frame height [px] (480)")
    s.add_argument("--renderer", default="auto", choices=["auto", "tiny", "egl"],
                   help="auto: EGL when its plugin loads, else TinyRenderer (reported); tiny; egl (error if absent)")
    s.add_argument("--format", default="auto", choices=["auto", "mp4", "webm", "png"],
                   help="video format: auto tries H.264 MP4, then VP9 WebM, then a PNG sequence")
    s.add_argument("--series", metavar="OUT.npz|OUT.h5|OUT.csv", help="with --robot: write the per-step time "
                   "series as grasp --series does (names as in dataset episodes, see bullet_dlo.data.recording)")
    s.set_defaults(func=cmd_render)
