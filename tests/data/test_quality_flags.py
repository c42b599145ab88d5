"""Episodes whose forces cannot be trusted are flagged with the reason, and filtered out by select()."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.loader import load_yaml
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.episode import run_episode
from bullet_dlo.data.quality import quality_issues, quality_metrics
from bullet_dlo.data.storage import episode_result

ROOT = Path(__file__).resolve().parents[2]


def short_spec(**quality) -> CaptureSpec:
    data = load_yaml(ROOT / "demos" / "specs" / "dr_small.yaml", "capture spec")
    data["episode"]["duration"] = 0.3
    data["sample"]["dt"] = {"dist": "fixed", "value": 1.0 / 240.0}
    if quality:
        data["quality"] = quality
    return CaptureSpec.from_dict(data)


def test_quality_issues_against_the_limits():
    t = np.arange(200) / 200.0
    model = np.zeros((200, 2, 3))
    sensor = model.copy()
    sensor[:, 0, 2] = 0.5  # a constant 0.5 N error on one axis: RMS over both ends sqrt(0.25 / 2)
    m = quality_metrics(t, sensor, model)
    assert m["sensor_model_rms"] == pytest.approx(np.sqrt(0.125))
    assert quality_issues(m, weight=0.3, max_rms_weights=1.0, max_hf=None)  # 0.354 N > 0.3 N
    assert not quality_issues(m, weight=0.3, max_rms_weights=2.0, max_hf=None)
    sensor[:, 0, 2] = 0.5 + np.sin(2 * np.pi * 40 * t)  # a 40 Hz ring
    m = quality_metrics(t, sensor, model)
    assert any("high-frequency" in s for s in quality_issues(m, 0.3, None, 0.5))
    assert not quality_issues({"sensor_model_rms": float("nan"), "hf_energy": float("nan")}, 0.3, 1.0, 0.5)


def test_record_status_and_reason():
    ok = episode_result(0, "f", True, None, None, {}, {}, {}, [])
    bad = episode_result(1, "f", True, None, None, {}, {}, {}, ["sensor-model RMS 1 N > 1 cable weights (0.3 N)"])
    unstable = episode_result(2, "f", False, 0.1, "non-finite state", {}, {}, {}, [])
    assert ok["status"] == "ok" and bad["status"] == "flagged" and unstable["status"] == "flagged"
    assert bad["reason"].startswith("quality: sensor-model RMS") and unstable["reason"] == "non-finite state"


def test_spec_quality_section():
    assert short_spec().max_sensor_model_rms == 1.0 and short_spec().max_hf_energy is None
    spec = short_spec(max_sensor_model_rms=0.5, max_hf_energy=0.2)
    assert CaptureSpec.from_dict(spec.to_dict()) == spec and spec.digest() != short_spec().digest()
    with pytest.raises(ParameterError, match="quality.max_hf_energy"):
        short_spec(max_hf_energy=2.0)
    with pytest.raises(ParameterError, match="quality"):
        short_spec(max_rms=1.0)


def test_an_episode_failing_the_limit_is_flagged_and_not_selected(tmp_path):
    """The same episode: ok under the default limits, flagged under a high-frequency share limit of 1e-9 (its
    sensor-model RMS, exact since issue 27, no longer fails even a 1e-6 weight limit)."""
    from bullet_dlo.data.reader import Dataset
    from bullet_dlo.data.storage import append_manifest, prepare

    strict = short_spec(max_hf_energy=1e-9)
    (tmp_path / "a").mkdir()
    out = tmp_path / "b"
    prepare(strict, out, resume=False)  # a capture directory of the strict spec
    rec_ok = run_episode(short_spec().to_dict(), 0, str(tmp_path / "a"))
    rec = run_episode(strict.to_dict(), 0, str(out))
    assert rec_ok["status"] == "ok" and rec_ok["metrics"] == rec["metrics"]
    assert rec["status"] == "flagged" and rec["reason"].startswith("quality: high-frequency share")
    assert rec["time_to_instability"] is None
    append_manifest(out, rec)
    ds = Dataset(out)
    assert ds.select(status="ok") == [] and len(ds.select(status="flagged")) == 1
    summary = ds.summary()
    assert summary["flagged_for_quality"] == 1 and summary["flagged_runs"][0]["reason"] == rec["reason"]
