"""Capture bookkeeping: nothing lost, nothing hidden, nothing mixed (issue 11).

The episodes here are :func:`fake_episode.fake_episode` (no physics, real episode files), so
workers can be killed on purpose and captures raced in a few seconds each.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fake_episode import fake_episode

from bullet_dlo.cli.main import main
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data import Dataset
from bullet_dlo.data.capture import capture
from bullet_dlo.data.storage import LOCK_FILE, MANIFEST, SPEC_FILE, read_manifest

HERE = Path(__file__).resolve().parent
SPEC = CaptureSpec(seed=1)


def manifest_lines(out: Path) -> list[dict]:
    """Every line of the manifest, parsed (fails on an unreadable line)."""
    return [json.loads(line) for line in (out / MANIFEST).read_text().splitlines()]


def run(out: Path, episodes: int, **kw):
    return capture(SPEC, out, episodes, progress=False, task=fake_episode, **kw)


def coordinator(out: Path, episodes: int, workers: int = 1, resume: bool = False) -> subprocess.Popen:
    """A capture of fake episodes in another process (its own session, so it can be killed alone)."""
    code = (f"import sys; sys.path.insert(0, {str(HERE)!r})\n"
            "from fake_episode import fake_episode\n"
            "from bullet_dlo.config.capture import CaptureSpec\n"
            "from bullet_dlo.data.capture import capture\n"
            f"capture(CaptureSpec(seed=1), {str(out)!r}, {episodes}, workers={workers}, resume={resume}, "
            "progress=False, task=fake_episode)\n")
    return subprocess.Popen([sys.executable, "-c", code], start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)


def wait_for(predicate, timeout: float = 60.0) -> bool:
    deadline = time.time() + timeout
    while time.time() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def alive(pid: int) -> bool:
    """True if ``pid`` runs (a zombie, dead but not yet reaped by its new parent, counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


def test_killed_worker_episode_is_rerun_not_lost(tmp_path):
    out = tmp_path / "cap"
    out.mkdir()
    (out / "kill-once-3").touch()  # the worker running episode 3 is SIGKILLed once
    res = run(out, 8, workers=2)
    assert res.complete and res.done == 8 and res.failed == 0
    assert sorted(r["episode"] for r in manifest_lines(out)) == list(range(8))  # one line each, none lost
    assert len(list(out.glob("episode_*.h5"))) == 8


def test_worker_dying_every_time_is_a_named_failure(tmp_path):
    out = tmp_path / "cap"
    out.mkdir()
    (out / "kill-always-2").touch()
    res = run(out, 4, workers=2)
    assert not res.complete and res.failed_episodes == (2,) and res.done == 4
    rec = read_manifest(out)[2]
    assert rec["status"] == "failed" and "died" in rec["error"]


def test_capture_cli_exits_1_naming_failed_episodes(tmp_path, capsys, monkeypatch):
    import bullet_dlo.data

    def killing_capture(spec, out, episodes, **kw):  # the real coordinator; episode 1's worker always dies
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "kill-always-1").touch()
        return capture(spec, out, episodes, task=fake_episode, **kw)

    monkeypatch.setattr(bullet_dlo.data, "capture", killing_capture)
    spec = tmp_path / "spec.yaml"
    spec.write_text("seed: 2\n")
    code = main(["capture", str(spec), "--out", str(tmp_path / "f"), "--episodes", "3", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and "1 of 3 episodes failed (episodes 1;" in err[0] and "--resume" in err[0]


def test_torn_manifest_line_is_repaired_on_resume(tmp_path):
    out = tmp_path / "cap"
    run(out, 4)
    text = (out / MANIFEST).read_bytes()
    (out / MANIFEST).write_bytes(text[:-25])  # a kill cut the last line
    with pytest.raises(ParameterError, match="--resume"):
        run(out, 4)
    res = run(out, 6, resume=True)
    assert res.complete and res.done == 6
    lines = manifest_lines(out)  # every line readable: the recovered record starts on a fresh line
    assert sorted({r["episode"] for r in lines}) == list(range(6))
    assert len(Dataset(out).records) == 6


def test_damaged_manifest_is_named_by_the_reader(tmp_path):
    out = tmp_path / "cap"
    run(out, 2)
    with open(out / MANIFEST, "a") as fh:
        fh.write("garbage\n")
    with pytest.raises(ParameterError, match=r"manifest.jsonl line 3"):
        Dataset(out)


def test_second_capture_into_a_locked_directory_refuses(tmp_path):
    out = tmp_path / "cap"
    out.mkdir()
    (out / "slow").write_text("0.5")
    first = coordinator(out, 6)
    try:
        assert wait_for(lambda: (out / LOCK_FILE).exists() and (out / LOCK_FILE).read_text().strip() ==
                        str(first.pid))
        for resume in (False, True):  # neither a second capture nor a resume may run beside it
            with pytest.raises(ParameterError, match=f"in use by another capture \\(pid {first.pid}\\)"):
                run(out, 6, resume=resume)
        assert first.wait(120) == 0
    finally:
        if first.poll() is None:
            os.killpg(first.pid, signal.SIGKILL)
    lines = manifest_lines(out)
    assert sorted(r["episode"] for r in lines) == list(range(6))  # each episode ran exactly once
    res = run(out, 6, resume=True)  # the lock went with the first process
    assert res.complete and res.ran == 0


def test_workers_exit_when_the_coordinator_is_killed(tmp_path):
    out = tmp_path / "cap"
    out.mkdir()
    (out / "slow").write_text("60")
    boss = coordinator(out, 4, workers=2)
    try:
        assert wait_for(lambda: len(list(out.glob("pid-*"))) == 2)
        pids = [int(p.read_text()) for p in out.glob("pid-*")]
        assert all(alive(p) for p in pids)
        os.kill(boss.pid, signal.SIGKILL)  # the coordinator alone
        boss.wait()
        assert wait_for(lambda: not any(alive(p) for p in pids), timeout=10.0), "orphan workers kept running"
    finally:
        for p in out.glob("pid-*"):
            if alive(int(p.read_text())):
                os.kill(int(p.read_text()), signal.SIGKILL)
    assert not list(out.glob("episode_*.h5"))  # nothing written that no manifest lists


def test_missing_or_damaged_spec_file_refuses_resume(tmp_path):
    out = tmp_path / "cap"
    run(out, 2)
    spec_text = (out / SPEC_FILE).read_text()
    (out / SPEC_FILE).unlink()
    with pytest.raises(ParameterError, match="no capture.json: their spec is unknown"):
        run(out, 3, resume=True)
    (out / SPEC_FILE).write_text(spec_text[:20])  # truncated
    with pytest.raises(ParameterError, match="capture.json is damaged"):
        run(out, 3, resume=True)
    (out / SPEC_FILE).write_text(spec_text)
    with pytest.raises(ParameterError, match="different spec"):
        capture(CaptureSpec(seed=2), out, 3, resume=True, progress=False, task=fake_episode)
    assert {r["episode"] for r in manifest_lines(out)} == {0, 1}  # nothing of the other spec was added
    assert run(out, 3, resume=True).complete


def test_episode_file_of_another_spec_is_never_mixed_in(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    capture(CaptureSpec(seed=2), a, 1, progress=False, task=fake_episode)
    run(b, 1)
    os.replace(a / "episode_000000.h5", b / "episode_000001.h5")  # a file of another spec, no manifest line
    with pytest.raises(ParameterError, match="captured with another spec"):
        run(b, 2, resume=True)


def test_bad_counts_and_paths_refused_before_anything_is_written(tmp_path):
    for episodes, workers, name in ((10**12, 1, "--episodes"), (0, 1, "--episodes"), (2, 10**12, "--workers")):
        with pytest.raises(ParameterError, match=name):
            run(tmp_path / "x", episodes, workers=workers)
    (tmp_path / "file").write_text("")
    with pytest.raises(ParameterError, match="--out .* is a file"):
        run(tmp_path / "file", 1)
    with pytest.raises(ParameterError, match="lies under the file"):
        run(tmp_path / "file" / "sub", 1)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
