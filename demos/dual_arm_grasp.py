"""Dual-arm cable manipulation with wrist F/T sensors, headless.

For each robot (KUKA iiwa with the project's F/T gripper, Franka Panda): both arms grasp
the Lv cable's ends, hold it (force balance against the cable's weight), run the study's
test (one end lifted 5 mm), then larger motions: bring the ends 15 cm together, lift both
by 20 cm, swing one end sideways. Writes into the output folder:

* ``<robot>_forces.png``: sensor force (tared, world frame) and the model's end force per arm
* ``summary.json``: force-balance errors, RMS tracking error, wall time per simulated second

Usage: ``python demos/dual_arm_grasp.py [--out DIR] [--robots kuka panda] [--quick]``
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from bullet_dlo.render.plots import plot_wrenches
from bullet_dlo.robots.dual_arm import DualArmConfig, DualArmScene

PHASES = ((1.0, 1.1, "5 mm"), (2.0, 3.5, "ends together"), (4.0, 5.5, "lift"), (6.0, 8.1, "swing"))


def choreography(scene: DualArmScene, quick: bool) -> float:
    """Schedule the moves; returns the total duration [s]."""
    t = 1.0
    scene.move("right", (0.0, 0.0, 0.005), 0.1, start=t)  # the study's test
    t += 1.0
    if quick:
        return t
    scene.move("right", (-0.15, 0.0, 0.0), 1.5, start=t)  # bring the ends together
    t += 2.0
    for arm in ("left", "right"):
        scene.move(arm, (0.0, 0.0, 0.2), 1.5, start=t)  # lift
    t += 2.0
    scene.move("right", (0.0, 0.1, 0.0), 0.7, start=t)  # swing sideways and back
    scene.move("right", (0.0, -0.2, 0.0), 1.4, start=t + 0.7)
    scene.move("right", (0.0, 0.1, 0.0), 0.7, start=t + 2.1)
    return t + 3.5


def run_robot(robot: str, dt: float, quick: bool) -> tuple[DualArmScene, dict]:
    scene = DualArmScene(DualArmConfig(robot=robot, dt=dt))
    scene.grasp()
    duration = choreography(scene, quick)
    wall_hold = scene.run(1.0)
    weight = scene.cable.model.spec.mass * 9.81
    hold = scene.window_mean(0.5)
    w, f = hold["wrench_world"][:, :3], hold["end_forces"]
    wall_rest = scene.run(duration - 1.0)
    rec = scene.record.arrays()
    err = rec["wrench_world"][:, :, :3] - rec["end_forces"]
    moving = rec["t"] > 1.0
    summary = dict(
        robot=robot, dt=dt, stable=bool(scene.cable.stable),
        vertical_balance_error=float((w[0, 2] + w[1, 2] + weight) / weight),
        horizontal_balance_error=float(abs(w[0, 0] + w[1, 0]) / weight),
        sensor_vs_model_static=float(np.max(np.abs(w - f)) / weight),
        rms_tracking_error_N=float(np.sqrt(np.mean(np.sum(err[moving] ** 2, axis=2)))),
        peak_force_N=float(np.max(np.linalg.norm(rec["end_forces"][moving], axis=2))),
        max_grasp_gap_m=float(np.max(np.linalg.norm(rec["grasp_pos"] - rec["cable_end_pos"], axis=2))),
        wall_time_per_sim_s=(wall_hold + wall_rest) / duration,
    )
    return scene, summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "dual_arm_grasp"), help="output folder")
    parser.add_argument("--robots", nargs="+", default=["kuka", "panda"], help="robots to run")
    parser.add_argument("--quick", action="store_true", help="only the hold and the 5 mm move (smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summaries = []
    for robot in args.robots:
        for dt in ((1 / 240,) if args.quick else (1 / 240, 1e-3)):
            scene, summary = run_robot(robot, dt, args.quick)
            if dt == 1 / 240:
                rec = scene.record.arrays()
                plot_wrenches(rec["t"], rec["wrench_world"], rec["end_forces"], out / f"{robot}_forces.png",
                              f"{robot}: hold, 5 mm lift, bring together, lift, swing", PHASES)
            scene.close()
            summaries.append(summary)
            print(f"{robot:6s} dt={dt:.4g}s stable={summary['stable']} vertical balance "
                  f"{100 * summary['vertical_balance_error']:+.3f} % W, horizontal "
                  f"{100 * summary['horizontal_balance_error']:.3f} % W, sensor-model "
                  f"{100 * summary['sensor_vs_model_static']:.3f} % W; RMS tracking "
                  f"{summary['rms_tracking_error_N']:.4f} N of peak {summary['peak_force_N']:.3f} N; "
                  f"grasp gap {1000 * summary['max_grasp_gap_m']:.4f} mm; "
                  f"{summary['wall_time_per_sim_s']:.3f} s per simulated s")
    (out / "summary.json").write_text(json.dumps(summaries, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
