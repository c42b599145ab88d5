"""Scene files and the bullet-dlo command line."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from bullet_dlo.cli.main import main
from bullet_dlo.config.scene import Scene
from bullet_dlo.sim import build
from bullet_dlo.core.validate import ParameterError

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "demos" / "scenes" / "lv_study.yaml"

ISSUE_SCENE = """
cable: {length: 0.3, diameter: 0.004, mass: 0.03, youngs_modulus: 126.0e6, n_masses: 10, damping: 0.01}
layout: {start: [0, 0, 0.5], direction: [1, 0, 0]}
ends: {first: clamped, last: clamped}
motion: [{end: last, displacement: [0, 0, 0.005], start: 0.5, duration: 0.1}]
gravity: [0, 0, -9.81]
integrator: implicit_euler
dt: 0.001
duration: 2.0
"""


def write(tmp_path, text, name="scene.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_simulate_writes_the_documented_json(tmp_path):
    scene = write(tmp_path, ISSUE_SCENE)
    out = tmp_path / "out.json"
    npz = tmp_path / "traj.npz"
    assert main(["simulate", str(scene), "--json", str(out), "--npz", str(npz)]) == 0
    data = json.loads(out.read_text())
    for key in ("stable", "time_to_instability", "critical_dt", "final_positions", "end_forces", "steps",
                "wall_time_s"):
        assert key in data
    assert data["stable"] is True and data["time_to_instability"] is None
    assert data["critical_dt"] is None  # implicit Euler: unconditionally stable
    assert data["steps"] == 2000
    assert np.array(data["final_positions"]).shape == (10, 3)
    first, last = np.array(data["end_forces"]["first"]), np.array(data["end_forces"]["last"])
    assert first[2] + last[2] == pytest.approx(-0.03 * 9.81, rel=2e-3)  # static again at t = 2 s
    traj = np.load(npz)
    assert traj["x"].shape[1:] == (10, 3) and traj["t"][-1] == pytest.approx(2.0)


def test_unstable_run_is_reported_not_raised(tmp_path, capsys):
    text = ISSUE_SCENE.replace("integrator: implicit_euler", "integrator: symplectic_euler")
    out = tmp_path / "out.json"
    assert main(["simulate", str(write(tmp_path, text)), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["stable"] is False
    assert 0 < data["time_to_instability"] < 2.0
    assert 2.0e-4 < data["critical_dt"] < 3.0e-4  # 1 ms is ~4x beyond symplectic Euler's limit
    assert data["end_forces"] == {"first": None, "last": None}
    assert "UNSTABLE" in capsys.readouterr().out


@pytest.mark.parametrize(
    "edit,needle",
    [
        (lambda d: d["cable"].update(length=-1), "cable.length must be in [0.001, 1000.0]"),
        (lambda d: d["cable"].update(n_masses=1), "cable.n_masses must be an integer in [2,"),
        (lambda d: d.update(dt=0), "dt: dt must be a finite number > 0"),
        (lambda d: d.update(dt=".nan"), "dt"),
        (lambda d: d.update(integrator="verlet"), "integrator must be one of"),
        (lambda d: d["ends"].update(first="glued"), "ends.first must be one of free, pinned, fork, clamped"),
        (lambda d: d.update(colour="red"), "unknown key(s) colour in scene"),
        (lambda d: d["layout"].update(direction=[0, 0, 0]), "layout.direction"),
        (lambda d: d["motion"][0].update(end="middle"), "motion: motion end must be 'first' or 'last'"),
        (lambda d: d["motion"][0].update(duration=-1), "motion duration"),
        (lambda d: d["cable"].update(youngs_modulus="stiff"), "youngs_modulus must be a number"),
        (lambda d: d.update(gravity=[0, 0]), "gravity"),
    ],
)
def test_invalid_scene_names_the_key_and_exits_2(tmp_path, capsys, edit, needle):
    data = yaml.safe_load(ISSUE_SCENE)
    edit(data)
    path = write(tmp_path, yaml.safe_dump(data))
    assert main(["simulate", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and needle in err and "\n" not in err


def test_missing_file_and_bad_yaml(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "nope.yaml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["simulate", str(write(tmp_path, "cable: [unclosed"))]) == 2
    assert "not valid YAML" in capsys.readouterr().err


def test_free_end_cannot_move():
    data = yaml.safe_load(ISSUE_SCENE)
    data["ends"]["last"] = "free"
    with pytest.raises(ParameterError, match="end 'last' is free"):
        Scene.from_dict(data)


def test_static_initial_state_and_preset():
    scene = Scene.from_dict({"cable": {"preset": "lv2017", "n_masses": 8}, "initial": "static",
                             "ends": {"first": "clamped", "last": "clamped"}, "duration": 0.05})
    sim = build(scene, "core")
    model, res = sim.model, sim.run()
    assert res.stable
    # starting from equilibrium, the cable barely moves
    assert np.max(np.abs(res.x[-1] - res.x[0])) < 1e-6


def test_stability_and_convergence_commands(tmp_path, capsys):
    out = tmp_path / "stab.json"
    assert main(["stability", str(STUDY), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["critical_dt"]["implicit_euler"] is None
    assert data["stable_at_dt"]["symplectic_euler"] is False
    assert main(["convergence", "--masses", "5", "10"]) == 0
    assert "| 10 |" in capsys.readouterr().out


def test_paper_table_small(tmp_path):
    md = tmp_path / "table.md"
    rc = main(["paper-table", "--moduli", "1002.6", "--masses", "6", "--steps", "5e-6", "--duration", "0.1",
               "--integrators", "explicit_euler", "symplectic_euler", "--markdown", str(md)])
    assert rc == 0
    text = md.read_text()
    assert "| 1002.6 | 6 | 5e-06 |" in text
    row = [line for line in text.splitlines() if line.startswith("| 1002.6")][0]
    assert "unstable@" in row.split("|")[6]  # explicit Euler, k_d = 0.01: unstable at 5 us
    assert row.split("|")[7].strip() == "stable"  # symplectic Euler is far inside its limit


def test_console_script_help():
    res = subprocess.run([sys.executable, "-m", "bullet_dlo.cli", "--help"], capture_output=True, text=True)
    assert res.returncode == 0
    for cmd in ("simulate", "stability", "paper-table", "convergence"):
        assert cmd in res.stdout
    res = subprocess.run([sys.executable, "-m", "bullet_dlo.cli", "simulate", "--help"], capture_output=True, text=True)
    assert "--json" in res.stdout and "--npz" in res.stdout and "--engine" in res.stdout
