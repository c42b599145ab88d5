"""Static equilibrium by damped Newton (Levenberg-Marquardt) on the banded stiffness.

Solves F_elastic(x) + m g + f_ext = 0 on the free nodes with the held ends at their start
poses. Used to start runs from a settled cable (the study's "settle" phase without
simulating it) and to measure discretisation error against beam theory without any
integrator in the loop.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bullet_dlo.core.kernels.banded import HALF, assemble_system, band_solve
from bullet_dlo.core.kernels.forces import force_jacobian, internal_energy, total_forces
from bullet_dlo.core.model import CableModel, CableState, ModelArrays


@dataclass
class StaticResult:
    """Equilibrium positions x [m] (n, 3), residual force [N] (max over free nodes), iterations."""

    x: np.ndarray
    residual: float
    iterations: int
    converged: bool

    def state(self) -> CableState:
        return CableState(self.x.copy(), np.zeros_like(self.x), 0.0)


def _potential(a: ModelArrays, x: np.ndarray, dirs: np.ndarray) -> float:
    """Elastic + gravitational + external-force potential [J] at positions x [m], (n, 3)."""
    e = internal_energy(a, x, dirs)
    return float(e - np.sum(a.mass[:, None] * a.gravity[None, :] * x) - np.sum(a.f_ext * x))


def solve_static(
    model: CableModel,
    x_start: np.ndarray | None = None,
    f_ext: np.ndarray | None = None,
    *,
    tol: float = 1e-10,
    max_iter: int = 200,
) -> StaticResult:
    """Equilibrium of ``model`` under gravity (and ``f_ext`` [N], (n, 3)) from ``x_start``.

    tol: convergence when the largest free-node force is below tol * (M |g| + sum |f_ext|) [N],
    or when a near-Newton step (regularisation at most its starting value) moves no node by more
    than the position round-off, 1e3 * eps * (|x| + L) [m]: the forces of stiff or finely
    discretised cables cannot be evaluated more precisely (their round-off grows like n^3; at
    n = 1000 it is ~5e-5 N, a sixth of a node's weight). A residual below some force floor is
    never taken for convergence by itself: the start, with no step taken, is not converged.
    """
    n = model.n
    fe = np.zeros((n, 3)) if f_ext is None else np.asarray(f_ext, dtype=float)
    a = model.kernel_arrays(model.control(fe))
    x = (model.x0 if x_start is None else np.asarray(x_start, dtype=float)).copy()
    x[0] = model.first.position if a.held[0] else x[0]
    x[-1] = model.last.position if a.held[-1] else x[-1]
    zeros_v = np.zeros((n, 3))  # static: no damping forces
    free = ~a.held
    dirs = model.holder_plan().start_dir
    scale = model.spec.mass * float(np.linalg.norm(a.gravity)) + float(np.abs(fe).sum()) + 1e-30
    target = tol * scale
    step_floor = 1e3 * np.finfo(float).eps * (float(np.abs(x).max()) + model.spec.length)  # [m]
    f = np.zeros((n, 3))
    jac = np.zeros((n, 5, 3, 3))
    band = np.zeros((3 * n, 2 * HALF + 1))

    def residual(xx: np.ndarray) -> tuple[np.ndarray, float]:
        total_forces(a, xx, zeros_v, dirs, f)
        r = f.copy()
        r[~free] = 0.0
        return r, float(np.abs(r).max())

    # Regularisation in units of M^-1 K: start tiny, grow when a step fails.
    mu0 = 1e-8 * float(np.max(a.k_stretch) / np.min(a.mass))
    mu = mu0
    r, res = residual(x)
    pot = _potential(a, x, dirs)
    it = 0
    at_roundoff = False
    while it < max_iter and res > target:
        it += 1
        force_jacobian(a, x, dirs, False, jac)
        assemble_system(a, jac, mu, 1.0, 0.0, band)
        rhs = r.reshape(-1).copy()
        band_solve(band, rhs)
        if mu <= mu0 and float(np.abs(rhs).max()) <= step_floor:
            at_roundoff = True  # the Newton step is below position round-off: nothing left to gain
            break
        x_try = x + rhs.reshape(n, 3)
        r_try, res_try = residual(x_try)
        pot_try = _potential(a, x_try, dirs)
        if np.isfinite(res_try) and (pot_try <= pot or res_try < res):
            x, r, res, pot = x_try, r_try, res_try, pot_try
            mu *= 0.1
        else:
            mu = max(mu, 1e-12) * 10.0
    return StaticResult(x, res, it, bool(res <= target or at_roundoff))
