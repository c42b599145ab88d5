"""``export lerobot``: a capture (with video) and a rollout directory written as LeRobot v3.0 datasets
and read back frame by frame against their HDF5 episodes.

The read-back follows LeRobot's own v3.0 reader (lerobot 0.4, ``lerobot/datasets/lerobot_dataset.py``
and ``utils.py``): ``meta/info.json`` (codebase_version, fps, features, ``data_path``/``video_path``
templates), the episodes from ``meta/episodes/*/*.parquet`` (``dataset_from_index``/``dataset_to_index``
into the concatenated ``data/*/*.parquet`` frames, ``videos/<key>/chunk_index``, ``file_index`` and
``from_timestamp``), video frames decoded at ``from_timestamp + timestamp`` within LeRobot's default
tolerance (1e-4 s), tasks by ``task_index`` from ``meta/tasks.parquet``. The ``lerobot`` package itself
cannot be installed beside this project (it needs torch<2.11, torchcodec, datasets, diffusers and wandb
and pins ``av<16``; this project runs PyAV 18): in a venv of its own, named by the environment variable
``BULLET_DLO_LEROBOT_PYTHON``, its ``LeRobotDataset`` reads the exports frame by frame
(``test_lerobot_dataset_in_its_own_environment_reads_every_frame``; skipped, saying so, without it).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import yaml

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

from bullet_dlo.cli.main import main  # noqa: E402
from bullet_dlo.config.capture import CaptureSpec  # noqa: E402
from bullet_dlo.core.validate import ParameterError  # noqa: E402
from bullet_dlo.data.capture import capture  # noqa: E402
from bullet_dlo.data.lerobot import CAMERA, export_lerobot  # noqa: E402
from bullet_dlo.data.reader import Dataset  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TOLERANCE_S = 1e-4  # LeRobotDataset's default tolerance_s between a query and a decoded frame's time


@pytest.fixture(scope="module")
def captured(tmp_path_factory) -> Path:
    """Two short episodes of the small randomised spec (two node counts), filmed at 30 fps."""
    data = yaml.safe_load((ROOT / "demos" / "specs" / "dr_small.yaml").read_text())
    data["episode"]["duration"] = 0.3
    data["camera"] = {"fps": 30, "width": 64, "height": 48}
    out = tmp_path_factory.mktemp("capture") / "cap"
    res = capture(CaptureSpec.from_dict(data), out, 2, progress=False)
    assert res.failed == 0
    return out


# ----- a v3.0 reader after LeRobot's ------------------------------------------------------------
def read_v3(root: Path) -> dict:
    """info, tasks, episodes (list of dicts) and frames (column -> array) as LeRobotDataset finds them."""
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    episodes = pa.concat_tables([pq.read_table(p) for p in sorted((root / "meta" / "episodes").glob("*/*.parquet"))])
    data = pa.concat_tables([pq.read_table(p) for p in sorted((root / "data").glob("*/*.parquet"))])
    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    task_of = dict(zip(tasks.column("task_index").to_pylist(), tasks.column("__index_level_0__").to_pylist()))
    frames = {}
    for key in data.column_names:
        column = data.column(key).combine_chunks()
        frames[key] = (np.asarray(column.flatten()).reshape(len(column), -1) if pa.types.is_fixed_size_list(column.type)
                       else np.asarray(column))
    return {"info": info, "episodes": episodes.to_pylist(), "frames": frames, "tasks": task_of,
            "stats": json.loads((root / "meta" / "stats.json").read_text())}


def decode_at(path: Path, timestamps: np.ndarray) -> np.ndarray:
    """Frames of the video at ``timestamps`` [s]: the decoded frame nearest each, within LeRobot's tolerance."""
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        decoded = [(float(f.pts * stream.time_base), f.to_ndarray(format="rgb24")) for f in container.decode(video=0)]
    times = np.array([t for t, _ in decoded])
    out = []
    for ts in timestamps:
        i = int(np.argmin(np.abs(times - ts)))
        assert abs(times[i] - ts) < TOLERANCE_S, f"no frame within {TOLERANCE_S} s of {ts}"
        out.append(decoded[i][1])
    return np.array(out)


def check_against_hdf5(root: Path, source: Path, cable_points: int | None = None) -> dict:
    """Every frame's values equal the HDF5 episode's row at its ``sim.time`` (as float32)."""
    v3 = read_v3(root)
    info, frames = v3["info"], v3["frames"]
    ds = Dataset(source)
    records = {int(r["episode"]): r for r in ds.records}
    fps = info["fps"]
    assert info["total_episodes"] == len(v3["episodes"]) and info["total_frames"] == len(frames["index"])
    for key, ft in info["features"].items():  # every non-video feature is a column of its shape
        if ft["dtype"] == "video":
            continue
        assert frames[key].shape[1:] in ((), tuple(ft["shape"])) and key in v3["stats"]
    np.testing.assert_array_equal(frames["index"], np.arange(len(frames["index"])))
    for e, meta in enumerate(v3["episodes"]):
        assert meta["episode_index"] == e and meta["tasks"] == [v3["tasks"][0]]
        lo, hi = meta["dataset_from_index"], meta["dataset_to_index"]
        assert hi - lo == meta["length"]
        ep = ds.load(records[meta["source_episode"]])
        assert meta["params/youngs_modulus"] == ep["params"]["youngs_modulus"]
        assert meta["params/integrator"] == ep["params"]["integrator"]
        assert json.loads(meta["bullet_dlo/params"]) == json.loads(json.dumps(ep["params"]))
        np.testing.assert_array_equal(frames["episode_index"][lo:hi], e)
        np.testing.assert_array_equal(frames["frame_index"][lo:hi], np.arange(hi - lo))
        np.testing.assert_array_equal(frames["timestamp"][lo:hi], (np.arange(hi - lo) / fps).astype(np.float32))
        rows = [int(np.flatnonzero(ep["t"] == t)[0]) for t in frames["sim.time"][lo:hi].ravel()]
        q, pos, quat = ep["joint_q"][rows], ep["ee_pos"][rows], ep["ee_quat"][rows]
        state = np.concatenate([np.concatenate([q[:, a], pos[:, a], quat[:, a]], axis=1) for a in range(2)], axis=1)
        np.testing.assert_array_equal(frames["observation.state"][lo:hi], state.astype(np.float32))
        for a, arm in enumerate(("left", "right")):
            np.testing.assert_array_equal(frames[f"observation.wrench.{arm}"][lo:hi],
                                          ep["wrench_sensor"][rows, a].astype(np.float32))
        x = ep["cable_x"][rows]
        if cable_points is None:
            expected = x.reshape(len(rows), -1)
        else:
            s = np.linspace(0, x.shape[1] - 1, cable_points)
            expected = np.stack([np.stack([np.interp(s, np.arange(x.shape[1]), xi[:, c]) for c in range(3)], axis=1)
                                 for xi in x]).reshape(len(rows), -1)
        np.testing.assert_allclose(frames["observation.environment_state"][lo:hi], expected.astype(np.float32),
                                   rtol=0, atol=1e-7)
        if "action" in frames:
            np.testing.assert_array_equal(frames["action"][lo:hi], ep["action"].astype(np.float32))
            np.testing.assert_array_equal(frames["next.reward"][lo:hi].ravel(), ep["reward"].astype(np.float32))
        if CAMERA in info["features"]:
            video = root / info["video_path"].format(video_key=CAMERA, chunk_index=meta[f"videos/{CAMERA}/chunk_index"],
                                                     file_index=meta[f"videos/{CAMERA}/file_index"])
            decoded = decode_at(video, meta[f"videos/{CAMERA}/from_timestamp"] + frames["timestamp"][lo:hi])
            t_frames = ep["frame_t"]
            nearest = [int(np.argmin(np.abs(t_frames - t))) for t in frames["sim.time"][lo:hi].ravel()]
            diff = np.abs(decoded.astype(float) - ep["frames"][nearest].astype(float))
            assert diff.mean() < 10.0, diff.mean()  # H.264 yuv420p at crf 23 on 64 x 48 px: about 5-7 of 255
    return v3


# ----- tests -------------------------------------------------------------------------------------
def test_capture_with_video_exports_and_reads_back_frame_by_frame(captured, tmp_path):
    with pytest.raises(ParameterError, match="--cable-points"):  # two node counts in one column
        export_lerobot(captured, tmp_path / "nodes")
    assert not (tmp_path / "nodes").exists()  # nothing left behind
    res = export_lerobot(captured, tmp_path / "lr", cable_points=10)
    assert res.episodes == 2 and res.video and res.fps == 30
    for rel in ("meta/info.json", "meta/stats.json", "meta/tasks.parquet", "meta/episodes/chunk-000/file-000.parquet",
                "data/chunk-000/file-000.parquet", f"videos/{CAMERA}/chunk-000/file-000.mp4"):
        assert (tmp_path / "lr" / rel).is_file(), rel
    v3 = check_against_hdf5(tmp_path / "lr", captured, cable_points=10)
    info = v3["info"]
    assert info["robot_type"].startswith("dual_") and info["data_path"] == \
        "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    feats = info["features"]
    assert feats["observation.wrench.left"]["names"] == ["fx", "fy", "fz", "mx", "my", "mz"]
    assert feats["observation.state"]["shape"] == [28] and feats["observation.environment_state"]["shape"] == [30]
    assert feats[CAMERA]["info"]["video.fps"] == 30 and feats[CAMERA]["shape"] == [48, 64, 3]
    assert np.array(v3["stats"][CAMERA]["mean"]).shape == (3, 1, 1)
    assert len({e["params/n_masses"] for e in v3["episodes"]}) == 2  # the per-episode parameters
    assert all(e["decision/substeps"] >= 1 for e in v3["episodes"])
    ends = [(e[f"videos/{CAMERA}/from_timestamp"], e[f"videos/{CAMERA}/to_timestamp"]) for e in v3["episodes"]]
    assert ends[0][0] == 0.0 and ends[1][0] == pytest.approx(ends[0][1])  # one file, episodes back to back


def test_rollouts_export_actions_at_the_control_rate(rolled, tmp_path):
    res = export_lerobot(rolled, tmp_path / "lr")
    assert res.fps == 20 and res.frames == 16 and not res.video
    v3 = check_against_hdf5(tmp_path / "lr", rolled)
    assert v3["info"]["features"]["action"]["shape"] == [6] and v3["info"]["video_path"] is None
    assert v3["frames"]["next.done"].ravel().tolist() == ([False] * 7 + [True]) * 2
    assert v3["episodes"][0]["bullet_dlo/truncated"] is True


def test_tasks_parquet_reads_as_lerobot_reads_it(rolled, tmp_path):
    pd = pytest.importorskip("pandas")
    export_lerobot(rolled, tmp_path / "lr")
    tasks = pd.read_parquet(tmp_path / "lr" / "meta" / "tasks.parquet")  # LeRobot's load_tasks
    assert tasks.iloc[0].name.startswith("follow a tension profile") and int(tasks.loc[tasks.index[0]].task_index) == 0


def test_lerobot_dataset_reads_the_export(rolled, tmp_path):
    """LeRobot's own reader, where the lerobot package is installed (see the module doc for why not here)."""
    pytest.importorskip("lerobot.datasets.lerobot_dataset",
                        reason="lerobot not installed (torch, torchcodec, datasets; pins av<16)")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    export_lerobot(rolled, tmp_path / "lr")
    lr = LeRobotDataset("local/bullet_dlo", root=tmp_path / "lr")
    v3 = read_v3(tmp_path / "lr")
    assert len(lr) == len(v3["frames"]["index"]) and lr.num_episodes == 2
    for i in range(len(lr)):
        item = lr[i]
        for key in ("observation.state", "observation.wrench.left", "action"):
            np.testing.assert_array_equal(item[key].numpy(), v3["frames"][key][i])


LEROBOT_PYTHON = os.environ.get("BULLET_DLO_LEROBOT_PYTHON")
READ_WITH_LEROBOT = """
import sys, numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset
import lerobot
ds = LeRobotDataset("local/bullet_dlo", root=sys.argv[1], video_backend="pyav")  # torchcodec needs system FFmpeg
items = [ds[i] for i in range(len(ds))]
out = {"len": np.array(len(ds)), "episodes": np.array(ds.num_episodes), "fps": np.array(ds.fps),
       "version": np.array(lerobot.__version__)}
for key, value in items[0].items():
    if hasattr(value, "numpy"):
        out["f/" + key] = np.stack([it[key].numpy() for it in items])
    else:
        out["s/" + key] = np.array([str(it[key]) for it in items])
np.savez(sys.argv[2], **out)
"""


@pytest.mark.skipif(not LEROBOT_PYTHON, reason="set BULLET_DLO_LEROBOT_PYTHON to a Python with lerobot installed (it "
                    "pins torch<2.11 and av<16, so it lives in its own venv; docs/guides/datasets.md says how)")
@pytest.mark.parametrize("source", ["captured", "rolled"])
def test_lerobot_dataset_in_its_own_environment_reads_every_frame(source, request, tmp_path):
    """LeRobot's own ``LeRobotDataset`` (in the interpreter ``BULLET_DLO_LEROBOT_PYTHON`` names) reads the export
    of a capture with video and of rollouts: every frame of every feature equals the export's columns (and
    through them the HDF5 episodes, :func:`check_against_hdf5`), the video frames decoded by LeRobot equal the
    rendered frames within the codec's error, and the task string is the dataset's."""
    import subprocess

    src = request.getfixturevalue(source)
    kw = {"cable_points": 10} if source == "captured" else {}
    export_lerobot(src, tmp_path / "lr", **kw)
    v3 = check_against_hdf5(tmp_path / "lr", src, **kw)
    script = tmp_path / "read.py"
    script.write_text(READ_WITH_LEROBOT)
    run = subprocess.run([LEROBOT_PYTHON, str(script), str(tmp_path / "lr"), str(tmp_path / "lr.npz")],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = dict(np.load(tmp_path / "lr.npz"))
    frames, info = v3["frames"], v3["info"]
    assert int(got["len"]) == len(frames["index"]) and int(got["episodes"]) == len(v3["episodes"])
    assert int(got["fps"]) == info["fps"]
    for key, ft in info["features"].items():
        if ft["dtype"] == "video":
            # LeRobot returns channel-first floats in [0, 1]; compare with the rendered frames, via our decoder
            decoded = np.moveaxis(got["f/" + key], 1, -1) * 255.0
            ours = np.concatenate([decode_at(tmp_path / "lr" / info["video_path"].format(
                video_key=key, chunk_index=e[f"videos/{key}/chunk_index"], file_index=e[f"videos/{key}/file_index"]),
                e[f"videos/{key}/from_timestamp"] + frames["timestamp"][e["dataset_from_index"]:e["dataset_to_index"]])
                for e in v3["episodes"]]).astype(float)
            assert decoded.shape == ours.shape and np.abs(decoded - ours).mean() < 1.0, np.abs(decoded - ours).mean()
            continue
        mine = frames[key].reshape(got["f/" + key].shape)
        np.testing.assert_array_equal(got["f/" + key], mine.astype(got["f/" + key].dtype), err_msg=key)
    tasks = set(got["s/task"].tolist())
    assert tasks == set(v3["tasks"].values())


def test_bad_input_is_one_line_and_exit_2(rolled, tmp_path, capsys):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    assert main(["export", "lerobot", str(tmp_path), str(tmp_path / "o")]) == 2  # not a dataset
    assert main(["export", "lerobot", str(rolled), str(tmp_path / "full")]) == 2  # OUT not empty
    err = capsys.readouterr().err.strip().splitlines()
    assert [line.split(":")[0] for line in err] == ["error", "error"]
    assert "not a capture directory" in err[0] and "not empty" in err[1]
    assert not (tmp_path / "o").exists()


def test_an_episode_with_nan_is_left_out_and_cable_points_are_bounded(rolled, tmp_path, capsys):
    """Issue 26 audit: a NaN inside a re-hashed episode reached the parquet and stats.json; --cable-points
    100000000 asked for 402 GiB (MemoryError traceback)."""
    import hashlib
    import shutil

    import h5py

    src = tmp_path / "roll"
    shutil.copytree(rolled, src)
    path = src / "episode_000001.h5"
    with h5py.File(path, "r+") as f:
        f["wrench_sensor"][0, 0, 0] = np.nan
    data = path.read_bytes()
    recs = [json.loads(line) for line in (src / "manifest.jsonl").read_text().splitlines()]
    for r in recs:
        if r["episode"] == 1:
            r.update(sha256=hashlib.sha256(data).hexdigest(), size=len(data))
    (src / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    res = export_lerobot(src, tmp_path / "lr")
    assert res.episodes == 1 and res.skipped == [(1, "NaN or inf in wrench_sensor")]
    stats = json.loads((tmp_path / "lr" / "meta" / "stats.json").read_text())
    assert np.all(np.isfinite(stats["observation.wrench.left"]["mean"]))
    assert main(["export", "lerobot", str(rolled), str(tmp_path / "big"), "--cable-points", "100000000"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--cable-points must be an integer in [2, 10000]" in err[0], err
