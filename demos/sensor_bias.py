"""Wrist-sensor bias in a static hold: sensor minus model end force, both robots, 240 Hz and 1 kHz.

Prints, per robot and rate, the difference between the tared wrist force (world frame) and the
cable model's end force, averaged over the last 0.5 s of a hold, as a share of the model force
(x along the cable, z vertical) and in mN sideways (y), with the tilt of the hand under the load
and the error that tilt alone would explain. Writes ``sensor_bias.json`` into ``--out``.

Usage: ``python demos/sensor_bias.py [--out DIR] [--quick]`` (``--quick``: 0.5 s holds).
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
import pybullet as pb

from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmScene, DualArmSpec


def frame(sensor) -> np.ndarray:
    """The sensor link's rotation matrix (sensor frame -> world), (3, 3)."""
    q = pb.getLinkState(sensor.robot.body, sensor.joint, computeForwardKinematics=True,
                        physicsClientId=sensor.robot.client)[1]
    return np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)


def hold(robot: str, dt: float, seconds: float) -> dict:
    """A static hold of the Lv cable: sensor-model differences and what the hand's tilt explains."""
    with DualArmScene(DualArmSpec(robot=robot, cable=CableSpec.lv2017(n_masses=10, damping=0.02), dt=dt)) as sc:
        sensor = sc.sensors[0]
        r0, f_tare = frame(sensor), np.array(sensor._tare[:3])
        sc.grasp()
        sc.run(seconds)
        r1 = frame(sensor)
        w = sc.window_mean(min(0.5, seconds / 2))
        err = w["wrench_world"][0, :3] - w["end_forces"][0]
        model = w["end_forces"][0]
        tilt_error = r1 @ (f_tare - r1.T @ r0 @ f_tare)  # the tare's payload weight, seen from the tilted frame
        tilt = float(np.degrees(np.arccos(np.clip((np.trace(r0.T @ r1) - 1) / 2, -1, 1))))
    return {"robot": robot, "rate_hz": round(1 / dt), "x_percent": float(100 * err[0] / abs(model[0])),
            "z_percent": float(100 * err[2] / abs(model[2])), "y_mN": float(1e3 * err[1]),
            "model_y_mN": float(1e3 * model[1]), "tilt_deg": tilt,
            "tilt_explains_mN": float(1e3 * np.linalg.norm(tilt_error)), "error_mN": float(1e3 * np.linalg.norm(err))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "sensor_bias"), help="output folder")
    parser.add_argument("--quick", action="store_true", help="0.5 s holds (a smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = [hold(robot, dt, 0.5 if args.quick else 2.0) for robot in ("panda", "kuka") for dt in (1 / 240, 1e-3)]
    print("| robot | rate | x: sensor - model | z: sensor - model | y sensor [mN] | y model [mN] | hand tilt | "
          "tilt explains | total error |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['robot']} | {r['rate_hz']} Hz | {r['x_percent']:+.3f} % | {r['z_percent']:+.3f} % | "
              f"{r['y_mN']:+.3f} | {r['model_y_mN']:+.3f} | {r['tilt_deg']:.1e} deg | {r['tilt_explains_mN']:.3f} mN | "
              f"{r['error_mN']:.3f} mN |")
    (out / "sensor_bias.json").write_text(json.dumps(rows, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
