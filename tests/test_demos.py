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
