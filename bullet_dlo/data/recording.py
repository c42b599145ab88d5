"""Time series of a dual-arm run on disk (NPZ, HDF5, CSV), and reading them back for ``bullet-dlo fit``.

``bullet-dlo grasp --series FILE`` records every Bullet step with :class:`SeriesRecorder` and
writes :func:`write_series`. The columns have the names and units of dataset episodes
(:mod:`bullet_dlo.data.episode`); left arm = the cable's first end, right arm = its last end;
k rows, n masses, j arm joints:

=============== ================================================================ ============
column          meaning                                                          shape
=============== ================================================================ ============
t               time [s]                                                         (k,)
cable_x         mass positions [m]                                               (k, n, 3)
wrench_world    tared wrist load on the tool, world frame [fx fy fz mx my mz]    (k, 2, 6)
                [N, N m] (the force the cable exerts on the gripper, as read)
wrench_sensor   the same in the sensor frame                                     (k, 2, 6)
end_forces      force of the cable model on each holder [N]                      (k, 2, 3)
end_moments     clamp torque of the cable model on each holder [N m]             (k, 2, 3)
joint_q/qd      arm joint angles [rad], velocities [rad/s]                       (k, 2, j)
ee_pos/quat     grasp-frame position [m] and quaternion (x, y, z, w)             (k, 2, 3/4)
=============== ================================================================ ============

Formats, by the file's suffix: ``.npz`` (numpy, the columns above plus ``attrs``, a JSON
string), ``.h5``/``.hdf5`` (one dataset per column, attributes as in episodes; a dataset
episode file is read as is), ``.csv`` (only what a fit needs, one row per sample, header
``t, left_x, left_y, left_z, left_qx, left_qy, left_qz, left_qw, left_fx, left_fy, left_fz``
and the same with ``right_``; SI units as above). A recording from a real robot in any of these
formats needs only ``t``, ``ee_pos``, ``ee_quat`` and ``wrench_world`` (forces; moments optional).

Optional columns a fit also uses (NPZ/HDF5): ``grasp_moment`` (k, 2, 3), the measured moments
about the grasp points [N m] (``wrench_world`` moments are about the sensor origin and are not
used as such); ``linear_map`` (k, q, 12) with ``linear_obs`` (k, q), a measurement linear in the
end wrenches (e.g. joint torques, see :mod:`bullet_dlo.analysis.fit_recording`). With
``forces="end_forces"`` the model's ``end_moments`` come along as the moments. The attributes
``integrator`` and ``dt`` [s] of a simulated file become the recording's ``source``.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from bullet_dlo.analysis.fit import Recording
from bullet_dlo.core.validate import ParameterError

SERIES_COLUMNS = ("t", "cable_x", "wrench_world", "wrench_sensor", "end_forces", "end_moments", "joint_q", "joint_qd",
                  "ee_pos", "ee_quat")
CSV_FIELDS = ("x", "y", "z", "qx", "qy", "qz", "qw", "fx", "fy", "fz")
FORMATS = (".npz", ".h5", ".hdf5", ".csv")
FORCE_SOURCES = ("wrench_world", "end_forces")


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


def series_format(path: str | Path) -> str:
    """The file's suffix if it names a series format (ParameterError otherwise)."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ParameterError(f"series file must end in {', '.join(FORMATS)}, got {str(path)!r}")
    return suffix


def write_series(path: str | Path, arrays: dict[str, np.ndarray], attrs: dict[str, Any] | None = None) -> Path:
    """Write the columns ``arrays`` (and JSON-able ``attrs``) to ``path`` in the format its suffix names."""
    path = Path(path)
    suffix = series_format(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    attrs = attrs or {}
    if suffix == ".npz":
        np.savez_compressed(path, **arrays, attrs=np.array(json.dumps(attrs, sort_keys=True, default=float)))
    elif suffix == ".csv":
        write_csv(path, Recording(arrays["t"], arrays["ee_pos"], arrays["ee_quat"], arrays["wrench_world"][:, :, :3]))
    else:
        import h5py

        with h5py.File(path, "w") as f:
            for key, arr in arrays.items():
                f.create_dataset(key, data=arr)
            for k, v in attrs.items():
                f.attrs[k] = v if isinstance(v, (int, float, str, bool)) else json.dumps(v, default=float)
    return path


def write_csv(path: str | Path, rec: Recording) -> None:
    """The CSV form of a recording (header in the module doc)."""
    header = ["t"] + [f"{arm}_{c}" for arm in ("left", "right") for c in CSV_FIELDS]
    cols = [rec.t[:, None]]
    for arm in (0, 1):
        cols += [rec.grasp_pos[:, arm], rec.grasp_quat[:, arm], rec.force[:, arm]]
    np.savetxt(path, np.hstack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.10g")


def read_columns(path: str | Path) -> dict[str, np.ndarray]:
    """The array columns of a series or episode file (NPZ or HDF5) by name."""
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"recording {str(path)!r} not found")
    suffix = series_format(path)
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files if k != "attrs"}
    import h5py

    with h5py.File(path, "r") as f:
        return {k: f[k][()] for k in f.keys() if isinstance(f[k], h5py.Dataset)}


def read_recording(path: str | Path, forces: str = "wrench_world") -> Recording:
    """A recording for :func:`bullet_dlo.analysis.fit.fit_cable` from a CSV, NPZ or HDF5 file (a dataset
    episode works as is). ``forces``: ``wrench_world`` (the wrist sensors, default) or ``end_forces``
    (the model's ground truth, for simulated files)."""
    if forces not in FORCE_SOURCES:
        raise ParameterError(f"forces must be one of {', '.join(FORCE_SOURCES)}, got {forces!r}")
    path = Path(path)
    if series_format(path) == ".csv":
        if not path.is_file():
            raise ParameterError(f"recording {str(path)!r} not found")
        try:
            data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
        except ValueError as err:
            raise ParameterError(f"recording {path.name}: not a numeric CSV ({err})") from None
        if data.shape[1] != 1 + 2 * len(CSV_FIELDS):
            raise ParameterError(f"recording {path.name} must have {1 + 2 * len(CSV_FIELDS)} columns "
                                 f"(t, then x y z qx qy qz qw fx fy fz per arm), got {data.shape[1]}")
        per_arm = data[:, 1:].reshape(len(data), 2, len(CSV_FIELDS))
        return Recording(data[:, 0], per_arm[:, :, :3], per_arm[:, :, 3:7], per_arm[:, :, 7:], name=path.stem)
    cols = read_columns(path)
    missing = [k for k in ("t", "ee_pos", "ee_quat", forces) if k not in cols]
    if missing:
        raise ParameterError(f"recording {path.name} lacks column(s) {', '.join(missing)}")
    moment_column = "end_moments" if forces == "end_forces" else "grasp_moment"
    moment = cols[moment_column][:, :, :3] if moment_column in cols else None
    linear = (cols["linear_map"], cols["linear_obs"]) if "linear_map" in cols and "linear_obs" in cols else (None, None)
    return Recording(cols["t"], cols["ee_pos"], cols["ee_quat"], cols[forces][:, :, :3], moment, *linear,
                     name=path.stem, source=read_source(path))


def read_source(path: Path) -> dict[str, Any] | None:
    """{"integrator", "dt"} from a simulated series file's attributes (None when it does not say)."""
    attrs: dict[str, Any] = {}
    if path.suffix.lower() == ".npz":
        with np.load(path, allow_pickle=False) as z:
            if "attrs" in z.files:
                try:
                    attrs = json.loads(str(z["attrs"]))
                except ValueError:
                    attrs = {}
    else:
        import h5py

        with h5py.File(path, "r") as f:
            attrs = {k: f.attrs[k] for k in ("integrator", "dt") if k in f.attrs}
    integrator, dt = attrs.get("integrator"), attrs.get("dt")
    if isinstance(integrator, bytes):
        integrator = integrator.decode()
    if not integrator or not dt:
        return None
    return {"integrator": str(integrator), "dt": float(dt)}
