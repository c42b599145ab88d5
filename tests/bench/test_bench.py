"""Benchmarks in --quick mode: the shape of the results (no speed assertions)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from bullet_dlo.analysis.resolve import resolve
from bullet_dlo.bench import scenarios as bench
from bullet_dlo.cli.main import main
from bullet_dlo.config.scene import Scene
from bullet_dlo.sim import resolve_problem


def test_work_precision_quick(tmp_path):
    assert main(["bench", "work-precision", "--quick", "--out", str(tmp_path)]) == 0
    rows = list(csv.DictReader(open(tmp_path / "work_precision.csv")))
    methods = {r["integrator"] for r in rows}
    assert methods == {"symplectic_euler", "rk4", "implicit_euler", "bdf2", "implicit_midpoint", "gauss_legendre"}
    assert {r["scenario"] for r in rows} == set(bench.SCENARIOS)
    assert {r["engine"] for r in rows} == {"core", "bullet"}
    unstable = [r for r in rows if r["stable"] == "False"]
    assert unstable and all(r["integrator"] in ("symplectic_euler", "rk4") for r in unstable)  # 1.2x their limit
    assert all(float(r["error"]) < 0.05 for r in rows if r["stable"] == "True" and r["scenario"] in ("S1", "S4"))
    assert (tmp_path / "work_precision.png").stat().st_size > 10_000
    summary = json.loads((tmp_path / "work_precision_summary.json").read_text())
    # second-order energy-conserving midpoint keeps S2's oscillation, implicit Euler damps it away
    assert summary["S2_amplitude/implicit_midpoint"] > 0.9 > summary["S2_amplitude/implicit_euler"]
    assert summary["S2_amplitude/gauss_legendre"] > 0.9  # symplectic and A-stable: no numerical damping either


def test_resolve_meets_its_tolerance_and_picks_few_masses():
    scene = resolve_problem(Scene(cable=bench.s1_spec(10), ends=("clamped", "free"), duration=1.0, name="S1"))
    r = resolve(scene, 0.03, "shape")
    check = bench.s1(r.n_masses, r.integrator, r.dt)
    assert check.error <= 0.03
    assert r.n_masses < 50 and r.predicted_error <= 0.03
    with pytest.raises(Exception, match="tol"):
        resolve(scene, -1.0)


def test_scene_auto_resolution(tmp_path):
    path = tmp_path / "auto.yaml"
    path.write_text("""
cable: {preset: lv2017, n_masses: auto, damping: 0.01}
ends: {first: clamped, last: clamped}
motion: [{end: last, displacement: [0, 0, 0.005], start: 0.2, duration: 0.1}]
dt: auto
duration: 0.6
initial: static
tolerance: {value: 0.05, target: forces}
""")
    out = tmp_path / "o.json"
    assert main(["simulate", str(path), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["stable"] and 5 <= data["n_masses"] < 50
    res = tmp_path / "r.json"
    assert main(["resolve", str(path), "--tol", "0.05", "--target", "forces", "--json", str(res)]) == 0
    r = json.loads(res.read_text())
    for key in ("n_masses", "dt", "integrator", "predicted_error", "wall_time_per_sim_s"):
        assert key in r
    assert r["n_masses"] == data["n_masses"] and r["dt"] == data["dt"]


def test_stability_quick(tmp_path):
    assert main(["bench", "stability", "--quick", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "stability.json").read_text())
    for r in rows:
        if r["predicted"] is not None:
            assert r["measured"] == pytest.approx(r["predicted"], rel=0.05)  # bisection agrees with theory
        else:
            assert r["measured"] is not None  # implicit: stable at 1 kHz and 60 Hz


def test_scaling_quick_with_progress_on_stderr_and_quiet(tmp_path, capsys):
    args = ["bench", "scaling", "--quick", "--out", str(tmp_path)]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "scaling" in captured.err and "cable" in captured.err  # the bar, on stderr
    assert "cost ~ n^" in captured.out
    result = json.loads((tmp_path / "scaling.json").read_text())
    # The exponent is the benchmark's least-squares fit of its own rows (a timing, so no bound on the
    # machine's speed here: bench/scaling and docs/results/speed.md report it with the load).
    rows = result["rows"]
    assert len(rows) >= 2 and all(r["seconds_per_step"] > 0 for r in rows)
    fit = np.polyfit(np.log([r["n_masses"] for r in rows]), np.log([r["seconds_per_step"] for r in rows]), 1)[0]
    assert result["exponent"] == pytest.approx(fit, rel=1e-9)
    assert "cable lying on a table in Bullet, contact on" in captured.out and (tmp_path / "scaling.png").is_file()
    for row in result["coupled"]:  # the timed cables lay still on the ground at one radius (the model's contact)
        assert row["stable"] and row["lowest_node_over_radius"] == pytest.approx(1.0, abs=0.01)
        assert row["cost_min"] <= row["cost"] <= row["cost_max"] and 0.0 < row["bullet"] < row["cost"]
    assert main(args + ["--quiet"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "cost ~ n^" in captured.out
