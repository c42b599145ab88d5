"""Peers (PyElastica, MuJoCo) on the cantilever: their clamp bias, and nothing left behind."""
from __future__ import annotations

import json
import os

import mujoco
import pytest

from bullet_dlo.bench.peers import run_mujoco
from bullet_dlo.bench.scenarios import s1_spec
from bullet_dlo.cli.main import main


def test_mujoco_warnings_are_captured_not_printed_nor_logged(tmp_path, monkeypatch, capfd):
    """RK4 at 0.1 ms blows up the stiff n = 20 rod: MuJoCo warns; the warning lands in the result only."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    res = run_mujoco(s1_spec(20), 1e-4, "static", 0.01, integrator="RK4")
    assert not res.stable
    assert res.warnings and "unstable" in res.warnings[0]
    assert os.listdir(cwd) == []  # no MUJOCO_LOG.TXT
    out, err = capfd.readouterr()
    assert "WARNING" not in out + err
    assert mujoco.get_mju_user_warning() is None  # MuJoCo's own hook is back


def test_mujoco_static_deflection_shows_its_clamp_bias(tmp_path, monkeypatch):
    """MuJoCo clamps its whole first edge: the tip deflection comes out about 2/n short."""
    monkeypatch.chdir(tmp_path)
    spec = s1_spec(10)
    res = run_mujoco(spec, 1e-3, "static", 0.1)
    from bullet_dlo.analysis.closed_forms import cantilever_deflection

    assert res.stable and res.warnings == []
    assert res.tip_deflection / cantilever_deflection(spec) - 1 == pytest.approx(-0.21, abs=0.03)
    assert os.listdir(tmp_path) == []


def test_peers_quick(tmp_path, monkeypatch):
    """``bench peers --quick`` from an empty working directory: PyElastica and MuJoCo run the same
    cantilever, their whole-first-segment clamp shows as ~ -2/n, warnings are counted into the
    output folder, and the working directory stays empty."""
    cwd, out = tmp_path / "cwd", tmp_path / "out"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    assert main(["bench", "peers", "--quick", "--out", str(out)]) == 0
    assert os.listdir(cwd) == []
    data = json.loads((out / "peers.json").read_text())
    points = data["points"]
    assert {p["peer"] for p in points} == {"pyelastica", "mujoco"}
    assert {p["scenario"] for p in points} == {"S1", "S2"}
    s1 = [p for p in points if p["scenario"] == "S1" and p["stable"] and p["n"] == 10]
    assert s1 and all(0.15 < p["error"] < 0.25 for p in s1)  # clamp bias: 2/n of the deflection
    assert data["ours"]["S1"]["error"] <= 0.01 and data["ours"]["S2"]["error"] <= 0.01
    log = (out / "peers_warnings.log").read_text().splitlines()
    assert len(log) == data["warnings"] == sum(p["warnings"] for p in points) > 0  # MuJoCo RK4 at n = 20 blows up
    assert all(p["stable"] is False for p in points if p["warnings"])
