"""The coupled implicit step of a cable with a material frame (issue 22, "exact Jacobians in the implicit
methods"): positions and twist angles in one Newton system, the twist integrated by the method itself.

Before it, each step advanced the positions with the twist held and then the twist by an implicit-Euler
sub-step (staggered): first order in dt whatever the method. On the scene below (a soft rectangle strip,
clamped-free under gravity, its clamp rolled 90 degrees while it moves) the staggered BDF2 had order 0.5-1.3
and errors 700x larger at dt 1.25 ms (x 1.5e-2 m, material axis 7e-2); this test fails on it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.integrators import NewtonOptions
from bullet_dlo.core.kernels.twist_coupled import _add_twist_ggt, band_solve_upper
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

T = 0.5  # [s] simulated: the whole roll


def _model() -> CableModel:
    """A soft steel-like strip (E 2 GPa: its twist mode ~3000 rad/s, Kelvin-Voigt damped by internal_damping
    1 ms so that its state is smooth in time), rolled 90 degrees and moved 5 cm sideways, 2 cm up over 0.5 s."""
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e9, section="rectangle", width=0.01,
                     thickness=0.001, n_masses=9, damping_rate=2.0, internal_damping=1e-3)
    return CableModel.straight(spec, ends=("clamped", "free"), start=(0, 0, 0), roll=(0.3, 0.0),
                               motion=[Move("first", rotation=(math.pi / 2, 0, 0), displacement=(0, 0.05, 0.02),
                                            duration=T)])


def _final(model: CableModel, method: str, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Node positions [m] and material axes m1 (unit) of the segments at T."""
    res = simulate(model, method, T / steps, T, newton=NewtonOptions(tol=1e-9, max_iter=50))
    assert res.stable
    tw = res.final_state.twist
    m1 = np.cos(tw.theta)[:, None] * tw.ref + np.sin(tw.theta)[:, None] * np.cross(tw.tan, tw.ref)
    return res.x[-1], m1


@pytest.mark.parametrize("method", ["bdf2", "implicit_midpoint"])
def test_coupled_twist_step_has_the_methods_second_order(method):
    """Errors of the positions and of the material frame against dt = T/6400 fall 4x per halving of dt
    (observed order 1.9-2.0 from dt 2.5 to 0.625 ms) and are small in absolute terms at dt 0.625 ms. (From 5 ms
    until 2026-12-07, when the strip's weak plane was damped by the mean of its two stiffnesses, 50x its own: since,
    its weaker damped modes leave the first halving from 5 ms before the asymptotic order, 1.62 for the frame.)"""
    model = _model()
    x_ref, m1_ref = _final(model, method, 6400)
    errs = []
    for steps in (200, 400, 800):
        x, m1 = _final(model, method, steps)
        errs.append((np.abs(x - x_ref).max(), np.abs(m1 - m1_ref).max()))
    for (ex0, em0), (ex1, em1) in zip(errs, errs[1:]):
        assert 1.8 < math.log2(ex0 / ex1) < 2.2
        assert 1.8 < math.log2(em0 / em1) < 2.2
    assert errs[-1][0] < 1e-4 and errs[-1][1] < 2e-4  # m, and rad of the material axis


def test_implicit_euler_coupled_is_first_order():
    model = _model()
    x_ref, m1_ref = _final(model, "implicit_euler", 6400)
    x0, m10 = _final(model, "implicit_euler", 400)
    ex0, em0 = np.abs(x0 - x_ref).max(), np.abs(m10 - m1_ref).max()
    x1, m11 = _final(model, "implicit_euler", 800)
    ex1, em1 = np.abs(x1 - x_ref).max(), np.abs(m11 - m1_ref).max()
    assert 0.8 < math.log2(ex0 / ex1) < 1.2 and 0.8 < math.log2(em0 / em1) < 1.2


def test_upper_band_solver_matches_dense():
    """The symmetric upper-band solver of the coupled step against numpy on a random SPD band matrix."""
    rng = np.random.default_rng(3)
    size, half = 40, 10
    a = np.zeros((size, size))
    for i in range(size):
        for j in range(i, min(size, i + half + 1)):
            a[i, j] = a[j, i] = rng.standard_normal()
    a += np.diag(np.abs(a).sum(axis=1) + 1.0)  # diagonally dominant
    band = np.zeros((size, half + 1))
    for i in range(size):
        for j in range(i, min(size, i + half + 1)):
            band[i, j - i] = a[i, j]
    b = rng.standard_normal(size)
    y = b.copy()
    band_solve_upper(band, y, half)
    np.testing.assert_allclose(y, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)


def test_upper_band_solver_with_the_coupled_layouts_envelope_matches_dense():
    """group = 4 (the coupled step's layout: each node's 4 rows end at the node's first row + 10) skips the work
    right of that envelope; on a random SPD matrix with exactly that sparsity it solves as numpy does and gives the
    bits of the full-band elimination (the skipped entries stay zero). Fails on a solver without ``group``."""
    rng = np.random.default_rng(5)
    size, half = 4 * 12, 10
    a = np.zeros((size, size))
    for i in range(size):
        for j in range(i, min(size, i - i % 4 + half + 1)):
            a[i, j] = a[j, i] = rng.standard_normal()
    a += np.diag(np.abs(a).sum(axis=1) + 1.0)
    band = np.zeros((size, half + 1))
    for i in range(size):
        for j in range(i, min(size, i + half + 1)):
            band[i, j - i] = a[i, j]
    b = rng.standard_normal(size)
    y, y_full = b.copy(), b.copy()
    band_solve_upper(band.copy(), y, half, 4)
    band_solve_upper(band.copy(), y_full, half)
    np.testing.assert_allclose(y, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)
    assert np.array_equal(y, y_full)


@pytest.mark.parametrize("present", [(True,) * 5, (False, True, True, False, True), (True, False, True, True, True),
                                     (True, True, False, True, False)])
def test_twist_rank_one_block_is_coef_g_gT_over_the_present_unknowns(present):
    """One node's twist block coef g g^T, g = dm_i/dq = (-kb/2la, -1, kb/2la - kb/2lb, +1, kb/2lb) over (x_{i-1},
    theta_{i-1}, x_i, theta_i, x_{i+1}), against the dense outer product restricted to the present unknowns
    (held or missing neighbours, an end's missing theta), in upper band storage at an offset."""
    rng = np.random.default_rng(7)
    coef, la, lb = 3.7, 0.011, 0.013
    kb = rng.standard_normal(3)
    pa, pi, pb, ta, tb = present
    gfull = np.concatenate([-kb / (2 * la), [-1.0], (kb / (2 * la) if ta else 0.0) - (kb / (2 * lb) if tb else 0.0),
                            [1.0], kb / (2 * lb)])
    mask = np.array([pa] * 3 + [ta] + [pi] * 3 + [tb] + [pb] * 3)
    g = np.where(mask, gfull, 0.0)
    base, size, half = 4, 20, 10
    band = np.zeros((size, half + 1))
    qa, qb = kb / (2 * la), kb / (2 * lb)
    _add_twist_ggt(band, base, coef, qa[0], qa[1], qa[2], qb[0], qb[1], qb[2], pa, pi, pb, ta, tb, np.empty(11),
                   np.empty(11))
    dense = np.zeros((size, size))
    dense[base:base + 11, base:base + 11] = coef * np.outer(g, g)
    got = np.zeros((size, size))
    for r in range(size):
        for c in range(r, min(size, r + half + 1)):
            got[r, c] = band[r, c - r]
    np.testing.assert_allclose(got, np.triu(dense), rtol=1e-14, atol=0.0)
