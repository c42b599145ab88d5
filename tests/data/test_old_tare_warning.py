"""Issue 27, item 4: episodes recorded before payload compensation whose grippers tilted are named by
``dataset summary`` (their wrist forces hold the hand's weight seen from a turned sensor); compensated
episodes and untilted ones are not."""
from __future__ import annotations

import json

from old_tare_episode import old_tare_episode

from bullet_dlo.cli.main import main
from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.data import Dataset
from bullet_dlo.data.capture import capture


def test_summary_names_old_tare_episodes_whose_grippers_tilted(tmp_path, capsys):
    out = tmp_path / "ds"
    capture(CaptureSpec(seed=1), out, 4, progress=False, task=old_tare_episode)
    assert Dataset(out).old_tare_episodes() == [2]  # old tare and 0.5 rad; not 0 (compensated), 1, 3 (< 0.01 rad)
    summary = tmp_path / "summary.json"
    main(["dataset", "summary", str(out), "--json", str(summary)])
    printed = capsys.readouterr().out
    assert "WARNING: 1 of them (episodes 2) were recorded before payload compensation" in printed
    assert json.loads(summary.read_text())["old_tare_tilted"] == [2]


def test_summary_names_joint_reaction_episodes_whose_grippers_turned_fast(tmp_path, capsys):
    """Issue 27, the turning error: episodes whose wrist forces came from Bullet's joint reaction (no
    ``sensor_transmitted``) and whose grippers turned faster than 0.1 rad/s are named (0 and 2: 1.25 rad/s);
    a slow one (3: 0.0125 rad/s), an unturned one (1) and one with the Newton-Euler wrench (4) are not."""
    out = tmp_path / "ds"
    capture(CaptureSpec(seed=1), out, 5, progress=False, task=old_tare_episode)
    assert Dataset(out).joint_reaction_episodes() == [0, 2]
    summary = tmp_path / "summary.json"
    main(["dataset", "summary", str(out), "--json", str(summary)])
    printed = capsys.readouterr().out
    assert "WARNING: 2 of them (episodes 0, 2) took their wrist forces from Bullet's joint reaction" in printed
    assert json.loads(summary.read_text())["joint_reaction_turned"] == [0, 2]
