"""The material frame (issue 22) against closed forms: sections, gradients, pure torsion, the anisotropic
cantilever strip, twist damping, and the opt-in (a round cable without twist has no frame at all)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.forces import clamp_torque, internal_energy, internal_forces
from bullet_dlo.core.kernels.twist import update_frames
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec, ParameterError
from bullet_dlo.core.stability import twist_frequency
from bullet_dlo.core.statics import solve_static

STRIP = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e11, section="rectangle", width=0.01,
                  thickness=0.001)


# ----- sections and the spec ---------------------------------------------------------------------
def test_section_constants():
    d = 0.004
    round_ = CableSpec.lv2017()
    assert round_.second_moments == (math.pi * d**4 / 64,) * 2
    assert round_.torsion_constant == pytest.approx(math.pi * d**4 / 32, rel=1e-15)
    assert round_.effective_shear_modulus == pytest.approx(126e6 / 2.6)
    tube = round_.with_(section="tube", inner_diameter=0.003)
    assert tube.area == pytest.approx(math.pi * (d**2 - 0.003**2) / 4)
    assert tube.torsion_constant == pytest.approx(math.pi * (d**4 - 0.003**4) / 32)
    b, h = 0.01, 0.001
    assert STRIP.second_moments == pytest.approx((b * h**3 / 12, h * b**3 / 12))
    # thin strip: J = b h^3 / 3 (1 - 0.63 h/b) to within the (h/b)^5 term
    assert STRIP.torsion_constant == pytest.approx(b * h**3 / 3 * (1 - 0.63 * h / b), rel=1e-5)
    square = STRIP.with_(width=h)
    assert square.torsion_constant == pytest.approx(0.1406 * h**4, rel=2e-3)  # the series solution
    assert STRIP.area == b * h and STRIP.twist_enabled and not round_.twist_enabled


def test_section_validation_and_round_trip():
    with pytest.raises(ParameterError, match="section"):
        CableSpec.lv2017(section="hexagon")
    with pytest.raises(ParameterError, match="inner_diameter"):
        CableSpec.lv2017(section="tube", inner_diameter=0.004)
    with pytest.raises(ParameterError, match="width"):
        CableSpec.lv2017(section="rectangle", thickness=0.001)
    with pytest.raises(ParameterError, match="rectangle only"):
        CableSpec.lv2017(width=0.01)
    with pytest.raises(ParameterError, match="twist"):
        CableSpec.lv2017(twist="yes")
    old = CableSpec.lv2017()
    assert set(old.to_dict()) == {"length", "diameter", "mass", "youngs_modulus", "n_masses", "damping",
                                  "damping_rate", "internal_damping", "dynamic_friction", "static_friction",
                                  "poisson_ratio", "discretisation"}  # old specs' dicts unchanged but for the rename friction -> dynamic_friction
    for spec in (old, old.with_(twist=True), old.with_(section="tube", inner_diameter=0.001), STRIP):
        assert CableSpec.from_dict(spec.to_dict()) == spec


def test_round_cable_without_twist_has_no_frame():
    model = CableModel.straight(CableSpec.lv2017())
    assert model.arrays.tw.k_twist.size == 0 and model.holder_plan().normal.shape[0] == 0


def test_a_clamp_rolled_on_a_cable_without_a_frame_is_reported():
    """A round cable without twist cannot feel its clamp's roll about its axis: the torque about the axis stays 0.
    The core API leaves the model as given (scene files turn the frame on), so the result says so; a swing of the
    same clamp (no roll) and the same roll with a frame are not reported. Before, nothing was said."""
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.02, youngs_modulus=2e9, n_masses=8)
    roll = Move("last", rotation=(math.pi / 2, 0, 0), duration=0.2)  # about x, the cable's axis
    res = simulate(CableModel.straight(spec, gravity=(0, 0, 0), motion=[roll]), "bdf2", 1e-3, 0.3)
    assert np.abs(res.end_moments[:, 0]).max() == 0.0
    assert any("last clamp rolls 90 deg about the cable's axis" in w and "twist" in w for w in res.warnings)
    swing = Move("last", rotation=(0, math.pi / 8, 0), duration=0.2)
    assert not any("rolls" in w for w in simulate(CableModel.straight(spec, gravity=(0, 0, 0), motion=[swing]),
                                                   "bdf2", 1e-3, 0.3).warnings)
    framed = CableModel.straight(spec.with_(twist=True), gravity=(0, 0, 0), motion=[roll])
    res = simulate(framed, "bdf2", 1e-3, 0.3)
    assert not any("rolls" in w for w in res.warnings)
    assert abs(res.end_moments[-1, 0]) > 0.0


# ----- gradients --------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", [CableSpec.lv2017(n_masses=7, twist=True), STRIP.with_(n_masses=7)],
                         ids=["round", "strip"])
def test_forces_and_clamp_moments_are_energy_gradients(spec):
    """Forces -dE/dx and the clamp moment -dE/d(rotation) by central differences, at a bent, twisted state
    (frames transported to it: the state where the DER gradients are exact)."""
    model = CableModel.straight(spec, ends=("clamped", "clamped"), roll=(0.3, 1.1), gravity=(0, 0, 0))
    m, x0 = model.kernel_arrays(), model.initial_state().x
    dirs = model.holder_plan().start_dir
    internal_energy(m, x0, dirs)
    rng = np.random.default_rng(1)
    m.tw.theta[:] += 0.2 * rng.standard_normal(m.tw.theta.shape)
    x = x0 + 0.01 * rng.standard_normal(x0.shape)
    update_frames(m, x, dirs)
    f = np.zeros_like(x)
    internal_forces(m, x, dirs, f)
    fd = np.zeros_like(x)
    eps = 1e-7
    for i in range(x.shape[0]):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += eps
            xm[i, j] -= eps
            fd[i, j] = -(internal_energy(m, xp, dirs) - internal_energy(m, xm, dirs)) / (2 * eps)
    assert np.abs(f - fd).max() <= 1e-6 * np.abs(fd).max()
    for end in (0, 1):
        tau = clamp_torque(m, x, np.zeros_like(x), dirs, end)
        tau_fd = np.zeros(3)
        for j in range(3):
            e = []
            for sign in (1, -1):
                turn = Rotation.from_rotvec(sign * 1e-7 * np.eye(3)[j])
                d2, c_old = dirs.copy(), m.tw.clamp[end].copy()
                d2[end] = turn.apply(dirs[end])
                m.tw.clamp[end] = turn.apply(c_old)
                e.append(internal_energy(m, x, d2))
                m.tw.clamp[end] = c_old
            tau_fd[j] = -(e[0] - e[1]) / 2e-7
        assert np.abs(tau - tau_fd).max() <= 1e-5 * np.abs(tau_fd).max()



def test_scalar_node_kernels_agree_with_the_node_geometry_and_a_rotation():
    """The per-node kernels the implicit step runs in scalars (no array views; issue 22 item 6) give the node
    geometry's twist and curvature binormal (``geometry_twist``: its very bits), and the scalar parallel transport
    is the minimal rotation taking the old tangent to the new one (scipy's rotation about t1 x t2 by their angle)."""
    from bullet_dlo.core.kernels.twist import (_transport, _transport_s, edge_frame, geometry_twist, node_geometry,
                                               node_twist, twist_of_frames)
    model = CableModel.straight(STRIP.with_(n_masses=9), ends=("clamped", "clamped"), roll=(0.3, 1.1),
                                gravity=(0, 0, 0))
    m, x0 = model.kernel_arrays(), model.initial_state().x
    dirs = model.holder_plan().start_dir
    internal_energy(m, x0, dirs)  # builds the frame
    rng = np.random.default_rng(3)
    m.tw.theta[:] += 0.3 * rng.standard_normal(m.tw.theta.shape)
    x = x0 + 0.01 * rng.standard_normal(x0.shape)
    update_frames(m, x, dirs)
    x = x + 0.003 * rng.standard_normal(x0.shape)  # frames transported within the evaluation, as in a Newton step
    tw = m.tw
    g = np.empty((12, 3))
    fb = edge_frame(x, dirs, tw.theta, tw.ref, tw.tan, tw.clamp, -1)
    n = x.shape[0]
    for i in range(n):
        fa, fb = fb, edge_frame(x, dirs, tw.theta, tw.ref, tw.tan, tw.clamp, i)
        twist, la, lb, *kb = node_twist(x, dirs, tw.theta, tw.ref, tw.tan, tw.clamp, tw.mref, i)
        assert (twist, la, lb, *kb) == twist_of_frames(fa, fb, tw.mref[i])
        ref_twist, ref_la, ref_lb = node_geometry(x, dirs, tw.theta, tw.ref, tw.tan, tw.clamp, tw.mref, i, g)[:3]
        assert twist == pytest.approx(ref_twist, abs=1e-14) and (la, lb) == (ref_la, ref_lb)
        assert np.array_equal(kb, g[9])
        # the twist energy, forces and clamp rates take node_geometry's bits from the frames alone
        assert geometry_twist(fa, fb, tw.mref[i]) == (ref_twist, ref_la, ref_lb, *g[9])
        assert la == (1.0 if i == 0 else pytest.approx(np.linalg.norm(x[i] - x[i - 1]), rel=1e-15))
        # the edge frame: unit tangent along the edge, unit director normal to it
        t, r = np.array(fb[1:4]), np.array(fb[4:7])
        assert abs(t @ r) < 1e-15 and np.linalg.norm(r) == pytest.approx(1.0, abs=1e-15)
    for _ in range(20):
        t1, t2 = (v / np.linalg.norm(v) for v in rng.standard_normal((2, 3)))
        u = np.cross(t1, rng.standard_normal(3))
        u /= np.linalg.norm(u)
        out = np.empty(3)
        _transport(u, t1, t2, out)
        assert np.array_equal(out, _transport_s(*u, *t1, *t2))
        axis = np.cross(t1, t2)
        turn = Rotation.from_rotvec(axis / np.linalg.norm(axis) * math.atan2(np.linalg.norm(axis), t1 @ t2))
        assert np.abs(out - turn.apply(u)).max() < 1e-14

# ----- pure torsion -------------------------------------------------------------------------------
@pytest.mark.parametrize("ends", ["clamped", "fork"])
@pytest.mark.parametrize("n", [3, 5, 10, 40])
def test_pure_torsion_static_is_exact_at_every_n(n, ends):
    """Clamped-clamped (or fork-fork) straight cable, the last end turned by theta about the axis: torque
    G J theta / L at both ends, about the axis only. The twist springs in series (two half-Voronoi end springs
    2 G J / l0, n - 2 interior G J / l0) are exact for any n: the discrete error is round-off (no order to measure)."""
    spec = CableSpec.lv2017(n_masses=n, twist=True)
    theta = 0.7
    model = CableModel.straight(spec, ends=(ends, ends), roll=(0.0, theta), gravity=(0, 0, 0))
    st = model.initial_state()
    dirs = model.holder_plan().start_dir
    expected = spec.torsional_rigidity * theta / spec.length
    axis = dirs[0]
    m = model.kernel_arrays()
    t0 = clamp_torque(m, st.x, st.v, dirs, 0)
    t1 = clamp_torque(m, st.x, st.v, dirs, 1)
    assert t0 @ axis == pytest.approx(expected, rel=1e-12)
    assert t1 @ axis == pytest.approx(-expected, rel=1e-12)
    assert np.linalg.norm(np.cross(t0, axis)) < 1e-12 * expected
    assert internal_energy(m, st.x, dirs) == pytest.approx(0.5 * expected * theta, rel=1e-12)


@pytest.mark.parametrize("n", [11, 17])
def test_pure_torsion_under_the_paper_discretisation_has_its_clamp_convention(n):
    """``discretisation: paper`` gives a clamp the interior springs (its bending convention, G J / l0 for the twist
    too): n springs in series, so pure torsion reads G J theta / (L + l0), (n - 1)/n of the exact value
    (docs/concepts/model.md, "Two discretisations"; an independent check found the -5.9 % at n = 17)."""
    spec = CableSpec.lv2017(n_masses=n, twist=True, discretisation="paper")
    theta = 0.7
    model = CableModel.straight(spec, ends=("clamped", "clamped"), roll=(0.0, theta), gravity=(0, 0, 0))
    st = model.initial_state()
    dirs = model.holder_plan().start_dir
    l0 = spec.length / (n - 1)
    t0 = clamp_torque(model.kernel_arrays(), st.x, st.v, dirs, 0)
    assert t0 @ dirs[0] == pytest.approx(spec.torsional_rigidity * theta / (spec.length + l0), rel=1e-12)


@pytest.mark.parametrize("ends", ["clamped", "fork"])
@pytest.mark.parametrize("integrator", ["implicit_euler", "bdf2", "implicit_midpoint"])
def test_gripper_turned_about_the_cable_axis_feels_torsion(integrator, ends):
    """A clamp (or a fork: the roll held, the direction free) turned by 90 degrees about the cable axis in a run: the
    engine's end moments read G J (pi/2) / L about the axis at both ends (within 1 %; the cable stays straight)."""
    spec = CableSpec.lv2017(n_masses=11, twist=True, damping_rate=5.0, internal_damping=1e-3)
    model = CableModel.straight(spec, ends=(ends, ends), gravity=(0, 0, 0),
                                motion=[Move("last", rotation=(math.pi / 2, 0, 0), duration=0.4)])
    res = simulate(model, integrator, 1e-3, 0.8)
    assert res.stable
    expected = spec.torsional_rigidity * (math.pi / 2) / spec.length
    assert res.end_moments[0, 0] == pytest.approx(expected, rel=0.01)
    assert res.end_moments[1, 0] == pytest.approx(-expected, rel=0.01)
    assert np.allclose(res.x[-1], model.x0, atol=1e-9)


# ----- anisotropic bending: the cantilever strip ---------------------------------------------------
def _strip_tip_error(n: int, axis: int) -> float:
    """Relative error of the tip deflection of a clamped strip under a tip load along ``axis`` (1: y, in
    the width direction, stiff E I2; 2: z, through the thickness, weak E I1) against P L^3 / (3 E I)."""
    spec = STRIP.with_(n_masses=n)
    ei = spec.bending_rigidities[0 if axis == 2 else 1]
    model = CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), gravity=(0, 0, 0))
    load = 1e-3 * 3 * ei / spec.length**2  # deflection 1e-3 L: geometric nonlinearity ~1e-6
    f = np.zeros((n, 3))
    f[-1, axis] = load
    res = solve_static(model, f_ext=f)
    assert res.converged
    return res.x[-1, axis] / (load * spec.length**3 / (3 * ei)) - 1.0


def test_cantilever_strip_bends_with_each_axis_stiffness_at_second_order():
    errors = {n: (_strip_tip_error(n, 2), _strip_tip_error(n, 1)) for n in (5, 9, 17, 33)}
    for n, (weak, stiff) in errors.items():
        assert weak == pytest.approx(stiff, abs=1e-6)  # deflections in the ratio E I2 / E I1 = 100
    assert abs(errors[9][0]) < 0.01 and abs(errors[17][0]) < 0.0025
    for coarse, fine in ((5, 9), (9, 17), (17, 33)):
        order = math.log(errors[coarse][0] / errors[fine][0]) / math.log((fine - 1) / (coarse - 1))
        assert 1.95 < order < 2.05, order


def test_strip_rolled_edge_on_in_a_run_sags_with_the_stiff_axis():
    """A strip under gravity whose clamp rolls 90 degrees about the cable axis ends edge-on: the tip sag of
    the stiff axis, w L^4 / (8 E I2) (about 100x less than flat), and the frame follows the clamp."""
    spec = STRIP.with_(n_masses=17, damping_rate=20.0, internal_damping=1e-4)
    model = CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0),
                                motion=[Move("first", rotation=(math.pi / 2, 0, 0), start=0.05, duration=0.3)])
    res = simulate(model, "implicit_euler", 1e-3, 0.8)
    assert res.stable and res.newton_failures == 0
    w = spec.mass * 9.81 / spec.length
    sag = w * spec.length**4 / (8 * spec.bending_rigidities[1])
    assert -res.x[-1, -1, 2] == pytest.approx(sag, rel=0.03)
    assert res.final_state.twist.theta[-1] == pytest.approx(math.pi / 2, abs=2e-3)


# ----- damping and stability ------------------------------------------------------------------------
@pytest.mark.parametrize("n", [5, 20])
def test_twist_drag_has_the_meaning_of_damping_rate(n):
    """A free spinning cable (no clamps): every segment's spin decays as exp(-c t) at any n (implicit
    Euler's (1 + c h)^-k, within 1 %)."""
    c = 3.0
    spec = CableSpec.lv2017(n_masses=n, twist=True, damping_rate=c)
    model = CableModel.straight(spec, ends=("free", "free"), gravity=(0, 0, 0))
    state = model.initial_state()
    state.twist = model.twist_state()
    internal_energy(model.kernel_arrays(twist=state.twist), state.x, model.holder_plan().start_dir)  # build, spin
    state.twist.omega[:] = 10.0
    res = simulate(model, "implicit_euler", 1e-3, 0.5, state=state)
    assert res.stable
    assert np.allclose(res.final_state.twist.omega, 10.0 * math.exp(-c * 0.5), rtol=0.01)


def test_twist_mode_frequency():
    spec = CableSpec.lv2017(n_masses=11, twist=True)
    g, rho = spec.effective_shear_modulus, spec.density
    # round section: J = J_p, the torsion wave speed sqrt(G / rho); highest mode 2 c / l0
    assert twist_frequency(spec) == pytest.approx(2.0 * math.sqrt(g / rho) / spec.rest_length, rel=1e-12)


@pytest.mark.parametrize("roll", [(0.0, 3.5), (0.0, 2 * math.pi + 0.3), (1.0, -2.5), (0.0, float("nan"))])
def test_start_rolls_a_half_turn_or_more_apart_are_refused(roll):
    """The start state takes the shortest turn between the clamps' sections: rolls 3.5 rad apart started the
    cable twisted by 3.5 - 2 pi (the torque's sign flipped), 2 pi + 0.3 apart by 0.3 (4.6 % of the torque)."""
    with pytest.raises(ParameterError, match=r"roll: .* must be in \(-pi, pi\)"):
        CableModel.straight(CableSpec.lv2017(n_masses=5, twist=True), ends=("clamped", "clamped"), roll=roll)


@pytest.mark.parametrize("width, thickness, name", [(-0.01, 0.001, "width"), (0.01, -0.002, "thickness")])
def test_a_rectangle_side_below_zero_is_told_the_range_it_needs(width, thickness, name):
    """A rectangle needs both sides > 0: a negative side was told ">= 0", and 0 then failed again."""
    with pytest.raises(ParameterError, match=rf"^{name} must be a finite number > 0, got -"):
        CableSpec(length=0.3, diameter=0.004, mass=0.03, youngs_modulus=1e8, section="rectangle", width=width,
                  thickness=thickness)
