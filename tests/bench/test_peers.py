"""Peers (PyElastica, MuJoCo, Newton) on the cantilever: a true clamp (each converges at its own order in n
on S1, so the old whole-first-element clamp, an error of about -2/n, cannot come back), MuJoCo's
warnings captured, and nothing left behind. No timings are asserted."""
from __future__ import annotations

import json
import os

import pytest

from bullet_dlo.analysis.closed_forms import cantilever_deflection
from bullet_dlo.bench.peers import (available, convergence_order, newton_options, peer_cases, run_mujoco, run_newton,
                                    run_pyelastica)
from bullet_dlo.bench.scenarios import s1_spec
from bullet_dlo.cli.main import main

HAVE = available()
needs_mujoco = pytest.mark.skipif(not HAVE["mujoco"], reason="MuJoCo is not installed (pip install '.[test]')")
needs_pyelastica = pytest.mark.skipif(not HAVE["pyelastica"],
                                      reason="PyElastica is not installed (pip install '.[test]')")
needs_newton = pytest.mark.skipif(not HAVE["newton"],
                                  reason="Newton is not installed (pip install '.[peers]'; the test extra leaves it out)")

SECOND_ORDER = (3.2, 5.0)
"""Band of error(n) / error(2n) accepted as second order (4 exactly; order 1.7-2.3)."""


def _s1_errors(run, n_masses):
    errors = []
    for n in n_masses:
        spec = s1_spec(n)
        res = run(spec)
        assert res.stable, res.note
        errors.append(res.tip_deflection / cantilever_deflection(spec) - 1.0)
    return errors


def _assert_second_order(errors, n_masses):
    ratios = [errors[i] / errors[i + 1] for i in range(len(errors) - 1)]
    assert all(SECOND_ORDER[0] < r < SECOND_ORDER[1] for r in ratios), (errors, ratios)
    assert all(1.7 < p < 2.3 for p in convergence_order(errors, n_masses))
    # a clamp one element in gives about -2/n: first order, negative, -10 % at n = 20
    assert all(e > 0 for e in errors) and abs(errors[1]) < 0.01


@needs_mujoco
def test_mujoco_converges_at_second_order_on_s1(tmp_path, monkeypatch):
    """MuJoCo (discrete, 1 ms), clamped by its pinned stub behind x = 0: S1 error ~ n^-2 (n = 10, 20, 40)."""
    monkeypatch.chdir(tmp_path)
    n_masses = (10, 20, 40)
    errors = _s1_errors(lambda spec: run_mujoco(spec, 1e-3, "static", 1.0), n_masses)
    _assert_second_order(errors, n_masses)
    assert os.listdir(tmp_path) == []


@needs_mujoco
def test_mujoco_chain_is_the_exact_discrete_chain_on_s1(tmp_path, monkeypatch):
    """MuJoCo's joint chain (ball joints with stiffness 2 EI / l at the clamp, EI / l inside; ``discrete`` at
    1/60 s), clamped at x = 0: its tip deflection is the discrete chain's exact (1 + 1/(n - 1)^2) w L^4 / (8 EI)
    within 1e-5 of w L^4 / (8 EI) (n = 8, 12, 20), second order in n; a chain clamped one segment in, or with
    E I / l at the clamp, would be off by 10-50 % at these n."""
    monkeypatch.chdir(tmp_path)
    n_masses = (8, 12, 20)
    errors = _s1_errors(lambda spec: run_mujoco(spec, 1 / 60, "static", 1.0, integrator="discrete chain"), n_masses)
    for n, e in zip(n_masses, errors):
        assert abs(e - _newton_chain_error(n)) < 1e-5, (n, e)
    assert all(1.7 < p < 2.3 for p in convergence_order(errors, [n - 1 for n in n_masses]))
    assert os.listdir(tmp_path) == []


@needs_pyelastica
def test_pyelastica_converges_at_second_order_on_s1():
    """PyElastica (PositionVerlet, 0.5 us), clamped by FixedConstraint on its stub: S1 error ~ n^-2
    (n = 8, 16; 100 000 steps each)."""
    n_masses = (8, 16)
    errors = _s1_errors(lambda spec: run_pyelastica(spec, 5e-7, "static", 0.05), n_masses)
    _assert_second_order(errors, n_masses)


def _newton_chain_error(n: int) -> float:
    """Relative S1 error of Newton's discrete rod, solved exactly: n - 1 rigid segments of length l with
    their weight at their centres, rotational springs EI / l at the inner nodes and 2 EI / l at the
    clamp (half the dual length): the tip deflection is (1 + 1/(n-1)^2) w L^4 / (8 EI)."""
    segments = n - 1
    l = 1.0 / segments  # L = 1, w = 1, EI = 1
    angle = tip = 0.0
    for j in range(1, segments + 1):
        moment = l * l * sum(k - j + 0.5 for k in range(j, segments + 1))
        angle += moment * l / (2.0 if j == 1 else 1.0)
        tip += l * angle
    return tip / 0.125 - 1.0


def test_newton_chain_closed_form():
    """The exact discrete-chain error used below is 1 / (n - 1)^2 (second order in the segment count)."""
    for n in (4, 8, 16):
        assert _newton_chain_error(n) == pytest.approx(1.0 / (n - 1) ** 2, rel=1e-9)


def test_newton_options_parse_and_refuse():
    assert newton_options("VBD10") == (10, 1.0)
    assert newton_options("VBD20 shear x0.03") == (20, 0.03)
    with pytest.raises(ValueError, match="VBD"):
        newton_options("XPBD10")


@needs_newton
def test_newton_converges_at_its_own_order_on_s1():
    """Newton (add_rod + SolverVBD, 10 sweeps, stretch and shear at 0.03 of the material's, 40 us),
    clamped by its kinematic stub behind x = 0: S1 error ~ (n - 1)^-2, as its discrete chain solved
    exactly (n = 4, 8: +11.1 %, +2.0 %) plus the shear compliance (+0.43 %); a whole kinematic first
    segment (Newton's examples' root) would clamp it one element in: about -2/n."""
    n_masses = (4, 8)
    errors = _s1_errors(lambda spec: run_newton(spec, 4e-5, "static", 0.044, integrator="VBD10 shear x0.03"),
                        n_masses)
    assert all(e > 0 for e in errors), errors
    orders = convergence_order(errors, [n - 1 for n in n_masses])
    assert all(1.7 < p < 2.3 for p in orders), (errors, orders)
    shear = 1.3e-4 / 0.03
    for n, e in zip(n_masses, errors):
        assert abs(e - (_newton_chain_error(n) + shear)) < 0.006, (n, e)


@needs_newton
def test_newton_refuses_bad_settings():
    from bullet_dlo.bench.peer_newton import NewtonRod

    with pytest.raises(ValueError, match="iterations"):
        NewtonRod(s1_spec(5), 1e-4, iterations=0)
    with pytest.raises(ValueError, match="shear_scale"):
        NewtonRod(s1_spec(5), 1e-4, shear_scale=2.0)


def test_newton_sweep_is_as_wide_as_the_others():
    """Newton's sweep covers S1 and S2, n up to 20 and dt down to 1e-5 s; absent, it has no cases."""
    cases = peer_cases({"newton": True})
    assert {c.scenario for c in cases} == {"S1", "S2"}
    assert max(c.n for c in cases) >= 20 and min(c.dt for c in cases) <= 1e-5
    assert peer_cases({"newton": False}) == []


@needs_mujoco
def test_mujoco_warnings_are_captured_not_printed_nor_logged(tmp_path, monkeypatch, capfd):
    """RK4 at 0.1 ms blows up the stiff n = 20 rod: MuJoCo warns; the warning lands in the result only."""
    import mujoco

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


@needs_mujoco
def test_mujoco_refuses_integrators_without_flex_elasticity():
    with pytest.raises(ValueError, match="discrete"):
        run_mujoco(s1_spec(10), 1e-3, "static", 0.01, integrator="implicitfast")


@needs_mujoco
@needs_pyelastica
def test_peers_quick(tmp_path, monkeypatch):
    """``bench peers --quick`` from an empty working directory: both peers run the same cantilever,
    MuJoCo reaches 1 % on S1 and gets an interleaved CPU-time ratio with its range and the load,
    warnings are counted into the output folder, and the working directory stays empty."""
    cwd, out = tmp_path / "cwd", tmp_path / "out"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    assert main(["bench", "peers", "--quick", "--quiet", "--out", str(out)]) == 0
    assert os.listdir(cwd) == []
    data = json.loads((out / "peers.json").read_text())
    points = data["points"]
    assert {p["peer"] for p in points} == {"pyelastica", "mujoco"} | ({"newton"} if HAVE["newton"] else set())
    assert {p["scenario"] for p in points} == {"S1", "S2"}
    s1 = [p for p in points if p["scenario"] == "S1" and p["stable"] and p["integrator"] != "RK4"
          and p["peer"] != "newton"]
    assert s1 and all(0.0 < p["signed_error"] < 0.02 for p in s1)  # a true clamp: +1.3 % at n = 10, not -21 %
    newton = [p["signed_error"] for p in points if p["peer"] == "newton"]
    if HAVE["newton"]:  # n = 4, 8: second order in the segment count, (7 / 3)^2 = 5.4
        assert len(newton) == 2 and all(e > 0 for e in newton) and 4.3 < newton[0] / newton[1] < 6.5
    timing = data["timing"]["mujoco/S1"]
    assert timing["ratio_min"] <= timing["ratio_median"] <= timing["ratio_max"] and timing["reps"] >= 3
    assert len(data["load_start"]) == 3 and data["versions"]["mujoco"]
    assert data["ours"]["S1"]["error"] <= 0.01 and data["ours"]["S2"]["error"] <= 0.01
    log = (out / "peers_warnings.log").read_text().splitlines()
    assert len(log) == data["warnings"] == sum(p["warnings"] for p in points) > 0  # MuJoCo RK4 at n = 20 blows up
    assert all(p["stable"] is False for p in points if p["warnings"])
