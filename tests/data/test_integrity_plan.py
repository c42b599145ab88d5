"""Issue 26 audit (second round): a vanished episode, NaN inside a verified file, an edited capture.json.
Fake episodes (no physics)."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from fake_episode import fake_episode

from bullet_dlo.cli.main import main
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data import Dataset
from bullet_dlo.data.storage import MANIFEST, SPEC_FILE, append_manifest, prepare

SPEC = CaptureSpec(seed=3)


def build(out: Path, episodes: int, resume: bool = False) -> None:
    """What ``capture`` writes, in this process (no worker pool: cheap): the plan, then the missing episodes."""
    have = prepare(SPEC, out, resume, episodes=episodes)
    for i in range(episodes):
        if i not in have:
            append_manifest(out, fake_episode(SPEC.to_dict(), i, str(out)))


def records(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / MANIFEST).read_text().splitlines()]


def write_records(out: Path, recs: list[dict]) -> None:
    (out / MANIFEST).write_text("".join(json.dumps(r) + "\n" for r in recs))


def vanish(out: Path, i: int) -> None:
    """Episode i's manifest line and file both gone (what neither hash nor file check can see)."""
    write_records(out, [r for r in records(out) if r["episode"] != i])
    (out / f"episode_{i:06d}.h5").unlink()


def test_a_vanished_episode_makes_the_dataset_incomplete_until_resumed(tmp_path, capsys):
    out = tmp_path / "cap"
    build(out, 4)
    assert json.loads((out / SPEC_FILE).read_text())["episodes"] == 4
    vanish(out, 3)  # the last one: no gap shows it, only the plan
    assert Dataset(out).missing() == [3] and not Dataset(out).verify().ok
    for argv in (["dataset", "verify", str(out)], ["dataset", "summary", str(out)]):
        assert main(argv) == 1
        cap = capsys.readouterr()
        assert "incomplete: 3 of 4 episodes recorded, missing 3" in cap.err and "no problems" not in cap.out
        assert "bullet-dlo capture ... --resume" in cap.err  # (a rollouts directory: the test below)
    assert main(["export", "lerobot", str(out), str(tmp_path / "lr")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "incomplete: 3 of 4" in err[0] and not (tmp_path / "lr").exists()
    build(out, 4, resume=True)  # capture --resume (prepare, then the episodes without a record)
    assert (out / "episode_000003.h5").exists() and Dataset(out).verify().ok
    build(out, 6, resume=True)  # the plan grows with the largest N asked for, never shrinks
    build(out, 2, resume=True)
    assert Dataset(out).planned == 6 and Dataset(out).verify().ok


def test_a_directory_without_a_stored_plan_still_shows_its_gaps(tmp_path):
    out = tmp_path / "cap"
    build(out, 4)
    meta = json.loads((out / SPEC_FILE).read_text())
    del meta["episodes"]  # written before the count was stored
    (out / SPEC_FILE).write_text(json.dumps(meta))
    vanish(out, 1)
    report = Dataset(out).verify()
    assert report.missing == [1] and report.planned is None and not report.ok
    assert any("does not store how many" in line for line in report.lines())
    build(out, 4, resume=True)
    assert Dataset(out).planned == 4 and Dataset(out).verify().ok


@pytest.mark.parametrize("manifest", ["rehashed", "old lines"])
def test_nan_inside_an_episode_fails_verification(tmp_path, capsys, manifest):
    out = tmp_path / "cap"
    build(out, 3)
    path = out / "episode_000001.h5"
    with h5py.File(path, "r+") as f:
        f["t"][1] = np.nan
    recs = records(out)
    for r in recs:
        if manifest == "rehashed" and r["episode"] == 1:
            data = path.read_bytes()
            r.update(sha256=hashlib.sha256(data).hexdigest(), size=len(data))
        elif manifest == "old lines":
            for k in ("size", "sha256", "version", "spec_digest"):
                r.pop(k)
    write_records(out, recs)
    report = Dataset(out).verify()
    assert [(p.episode, p.kind) for p in report.problems] == [(1, "non-finite")], report.problems
    assert "NaN or inf in t (1 value)" in str(report.problems[0])
    assert main(["dataset", "verify", str(out)]) == 1
    assert "non-finite" in capsys.readouterr().out


def test_an_edited_spec_with_its_old_digest_is_refused(tmp_path):
    out = tmp_path / "cap"
    build(out, 2)
    meta = json.loads((out / SPEC_FILE).read_text())
    meta["spec"]["seed"] = 8  # the episodes were drawn with seed 3
    (out / SPEC_FILE).write_text(json.dumps(meta))
    with pytest.raises(ParameterError, match="does not match its digest"):
        Dataset(out)
    with pytest.raises(ParameterError, match="does not match its digest"):
        build(out, 2, resume=True)


def test_an_incomplete_rollouts_directory_points_to_rollouts_resume(tmp_path, capsys):
    """A rollouts directory is resumed by ``rollouts``, not ``capture`` (its hint said capture)."""
    from bullet_dlo.data.storage import _write_spec_file, spec_digest

    out = tmp_path / "ro"
    build(out, 3)
    spec = {"rollout": {"env_id": "bullet_dlo/TensionTracking-v0", "policy": "random"}, "randomisation": {}}
    _write_spec_file(out, spec_digest(spec), spec, 3)
    vanish(out, 2)
    assert main(["dataset", "verify", str(out)]) == 1
    err = capsys.readouterr().err
    assert "bullet-dlo rollouts ... --resume" in err and "capture ..." not in err

