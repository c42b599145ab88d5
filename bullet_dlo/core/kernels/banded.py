"""O(n) banded linear algebra for the implicit integrators (Numba).

The system matrix of an implicit step, A = M - a K + b C, inherits the block-banded
structure of the force Jacobian: 3x3 blocks up to two nodes apart, i.e. a scalar band of
half-width 8. It is stored as ``band[r, c - r + HALF]`` (shape (3n, 2*HALF+1)). A is
symmetric (conservative forces, diagonal drag, Kelvin-Voigt dampers -c G^T G added into the
Jacobian by the caller, held nodes as identity rows and columns),
so it is factorised by symmetric elimination without pivoting, which is safe because A is
dominated by its positive diagonal (mass) plus a positive semi-definite (filtered) stiffness.
"""
from __future__ import annotations

import numpy as np

from bullet_dlo.core.kernels.forces import BAND
from bullet_dlo.core.kernels.jit import njit

HALF = 3 * BAND + 2  # scalar half-bandwidth: 8


@njit(cache=True, error_model="numpy", inline="always")  # passing m: ~0.3-0.5 us a call (Numba's pipeline): 3 arrays
def assemble_system(m, jac, m_coef, k_coef, c_coef, band):
    """band <- m_coef M - k_coef K + c_coef C, held nodes replaced by identity rows and columns.

    m: ModelArrays (M = diag(mass) [kg], C = diag(damp) [N s/m], held nodes); jac: force
    Jacobian K = dF/dx [N/m], shape (n, 5, 3, 3) (an implicit step adds (cv/cx) times the
    Kelvin-Voigt dF/dv into it, see :func:`~bullet_dlo.core.kernels.forces.add_damping_jacobian`);
    band: output, shape (3n, 2*HALF+1).
    An implicit step uses m_coef = 1, k_coef = hf cx [s^2], c_coef = hf cv [s] (see
    :mod:`bullet_dlo.core.kernels.steppers`); the static solver (mu [1/s^2], 1, 0).
    """
    _assemble(m.mass, m.damp, m.held, jac, m_coef, k_coef, c_coef, band)


@njit(cache=True, error_model="numpy")
def _assemble(mass, damp, held, jac, m_coef, k_coef, c_coef, band):
    """:func:`assemble_system` from the masses [kg], drag coefficients [N s/m] and held flags."""
    n = mass.shape[0]
    band[:, :] = 0.0
    for i in range(n):
        for o in range(2 * BAND + 1):
            j = i + o - BAND
            if j < 0 or j >= n or held[i] or held[j]:
                continue
            for r in range(3):
                for c in range(3):
                    band[3 * i + r, 3 * j + c - 3 * i - r + HALF] = -k_coef * jac[i, o, r, c]
        for r in range(3):
            if held[i]:
                band[3 * i + r, HALF] = 1.0
            else:
                band[3 * i + r, HALF] += m_coef * mass[i] + c_coef * damp[i]


@njit(cache=True, error_model="numpy", inline="always")
def _back_substitute(band, rhs):
    """Back substitution in place with the upper band of an eliminated matrix: rhs (3n,) becomes the solution."""
    size = rhs.shape[0]
    for k in range(size - 1, -1, -1):
        acc = rhs[k]
        last = min(k + HALF, size - 1)
        for j in range(k + 1, last + 1):
            acc -= band[k, j - k + HALF] * rhs[j]
        rhs[k] = acc / band[k, HALF]


@njit(cache=True, error_model="numpy")
def band_solve(band, rhs):
    """Solve band * y = rhs in place for a *symmetric* band matrix (rhs, shape (3n,), becomes y).

    Gaussian elimination without pivoting that updates only the upper triangle (the lower
    multipliers equal the upper entries by symmetry): half the work of a general band LU.
    ``band`` is destroyed. Returns min |pivot|.
    """
    size = rhs.shape[0]
    min_pivot = np.inf
    for k in range(size):
        piv = band[k, HALF]
        if abs(piv) < min_pivot:
            min_pivot = abs(piv)
        last = min(k + HALF, size - 1)
        for i in range(k + 1, last + 1):
            f = band[k, i - k + HALF] / piv  # = a_ik / a_kk by symmetry
            if f == 0.0:
                continue
            for j in range(i, last + 1):
                band[i, j - i + HALF] -= f * band[k, j - k + HALF]
            rhs[i] -= f * rhs[k]
    _back_substitute(band, rhs)
    return min_pivot


@njit(cache=True, error_model="numpy")
def band_substitute(band, rhs):
    """Solve in place with a band already eliminated by :func:`band_solve` (its multipliers are the upper entries
    over the pivots): the same forward elimination on rhs (3n,) and back substitution, without the O(n HALF^2)
    elimination of the matrix. A chord iteration takes the factors of an earlier iterate this way."""
    size = rhs.shape[0]
    for k in range(size):
        piv = band[k, HALF]
        last = min(k + HALF, size - 1)
        for i in range(k + 1, last + 1):
            rhs[i] -= band[k, i - k + HALF] / piv * rhs[k]
    _back_substitute(band, rhs)


def band_matrix_to_dense(band: np.ndarray) -> np.ndarray:
    """Expand scalar band storage (3n, 2*HALF+1) to a dense (3n, 3n) matrix (tests)."""
    size = band.shape[0]
    dense = np.zeros((size, size))
    for r in range(size):
        for c in range(max(0, r - HALF), min(size, r + HALF + 1)):
            dense[r, c] = band[r, c - r + HALF]
    return dense
