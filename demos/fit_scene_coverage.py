"""Do fit's intervals hold the truth on recordings made through the full Panda dual-arm scene?

Per seed: hidden E, damping_rate and internal_damping drawn log-uniformly, a 0.3 m cable (d 5 mm, 35 g, n 12)
held by two Panda arms (BDF2 at 0.5 ms), the first end swaying 8 mm at 1.8 Hz while turning 0.08 rad about z,
the last lifting 6 mm at 2.4 Hz, 1.3 s of motion and ringing to 2 s, recorded at 500 Hz with 5 mN white noise;
then `fit_cable` from E 1e8, c 1, tau 3e-3 with its defaults. SOURCE: ``end`` fits the model's end forces,
``wrist`` the wrist sensors' (world frame; they read the load of one Bullet step before, so the recording's
``force_delay`` is dt, as `read_recording` sets it for a simulated file). One JSON line per seed: each
parameter's fitted value and interval over the truth.

usage: python demos/fit_scene_coverage.py SOURCE [SEED ...]     (about 10 s CPU per seed)
"""
from __future__ import annotations

import json
import sys

import numpy as np

from bullet_dlo.analysis.fit import FitOptions, Recording, fit_cable
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.core.boundary import Sine
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmScene
from bullet_dlo.robots.dual_arm.series import SeriesRecorder

DT = 5e-4  # [s] the scene's Bullet step
BASE = CableSpec.lv2017(n_masses=12, diameter=0.005, mass=0.035)
NAMES = ["youngs_modulus", "damping_rate", "internal_damping"]
MOTION = [Sine("first", (0.0, 0.008, 0.0), 1.8, start=0.1, duration=1.3, ramp=0.2, rotation=(0.0, 0.0, 0.08)),
          Sine("last", (0.0, 0.0, 0.006), 2.4, start=0.1, duration=1.3, ramp=0.2)]


def hidden_truth(seed: int) -> dict[str, float]:
    rng = np.random.default_rng(2000 + seed)
    return dict(youngs_modulus=float(np.exp(rng.uniform(np.log(6e7), np.log(4e8)))),
                damping_rate=float(np.exp(rng.uniform(np.log(0.3), np.log(4.0)))),
                internal_damping=float(np.exp(rng.uniform(np.log(1e-3), np.log(1.5e-2)))))


def covered(source: str, seed: int) -> dict:
    truth = hidden_truth(seed)
    with DualArmScene(DualArmSpec(robot="panda", dt=DT, integrator="bdf2", cable=BASE.with_(**truth))) as scene:
        scene.grasp()
        scene.follow_motion(MOTION)
        recorder = SeriesRecorder(scene, every=4)  # 500 Hz
        scene.world.after_step.append(recorder)
        scene.run(2.0)
        a = recorder.arrays()
    force = a["wrench_world"][:, :, :3] if source == "wrist" else a["end_forces"]
    force = force + np.random.default_rng(seed).normal(0.0, 0.005, force.shape)
    rec = Recording(a["t"], a["ee_pos"], a["ee_quat"], force, force_delay=DT if source == "wrist" else 0.0)
    res = fit_cable(rec, BASE.with_(youngs_modulus=1e8, damping_rate=1.0, internal_damping=3e-3), NAMES,
                    FitOptions(max_evaluations=40, profile_points=0))
    row = {"source": source, "seed": seed}
    for name in NAMES:
        iv = res.intervals[name]
        row[name] = {"value": round(res.values[name] / truth[name], 5),
                     "interval": None if iv is None else [round(x / truth[name], 5) for x in iv],
                     "covered": None if iv is None else bool(iv[0] <= truth[name] <= iv[1])}
    return row


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in ("end", "wrist"):
        sys.exit("usage: python demos/fit_scene_coverage.py end|wrist [SEED ...]")
    for s in [int(x) for x in sys.argv[2:]] or [0, 1, 2, 3]:
        print(json.dumps(covered(sys.argv[1], s)), flush=True)
