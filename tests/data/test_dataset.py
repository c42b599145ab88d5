"""Dataset capture: reproducibility, interruption, stability policies, spec validation."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from bullet_dlo.cli.main import main
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.capture import Dataset, capture, load_episode, plan_episode

ROOT = Path(__file__).resolve().parents[2]
SMALL = yaml.safe_load((ROOT / "demos" / "specs" / "dr_small.yaml").read_text())


def short(spec: dict, duration: float = 0.5, **changes) -> CaptureSpec:
    data = json.loads(json.dumps(spec))
    data["episode"]["duration"] = duration
    data.update(changes)
    return CaptureSpec.from_dict(data)


def test_same_seed_same_files_with_1_and_2_workers(tmp_path):
    spec = short(SMALL)
    one = capture(spec, tmp_path / "w1", 3, workers=1, progress=False)
    two = capture(spec, tmp_path / "w2", 3, workers=2, progress=False)
    assert one.done == two.done == 3 and one.failed == two.failed == 0
    for i in range(3):
        name = f"episode_{i:06d}.h5"
        assert (tmp_path / "w1" / name).read_bytes() == (tmp_path / "w2" / name).read_bytes()
    # episode i depends only on (seed, i)
    assert spec.draw(2) == CaptureSpec.from_dict(spec.to_dict()).draw(2) != spec.draw(1)


def test_ray_backend_writes_identical_files(tmp_path):
    """A local Ray instance (Ray is in the test extra) gives the same bytes as the process pool."""
    spec = short(SMALL)
    capture(spec, tmp_path / "local", 2, workers=1, progress=False)
    res = capture(spec, tmp_path / "ray", 2, workers=2, backend="ray", progress=False)
    assert res.done == 2
    for i in range(2):
        name = f"episode_{i:06d}.h5"
        assert (tmp_path / "local" / name).read_bytes() == (tmp_path / "ray" / name).read_bytes()


def test_killed_capture_resumes_to_exactly_n_episodes(tmp_path):
    spec_file = tmp_path / "spec.yaml"
    data = json.loads(json.dumps(SMALL))
    data["episode"]["duration"] = 1.0
    spec_file.write_text(yaml.safe_dump(data))
    out = tmp_path / "cap"
    cmd = [sys.executable, "-m", "bullet_dlo.cli", "capture", str(spec_file), "--out", str(out), "--episodes", "6",
           "--quiet"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while time.time() < deadline and len(list(out.glob("episode_*.h5"))) < 2:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the coordinator and its workers, mid-episode
    proc.wait()
    before = len(list(out.glob("episode_*.h5")))
    assert 2 <= before < 6
    with pytest.raises(ParameterError, match="pass --resume"):
        capture(CaptureSpec.from_yaml(spec_file), out, 6, progress=False)
    res = capture(CaptureSpec.from_yaml(spec_file), out, 6, resume=True, progress=False)
    files = sorted(out.glob("episode_*.h5"))
    assert [f.name for f in files] == [f"episode_{i:06d}.h5" for i in range(6)]
    assert not list(out.glob("*.tmp*"))
    assert res.ran <= 6 - before + 1  # finished episodes were not re-run
    ds = Dataset(out)
    assert sorted(r["episode"] for r in ds.records) == list(range(6))
    for f in files:
        ep = load_episode(f)
        assert np.all(np.isfinite(ep["cable_x"])) and ep["t"][-1] == pytest.approx(1.0, abs=0.02)


@pytest.mark.parametrize("policy", ["reject", "implicit", "substeps"])
def test_stiff_symplectic_at_1ms_never_gives_unflagged_unstable_data(tmp_path, policy):
    data = {"seed": 3, "episode": {"duration": 0.6, "record_rate": 240}, "policy": policy,
            "sample": {"youngs_modulus": {"dist": "log_uniform", "low": 1.0e8, "high": 5.0e9},
                       "integrator": {"dist": "choice", "values": ["symplectic_euler"]},
                       "dt": {"dist": "fixed", "value": 0.001}}}
    spec = CaptureSpec.from_dict(data)
    res = capture(spec, tmp_path / policy, 3, workers=2, progress=False)
    assert res.failed == 0
    for rec in Dataset(tmp_path / policy).select(status=None):
        ep = load_episode(tmp_path / policy / rec["file"])
        crit = rec["decision"]["critical_dt"]
        assert crit is not None and crit < 0.9e-3  # every sample was beyond the limit at 1 ms
        assert rec["decision"]["action"] != "none"  # the policy acted on each
        if rec["status"] == "ok":
            assert bool(ep["stable"])
            assert np.all(np.isfinite(ep["wrench_world"])) and np.max(np.abs(ep["end_forces"])) < 100.0
        else:
            assert rec["status"] == "flagged" and rec["time_to_instability"] > 0


def test_policy_decisions_are_recorded():
    data = {"seed": 1, "sample": {"youngs_modulus": {"dist": "fixed", "value": 5.0e9},
                                  "integrator": {"dist": "fixed", "value": "symplectic_euler"},
                                  "dt": {"dist": "fixed", "value": 0.001}}}
    for policy, expect in (("implicit", "switched"), ("substeps", "substeps"), ("reject", "switched")):
        params, decision = plan_episode(CaptureSpec.from_dict({**data, "policy": policy}), 0)
        assert decision["action"].startswith(expect) and decision["policy"] == policy
        if expect == "substeps":
            assert 0.001 / decision["substeps"] <= 0.9 * decision["critical_dt"]
        else:
            assert params["integrator"] == "implicit_euler"


@pytest.mark.parametrize(
    "sample,needle",
    [
        ({"damping": {"dist": "uniform", "low": -1.0, "high": 0.1}}, "sample.damping.low = -1.0 is outside"),
        ({"stiffness": {"dist": "fixed", "value": 1.0}}, "unknown parameter sample.stiffness"),
        ({"youngs_modulus": {"dist": "uniform", "low": 2e9, "high": 1e8}}, "sample.youngs_modulus: low"),
        ({"robot": {"dist": "choice", "values": ["kuka", "ur5"]}}, "unknown robot 'ur5'"),
        ({"n_masses": {"dist": "gamma", "k": 2}}, "sample.n_masses.dist must be one of"),
    ],
)
def test_invalid_specs_fail_before_any_episode(tmp_path, capsys, sample, needle):
    spec_file = tmp_path / "bad.yaml"
    spec_file.write_text(yaml.safe_dump({"seed": 1, "sample": sample}))
    out = tmp_path / "never"
    assert main(["capture", str(spec_file), "--out", str(out), "--episodes", "2"]) == 2
    assert needle in capsys.readouterr().err
    assert not out.exists()


def test_directory_of_another_spec_is_refused(tmp_path):
    capture(short(SMALL, 0.3), tmp_path / "c", 1, progress=False)
    with pytest.raises(ParameterError, match="different spec"):
        capture(short(SMALL, 0.4), tmp_path / "c", 1, resume=True, progress=False)


def test_failed_episode_is_recorded_with_its_error(tmp_path):
    data = {"seed": 2, "episode": {"duration": 0.3},
            "sample": {"hold_height": {"dist": "fixed", "value": 0.6},
                       "displacement_z": {"dist": "fixed", "value": 0.2}}}  # 0.8 m up: out of reach
    res = capture(CaptureSpec.from_dict(data), tmp_path / "f", 1, progress=False)
    assert res.failed == 1
    rec = Dataset(tmp_path / "f").select(status="failed")[0]
    assert "pose unreachable" in rec["error"]


def test_reader_filters_and_summary(tmp_path):
    capture(short(SMALL, 0.5), tmp_path / "d", 4, workers=2, progress=False)
    ds = Dataset(tmp_path / "d")
    assert len(ds.select(status=None)) == 4
    kuka = ds.select(status=None, where=lambda p: p["robot"] == "kuka")
    assert all(r["params"]["robot"] == "kuka" for r in kuka) and len(kuka) < 4
    ep = ds.load(ds.select(status=None)[0])
    k = len(ep["t"])
    assert ep["wrench_world"].shape == (k, 2, 6) and ep["wrench_raw"].shape == (k, 2, 6)
    assert ep["joint_q"].shape == (k, 2, 7) and ep["ee_pos"].shape == (k, 2, 3)
    n = ep["params"]["n_masses"]
    assert ep["cable_x"].shape == (k, n, 3)
    assert {"hf_energy", "peak_to_mean", "sensor_model_rms"} <= set(ep["metrics"])
    summary = ds.summary(tmp_path / "q.png")
    # every episode is stable; one (symplectic Euler with 48 substeps, E = 0.7 GPa) fails the default
    # force-quality limit (sensor-model RMS above one cable weight) and is flagged for it
    assert summary["ok"] + summary["flagged_for_quality"] == 4 and summary["flagged"] == summary["flagged_for_quality"]
    assert len(ds.select()) == summary["ok"] and "youngs_modulus" in summary["coverage"]
    assert (tmp_path / "q.png").stat().st_size > 1000
    assert main(["dataset", "summary", str(tmp_path / "d")]) == 0


def test_frames_are_stored_compressed(tmp_path):
    data = json.loads(json.dumps(SMALL))
    data["episode"]["duration"] = 0.5
    data["camera"] = {"fps": 10, "width": 96, "height": 72}
    capture(CaptureSpec.from_dict(data), tmp_path / "v", 1, progress=False)
    ep = load_episode(tmp_path / "v" / "episode_000000.h5")
    assert ep["frames"].shape == (6, 72, 96, 3) and ep["frames"].dtype == np.uint8
    assert ep["frames"].std() > 5.0 and np.allclose(np.diff(ep["frame_t"]), 0.1, atol=0.01)


def test_auto_masses_per_episode(tmp_path):
    data = json.loads(json.dumps(SMALL))
    data["episode"]["duration"] = 0.6
    data["sample"]["n_masses"] = "auto"
    data["resolve_tol"] = 0.05
    spec = CaptureSpec.from_dict(data)
    params, decision = plan_episode(spec, 0)
    assert isinstance(params["n_masses"], int) and 5 <= params["n_masses"] <= 80
    assert decision["resolved_n_masses"] == params["n_masses"]
    assert CaptureSpec.from_dict(spec.to_dict()).sample["n_masses"].value == "auto"  # round-trips
    res = capture(spec, tmp_path / "auto", 1, progress=False)
    assert res.done == 1 and res.failed == 0
