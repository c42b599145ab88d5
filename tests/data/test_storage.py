"""Episode files, the manifest and force-quality numbers, without running a simulation."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data import Dataset, load_episode
from bullet_dlo.data.plan import gripper_move
from bullet_dlo.data.quality import quality_metrics
from bullet_dlo.data.storage import (
    append_manifest,
    episode_record,
    episode_result,
    prepare,
    read_manifest,
    write_episode,
)

PARAMS = {"robot": "kuka", "youngs_modulus": 1e8}
DECISION = {"action": "none", "substeps": 1}
METRICS = {"hf_energy": 0.1, "peak_to_mean": 1.2, "sensor_model_rms": 0.01}


def write(out, index, stable=True, t_bad=None):
    arrays = {"t": np.arange(5) * 0.01, "end_forces": np.ones((5, 2, 3))}
    attrs = {"params": PARAMS, "decision": DECISION, "metrics": METRICS, "episode": index, "stable": stable,
             "time_to_instability": -1.0 if t_bad is None else t_bad}
    frames = np.zeros((2, 4, 6, 3), dtype=np.uint8)
    return write_episode(out, index, arrays, attrs, frames, np.array([0.0, 0.1]))


def test_episode_file_is_atomic_deterministic_and_round_trips(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    name = write(tmp_path / "a", 12)
    assert name == "episode_000012.h5" and sorted(p.name for p in (tmp_path / "a").iterdir()) == [name]
    write(tmp_path / "b", 12)
    assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()  # no timestamps
    ep = load_episode(tmp_path / "a" / name)
    assert ep["params"] == PARAMS and ep["metrics"] == METRICS and ep["episode"] == 12
    assert ep["frames"].shape == (2, 4, 6, 3) and ep["frames"].dtype == np.uint8
    np.testing.assert_array_equal(ep["t"], np.arange(5) * 0.01)


def test_record_rebuilt_from_file_equals_the_live_record(tmp_path):
    name = write(tmp_path, 3, stable=False, t_bad=0.25)
    live = episode_result(3, name, False, 0.25, None, PARAMS, DECISION, METRICS)
    assert live["status"] == "flagged"
    assert episode_record(tmp_path / name) == live
    corrupt = tmp_path / "episode_000004.h5"
    corrupt.write_bytes(b"not hdf5")
    assert episode_record(corrupt) is None and not corrupt.exists()  # re-run, not trusted


def test_prepare_recovers_lost_manifest_lines_and_refuses_other_specs(tmp_path):
    spec = CaptureSpec(seed=1)
    assert prepare(spec, tmp_path, resume=False) == {}
    write(tmp_path, 0)
    write(tmp_path, 1)
    append_manifest(tmp_path, episode_result(0, "episode_000000.h5", True, None, None, PARAMS, DECISION, METRICS))
    with open(tmp_path / "manifest.jsonl", "a") as fh:
        fh.write('{"episode": 1, "file": "epis')  # a line cut by a kill
    (tmp_path / "episode_000002.h5.tmp-999").write_bytes(b"partial")
    with pytest.raises(ParameterError, match="pass --resume"):
        prepare(spec, tmp_path, resume=False)
    records = prepare(spec, tmp_path, resume=True)
    assert sorted(records) == [0, 1] and records[1]["status"] == "ok"
    assert not list(tmp_path.glob("*.tmp-*"))
    assert sorted(read_manifest(tmp_path)) == [0, 1]
    assert [r["episode"] for r in Dataset(tmp_path).select()] == [0, 1]
    with pytest.raises(ParameterError, match="different spec"):
        prepare(CaptureSpec(seed=2), tmp_path, resume=True)
    assert json.loads((tmp_path / "capture.json").read_text())["digest"] == spec.digest()


def test_quality_metrics_against_known_signals():
    t = np.arange(1000) / 1000.0  # 1 s at 1 kHz
    slow = np.zeros((1000, 2, 3))
    slow[:, :, 2] = 1.0 + 0.1 * np.sin(2 * np.pi * 2.0 * t)[:, None]  # 2 Hz: below the 10 Hz cutoff
    fast = slow.copy()
    fast[:, :, 2] = 1.0 + 0.1 * np.sin(2 * np.pi * 50.0 * t)[:, None]  # 50 Hz: oscillation
    model = np.zeros_like(slow)
    model[:, :, 2] = 1.0
    m_slow, m_fast = quality_metrics(t, slow, model), quality_metrics(t, fast, model)
    assert m_slow["hf_energy"] < 1e-6 and m_fast["hf_energy"] > 1 - 1e-6
    assert m_fast["peak_to_mean"] == pytest.approx(1.1, rel=1e-3)
    assert m_fast["sensor_model_rms"] == pytest.approx(0.1 / np.sqrt(2), rel=1e-3)  # RMS of a sine
    assert np.isnan(quality_metrics(t[:3], slow[:3], model[:3])["hf_energy"])


def test_gripper_move_duration_is_distance_over_speed():
    params = {"displacement_x": 0.03, "displacement_y": 0.0, "displacement_z": 0.04, "speed": 0.1}
    d, duration = gripper_move(params)
    np.testing.assert_array_equal(d, [0.03, 0.0, 0.04])
    assert duration == pytest.approx(0.5)  # 5 cm at 10 cm/s
    assert gripper_move({**params, "displacement_x": 0.0, "displacement_z": 0.0})[1] == 0.0
