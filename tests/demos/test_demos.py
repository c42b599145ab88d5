"""Every demo runs and writes its outputs into the folder it prints."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


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


def test_render_demo_quick(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "render_demo.py"), "--quick", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert str(tmp_path.resolve()) in res.stdout
    for name in ("scene.mp4", "side_by_side.mp4", "forces.png", "still.png", "render.json", "frame_times.json"):
        assert (tmp_path / name).stat().st_size > 100, name


def test_cli_render(tmp_path):
    from bullet_dlo.cli.main import main

    scene = tmp_path / "s.yaml"
    scene.write_text("""
cable: {preset: lv2017, n_masses: 8}
layout: {start: [0, 0, 0.3], direction: [1, 0, 0]}
ends: {first: clamped, last: free}
dt: 0.004166666666666667
duration: 0.5
""")
    out = tmp_path / "r"
    assert main(["render", str(scene), "--out", str(out), "--width", "160", "--height", "120", "--fps", "20",
                 "--renderer", "tiny", "--quiet"]) == 0
    import json

    summary = json.loads((out / "render.json").read_text())
    assert summary["renderer"] == "tiny" and summary["codec"] == "h264"
    assert summary["decoded"]["frames"] == 11 and summary["decoded"]["width"] == 160
