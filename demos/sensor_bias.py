"""Wrist-sensor bias in a static hold: sensor minus model end force, both robots, 240 Hz and 1 kHz, and its cause.

Three tables:

1. per robot and rate, the difference between the tared wrist force (world frame) and the
   cable model's end force, averaged over the last 0.5 s of a hold, as a share of the model
   force (x along the cable, z vertical) and in mN sideways (y), with the tilt of the hand
   under the load and the error that tilt alone would explain;
2. the cause (with the tare of wave 1, after 22 settle steps; now ``SETTLE_STEPS`` = 150):
   the arms are still settling when the sensors tare (the position motors remove
   10 % of the arm's sag per step, Bullet's default position gain 0.1), so a tare of Bullet's
   joint reaction held the payload's inertial force m a of that step, and every later reading
   carried it (Panda 1 kHz: 0.78, -0.47, 1.52 mN, equal to m a). Since issue 27 the transmitted
   wrench is computed from the same momenta the compensation removes, so even that early tare
   leaves nothing. Shown without any load: the reading of an unloaded arm after the hold (now
   below 1 uN) beside m a at the tare step (from the payload momentum one step before and at
   the tare: (p_T - p_{T-1}) / dt), the bias the joint-reaction tare held;
3. suspects, one varied at a time from the 22-step tare of wave 1 (a module constant, an engine parameter or the arms'
   control patched for that run only): the bias at each robot and rate, and the vertical
   balance (both sensors' vertical forces plus the cable weight W, in % of W).

Writes ``sensor_bias.json`` (table 1), ``sensor_bias_cause.json`` and
``sensor_bias_suspects.json`` into ``--out``.

Usage: ``python demos/sensor_bias.py [--out DIR] [--quick]`` (``--quick``: 0.5 s holds and
only the baseline and settled-tare suspects).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
from pathlib import Path
from typing import Callable, ContextManager
from unittest import mock

import numpy as np
import pybullet as pb

import bullet_dlo.robots.dual_arm.physics as physics_module
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.arm import Robot
from bullet_dlo.robots.dual_arm import DualArmScene, DualArmSpec
from bullet_dlo.robots.dual_arm.physics import DualArmPhysics
from bullet_dlo.robots.sensors import WristSensor

CASES = (("panda", 1 / 240), ("panda", 1e-3), ("kuka", 1 / 240), ("kuka", 1e-3))
SETTLED_STEPS = 150
OLD_SETTLE_STEPS = 22  # the settle steps before the fix, kept to show the cause
"""Settle steps after which the motors' transient (x 0.9 per step) is below 1e-6 of its start."""


def spec(robot: str, dt: float) -> DualArmSpec:
    """The scene of every measurement here: the 10-mass Lv cable held by ``robot`` at step dt [s]."""
    return DualArmSpec(robot=robot, cable=CableSpec.lv2017(n_masses=10, damping=0.02), dt=dt)


def frame(sensor) -> np.ndarray:
    """The sensor link's rotation matrix (sensor frame -> world), (3, 3)."""
    q = pb.getLinkState(sensor.robot.body, sensor.joint, computeForwardKinematics=True,
                        physicsClientId=sensor.robot.client)[1]
    return np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)


def hold(robot: str, dt: float, seconds: float) -> dict:
    """A static hold of the Lv cable: sensor-model differences and what the hand's tilt explains."""
    with DualArmScene(spec(robot, dt)) as sc:
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
        weight = sc.cable.model.spec.mass * float(np.linalg.norm(sc.world.gravity))
        balance = (w["wrench_world"][0, 2] + w["wrench_world"][1, 2] + weight) / weight
    return {"robot": robot, "rate_hz": round(1 / dt), "x_percent": float(100 * err[0] / abs(model[0])),
            "z_percent": float(100 * err[2] / abs(model[2])), "y_mN": float(1e3 * err[1]),
            "model_y_mN": float(1e3 * model[1]), "tilt_deg": tilt,
            "tilt_explains_mN": float(1e3 * np.linalg.norm(tilt_error)), "error_mN": float(1e3 * np.linalg.norm(err)),
            "balance_percent_W": float(100 * balance)}


# ----- the cause -------------------------------------------------------------------------------
def payload_momentum(robot: str, dt: float, settle_steps: int) -> np.ndarray:
    """World momentum [kg m/s] (3,) of the left sensor's payload after ``settle_steps`` settle steps
    (Bullet is deterministic: a scene built again with one step less gives the step before)."""
    with mock.patch.object(physics_module, "SETTLE_STEPS", settle_steps):
        ph = DualArmPhysics(spec(robot, dt))
    try:
        return WristSensor(ph.robots[0], ph.world.gravity).payload_momentum()
    finally:
        ph.close()


def tare_inertia(robot: str, dt: float, seconds: float) -> dict:
    """The unloaded arm's reading [mN] after ``seconds`` of hold against the payload's m a [mN] at the tare step."""
    steps = OLD_SETTLE_STEPS
    ma = (payload_momentum(robot, dt, steps) - payload_momentum(robot, dt, steps - 1)) / dt
    with mock.patch.object(physics_module, "SETTLE_STEPS", steps), DualArmScene(spec(robot, dt)) as sc:
        sc.run(seconds)  # no grasp: nothing loads the grippers
        reading = sc.window_mean(min(0.5, seconds / 2))["wrench_world"][0, :3]
    return {"robot": robot, "rate_hz": round(1 / dt), "settle_steps": steps,
            "unloaded_reading_mN": (1e3 * reading).tolist(), "m_a_at_tare_mN": (1e3 * ma).tolist()}


# ----- suspects, one varied at a time ----------------------------------------------------------
def engine(**params) -> ContextManager:
    """Bullet engine parameters set on every world built inside the context (before the arms settle)."""
    init = BulletWorld.__init__

    def patched(self, *args, **kwargs):
        init(self, *args, **kwargs)
        pb.setPhysicsEngineParameter(physicsClientId=self.client, **params)
    return mock.patch.object(BulletWorld, "__init__", patched)


def after_load(change: Callable[[Robot], None]) -> ContextManager:
    """``change`` applied to every robot right after :meth:`Robot.load` inside the context."""
    load = Robot.load.__func__

    def patched(cls, *args, **kwargs):
        robot = load(cls, *args, **kwargs)
        change(robot)
        return robot
    return mock.patch.object(Robot, "load", classmethod(patched))


def no_link_damping(robot: Robot) -> None:
    for j in range(-1, pb.getNumJoints(robot.body, physicsClientId=robot.client)):
        pb.changeDynamics(robot.body, j, linearDamping=0.0, angularDamping=0.0, physicsClientId=robot.client)


def stronger_arm(robot: Robot) -> None:
    robot._arm_force = [10.0 * f for f in robot._arm_force]
    robot.set_targets(robot.joint_positions())


def arm_gain(kp: float) -> ContextManager:
    """Arm position gain ``kp`` (Bullet's default 0.1: the share of the position error removed per step)."""
    set_targets = Robot.set_targets

    def patched(self, q):
        set_targets(self, q)
        pb.setJointMotorControlArray(self.body, self.arm_joints, pb.POSITION_CONTROL, targetPositions=list(q),
                                     forces=self._arm_force, positionGains=[kp] * len(self.arm_joints),
                                     physicsClientId=self.client)
    return mock.patch.object(Robot, "set_targets", patched)


@contextlib.contextmanager
def no_inertia_compensation():
    init = DualArmScene.__init__

    def patched(self, *args, **kwargs):
        init(self, *args, **kwargs)
        for s in self.sensors:
            s.compensate_inertia = False
    with mock.patch.object(DualArmScene, "__init__", patched):
        yield


SUSPECTS: dict[str, Callable[[], ContextManager]] = {
    f"baseline: tare after {OLD_SETTLE_STEPS} settle steps (wave 1)": contextlib.nullcontext,
    f"tare after {SETTLED_STEPS} settle steps (now)":
        lambda: mock.patch.object(physics_module, "SETTLE_STEPS", SETTLED_STEPS),
    "numSolverIterations 200": lambda: engine(numSolverIterations=200),
    "solverResidualThreshold 1e-12": lambda: engine(solverResidualThreshold=1e-12),
    "erp, contactERP, frictionERP 0.8": lambda: engine(erp=0.8, contactERP=0.8, frictionERP=0.8),
    "globalCFM 1e-4": lambda: engine(globalCFM=1e-4),
    "arm motor forces x 10": lambda: after_load(stronger_arm),
    "link damping 0": lambda: after_load(no_link_damping),
    "arm position gain 0.5": lambda: arm_gain(0.5),
    "inertia compensation off": no_inertia_compensation,
}
QUICK_SUSPECTS = tuple(list(SUSPECTS)[:2])


def suspects(names, seconds: float) -> list[dict]:
    """Each suspect's holds at every robot and rate."""
    out = []
    for name in names:  # each from the wave-1 tare; the settled-tare suspect patches it back
        with mock.patch.object(physics_module, "SETTLE_STEPS", OLD_SETTLE_STEPS), SUSPECTS[name]():
            out.append({"suspect": name, "holds": [hold(robot, dt, seconds) for robot, dt in CASES]})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join("out", "sensor_bias"), help="output folder")
    parser.add_argument("--quick", action="store_true", help="0.5 s holds, two suspects (a smoke test)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    seconds = 0.5 if args.quick else 2.0
    rows = [hold(robot, dt, seconds) for robot, dt in CASES]
    print("| robot | rate | x: sensor - model | z: sensor - model | y: sensor - model [mN] | y model [mN] | hand tilt | "
          "tilt explains | total error |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['robot']} | {r['rate_hz']} Hz | {r['x_percent']:+.3f} % | {r['z_percent']:+.3f} % | "
              f"{r['y_mN']:+.3f} | {r['model_y_mN']:+.3f} | {r['tilt_deg']:.1e} deg | {r['tilt_explains_mN']:.3f} mN | "
              f"{r['error_mN']:.3f} mN |")
    (out / "sensor_bias.json").write_text(json.dumps(rows, indent=2))

    cause = [tare_inertia(robot, dt, seconds) for robot, dt in CASES]
    print(f"\nCause: unloaded arm (no grasp) tared after {OLD_SETTLE_STEPS} settle steps, reading after the hold (a "
          "joint-reaction tare read m a; the Newton-Euler one reads 0) and the payload's m a at the tare step [mN, world]\n")
    print("| robot | rate | unloaded reading x, y, z | m a at the tare x, y, z |")
    print("|---|---|---|---|")
    for c in cause:
        print(f"| {c['robot']} | {c['rate_hz']} Hz | " + ", ".join(f"{v:+.3f}" for v in c["unloaded_reading_mN"])
              + " | " + ", ".join(f"{v:+.3f}" for v in c["m_a_at_tare_mN"]) + " |")
    (out / "sensor_bias_cause.json").write_text(json.dumps(cause, indent=2))

    table = suspects(QUICK_SUSPECTS if args.quick else SUSPECTS, seconds)
    print("\nSuspects, one at a time: z: sensor - model [% of model] / y: sensor - model [mN] / vertical balance [% W]\n")
    print("| suspect | " + " | ".join(f"{robot} {round(1 / dt)} Hz" for robot, dt in CASES) + " |")
    print("|---|" + "---|" * len(CASES))
    for s in table:
        print(f"| {s['suspect']} | " + " | ".join(f"{h['z_percent']:+.3f} % / {h['y_mN']:+.3f} / "
                                                   f"{h['balance_percent_W']:+.3f} %" for h in s["holds"]) + " |")
    (out / "sensor_bias_suspects.json").write_text(json.dumps(table, indent=2))
    print(f"\noutputs written to {out.resolve()}")


if __name__ == "__main__":
    main()
