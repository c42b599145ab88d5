"""The quadratic (Morison-type) fluid drag law against closed forms.

* terminal velocity of a horizontal cable falling broadside, and its transient v(t) = v_t tanh(g t / v_t)
  (order 1 for implicit Euler, 2 for BDF2 and implicit midpoint in dt);
* free decay of a cantilever's first mode under quadratic drag (energy balance with the mode shape:
  1/A(t) = 1/A0 + 4 c' omega kappa t / (3 pi mu), second order in n);
* no drag for motion along the axis (round) or along the width (rectangle: the face normal only);
* the velocity Jacobian against finite differences; large implicit steps stay stable; off by default.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.kernels.drag import add_drag_forces, add_drag_jacobian, drag_dissipation, drag_power
from bullet_dlo.core.kernels.forces import jacobian_blocks_to_dense
from bullet_dlo.core.kernels.twist import twist_ready
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec, ParameterError

pytestmark = pytest.mark.core

G = 9.81
FALLER = CableSpec(length=1.0, diameter=0.01, mass=0.05, youngs_modulus=1e7, n_masses=11, drag_coefficient=1.2)


def _terminal_velocity(spec: CableSpec) -> float:
    """v_t = sqrt(2 m g / (rho C_d d L)) [m/s]: weight = drag on the whole broadside cable."""
    return math.sqrt(2 * spec.mass * G / (spec.fluid_density * spec.drag_coefficient * spec.diameter * spec.length))


def _faller() -> CableModel:
    return CableModel.straight(FALLER, start=(0, 0, 10), direction=(1, 0, 0), ends=("free", "free"))


def test_spec_fields_and_defaults():
    spec = CableSpec.lv2017()
    assert spec.drag_coefficient == 0.0 and spec.fluid_density == 1.204
    assert CableModel.straight(spec).arrays.drag_k.shape == (0,)  # off: the kernels see no drag law
    assert "drag_coefficient" not in spec.to_dict()  # digests of old specs unchanged
    with_drag = spec.with_(drag_coefficient=2.0, fluid_density=998.0)
    assert with_drag.to_dict()["drag_coefficient"] == 2.0
    assert with_drag.drag_constant == pytest.approx(0.5 * 998.0 * 2.0 * spec.diameter * spec.rest_length)
    strip = CableSpec(length=0.5, diameter=0.001, mass=0.3, youngs_modulus=2e11, section="rectangle", width=0.08,
                      thickness=0.001, drag_coefficient=1.0)
    assert strip.projected_width == 0.08
    assert spec.with_(drag_width=0.05).projected_width == 0.05
    for key, bad in (("drag_coefficient", -1.0), ("fluid_density", -0.1), ("drag_width", -1e-3)):
        with pytest.raises(ParameterError, match=key):
            spec.with_(**{key: bad})


def test_off_is_identical():
    """drag_coefficient 0 runs the same arithmetic as a cable that never heard of the law."""
    spec = CableSpec.lv2017(n_masses=12, damping_rate=0.5)
    a = simulate(CableModel.straight(spec, ends=("clamped", "free")), "bdf2", dt=1e-3, duration=0.3)
    b = simulate(CableModel.straight(spec.with_(fluid_density=998.0, drag_width=0.1), ends=("clamped", "free")),
                 "bdf2", dt=1e-3, duration=0.3)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.v, b.v)


def test_terminal_velocity():
    """Long after release every node falls at v_t (the ends' half masses meet half a segment's drag)."""
    spec = FALLER
    vt = _terminal_velocity(spec)
    r = simulate(_faller(), "implicit_euler", dt=0.05, duration=10.0)  # 10 s = 12 v_t / g
    assert r.stable
    assert r.final_state.v[:, 2] == pytest.approx(-vt, rel=1e-6)
    assert np.ptp(r.final_state.v[:, 2]) < 1e-10  # broadside: no bending, no rotation


@pytest.mark.parametrize("integrator, order", [("implicit_euler", 1), ("bdf2", 2), ("implicit_midpoint", 2)])
def test_fall_transient_order(integrator, order):
    """v(t) = -v_t tanh(g t / v_t) (dv/dt = -g + g v^2/v_t^2): error at t = 2 s falls as dt^order."""
    vt = _terminal_velocity(FALLER)
    duration = 2.0
    exact = -vt * math.tanh(G * duration / vt)
    errs = []
    for dt in (0.04, 0.02, 0.01):
        r = simulate(_faller(), integrator, dt=dt, duration=duration)
        errs.append(abs(r.final_state.v[:, 2].mean() - exact))
    rates = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(abs(rate - order) < 0.15 for rate in rates), (errs, rates)
    assert errs[-1] < 0.01 * vt


def test_large_steps_stay_stable():
    """dt = 1 s, 2.4x the drag's time constant v_t / (2 g) = 0.42 s: the exact dF/dv in Newton keeps every
    step converged and the fall monotone towards v_t (an explicit step that large oscillates and blows up)."""
    vt = _terminal_velocity(FALLER)
    r = simulate(_faller(), "implicit_euler", dt=1.0, duration=30.0, record_every=1)
    assert r.stable and r.newton_failures == 0
    vz = r.v[:, :, 2].mean(axis=1)
    assert np.all(np.diff(vz) <= 1e-12) and vz[-1] == pytest.approx(-vt, rel=1e-8)
    assert r.newton_iterations <= 4 * r.steps  # quadratic convergence from the exact Jacobian
    explicit = simulate(_faller(), "symplectic_euler", dt=1.0, duration=30.0)
    assert not explicit.stable or abs(explicit.final_state.v[:, 2].mean() + vt) > 0.1 * vt


def _cantilever_mode(xi: np.ndarray) -> np.ndarray:
    """First mode of a clamped-free Euler-Bernoulli beam, tip value 1."""
    beta = 1.8751040687119611
    sig = (math.cosh(beta) + math.cos(beta)) / (math.sinh(beta) + math.sin(beta))
    phi = np.cosh(beta * xi) - np.cos(beta * xi) - sig * (np.sinh(beta * xi) - np.sin(beta * xi))
    return phi / 2.0  # phi(1) = 2 for this normalisation


def _decay_slope(n: int) -> tuple[float, float]:
    """Measured d(1/A_tip)/dt [1/(m s)] of a cantilever released in its first mode, and the closed form.

    Energy balance over a cycle of w = A phi(s) cos(omega t) with f = -c' |w_t| w_t per length
    (c' = 1/2 rho C_d d): the drag takes c' A^3 omega^2 (8/3) int |phi|^3 ds, the mode holds
    1/2 mu omega^2 A^2 int phi^2 ds, so per cycle dA = (8/3) (c'/mu) kappa A^2 with
    kappa = int |phi|^3 / int phi^2 = 0.7389 (tip-normalised first mode), i.e.
    dA/dt = -(4 / (3 pi)) (c'/mu) omega kappa A^2 and 1/A(t) = 1/A0 + 4 c' omega kappa t / (3 pi mu)
    (equivalent damping ratio 4 c' kappa A / (3 pi mu), linear in the amplitude).
    """
    length, mu, d, ei = 1.0, 0.1, 0.01, 1.28
    rho_f, cd = 998.0, 0.05
    spec = CableSpec(length=length, diameter=d, mass=mu * length, youngs_modulus=ei / (math.pi * d**4 / 64),
                     n_masses=n, drag_coefficient=cd, fluid_density=rho_f)
    model = CableModel.straight(spec, start=(0, 0, 0), direction=(1, 0, 0), ends=("clamped", "free"), gravity=(0, 0, 0))
    x = model.x0.copy()
    x[:, 2] = 0.02 * _cantilever_mode(x[:, 0] / length)  # A0 = 2 cm (2 % of L: geometrically linear)
    dt = 5e-4
    r = simulate(model, "bdf2", dt=dt, duration=5.0, state=CableState(x, np.zeros_like(x), 0.0),
                 record_every=1, max_records=20001)
    assert r.stable
    a, t = np.abs(r.x[:, -1, 2]), r.t
    peaks, times = [], []
    for i in range(1, len(a) - 1):
        if a[i] >= a[i - 1] and a[i] > a[i + 1]:  # each half cycle's extreme, refined by a parabola
            y0, y1, y2 = a[i - 1], a[i], a[i + 1]
            off = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
            peaks.append(y1 - 0.25 * (y0 - y2) * off)
            times.append(t[i] + off * dt)
    xi = np.linspace(0.0, 1.0, 200_001)
    phi = _cantilever_mode(xi)
    kappa = np.trapezoid(np.abs(phi) ** 3, xi) / np.trapezoid(phi**2, xi)
    omega = 1.8751040687119611**2 * math.sqrt(ei / (mu * length**4))
    c_len = 0.5 * rho_f * cd * d
    assert peaks[-1] < 0.6 * peaks[0]  # the drag did most of the work: A halves over 10 cycles
    return np.polyfit(times, 1.0 / np.array(peaks), 1)[0], 4 * c_len * omega * kappa / (3 * math.pi * mu)


def test_cantilever_decay_quadratic_drag():
    """1/A grows linearly in t at the energy balance's rate; the error falls as 1/n^2."""
    errs = []
    for n in (11, 21, 41):
        measured, closed = _decay_slope(n)
        errs.append(abs(measured / closed - 1.0))
    assert errs[-1] < 0.005, errs
    rates = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(1.7 < rate < 2.3 for rate in rates), (errs, rates)


def _forces(model: CableModel, x: np.ndarray, v: np.ndarray, m=None) -> np.ndarray:
    """The drag forces [N] at (x, v); ``m``: the kernels' arrays to use (default: the model's, a new twist state)."""
    out = np.zeros_like(x)
    add_drag_forces(model.kernel_arrays() if m is None else m, x, v, out)
    return out


def test_no_drag_along_the_axis():
    model = CableModel.straight(FALLER, direction=(1, 0, 0), ends=("free", "free"))
    x = model.x0.copy()
    v = np.zeros_like(x)
    v[:, 0] = 3.0
    assert np.all(_forces(model, x, v) == 0.0)
    v[:, 1] = 2.0  # cross-flow part only: -k |u_n| u_n on the y component, shared by the nodes
    f = _forces(model, x, v)
    k = FALLER.drag_constant
    assert f[:, 0] == pytest.approx(0.0, abs=1e-15)
    assert f.sum(axis=0)[1] == pytest.approx(-(FALLER.n_masses - 1) * k * 4.0, rel=1e-13)


def test_rectangle_face_normal():
    """A strip feels drag on its face-normal velocity only: none edge first (along the width), the full
    1/2 rho C_d b l0 s^2 face first, and the face-normal part of an oblique velocity."""
    spec = CableSpec(length=0.52, diameter=0.001, mass=0.33, youngs_modulus=2e11, n_masses=9, section="rectangle",
                     width=0.08, thickness=0.001, drag_coefficient=2.0)
    model = CableModel.straight(spec, direction=(1, 0, 0), ends=("clamped", "free"))
    x = model.x0.copy()
    m = model.kernel_arrays()
    twist_ready(m, x, np.array([[1.0, 0, 0], [1.0, 0, 0]]))
    d1 = model.first.normal  # width axis; the face normal is d2 = t x d1
    d2 = np.cross([1.0, 0, 0], d1)
    v = np.zeros_like(x)
    v[:] = 1.5 * d1
    assert np.abs(_forces(model, x, v, m)).max() < 1e-14
    v[:] = 1.5 * d2 + 0.7 * d1 + 0.3 * np.array([1.0, 0, 0])
    f = _forces(model, x, v, m).sum(axis=0)
    assert f == pytest.approx(-(spec.n_masses - 1) * spec.drag_constant * 1.5**2 * d2, rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("face", [False, True])
def test_velocity_jacobian_and_dissipation(face):
    """dF/dv against central differences; F = -dR/dv; the power 3 R is what the forces take."""
    rng = np.random.default_rng(3)
    if face:
        spec = CableSpec(length=0.5, diameter=0.001, mass=0.3, youngs_modulus=2e11, n_masses=7, section="rectangle",
                         width=0.08, thickness=0.001, drag_coefficient=3.0)
    else:
        spec = FALLER.with_(n_masses=7)
    model = CableModel.straight(spec, ends=("free", "free"))
    x = model.x0 + 0.02 * rng.standard_normal(model.x0.shape)
    m = model.kernel_arrays()
    if face:
        twist_ready(m, x, np.array([[1.0, 0, 0], [1.0, 0, 0]]))
        m.tw_theta[:] = 0.3 * rng.standard_normal(spec.n_masses - 1)
    v = rng.standard_normal(x.shape)
    n = spec.n_masses
    jac = np.zeros((n, 5, 3, 3))
    add_drag_jacobian(m, x, v, 1.0, jac)
    dense = jacobian_blocks_to_dense(jac)
    fd = np.zeros((3 * n, 3 * n))
    grad_r = np.zeros(3 * n)
    eps = 1e-6
    for col in range(3 * n):
        vp, vm = v.copy(), v.copy()
        vp.flat[col] += eps
        vm.flat[col] -= eps
        fd[:, col] = (_forces(model, x, vp, m) - _forces(model, x, vm, m)).ravel() / (2 * eps)
        grad_r[col] = (drag_dissipation(m, x, vp) - drag_dissipation(m, x, vm)) / (2 * eps)
    scale = np.abs(dense).max()
    assert np.abs(dense - fd).max() < 1e-7 * scale
    assert np.allclose(dense, dense.T, atol=1e-14 * scale)
    assert np.linalg.eigvalsh(dense).max() < 1e-12 * scale  # dissipative: negative semi-definite
    f = _forces(model, x, v, m)
    assert np.abs(-grad_r - f.ravel()).max() < 1e-7 * np.abs(f).max()
    assert drag_power(m, x, v) == pytest.approx(-np.sum(f * v), rel=1e-12)
