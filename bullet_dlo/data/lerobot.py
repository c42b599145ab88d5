"""Export a capture or rollout directory as a LeRobot v3.0 dataset (parquet + MP4, ``meta/info.json``).

``export_lerobot(dataset_dir, out_dir)`` (command line: ``bullet-dlo export lerobot DATASET OUT``)
writes the layout of LeRobot's ``codebase_version`` "v3.0" (``lerobot/datasets/utils.py`` and
``lerobot_dataset.py`` of lerobot 0.4; one chunk, one file each)::

    meta/info.json                                  fps, robot_type, features (dtype, shape, names, units), paths
    meta/stats.json                                 min, max, mean, std, count, q01 q10 q50 q90 q99 per feature
    meta/tasks.parquet                              task strings (the pandas index) -> task_index
    meta/episodes/chunk-000/file-000.parquet        one row per episode: length, indices into the data and
                                                    video files, per-episode stats, the randomised parameters
    data/chunk-000/file-000.parquet                 one row per frame
    videos/observation.images.overview/chunk-000/file-000.mp4   every episode's frames one after another
                                                    (only when the capture rendered frames)

**Frames.** A LeRobot dataset has one rate ``fps`` for every column and camera. A capture is
exported on the grid t0 + k / fps of each episode (t0 its first recorded row; ``fps`` the
camera rate when it rendered frames, else its record rate; or ``fps=``), every frame taking the
recorded row nearest in time (values as recorded, no interpolation; ``sim.time`` is that row's
time) and the rendered picture nearest in time. A rollout is exported at its control rate: frame
i is the state when action i was chosen (the observation at reset, then after each step) with
that action, its reward and ``next.done`` on the last frame; the state after the last action is
not a frame (LeRobot's convention). Episodes of status ``ok`` are exported (``include_flagged``:
flagged ones too); LeRobot's ``episode_index`` counts them from 0, ``source_episode`` is the
episode number in the capture. An episode whose file holds NaN or inf in any column is left out
like a flagged one, its reason in ``skipped``; a dataset with planned episodes that have no record
(an interrupted capture, see :mod:`bullet_dlo.data.integrity`) is refused: resume it first.

**Features** (float32 unless said; arms left, right as in the capture; j arm joints, n cable nodes):

* ``observation.state`` (2 j + 14,): per arm the joint angles (j) [rad], the grasp-frame position
  (3) [m] and quaternion x y z w (4).
* ``observation.wrench.left`` / ``observation.wrench.right`` (6,): wrist F/T in the sensor frame
  (the capture's ``wrench_sensor``), names fx fy fz [N], mx my mz [N m].
* ``observation.environment_state`` (3 n,): cable node positions [m], world frame, node-major
  (x0 y0 z0 x1 ...); with ``cable_points=K`` (3 K,): K points evenly spaced by node index, linearly
  interpolated (needed when episodes differ in n).
* ``observation.images.overview`` (h, w, 3): video, captures that rendered frames.
* ``action`` (a,): rollouts, the policy's action as given; ``next.reward`` (1,) the reward of that
  step; ``next.done`` (1,) bool, true on an episode's last frame if it terminated or was truncated.
* ``sim.time`` (1,) float64: simulation time [s] of the recorded row the frame took.
* ``timestamp`` [s] (= frame_index / fps), ``frame_index``, ``episode_index``, ``index``,
  ``task_index``: LeRobot's default features.

Every feature in ``info.json`` has ``dtype``, ``shape`` and ``names``; the physical ones also ``units``.

**Per episode** (``meta/episodes``): beside LeRobot's columns, ``params/<name>`` for every scalar
randomised parameter (``params/youngs_modulus`` [Pa], ``params/damping``, ``params/dynamic_friction``,
``params/n_masses``, ``params/integrator``, ``params/dt`` [s], ...), ``decision/<name>`` (the stability
policy's choice, ``decision/substeps``), ``bullet_dlo/params`` and ``bullet_dlo/decision`` (the whole
dicts as JSON), ``bullet_dlo/status``, ``source_episode`` and, for rollouts, ``bullet_dlo/return``,
``bullet_dlo/terminated`` and ``bullet_dlo/truncated``. So a policy, or ``fit``, can condition on them.

Written with pyarrow (``pip install 'bullet-dlo[lerobot]'``) and the project's video writer (H.264).
The output directory is written under a temporary name and renamed when complete.
"""
from __future__ import annotations

import json
import math
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bullet_dlo.core.validate import ParameterError

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # LeRobot's DEFAULT_CHUNK_SIZE, DEFAULT_DATA_FILE_SIZE_IN_MB, DEFAULT_VIDEO_FILE_SIZE_IN_MB
DATA_FILE_MB = 100
VIDEO_FILE_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
CAMERA = "observation.images.overview"
MAX_CABLE_POINTS = 10_000
"""Largest ``--cable-points`` (the capture's cables have at most 200 nodes; 10^4 points are ~0.1 MB a frame)."""
QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
WRENCH_NAMES = ["fx", "fy", "fz", "mx", "my", "mz"]
WRENCH_UNITS = ["N", "N", "N", "N m", "N m", "N m"]
ARMS = ("left", "right")
CAPTURE_TASK = "hold a cable in both grippers while the grippers move (bullet_dlo force capture)"
ENV_TASKS = {
    "bullet_dlo/TensionTracking-v0": "follow a tension profile with a held cable while carrying its midpoint",
    "bullet_dlo/Shaping-v0": "bring a cable held in both grippers to a target shape",
    "bullet_dlo/Routing-v0": "route a cable around pegs and into a clip with the right gripper",
}
ACTION_NAMES = {
    6: (["left.vx", "left.vy", "left.vz", "right.vx", "right.vy", "right.vz"], "fraction of max_speed"),
    4: (["right.vx", "right.vy", "right.vz", "right.yaw_rate"], "fraction of max_speed / max_yaw_rate"),
}


@dataclass
class ExportResult:
    """What :func:`export_lerobot` wrote: the directory, counts, the rate and whether there is a video."""

    out: Path
    episodes: int
    frames: int
    fps: int
    video: bool
    skipped: list[tuple[int, str]] = field(default_factory=list)  # (source episode, status or reason) not exported


def _require_pyarrow():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise ParameterError("export lerobot needs pyarrow: pip install 'bullet-dlo[lerobot]'") from None
    return pa, pq


def check_output_dir(out: Path) -> None:
    """ParameterError unless ``out`` is missing or an empty directory (never written through a link)."""
    if out.is_symlink():
        raise ParameterError(f"OUT {out} is a link; give a new directory")
    if out.exists():
        if not out.is_dir():
            raise ParameterError(f"OUT {out} exists and is not a directory")
        if any(out.iterdir()):
            raise ParameterError(f"OUT {out} exists and is not empty; give a new or empty directory")


# ----- frames ------------------------------------------------------------------------------------
def _nearest(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Indices of the entries of the increasing ``t`` nearest to each of ``times``."""
    i = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    return np.where(np.abs(t[i - 1] - times) <= np.abs(t[i] - times), i - 1, i)


def _capture_frames(ep: dict, fps: int) -> tuple[np.ndarray, np.ndarray | None]:
    """Rows (and rendered pictures) of a capture episode on the grid t0 + k / fps."""
    t = np.asarray(ep["t"], dtype=float)
    if len(t) == 0:
        raise ParameterError(f"episode {ep.get('episode')} has no recorded rows")
    if len(t) > 1 and float(np.median(np.diff(t))) > (1.0 + 1e-6) / fps:
        raise ParameterError(f"--fps {fps} is above the recorded rate {1.0 / float(np.median(np.diff(t))):.6g} Hz "
                             f"of episode {ep.get('episode')}; frames would repeat rows")
    count = int(math.floor((t[-1] - t[0]) * fps + 1e-6)) + 1
    times = t[0] + np.arange(count) / fps
    rows = _nearest(t, times) if len(t) > 1 else np.zeros(count, dtype=int)
    pictures = None
    if "frames" in ep and len(ep["frames"]):
        ft = np.asarray(ep["frame_t"], dtype=float)
        pictures = _nearest(ft, times) if len(ft) > 1 else np.zeros(count, dtype=int)
    return rows, pictures


def _rollout_frames(ep: dict) -> tuple[np.ndarray, int]:
    """Rows of a rollout episode at the moments each action was chosen, and the control rate [Hz]."""
    t = np.asarray(ep["t"], dtype=float)
    control_t = np.asarray(ep["control_t"], dtype=float)
    if len(control_t) == 0:
        raise ParameterError(f"rollout episode {ep.get('episode')} has no control steps")
    times = np.concatenate([[t[0]], control_t[:-1]])
    period = float(np.median(np.diff(np.concatenate([[t[0]], control_t])))) if len(control_t) else 0.0
    return _nearest(t, times), _integer_rate(1.0 / period, "the control rate")


def _integer_rate(rate: float, what: str) -> int:
    fps = int(round(rate))
    if fps < 1 or abs(rate - fps) > 1e-6 * max(rate, 1.0):
        raise ParameterError(f"{what} {rate:.6g} Hz is not a whole number of frames per second; LeRobot needs one "
                             "(pass --fps)")
    return fps


def _cable(x: np.ndarray, points: int | None) -> np.ndarray:
    """Cable nodes (k, n, 3) as (k, 3 n), or ``points`` points by node index, linearly interpolated."""
    if points is None:
        return x.reshape(len(x), -1)
    n = x.shape[1]
    s = np.linspace(0.0, n - 1.0, points)
    i0 = np.clip(np.floor(s).astype(int), 0, n - 2)
    w = (s - i0)[None, :, None]
    return ((1 - w) * x[:, i0] + w * x[:, i0 + 1]).reshape(len(x), -1)


# ----- stats -------------------------------------------------------------------------------------
def feature_stats(values: np.ndarray, image: bool = False) -> dict[str, np.ndarray]:
    """LeRobot's statistics of one feature over frames (axis 0): min, max, mean, std, count, quantiles;
    images (k, h, w, 3) uint8 per channel in [0, 1], shaped (3, 1, 1) as LeRobot's ``compute_episode_stats``."""
    a = np.asarray(values, dtype=np.float64)
    if image:
        a = a.reshape(-1, 3) / 255.0
    elif a.ndim == 1:
        a = a[:, None]
    out = {"min": a.min(axis=0), "max": a.max(axis=0), "mean": a.mean(axis=0), "std": a.std(axis=0)}
    out.update({k: np.quantile(a, q, axis=0) for k, q in QUANTILES.items()})
    if image:
        out = {k: v.reshape(3, 1, 1) for k, v in out.items()}
    out["count"] = np.array([len(values)])
    return out


def _sample_pictures(frames: np.ndarray) -> np.ndarray:
    """At most ~100 evenly spaced pictures (LeRobot samples a subset of an episode's images for its stats)."""
    step = max(1, len(frames) // 100)
    return frames[::step]


# ----- writing -----------------------------------------------------------------------------------
def _arrow_column(pa, values: np.ndarray, dtype: str):
    """A parquet column: scalars as values, vectors as fixed-size lists (LeRobot's Sequence(length=n))."""
    arrow_type = {"float32": pa.float32(), "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_()}[dtype]
    values = np.asarray(values)
    if values.ndim == 1:
        return pa.array(values, type=arrow_type)
    flat = pa.array(values.reshape(-1), type=arrow_type)
    return pa.FixedSizeListArray.from_arrays(flat, values.shape[1])


def _episode_column(pa, values: list):
    """An episodes-metadata column from per-episode Python values (mixed types become JSON text)."""
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([json.dumps(v, sort_keys=True) for v in values])


def _write_tasks(pa, pq, tasks: list[str], path: Path) -> None:
    """``meta/tasks.parquet`` as pandas writes ``DataFrame({"task_index": ...}, index=tasks)``: the task
    strings are the (unnamed) index, restored by ``pandas.read_parquet`` from the pandas metadata."""
    table = pa.table({"task_index": pa.array(range(len(tasks)), pa.int64()), "__index_level_0__": pa.array(tasks)})
    pandas_meta = {
        "index_columns": ["__index_level_0__"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode", "numpy_type": "object",
                            "metadata": {"encoding": "UTF-8"}}],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64", "numpy_type": "int64",
                     "metadata": None},
                    {"name": None, "field_name": "__index_level_0__", "pandas_type": "unicode",
                     "numpy_type": "object", "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.0",
    }
    table = table.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})
    pq.write_table(table, path)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _scalar(value: Any) -> bool:
    return value is None or isinstance(value, (bool, int, float, str, np.generic))


def _attr(ep: dict, key: str, default: Any = None) -> Any:
    value = ep.get(key, default)
    if isinstance(value, bytes):
        value = value.decode()
    return value.item() if isinstance(value, np.generic) else value


def export_lerobot(dataset_dir: str | Path, out_dir: str | Path, *, fps: int | None = None,
                   cable_points: int | None = None, include_flagged: bool = False,
                   progress: bool = False) -> ExportResult:
    """Write the capture or rollout directory ``dataset_dir`` as a LeRobot v3.0 dataset into ``out_dir``
    (see the module doc). ``out_dir`` must be missing or empty. ``fps``: captures only (default: the
    camera rate if frames were rendered, else the record rate); ``cable_points``: resample the cable to
    that many points (needed when episodes differ in node count). ParameterError for bad input."""
    from tqdm import tqdm

    from bullet_dlo.data.integrity import nonfinite_columns
    from bullet_dlo.data.reader import Dataset, parse_episode

    pa, pq = _require_pyarrow()
    dataset_dir, out_dir = Path(dataset_dir), Path(out_dir)
    if not dataset_dir.is_dir():
        raise ParameterError(f"DATASET {dataset_dir} is not a directory")
    check_output_dir(out_dir)
    if cable_points is not None and not (isinstance(cable_points, int) and not isinstance(cable_points, bool)
                                         and 2 <= cable_points <= MAX_CABLE_POINTS):
        raise ParameterError(f"--cable-points must be an integer in [2, {MAX_CABLE_POINTS}], got {cable_points!r}")
    ds = Dataset(dataset_dir)
    missing = ds.missing()
    if missing:
        from bullet_dlo.data.integrity import VerifyReport

        gap = VerifyReport(planned=ds.planned, missing=missing, recorded=len(ds.records)).incomplete()
        raise ParameterError(f"DATASET {dataset_dir} is {gap}; bullet-dlo capture ... --resume runs them "
                             "(dataset verify names every problem)")
    spec = ds.spec["spec"]
    rollout = "rollout" in spec
    statuses = ("ok", "flagged") if include_flagged else ("ok",)
    records = [r for r in ds.records if r["status"] in statuses]
    skipped = [(int(r["episode"]), str(r["status"])) for r in ds.records if r["status"] not in statuses]
    if not records:
        raise ParameterError(f"{dataset_dir} has no episode of status {' or '.join(statuses)} to export")
    if rollout:
        if fps is not None:
            raise ParameterError("--fps applies to captures; a rollout is exported at its control rate")
        task = ENV_TASKS.get(spec["rollout"]["env_id"], spec["rollout"]["env_id"])
    else:
        camera_fps = float(spec.get("camera", {}).get("fps", 0.0))
        rate = float(fps) if fps is not None else (camera_fps if camera_fps > 0 else float(spec["episode"]["record_rate"]))
        fps = _integer_rate(rate, "--fps" if fps is not None else ("the camera rate" if camera_fps > 0 else
                                                                 "the record rate"))
        task = CAPTURE_TASK

    cols: dict[str, list[np.ndarray]] = {}
    pictures: list[np.ndarray] = []
    episodes: list[dict[str, Any]] = []
    robots, joints, nodes = set(), set(), set()
    total = 0
    for record in tqdm(records, desc="export lerobot", unit="ep", disable=not progress):
        e = len(episodes)
        data = ds._checked_bytes(record)
        bad = nonfinite_columns(data)
        if bad:
            skipped.append((int(record["episode"]), "NaN or inf in " + ", ".join(sorted(bad))))
            continue
        ep = parse_episode(data)
        if rollout:
            rows, rate = _rollout_frames(ep)
            if fps is None:
                fps = rate
            elif rate != fps:
                raise ParameterError(f"rollout episodes at {fps} and {rate} Hz: LeRobot needs one rate")
            pics = None
        else:
            rows, pics = _capture_frames(ep, fps)
        k = len(rows)
        q, pos, quat = ep["joint_q"][rows], ep["ee_pos"][rows], ep["ee_quat"][rows]
        joints.add(q.shape[2])
        nodes.add(ep["cable_x"].shape[1])
        state = np.concatenate([np.concatenate([q[:, a], pos[:, a], quat[:, a]], axis=1) for a in range(2)], axis=1)
        frame = {"observation.state": state.astype(np.float32),
                 "observation.wrench.left": ep["wrench_sensor"][rows, 0].astype(np.float32),
                 "observation.wrench.right": ep["wrench_sensor"][rows, 1].astype(np.float32),
                 "observation.environment_state": _cable(ep["cable_x"][rows], cable_points).astype(np.float32)}
        if rollout:
            frame["action"] = np.asarray(ep["action"], dtype=np.float32).reshape(k, -1)
            frame["next.reward"] = np.asarray(ep["reward"], dtype=np.float32)
            done = np.zeros(k, dtype=bool)
            done[-1] = bool(_attr(ep, "terminated", False) or _attr(ep, "truncated", False))
            frame["next.done"] = done
        frame.update({"sim.time": np.asarray(ep["t"], dtype=np.float64)[rows],
                      "timestamp": (np.arange(k) / fps).astype(np.float32),
                      "frame_index": np.arange(k, dtype=np.int64),
                      "episode_index": np.full(k, e, dtype=np.int64),
                      "index": np.arange(total, total + k, dtype=np.int64),
                      "task_index": np.zeros(k, dtype=np.int64)})
        shapes = {key: v.shape[1:] for key, v in frame.items()}
        if cols and any(cols[key][0].shape[1:] != s for key, s in shapes.items()):
            differs = [key for key, s in shapes.items() if cols[key][0].shape[1:] != s]
            hint = " (episodes differ in cable node count: pass --cable-points K)" \
                if "observation.environment_state" in differs else ""
            raise ParameterError(f"episode {record['episode']}: {', '.join(differs)} change shape between "
                                 f"episodes{hint}")
        for key, v in frame.items():
            cols.setdefault(key, []).append(v)
        params = ep.get("params") or {}
        robots.add(str(params.get("robot", "unknown")))
        ep_pictures = ep["frames"][pics] if pics is not None else None
        if ep_pictures is not None:
            pictures.append(ep_pictures)
        info = {"episode_index": e, "tasks": [task], "length": k, "source_episode": int(record["episode"]),
                "bullet_dlo/status": str(record["status"]),
                "bullet_dlo/params": json.dumps(_jsonable(params), sort_keys=True),
                "bullet_dlo/decision": json.dumps(_jsonable(ep.get("decision") or {}), sort_keys=True)}
        info.update({f"params/{k_}": _jsonable(v) for k_, v in sorted(params.items()) if _scalar(v)})
        info.update({f"decision/{k_}": _jsonable(v) for k_, v in sorted((ep.get("decision") or {}).items())
                     if _scalar(v)})
        if rollout:
            info.update({"bullet_dlo/return": float(_attr(ep, "return", 0.0)),
                         "bullet_dlo/terminated": bool(_attr(ep, "terminated", False)),
                         "bullet_dlo/truncated": bool(_attr(ep, "truncated", False))})
        info["_stats_frames"] = frame
        info["_stats_pictures"] = ep_pictures
        episodes.append(info)
        total += k
    if not episodes:
        raise ParameterError(f"{dataset_dir} has no episode to export: " + "; ".join(
            f"episode {i}: {why}" for i, why in skipped if why not in ("ok", "flagged", "failed"))[:300])
    if len(joints) != 1:
        raise ParameterError(f"episodes with arms of {sorted(joints)} joints cannot share observation.state")
    if pictures and len(pictures) != len(episodes):
        raise ParameterError("some episodes have rendered frames and others not; export them separately")
    j = joints.pop()
    features = _features(j, cols, rollout, pictures[0].shape[1:] if pictures else None, cable_points, nodes)

    tmp = out_dir.parent / f".{out_dir.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        _write(pa, pq, tmp, features, cols, pictures, episodes, task, fps, robots, spec, dataset_dir, rollout,
               cable_points)
        if out_dir.exists():
            out_dir.rmdir()  # empty (checked above)
        os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return ExportResult(out_dir, len(episodes), total, int(fps), bool(pictures), skipped)


def _features(j: int, cols: dict, rollout: bool, picture_shape: tuple | None, cable_points: int | None,
              nodes: set[int]) -> dict[str, dict]:
    """info.json's features: dtype, shape, names and units of every column (LeRobot's defaults last)."""
    state_names, state_units = [], []
    for arm in ARMS:
        state_names += [f"{arm}.joint_{i}" for i in range(j)] + [f"{arm}.gripper.{c}" for c in "xyz"] + \
                       [f"{arm}.gripper.q{c}" for c in "xyzw"]
        state_units += ["rad"] * j + ["m"] * 3 + ["1"] * 4
    points = cable_points if cable_points is not None else next(iter(nodes))
    what = "point" if cable_points is not None else "node"
    f: dict[str, dict] = {
        "observation.state": {"dtype": "float32", "shape": [len(state_names)], "names": state_names,
                              "units": state_units},
        "observation.wrench.left": {"dtype": "float32", "shape": [6], "names": WRENCH_NAMES, "units": WRENCH_UNITS,
                                    "frame": "sensor"},
        "observation.wrench.right": {"dtype": "float32", "shape": [6], "names": WRENCH_NAMES, "units": WRENCH_UNITS,
                                     "frame": "sensor"},
        "observation.environment_state": {"dtype": "float32", "shape": [3 * points],
                                          "names": [f"cable.{what}_{i}.{c}" for i in range(points) for c in "xyz"],
                                          "units": "m", "frame": "world"},
    }
    if picture_shape is not None:
        h, w = picture_shape[0] // 2 * 2, picture_shape[1] // 2 * 2  # the H.264 writer keeps even sizes
        f[CAMERA] = {"dtype": "video", "shape": [h, w, 3], "names": ["height", "width", "channels"], "info": None}
    if rollout:
        a = cols["action"][0].shape[1]
        names, units = ACTION_NAMES.get(a, ([f"action_{i}" for i in range(a)], "1"))
        f["action"] = {"dtype": "float32", "shape": [a], "names": names, "units": units}
        f["next.reward"] = {"dtype": "float32", "shape": [1], "names": None, "units": "1"}
        f["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    f["sim.time"] = {"dtype": "float64", "shape": [1], "names": None, "units": "s"}
    f.update({"timestamp": {"dtype": "float32", "shape": [1], "names": None, "units": "s"},
              "frame_index": {"dtype": "int64", "shape": [1], "names": None},
              "episode_index": {"dtype": "int64", "shape": [1], "names": None},
              "index": {"dtype": "int64", "shape": [1], "names": None},
              "task_index": {"dtype": "int64", "shape": [1], "names": None}})
    return f


def _write(pa, pq, root: Path, features: dict, cols: dict, pictures: list, episodes: list[dict], task: str,
           fps: int, robots: set, spec: dict, source: Path, rollout: bool, cable_points: int | None) -> None:
    from bullet_dlo.data.storage import version
    from bullet_dlo.render.video import VideoWriter, probe_video

    (root / "meta").mkdir(parents=True)
    data = {key: np.concatenate(parts) for key, parts in cols.items()}
    columns = [key for key, ft in features.items() if ft["dtype"] != "video"]
    table = pa.table({key: _arrow_column(pa, data[key], features[key]["dtype"]) for key in columns})
    path = root / DATA_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True)
    pq.write_table(table, path, compression="snappy")

    video_info = None
    if pictures:
        path = root / VIDEO_PATH.format(video_key=CAMERA, chunk_index=0, file_index=0)
        with VideoWriter(path, fps, fmt="mp4") as writer:
            for block in pictures:
                for img in block:
                    writer.write(img)
        probe = probe_video(writer.path)
        video_info = {"video.height": probe["height"], "video.width": probe["width"], "video.codec": probe["codec"],
                      "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": int(fps),
                      "video.channels": 3, "has_audio": False}
        features[CAMERA]["info"] = video_info

    stats_keys = [k for k in features if features[k]["dtype"] not in ("video", "string")]
    metas: list[dict] = []
    start, offset = 0, 0
    for ep in episodes:
        frames, pics = ep.pop("_stats_frames"), ep.pop("_stats_pictures")
        k = ep["length"]
        meta = dict(ep)
        meta.update({"data/chunk_index": 0, "data/file_index": 0, "dataset_from_index": start,
                     "dataset_to_index": start + k})
        if pics is not None:
            meta.update({f"videos/{CAMERA}/chunk_index": 0, f"videos/{CAMERA}/file_index": 0,
                         f"videos/{CAMERA}/from_timestamp": offset / fps,
                         f"videos/{CAMERA}/to_timestamp": (offset + len(pics)) / fps})
            offset += len(pics)
        meta.update({"meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0})
        stats = {key: feature_stats(frames[key]) for key in stats_keys}
        if pics is not None:
            stats[CAMERA] = feature_stats(_sample_pictures(pics), image=True)
        for key, st in stats.items():
            for name, value in st.items():
                meta[f"stats/{key}/{name}"] = value.tolist()
        metas.append(meta)
        start += k
    keys = list(dict.fromkeys(key for meta in metas for key in meta))
    table = pa.table({key: _episode_column(pa, [meta.get(key) for meta in metas]) for key in keys})
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True)
    pq.write_table(table, path, compression="snappy")

    _write_tasks(pa, pq, [task], root / "meta" / "tasks.parquet")

    stats = {key: feature_stats(data[key]) for key in stats_keys}
    if pictures:
        stats[CAMERA] = feature_stats(_sample_pictures(np.concatenate(pictures)), image=True)
    (root / "meta" / "stats.json").write_text(json.dumps(
        {key: {name: v.tolist() for name, v in st.items()} for key, st in stats.items()}, indent=4))

    info = {"codebase_version": CODEBASE_VERSION,
            "robot_type": "dual_" + "+".join(sorted(robots)),
            "total_episodes": len(episodes), "total_frames": int(len(data["index"])), "total_tasks": 1,
            "chunks_size": CHUNKS_SIZE, "data_files_size_in_mb": DATA_FILE_MB, "video_files_size_in_mb": VIDEO_FILE_MB,
            "fps": int(fps), "splits": {"train": f"0:{len(episodes)}"},
            "data_path": DATA_PATH, "video_path": VIDEO_PATH if pictures else None,
            "features": features,
            "bullet_dlo": {"source": str(source), "kind": "rollouts" if rollout else "capture", "version": version(),
                           "spec": spec, "cable": (f"{cable_points} points by node index" if cable_points
                                                   else "the model's nodes"),
                           "arms": "left = the cable's first end, right = its last end",
                           "frames": "each frame takes the recorded row nearest in time (sim.time); see "
                                     "bullet_dlo.data.lerobot"}}
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4, ensure_ascii=False))
