"""The 2-stage Gauss-Legendre integrator against closed forms: 4th order in dt, no numerical damping of an
undamped linear mode, A-stability at h omega >> 1, the held ends' stage poses, the exact Jacobian of the
coupled stage system's transformed Newton direction and the band solver."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.analysis.closed_forms import cantilever_model
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import INTEGRATORS, get_integrator, make_stepper
from bullet_dlo.core.kernels.banded import HALF
from bullet_dlo.core.kernels.gauss_legendre import (
    C1,
    C2,
    _gl_direction,
    _gl_residual,
    _gl_transformed_matrix,
    gl_band_factor,
    gl_band_solve,
    stage_holders,
)
from bullet_dlo.core.kernels.holders import empty_samples, sample_holders
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt


def _oscillator():
    """One free mass on one axial spring, no gravity, released 1e-3 l0 from rest length: a linear oscillator
    x(t) = l0 + A cos(omega t), omega^2 = k / m (closed form). Returns (model, start, omega, A)."""
    spec = CableSpec.lv2017(n_masses=2, damping=0.0)
    model = CableModel.straight(spec, (0, 0, 0), (1, 0, 0), ("pinned", "free"), (), (0.0, 0.0, 0.0))
    a = model.arrays
    omega = math.sqrt(a.k_stretch[0] / a.mass[1])
    amp = 1e-3 * a.rest_length[0]
    x0 = model.x0.copy()
    x0[1, 0] += amp
    return model, CableState(x0, np.zeros_like(x0)), omega, amp


def _oscillator_error(integrator: str, steps_per_period: int) -> float:
    model, start, omega, amp = _oscillator()
    period = 2 * math.pi / omega
    res = simulate(model, integrator, period / steps_per_period, 3 * period, state=start, record_every=1)
    exact = start.x[1, 0] - amp + amp * np.cos(omega * res.t)
    return float(np.max(np.abs(res.x[:, 1, 0] - exact)) / amp)


def test_registered_as_fourth_order_implicit():
    integ = get_integrator("gauss_legendre")
    assert integ is INTEGRATORS["gauss_legendre"] and integ.order == 4 and not integ.explicit
    model, _, _, _ = _oscillator()
    assert critical_dt(model, "gauss_legendre") is None  # unconditionally stable, like the other implicit methods
    assert make_stepper("gauss_legendre", 1e-3).tol == 1e-9  # (its simplified Newton stops just under it: module doc)


@pytest.mark.parametrize("integrator,order", [("gauss_legendre", 4), ("implicit_midpoint", 2)])
def test_linear_oscillator_order(integrator, order):
    """Error against the closed form at 10, 20, 40 steps per period: the observed order is the method's
    (the 4th-order assertion fails on the midpoint's 2)."""
    errs = [_oscillator_error(integrator, k) for k in (10, 20, 40)]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(abs(p - order) < 0.2 for p in orders), (orders, errs)


def test_phase_error_matches_pade_closed_form():
    """One step of a linear mode turns by 2 atan((w h / 2) / (1 - (w h)^2 / 12)) (the (2, 2) Pade of exp(i w h)):
    the zero crossings of the run sit where that phase says, at 8 steps per period (phase error -0.4 %)."""
    model, start, omega, amp = _oscillator()
    z = 2 * math.pi / 8
    res = simulate(model, "gauss_legendre", z / omega, 20 * 2 * math.pi / omega, state=start, record_every=1)
    y = res.x[:, 1, 0] - (start.x[1, 0] - amp)
    phase = 2 * math.atan((z / 2) / (1 - z * z / 12))  # per step
    k = np.arange(len(y))
    assert np.allclose(y / amp, np.cos(phase * k), atol=1e-6)
    assert not np.allclose(y / amp, np.cos(z * k), atol=1e-2)  # the exact phase is measurably different


@pytest.mark.parametrize("h_omega", [0.5, 100.0, 1e4])
def test_no_damping_and_no_blow_up(h_omega):
    """Undamped linear mode: the energy is kept to round-off at any h omega (|R(i w h)| = 1: A-stable and
    without numerical damping), also far beyond any explicit limit; implicit Euler loses it."""
    model, start, omega, amp = _oscillator()
    dt = h_omega / omega
    res = simulate(model, "gauss_legendre", dt, 400 * dt, state=start, record_every=1)
    assert res.stable and res.newton_failures == 0
    assert np.max(np.abs(res.energy - res.energy[0])) <= 1e-9 * res.energy[0]
    assert np.max(np.abs(res.x[:, 1, 0] - (start.x[1, 0] - amp))) <= amp * (1 + 1e-9)
    euler = simulate(model, "implicit_euler", dt, 400 * dt, state=start, record_every=1)
    assert euler.energy[-1] < 0.5 * euler.energy[0]


def test_cantilever_order_and_energy():
    """A swinging damped cantilever (nonlinear, 5 masses, held clamp): 4th order against an RK4 reference at
    a 16x smaller step; undamped, the swing's energy does not drift."""
    spec = CableSpec.lv2017(n_masses=5, youngs_modulus=1e6, damping=0.05)
    model = cantilever_model(spec)
    ref = simulate(model, "rk4", 2e-3 / 4 / 16, 0.2).final_state.x
    errs = [np.max(np.abs(simulate(model, "gauss_legendre", dt, 0.2).final_state.x - ref))
            for dt in (2e-3, 1e-3, 5e-4)]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    assert all(abs(p - 4) < 0.5 for p in orders), (orders, errs)
    free = CableSpec.lv2017(n_masses=10, damping=0.0)
    res = simulate(cantilever_model(free), "gauss_legendre", 2e-3, 2.0, max_records=2001)
    e = res.energy
    swing = free.mass * 9.81 * free.length
    k = len(e) // 10
    assert res.stable and abs(np.mean(e[-k:]) - np.mean(e[:k])) < 0.01 * swing


def test_stage_poses_of_a_moving_end_are_exact():
    """A minimum-jerk move is a quintic in time: the quintic Hermite interpolation of the step's samples gives
    the held end's pose at the stage times exactly (to round-off), the direction of a fixed clamp exactly."""
    spec = CableSpec.lv2017(n_masses=6)
    move = Move("last", (0.01, -0.02, 0.03), start=0.0, duration=0.5)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move])
    plan = model.holder_plan(model.control())
    t, h = 0.11, 0.04
    samples, exact = empty_samples(), empty_samples()
    sample_holders(plan, t, h, samples)
    pos, vel, dirs = np.empty((2, 3)), np.empty((2, 3)), np.empty((2, 3))
    for c in (C1, C2):
        stage_holders(samples, c, h, pos, vel, dirs)
        sample_holders(plan, t + c * h, 0.0, exact)
        assert np.allclose(pos, exact.pos[0], rtol=0, atol=1e-15)
        assert np.allclose(vel, exact.vel[0], rtol=0, atol=1e-13)
        assert np.allclose(dirs, exact.dir[0], rtol=0, atol=1e-15)


def test_the_transformed_newton_direction_solves_the_stage_system():
    """Where both stages sit at one state (v = V_1 = V_2 = 0: X_1 = X_2 = x) the stage system's Jacobian is the
    one the step factorises, AI (x) M - h^2 A (x) K - h I (x) D (module doc): the direction from the complex system
    C (Butcher's transformation, half the unknowns) equals the dense solve of -dR/dV by central differences of
    the residual (a bent cable with drag and Kelvin-Voigt dampers, no stiffness filter); and the real band solver
    (the twisting and contact steps') solves a random band exactly."""
    spec = CableSpec.lv2017(n_masses=6, damping=0.3).with_(internal_damping=2e-3)
    model = CableModel.straight(spec, ends=("clamped", "free"))
    m = model.kernel_arrays()
    n = model.n
    rng = np.random.default_rng(3)
    x = model.x0 + 1e-3 * rng.standard_normal((n, 3))
    x[0] = model.x0[0]
    v = np.zeros((n, 3))
    h = 2e-3
    samples = empty_samples()
    sample_holders(model.holder_plan(model.control()), 0.0, h, samples)
    hpos, hvel, hdir = np.empty((2, 2, 3)), np.empty((2, 2, 3)), np.empty((2, 2, 3))
    stage_holders(samples, C1, h, hpos[0], hvel[0], hdir[0])
    stage_holders(samples, C2, h, hpos[1], hvel[1], hdir[1])
    vs = np.zeros((2, n, 3))
    xs, vst, f = np.empty((2, n, 3)), np.empty((2, n, 3)), np.empty((2, n, 3))
    r = np.empty(6 * n)
    _gl_residual(m, x, v, h, vs, xs, vst, f, hpos, hvel, hdir, r)
    fd = np.zeros((6 * n, 6 * n))
    eps = 1e-7
    for i in range(1, n):  # free nodes' columns (node 0 is held)
        for s in range(2):
            for j in range(3):
                rp, rm = np.empty(6 * n), np.empty(6 * n)
                vp = vs.copy()
                vp[s, i, j] += eps
                _gl_residual(m, x, v, h, vp, xs, vst, f, hpos, hvel, hdir, rp)
                vp[s, i, j] -= 2 * eps
                _gl_residual(m, x, v, h, vp, xs, vst, f, hpos, hvel, hdir, rm)
                fd[:, 6 * i + 3 * s + j] = -(rp - rm) / (2 * eps)
    _gl_residual(m, x, v, h, vs, xs, vst, f, hpos, hvel, hdir, r)  # (the stage states at the iterate again)
    band = np.empty((3 * n, 2 * HALF + 1), dtype=np.complex128)
    jx, jv = np.empty((n, 5, 3, 3)), np.empty((n, 5, 3, 3))
    _gl_transformed_matrix(m, h, xs, vst, hdir, False, np.empty((n, 3)), np.empty((n, 3)), np.empty((2, 3)), jx, jv,
                           band)
    gl_band_factor(band, HALF)
    dv = np.empty(6 * n)
    _gl_direction(band, r, np.empty(3 * n, dtype=np.complex128), dv)
    free = slice(6, 6 * n)
    assert np.allclose(dv[:6], 0.0) and np.max(np.abs(dv)) > 0.0
    exact = np.linalg.solve(fd[free, free], r[free])
    assert np.allclose(dv[free], exact, rtol=1e-5, atol=1e-6 * np.max(np.abs(exact)))
    size, half = 30, 4
    dense = np.diag(np.full(size, 8.0)) + sum(np.diag(rng.standard_normal(size - abs(k)), k)
                                              for k in range(-half, half + 1) if k)
    rb = np.zeros((size, 2 * half + 1))
    for row in range(size):
        for col in range(max(0, row - half), min(size, row + half + 1)):
            rb[row, col - row + half] = dense[row, col]
    rhs = rng.standard_normal(size)
    y = rhs.copy()
    gl_band_solve(rb, y, half)
    assert np.allclose(y, np.linalg.solve(dense, rhs), rtol=1e-10, atol=1e-12)


def test_resting_end_fast_path_gives_the_general_samples_bit_for_bit():
    """sample_holders' fast path for an end that never moves writes exactly what the general sampler (held_pose
    with empty tables) writes; the moving end of the same plan still follows its move."""
    from bullet_dlo.core.kernels.holders import held_pose

    spec = CableSpec.lv2017(n_masses=6)
    move = Move("last", (0.01, -0.02, 0.03), start=0.0, duration=0.5, rotation=(0.0, 0.0, 0.2))
    model = CableModel.straight(spec, (0.1, 0.2, 0.3), (0.6, 0.8, 0.0), ends=("clamped", "clamped"), motion=[move])
    plan = model.holder_plan(model.control())
    fast, general = empty_samples(), empty_samples()
    for arr in (*fast, *general):
        arr[:] = np.nan  # every entry must be written
    t, h = 0.2, 0.01
    sample_holders(plan, t, h, fast)
    for end in (0, 1):
        for k in range(3):
            held_pose(plan, end, t + 0.5 * h * k, general, k)
    for a, b in zip(fast, general):
        assert np.array_equal(a, b)
    assert not np.array_equal(fast.pos[0, 1], fast.pos[2, 1])  # the last end moves within the step


def test_the_block_substitution_gives_each_columns_substitution_bit_for_bit():
    """The free bodies' Schur complement (core/kernels/contact.py, coupled_solve) substitutes its columns together,
    from the first row they fill: each column must come out as gl_band_substitute's, bit for bit (rows from
    ``first`` on), and solve the band system (dense solve within round-off)."""
    from bullet_dlo.core.kernels.banded import HALF
    from bullet_dlo.core.kernels.contact import _substitute_columns
    from bullet_dlo.core.kernels.gauss_legendre import gl_band_factor, gl_band_substitute

    rng = np.random.default_rng(3)
    size, m, first = 60, 6, 21
    band = rng.normal(size=(size, 2 * HALF + 1))
    band[:, HALF] = 4.0 * HALF + rng.random(size)  # diagonally dominant: no pivoting needed
    dense = np.zeros((size, size))
    for r in range(size):
        for c in range(max(0, r - HALF), min(size, r + HALF + 1)):
            dense[r, c] = band[r, c - r + HALF]
    gl_band_factor(band, HALF)
    rhs = np.zeros((size, m))
    rhs[first:first + 12] = rng.normal(size=(12, m))
    block = rhs.copy()
    _substitute_columns(band, block, HALF, first)
    for q in range(m):
        col = rhs[:, q].copy()
        gl_band_substitute(band, col, HALF)
        assert col[first:].tobytes() == block[first:, q].tobytes()
        np.testing.assert_allclose(col, np.linalg.solve(dense, rhs[:, q]), rtol=1e-10, atol=1e-12)


def test_a_cable_pushed_in_at_60_hz_takes_converged_steps():
    """The study's cable clamped at both ends, its last end pushed 30 % in over 1 s (it buckles), at 60 Hz: the
    collocation system needs about 13 Newton iterations a step there, so Gauss-Legendre's default cap
    (``MAX_ITER_GAUSS_LEGENDRE``) lets every solve converge, and the end state is a 1 kHz run's within 2 mm (0.4 mm). Before,
    with the implicit methods' cap of 8, 32 of the first 40 solves failed and the run was stopped at 0.67 s."""
    spec = CableSpec.lv2017(n_masses=40, damping_rate=2.0)
    move = Move("last", displacement=(-0.3 * spec.length, 0.0, 0.0), duration=1.0)
    model = CableModel.straight(spec, ends=("clamped", "clamped"), motion=[move])
    coarse = simulate(model, "gauss_legendre", 1.0 / 60.0, 1.5, max_records=3)
    assert coarse.stable, coarse.reason
    assert coarse.newton_failures == 0
    assert coarse.newton_iterations > 8 * coarse.steps  # (the case needs more than the other methods' cap)
    fine = simulate(model, "gauss_legendre", 1e-3, 1.5, max_records=3)
    err = np.abs(coarse.final_state.x - fine.final_state.x).max()
    print("60 Hz against 1 kHz [m]", err)
    assert err < 2e-3
