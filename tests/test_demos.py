"""Every demo runs and writes its outputs into the folder it prints."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_main_demo_quick(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "main_demo.py"), "--quick", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert str(tmp_path.resolve()) in res.stdout
    for name in ("end_forces.png", "convergence.png", "summary.json"):
        assert (tmp_path / name).stat().st_size > 1000
    assert "implicit_euler" in res.stdout


def test_dual_arm_demo_quick(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "dual_arm_grasp.py"), "--quick", "--robots", "kuka",
                          "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert str(tmp_path.resolve()) in res.stdout
    assert (tmp_path / "kuka_forces.png").stat().st_size > 1000
    import json

    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary[0]["stable"] and abs(summary[0]["vertical_balance_error"]) < 0.01


def test_bullet_overhead_demo_runs(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "bullet_overhead.py"), "--masses", "10",
                          "--integrators", "implicit_euler", "--repeats", "1", "--block", "20", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "bullet_overhead.json").is_file()
