"""Damping with an n-independent meaning (issue 12, item 1).

``damping_rate`` c [1/s]: drag -c m_i v_i; a free mass's velocity decays as exp(-c t), an
oscillating mode's amplitude as exp(-c t / 2), at any n. ``internal_damping`` tau [s]:
Kelvin-Voigt, mode k's amplitude decays as exp(-tau omega_k^2 t / 2) and rigid motion is not
damped. The paper's k_d makes the decay rate k_d n / (2M): it grows with n.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import cantilever_angular_frequency, cantilever_release
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.forces import (
    add_damping_jacobian,
    dissipation,
    force_jacobian,
    internal_damping_forces,
    jacobian_blocks_to_dense,
    total_forces,
)
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt
from bullet_dlo.core.statics import solve_static
from bullet_dlo.core.validate import ParameterError

NS = (10, 20, 40, 80)


def _bent(n=7, ends=("free", "free"), tau=0.01, seed=0):
    spec = CableSpec.lv2017(n_masses=n, internal_damping=tau)
    model = CableModel.straight(spec, ends=ends, gravity=(0.0, 0.0, 0.0))
    rng = np.random.default_rng(seed)
    x = model.x0 + 0.01 * rng.standard_normal(model.x0.shape)
    return model, x, rng


@pytest.mark.parametrize("ends", [("free", "free"), ("clamped", "clamped"), ("clamped", "free")])
def test_damping_forces_derive_from_the_dissipation_function_with_exact_jacobian(ends):
    model, x, rng = _bent(ends=ends)
    check_dampers(model.kernel_arrays(), x, rng.standard_normal(x.shape), model.holder_plan().start_dir)


def check_dampers(m, x, v, dirs) -> None:
    """The Kelvin-Voigt forces of kernel arrays ``m`` at positions x [m], velocities v [m/s] are -dR/dv of the
    dissipation function (central differences), and the damping Jacobian is their exact, symmetric, negative
    semi-definite velocity derivative (also used by tests/core/test_flat_section_damping.py)."""
    f = np.zeros_like(x)
    internal_damping_forces(m, x, v, dirs, f)
    grad = np.zeros_like(v)
    eps = 1e-6
    for i in range(v.shape[0]):
        for j in range(3):
            vp, vm = v.copy(), v.copy()
            vp[i, j] += eps
            vm[i, j] -= eps
            grad[i, j] = (dissipation(m, x, vp, dirs) - dissipation(m, x, vm, dirs)) / (2 * eps)
    assert np.allclose(f, -grad, rtol=0, atol=1e-7 * np.abs(f).max())
    jac = np.zeros((x.shape[0], 5, 3, 3))
    add_damping_jacobian(m, x, dirs, 1.0, jac)
    dense = jacobian_blocks_to_dense(jac)
    assert np.allclose(dense @ v.ravel(), f.ravel(), atol=1e-12 * np.abs(f).max())  # F linear in v: exact
    assert np.allclose(dense, dense.T, atol=1e-14 * np.abs(dense).max())
    assert np.all(np.linalg.eigvalsh(dense) <= 1e-12 * np.abs(dense).max())  # dissipative


def test_internal_damping_is_tau_times_stiffness_about_a_straight_cable():
    spec = CableSpec.lv2017(n_masses=8, internal_damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "free"), gravity=(0.0, 0.0, 0.0))
    dirs = model.holder_plan().start_dir
    c = np.zeros((8, 5, 3, 3))
    k = np.zeros((8, 5, 3, 3))
    add_damping_jacobian(model.kernel_arrays(), model.x0.copy(), dirs, 1.0, c)
    force_jacobian(model.kernel_arrays(), model.x0.copy(), dirs, False, k)
    assert np.allclose(c, 0.01 * k, atol=1e-12 * np.abs(k).max())


def test_translation_and_in_plane_rotation_feel_no_internal_damping():
    model, x, rng = _bent()
    x[:, 2] = 0.5  # bent in the horizontal plane
    m, dirs = model.kernel_arrays(), model.holder_plan().start_dir
    for omega in ([0.0, 0.0, 2.0], [0.0, 0.0, -0.7]):
        v = np.array([0.3, -0.1, 0.2]) + np.cross(np.array(omega), x)
        f = np.zeros_like(x)
        internal_damping_forces(m, x, v, dirs, f)
        assert np.abs(f).max() < 1e-12 and dissipation(m, x, v, dirs) < 1e-20


def _decay_rate(spec, dt=2e-3, duration=4.0):
    """Amplitude decay rate [1/s] of the released cantilever's tip (first mode), from its peaks."""
    model, start = cantilever_release(spec, 1e-3)
    res = simulate(model, "bdf2", dt, duration, state=start, record_every=1)
    a = np.abs(res.x[:, -1, 2] - model.x0[-1, 2])
    peaks = [i for i in range(1, len(a) - 1) if a[i] >= a[i - 1] and a[i] > a[i + 1]]
    return -np.polyfit(res.t[peaks], np.log(a[peaks]), 1)[0]


@pytest.mark.parametrize("n", NS)
def test_first_mode_decay_matches_closed_form_at_any_n(n):
    rate = _decay_rate(CableSpec.lv2017(n_masses=n, damping_rate=0.5))
    assert rate == pytest.approx(0.5 / 2, rel=0.02)  # amplitude decays at c / 2
    spec = CableSpec.lv2017(n_masses=n, internal_damping=0.02)
    w1 = cantilever_angular_frequency(spec)  # continuum omega_1
    assert _decay_rate(spec) == pytest.approx(0.02 * w1**2 / 2, rel=0.025)


def test_paper_damping_decay_grows_with_n():
    rates = [_decay_rate(CableSpec.lv2017(n_masses=n, damping=1e-3, discretisation="paper")) for n in (10, 80)]
    assert rates[1] / rates[0] == pytest.approx(8.0, rel=0.03)  # k_d n / (2M)


@pytest.mark.parametrize("n", NS)
def test_damped_linear_eigenvalues_match_closed_form(n):
    """Eigenvalues of M x'' + C x' + K x = 0 (clamped-free, no gravity): Re = -(c + tau w^2) / 2
    for every mode, and the first two bending modes' rates match the continuum closed form."""
    c, tau = 0.4, 2e-3
    spec = CableSpec.lv2017(n_masses=n, damping_rate=c, internal_damping=tau)
    model = CableModel.straight(spec, ends=("clamped", "free"), gravity=(0.0, 0.0, 0.0))
    dirs = model.holder_plan().start_dir
    kj = np.zeros((n, 5, 3, 3))
    cj = np.zeros((n, 5, 3, 3))
    force_jacobian(model.kernel_arrays(), model.x0.copy(), dirs, False, kj)
    add_damping_jacobian(model.kernel_arrays(), model.x0.copy(), dirs, 1.0, cj)
    free = slice(3, 3 * n)
    k = -jacobian_blocks_to_dense(kj)[free, free]
    cm = -jacobian_blocks_to_dense(cj)[free, free] + np.diag(np.repeat(spec.damping_coefficients()[1:], 3))
    minv = np.diag(1.0 / np.repeat(spec.point_masses()[1:], 3))
    size = k.shape[0]
    a = np.block([[np.zeros((size, size)), np.eye(size)], [-minv @ k, -minv @ cm]])
    lam = np.linalg.eigvals(a)
    osc = lam[lam.imag > 1e-6]
    w2 = np.abs(osc) ** 2  # |lambda|^2 = omega^2 for a damped oscillator
    assert np.allclose(-osc.real, (c + tau * w2) / 2, rtol=1e-6)
    bending = np.sort(np.sqrt(w2))[::2][:2]  # y and z modes come in pairs
    beta_l = np.array([1.8751041, 4.6940911])
    w_cont = beta_l**2 * math.sqrt(spec.bending_rigidity / spec.linear_density) / spec.length**2
    assert np.allclose(bending, w_cont, rtol=5.0 / (n - 1) ** 2)  # second order in l0: 5.5 % (mode 2) at n = 10
    rates = (c + tau * bending**2) / 2
    assert np.allclose(rates, (c + tau * w_cont**2) / 2, rtol=10.0 / (n - 1) ** 2)
    assert w_cont[0] == pytest.approx(cantilever_angular_frequency(spec), rel=1e-6)


def test_free_cable_keeps_momentum_and_spin_under_internal_damping():
    """Zero gravity, no holders: a straight cable spinning about an oblique axis and a cable bent
    in a plane spinning in that plane, both translating, with internal vibration: linear and
    angular momentum stay (implicit midpoint conserves both for these forces), the vibration decays."""
    spec = CableSpec.lv2017(n_masses=12, internal_damping=5e-3, youngs_modulus=5e6)
    model = CableModel.straight(spec, ends=("free", "free"), gravity=(0.0, 0.0, 0.0))
    rng = np.random.default_rng(3)
    m = spec.point_masses()[:, None]
    cases = []
    x = model.x0.copy()
    cases.append((x, np.array([0.1, 0.0, -0.2]) + np.cross([0.3, 2.0, 1.0], x - x.mean(0))))
    xb = model.x0.copy()
    xb[:, 1] += 0.02 * np.sin(np.linspace(0, 3, 12))  # bent in the z = const plane
    vb = np.array([0.2, 0.1, 0.0]) + np.cross([0.0, 0.0, 3.0], xb - xb.mean(0))
    vb[:, :2] += 0.05 * rng.standard_normal((12, 2))  # in-plane vibration
    cases.append((xb, vb))
    for x0, v0 in cases:
        res = simulate(model, "implicit_midpoint", 1e-3, 1.0, state=CableState(x0.copy(), v0.copy()),
                       max_records=3)
        assert res.stable
        xf, vf = res.final_state.x, res.final_state.v
        p0, pf = (m * v0).sum(0), (m * vf).sum(0)
        l0, lf = np.cross(x0, m * v0).sum(0), np.cross(xf, m * vf).sum(0)
        assert np.allclose(pf, p0, rtol=0, atol=1e-10 * np.abs(p0).max())
        assert np.allclose(lf, l0, rtol=0, atol=1e-8 * np.abs(l0).max())
    # the bent cable's vibration decayed: its energy fell, but not below the rigid spin's
    ke = lambda v: 0.5 * float(np.sum(m * v**2))  # noqa: E731
    assert ke(vf) < ke(vb)


def _move_forces(spec, n, dt=2.5e-4, duration=0.3):
    """End forces [N], (k, 6), of the study's move: both ends clamped, settled, last end up 5 mm in 50 ms."""
    model = CableModel.straight(spec.with_(n_masses=n), ends=("clamped", "clamped"),
                                motion=[Move("last", (0.0, 0.0, 0.005), 0.02, 0.05)])
    res = simulate(model, "bdf2", dt, duration, state=solve_static(model).state(), record_every=1)
    return res.end_forces.reshape(len(res.t), 6)


@pytest.mark.parametrize("spec", [CableSpec.lv2017(damping_rate=5.0), CableSpec.lv2017(internal_damping=1e-3)],
                         ids=["damping_rate", "internal_damping"])
def test_end_force_histories_converge_at_second_order(spec):
    ref = _move_forces(spec, 160)
    scale = np.sqrt(np.mean(np.sum((ref - ref[0]) ** 2, axis=1)))  # RMS of the dynamic part [N]
    errs = [np.sqrt(np.mean(np.sum((_move_forces(spec, n) - ref) ** 2, axis=1))) / scale for n in (10, 20, 40)]
    order = math.log(errs[1] / errs[2]) / math.log(39 / 19)
    assert order > 1.7, errs
    assert errs[2] < 0.05, errs


def test_end_force_histories_with_paper_k_d_do_not_converge():
    spec = CableSpec.lv2017(damping=0.01)
    ref = _move_forces(spec, 160)
    scale = np.sqrt(np.mean(np.sum((ref - ref[0]) ** 2, axis=1)))
    err = np.sqrt(np.mean(np.sum((_move_forces(spec, 40) - ref) ** 2, axis=1))) / scale
    assert err > 0.5  # k_d's rate k_d n / M quadruples from n = 40 to 160: a different cable


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_critical_step_with_internal_damping_matches_measurement(integrator):
    """Internal damping overdamps the stiff modes (fast eigenvalue near -tau omega^2): the
    explicit limit drops well below the undamped one, as predicted."""
    spec = CableSpec.lv2017(n_masses=10, damping=0.01, internal_damping=1e-3)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[Move("last", (0, 0, 0.005), 0.02, 0.05)])
    h = critical_dt(model, integrator)
    assert h < 0.5 * critical_dt(CableModel.straight(spec.with_(internal_damping=0.0)), integrator)
    start = solve_static(model).state()
    assert simulate(model, integrator, 0.9 * h, 0.2, state=start, max_records=3).stable
    assert not simulate(model, integrator, 1.1 * h, 0.2, state=start, max_records=3).stable


def test_drag_and_the_implicit_step_agree_with_the_free_mass_closed_form():
    """Rigid translation under damping_rate c: v(t) = v0 exp(-c t) (backward Euler: (1 + c h)^-k)."""
    spec = CableSpec.lv2017(n_masses=5, damping_rate=2.0, internal_damping=1e-3)
    model = CableModel.straight(spec, ends=("free", "free"), gravity=(0.0, 0.0, 0.0))
    v0 = np.tile([0.5, -0.2, 0.1], (5, 1))
    res = simulate(model, "implicit_midpoint", 1e-3, 0.5, state=CableState(model.x0.copy(), v0), max_records=3)
    assert np.allclose(res.final_state.v, v0 * math.exp(-2.0 * 0.5), rtol=1e-6)
    f = np.zeros((5, 3))
    total_forces(model.kernel_arrays(), model.x0.copy(), v0, model.holder_plan().start_dir, f)
    assert np.allclose(f, -2.0 * spec.point_masses()[:, None] * v0)  # internal damping: nothing on translation


@pytest.mark.parametrize("key,value,text", [
    ("damping_rate", -1.0, "damping_rate must be in [0.0, 10000.0]"),
    ("damping_rate", math.nan, "damping_rate must be in"),
    ("internal_damping", 2.0, "internal_damping must be in [0.0, 1.0]"),
    ("internal_damping", "x", "internal_damping must be a number"),
])
def test_bad_damping_values_name_the_key_and_range(key, value, text):
    with pytest.raises(ParameterError, match=text.replace("[", r"\[").replace("]", r"\]")):
        CableSpec.lv2017(**{key: value})


def test_damping_keys_in_scene_files_and_capture_specs():
    from bullet_dlo.config.capture import CaptureSpec
    from bullet_dlo.config.scene import Scene

    scene = Scene.from_dict({"cable": {"preset": "lv2017", "damping_rate": 3.0, "internal_damping": 2e-3}})
    assert scene.cable.damping_rate == 3.0 and scene.build_model().arrays.c_stretch[0] == pytest.approx(
        scene.cable.k_stretch * 2e-3)
    spec = CaptureSpec.from_dict({"sample": {"internal_damping": {"dist": "uniform", "low": 1e-4, "high": 1e-3},
                                             "damping_rate": {"dist": "log_uniform", "low": 0.1, "high": 10.0}}})
    draws = [spec.draw(i) for i in range(5)]
    assert all(1e-4 <= d["internal_damping"] <= 1e-3 and 0.1 <= d["damping_rate"] <= 10 for d in draws)
    assert len({d["internal_damping"] for d in draws}) == 5
    with pytest.raises(ParameterError, match="sample.internal_damping"):
        CaptureSpec.from_dict({"sample": {"internal_damping": {"dist": "fixed", "value": 5.0}}})
