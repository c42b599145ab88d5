"""Recorded runs of every kind as one :class:`bullet_dlo.render.viewer.Run`, for ``bullet-dlo view``.

:func:`load_run` reads, by what the path is:

================================ ============================================================
path                             read as
================================ ============================================================
capture or rollout directory     one episode (``episode=``, default the first ok one), through
                                 :class:`~bullet_dlo.data.reader.Dataset` (checksums checked)
episode file ``.h5``/``.hdf5``   :func:`~bullet_dlo.data.reader.load_episode` (captures,
                                 rollouts, ``grasp --series OUT.h5``)
``.npz`` with ``cable_x``        ``grasp --series`` / ``render --series`` (arms, wrenches)
``.npz`` with ``x``              ``simulate --npz`` (cable only: t, x, v, end_forces)
``render`` output directory      its ``render.json``: the cable's final shape (one row; a
                                 render run with ``--series`` is viewed through that file)
================================ ============================================================

Episodes know their robot, cable and table (their ``params``); a series file its robot and cable
(its ``attrs``). ``scene=`` (a :class:`~bullet_dlo.config.scene.Scene`, the CLI's ``--scene``)
adds what the files do not hold: the scene's obstacles and ground, its cable (for ``simulate``
results) and its arms' table. Anything unreadable is a ParameterError naming the file.
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.render.viewer import Run

ARMS_TABLE_HEIGHT = 0.2  # [m] ArmsOptions' default table, what captures and environments use


def table_box(length: float, table_height: float) -> tuple[tuple, tuple] | None:
    """The dual-arm scene's table (half extents, centre) [m] for a cable of ``length`` (None: no table);
    as :meth:`bullet_dlo.robots.dual_arm.physics.DualArmPhysics._add_table` builds it."""
    if table_height <= 0:
        return None
    return (max(0.5 * length - 0.05, 0.05), 0.3, table_height / 2), (0.0, 0.0, table_height / 2)


def load_run(path: str | Path, episode: int | None = None, scene=None) -> Run:
    """The run stored at ``path`` (see the module doc); ``scene`` adds obstacles, ground and table."""
    path = Path(path)
    if not path.exists():
        raise ParameterError(f"{path}: no such file or directory")
    if path.is_dir():
        if (path / "capture.json").is_file():
            arrays, source = _dataset_episode(path, episode)
        elif (path / "render.json").is_file() and (path / "run.npz").is_file():  # the whole run, at the video's rate
            arrays, source = _npz(path / "run.npz"), f"{path} (render)"
        elif (path / "render.json").is_file():  # an older render: its last shape only
            arrays, source = _render_dir(path), f"{path} (render: final shape)"
        else:
            raise ParameterError(f"{path} is neither a capture/rollout directory (capture.json) nor a render output "
                                 "(render.json)")
    elif path.suffix.lower() in (".h5", ".hdf5"):
        from bullet_dlo.data.reader import load_episode

        try:
            arrays, source = load_episode(path), str(path)
        except OSError as err:
            raise ParameterError(f"{path}: not a readable HDF5 file ({err})") from None
    elif path.suffix.lower() == ".npz":
        arrays, source = _npz(path), str(path)
    else:
        raise ParameterError(f"{path}: expected a capture/rollout/render directory, an episode .h5 or an .npz")
    if episode is not None and not path.is_dir():
        raise ParameterError("--episode applies to a capture or rollout directory only")
    return run_from_arrays(arrays, source, scene)


def _dataset_episode(root: Path, episode: int | None) -> tuple[dict, str]:
    from bullet_dlo.data.reader import Dataset

    ds = Dataset(root)
    records = [r for r in ds.records if r.get("status") != "failed"]
    if episode is None:
        ok = [r for r in records if r.get("status") == "ok"] or records
        if not ok:
            raise ParameterError(f"{root} has no recorded episode")
        record = ok[0]
    else:
        record = next((r for r in records if r.get("episode") == episode), None)
        if record is None:
            have = ", ".join(str(r.get("episode")) for r in records[:20]) or "none"
            raise ParameterError(f"--episode {episode}: not recorded in {root} (episodes: {have})")
    return ds.load(record), f"{root} episode {record.get('episode')}"


def _render_dir(root: Path) -> dict:
    try:
        summary = json.loads((root / "render.json").read_text())
        x = np.asarray(summary["final_positions"], dtype=float)
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ParameterError(f"{root / 'render.json'}: not a render summary ({err})") from None
    return {"t": np.zeros(1), "cable_x": x[None]}


def _npz(path: Path) -> dict:
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise ParameterError(f"{path}: not a readable .npz ({err})") from None
    if "attrs" in data:
        try:
            data.update({k: v for k, v in json.loads(str(data.pop("attrs"))).items() if k not in data})
        except ValueError:
            raise ParameterError(f"{path}: its attrs entry is not JSON") from None
    if "cable_x" not in data and "x" in data:  # simulate --npz
        data["cable_x"], data["cable_v"] = data.pop("x"), data.pop("v", None)
        if data.get("end_forces") is not None and np.asarray(data["end_forces"]).ndim != 3:
            data.pop("end_forces")
    if "cable_x" not in data or "t" not in data:
        raise ParameterError(f"{path}: no cable positions (expected t and cable_x, or t and x as simulate --npz "
                             "writes)")
    return data


def run_from_arrays(data: dict[str, Any], source: str, scene=None) -> Run:
    """A :class:`Run` from an episode's or series file's columns and attributes (``params`` of an
    episode, ``robot``/``cable`` of a series file), completed by ``scene``."""
    from bullet_dlo.core.spec import CableSpec

    params = data.get("params") if isinstance(data.get("params"), dict) else {}
    cable = None
    if params:
        from bullet_dlo.data.plan import cable_spec

        try:
            cable = cable_spec(params)
        except (KeyError, ParameterError):
            cable = None
    elif isinstance(data.get("cable"), dict):
        try:
            cable = CableSpec.from_dict(data["cable"])
        except (ParameterError, TypeError, KeyError):
            cable = None
    if scene is not None and cable is None:
        cable = scene.cable
    robot = params.get("robot") or data.get("robot")
    if robot is not None and data.get("joint_q") is None:
        robot = None
    if robot is None and scene is not None and scene.arms is not None and data.get("joint_q") is not None:
        robot = scene.arms.robot or "kuka"
    if robot is None and data.get("joint_q") is not None:
        robot = "kuka"  # grasp's default
    ground, table, obstacles = 0.0, None, ()
    if scene is not None:
        opts = scene.bullet
        ground = opts.ground_height if opts.ground else None
        obstacles = tuple(opts.obstacles)
    elif data.get("obstacles"):  # a rollout records its episode's obstacles (Routing's pegs and clip)
        try:
            recorded = json.loads(str(data["obstacles"]))
        except ValueError:
            raise ParameterError(f"{source}: its obstacles attribute is not JSON") from None
        obstacles = tuple(ob for ob in recorded if isinstance(ob, dict))
    if robot is not None:
        th = scene.arms.table_height if scene is not None and scene.arms is not None else ARMS_TABLE_HEIGHT
        length = cable.length if cable is not None else float(np.linalg.norm(
            np.diff(np.asarray(data["cable_x"], float)[0], axis=0), axis=1).sum())
        table = table_box(length, th)
    radius = 0.5 * cable.diameter if cable is not None else 0.002
    cx = np.asarray(data["cable_x"], dtype=float)
    if cable is not None and cable.n_masses != cx.shape[1]:
        cable = None
    return Run(t=data["t"], cable_x=cx, radius=radius, robot=robot,
               joint_q=data.get("joint_q") if robot else None, ee_pos=data.get("ee_pos") if robot else None,
               ee_quat=data.get("ee_quat") if robot else None, wrench_world=data.get("wrench_world"),
               end_forces=data.get("end_forces"), cable_v=data.get("cable_v"), cable=cable, ground_height=ground,
               table=table, obstacles=obstacles, source=source)
