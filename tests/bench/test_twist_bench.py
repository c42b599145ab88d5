"""The twisting bench scenarios (issue 22): T1 pure torsion is exact at any n and step once settled (twist
springs in series); T2, the strip rolled edge-on, converges to w L^4 / (8 E I_strong) at second order in n;
the cost benchmark runs both models of one scene (no timing assertions)."""
from __future__ import annotations

import math

from bullet_dlo.bench import scenarios as bench
from bullet_dlo.bench.sweeps import twist_cost, twist_cost_model, work_precision_cases


def test_t1_pure_torsion_reads_gj_theta_over_l():
    for n, integrator, dt in ((10, "implicit_euler", 1 / 60), (20, "bdf2", 1e-3)):
        point = bench.t1(n, integrator, dt)
        assert point.stable and point.error < 1e-9, point
    # The implicit midpoint rule adds no numerical damping: after the roll the torsion mode decays only
    # physically (damping rate 5 1/s, internal damping 1 ms), so at 1 s a transient of ~1e-7 is left.
    # What the test holds it to: that remainder is a decaying transient, not a bias of the twist springs.
    early, late = (bench.t1(40, "implicit_midpoint", 1 / 240, duration=d) for d in (1.0, 2.0))
    assert early.stable and late.stable and early.error < 1e-6, early
    assert late.error < 0.5 * early.error, (early, late)


def test_t2_strip_edge_on_converges_at_second_order():
    errors = {n: bench.t2(n, "implicit_euler", 1 / 240).error for n in (10, 20, 40)}
    assert errors[20] < 0.005 and errors[40] < 0.0015
    for coarse, fine in ((10, 20), (20, 40)):
        order = math.log(errors[coarse] / errors[fine]) / math.log((fine - 1) / (coarse - 1))
        assert 1.8 < order < 2.2, (errors, order)


def test_twisting_scenarios_run_the_implicit_core_only():
    cases = work_precision_cases(scenarios=bench.TWIST_SCENARIOS, n_masses=(10,), engines=("core", "bullet"),
                                 quick=True)
    assert cases and {c.engine for c in cases} == {"core"}
    # Gauss-Legendre runs twist with its staggered sub-step; the explicit methods have no twist
    assert {c.integrator for c in cases} == {"implicit_euler", "bdf2", "implicit_midpoint", "gauss_legendre"}


def test_twist_cost_compares_the_same_scene_with_and_without_frame():
    assert twist_cost_model(10, True).spec.twist_enabled and not twist_cost_model(10, False).spec.twist_enabled
    rows = twist_cost(n_masses=(6,), integrators=("implicit_euler",), sim_time=0.02, repeats=2)
    assert len(rows) == 1 and rows[0]["ratio"] > 0 and rows[0]["round_min"] <= rows[0]["round"] <= rows[0]["round_max"]
