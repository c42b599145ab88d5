"""Curved rest shape (rest turning angles, core/kernels/rest_shape.py): forces are the energy's gradient,
the Jacobian the forces' derivative, a cantilever with uniform rest curvature kappa0 rests as the arc of
radius 1/kappa0, and under a small tip load deflects from it as the linear curved beam says (Castigliano)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad

from bullet_dlo.core.kernels.forces import force_jacobian, internal_energy, internal_forces
from bullet_dlo.core.model import CableModel, read_only
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

pytestmark = pytest.mark.core
L, KAPPA0 = 0.5, 2.0  # cable length [m], rest curvature [1/m]: the arc turns 1 rad


def curved(n: int, kappa0: float = KAPPA0, ends=("clamped", "free")) -> CableModel:
    """A steel-wire-like cable along x, zero gravity, uniform rest angle kappa0 l0 at its interior nodes."""
    spec = CableSpec(length=L, diameter=0.002, mass=0.01, youngs_modulus=2e9, n_masses=n)
    model = CableModel.straight(spec, start=(0.0, 0.0, 0.0), ends=ends, gravity=(0.0, 0.0, 0.0))
    beta0 = np.full(n, kappa0 * spec.rest_length)
    return dataclasses.replace(model, arrays=model.arrays._replace(rest_angle=beta0))


def arc(n: int, kappa0: float = KAPPA0) -> np.ndarray:
    """Start positions on the (x, y) arc of curvature kappa0 tangent to x at the origin, (n, 3)."""
    s = np.linspace(0.0, L, n)
    return np.stack([np.sin(kappa0 * s) / kappa0, (1 - np.cos(kappa0 * s)) / kappa0, 0 * s], axis=1)


def test_forces_are_minus_the_energy_gradient_and_jacobian_their_derivative():
    model = curved(7, ends=("free", "free"))
    # stretch springs off: they would dwarf the bending forces this checks
    # read-only as the model's own arrays: a writable one is another argument type (the kernels compiled again)
    a = model.kernel_arrays()._replace(k_stretch=read_only(np.zeros(6)))
    dirs = model.holder_plan().start_dir
    rng = np.random.default_rng(3)
    x = arc(7, 3.0) + 0.01 * rng.normal(size=(7, 3))
    f = np.zeros((7, 3))
    internal_forces(a, x, dirs, f)
    h = 1e-7
    grad = np.zeros((7, 3))
    for i in range(7):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += h
            xm[i, j] -= h
            grad[i, j] = (internal_energy(a, xp, dirs) - internal_energy(a, xm, dirs)) / (2 * h)
    assert np.allclose(f, -grad, rtol=1e-5, atol=1e-6 * np.abs(f).max())
    # the rest term is really there: without it the forces differ by far more than the tolerance
    f0 = np.zeros((7, 3))
    internal_forces(a._replace(rest_angle=read_only(np.zeros(0))), x, dirs, f0)
    assert np.abs(f - f0).max() > 0.3 * np.abs(f).max()
    jac = np.zeros((7, 5, 3, 3))
    force_jacobian(a, x, dirs, False, jac)
    for i in range(7):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += h
            xm[i, j] -= h
            fp, fm = np.zeros((7, 3)), np.zeros((7, 3))
            internal_forces(a, xp, dirs, fp)
            internal_forces(a, xm, dirs, fm)
            col = (fp - fm) / (2 * h)  # dF/dx_ij
            for r in range(max(0, i - 2), min(7, i + 3)):
                assert np.allclose(jac[r, i - r + 2][:, j], col[r], rtol=1e-4, atol=1e-5 * np.abs(jac).max())


def tip(n: int, load: float = 0.0) -> np.ndarray:
    """Tip position [m] of the curved cantilever at equilibrium under a tip load ``load`` [N] along -x."""
    model = curved(n)
    fe = np.zeros((n, 3))
    fe[-1, 0] = -load
    res = solve_static(model, arc(n), f_ext=fe)
    assert res.converged
    return res.x[-1]


def test_unloaded_cantilever_rests_as_the_arc_of_radius_one_over_kappa0_converging_in_n():
    """Discrete: the first segment leaves the clamp along it, then every node turns kappa0 l0, a regular
    polygon (exact to the solver); it converges to the arc's tip R (sin(L/R), 1 - cos(L/R)) at first order
    (the clamp node carries no rest angle: the polygon starts half a turn late)."""
    exact = np.array([math.sin(KAPPA0 * L), 1 - math.cos(KAPPA0 * L), 0.0]) / KAPPA0
    errs = []
    for n in (11, 21, 41, 81):
        x = tip(n)
        l0, b0 = L / (n - 1), KAPPA0 * L / (n - 1)
        ang = b0 * np.arange(n - 1)  # direction of segment k
        polygon = l0 * np.array([np.cos(ang).sum(), np.sin(ang).sum(), 0.0])
        assert np.allclose(x, polygon, atol=1e-6 * L)
        errs.append(np.linalg.norm(x - exact))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert errs[-1] < 0.01 * L
    assert np.all((ratios > 1.8) & (ratios < 2.2)), ratios  # first order in 1/n


def castigliano(load: float) -> np.ndarray:
    """Tip deflection [m] of a clamped circular arc (radius 1/kappa0, length L, tangent x at the clamp) under
    a tip load ``load`` along -x, linear in-plane bending (Castigliano: delta_j = int M dM/dF_j ds / EI)."""
    spec = curved(3).spec
    ei = spec.bending_rigidity
    r = lambda s: np.array([math.sin(KAPPA0 * s), 1 - math.cos(KAPPA0 * s)]) / KAPPA0  # noqa: E731
    rt = r(L)
    cross = lambda d, f: d[0] * f[1] - d[1] * f[0]  # noqa: E731
    force = np.array([-load, 0.0])
    out = np.zeros(3)
    for j, e in enumerate((np.array([1.0, 0.0]), np.array([0.0, 1.0]))):
        out[j] = quad(lambda s: cross(rt - r(s), force) * cross(rt - r(s), e), 0.0, L)[0] / ei
    return out


def test_curved_cantilever_under_a_tip_load_deflects_as_the_linear_curved_beam():
    """Load P = 0.01 EI / L^2 along -x (the tip moves by about 0.3 % of L): the model's deflection from its
    unloaded equilibrium converges to Castigliano's on the continuous arc, first order in 1/n."""
    ei = curved(3).spec.bending_rigidity
    p = 0.01 * ei / L**2
    want = castigliano(p)
    errs = []
    for n in (11, 21, 41, 81):
        got = tip(n, p) - tip(n)
        errs.append(np.linalg.norm(got - want) / np.linalg.norm(want))
    assert errs[-1] < 0.03, errs
    assert errs[0] > errs[1] > errs[2] > errs[3], errs
    # a straight cantilever's deflection (P L^3 / 3 EI along the load) is a different answer: the arc matters
    assert abs(np.linalg.norm(want) - p * L**3 / (3 * ei)) > 0.2 * np.linalg.norm(want)
