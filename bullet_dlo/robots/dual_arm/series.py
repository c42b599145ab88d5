"""One row per step (or per ``every`` steps) of a dual-arm run: the columns a series file and a viewer read.

The columns have the names and units of dataset episodes; their table is in
:mod:`bullet_dlo.data.recording`, which writes them in every format. Here, in the robots layer, so that
the renderer (below the data layer) records the run it films with the same recorder.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

SERIES_COLUMNS = ("t", "cable_x", "wrench_world", "wrench_sensor", "end_forces", "end_moments", "joint_q", "joint_qd",
                  "ee_pos", "ee_quat")
SERIES_UNITS = {"t": "s", "cable_x": "m", "wrench_world": "N, N m", "wrench_sensor": "N, N m", "end_forces": "N",
                "end_moments": "N m", "joint_q": "rad", "joint_qd": "rad/s", "ee_pos": "m", "ee_quat": "1"}
"""Units written with each column (HDF5 ``units`` attributes, NPZ ``attrs["units"]``)."""


class SeriesRecorder:
    """An ``after_step`` hook of a :class:`~bullet_dlo.robots.dual_arm.DualArmScene`'s world: one row per
    ``every`` steps of the columns in the module table."""

    def __init__(self, scene, every: int = 1):
        self.scene = scene
        self.every = max(1, int(every))
        self.rows: dict[str, list] = {k: [] for k in SERIES_COLUMNS}

    def __call__(self) -> None:
        sc, rows = self.scene, self.rows
        if sc.world.steps % self.every:
            return
        import pybullet as pb

        rows["t"].append(sc.world.time)
        rows["cable_x"].append(sc.cable.x.copy())
        rows["wrench_world"].append([s.last.world() for s in sc.sensors])
        rows["wrench_sensor"].append([s.last.sensor() for s in sc.sensors])
        rows["end_forces"].append(sc.cable.end_forces())
        rows["end_moments"].append(sc.cable.end_moments())
        states = [pb.getJointStates(r.body, r.arm_joints, physicsClientId=r.client) for r in sc.robots]
        rows["joint_q"].append([[s[0] for s in st] for st in states])
        rows["joint_qd"].append([[s[1] for s in st] for st in states])
        poses = [r.grasp_pose() for r in sc.robots]
        rows["ee_pos"].append([p for p, _ in poses])
        rows["ee_quat"].append([q for _, q in poses])

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns as float arrays (shapes in the module table)."""
        return {k: np.asarray(v, dtype=float) for k, v in self.rows.items()}


def save_npz(path: str | Path, arrays: dict[str, np.ndarray], attrs: dict | None = None) -> Path:
    """The columns ``arrays`` and JSON-able ``attrs`` (with the columns' units added) as one compressed .npz."""
    path = Path(path)
    units = {k: SERIES_UNITS[k] for k in arrays if k in SERIES_UNITS}
    attrs = {"units": units, **(attrs or {})}
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays, attrs=np.array(json.dumps(attrs, sort_keys=True, default=float)))
    return path
