"""demos/routing_demo.py runs in its --quick form and writes its baselines (the pattern of test_demos.py)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.bullet


def test_routing_demo_quick(tmp_path):
    res = subprocess.run([sys.executable, str(ROOT / "demos" / "routing_demo.py"), "--quick", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert f"outputs written to {tmp_path.resolve()}" in res.stdout
    data = json.loads((tmp_path / "routing_baselines.json").read_text())
    assert set(data) == {"scripted", "random"}
    for policy in data.values():
        assert len(policy["episodes"]) == 2
        assert policy["success_rate"] == sum(e["success"] for e in policy["episodes"]) / 2
    assert data["scripted"]["success_rate"] == 1.0  # seeds 0 and 1: two-peg routes the scripted policy completes
    assert all(len(e["wraps_deg"]) == e["pegs"] for e in data["scripted"]["episodes"])
