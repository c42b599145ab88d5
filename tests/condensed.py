"""The condensed stiffness of a cable with a material frame, shared by the buckling tests of several files
(imported as ``from condensed import ...``: pytest puts ``tests/`` on ``sys.path`` for its conftest)."""
from __future__ import annotations

import numpy as np

from bullet_dlo.core.kernels.forces import internal_forces
from bullet_dlo.core.kernels.twist import twist_solve


def lowest_condensed_stiffness(m, x0: np.ndarray, dirs: np.ndarray, free: slice, h: float) -> float:
    """Lowest eigenvalue [N/m] of the stiffness of the nodes ``free`` (a slice of node indices) of kernel arrays
    ``m`` at positions x0 [m] (n, 3), the twist angles in equilibrium at every position (the static condensation:
    by the envelope theorem the condensed stiffness is -d/dx of the forces at the equilibrium twist), by central
    differences of step h [m]. ``m``'s twist angles are those of x0's equilibrium before and after."""
    theta0 = m.tw_theta.copy()
    nodes = np.arange(x0.shape[0])[free]
    f = np.zeros_like(x0)

    def forces(x):
        m.tw_theta[:] = theta0
        twist_solve(m, x, dirs, 1.0, False, m.tw_mref)
        internal_forces(m, x, dirs, f)
        return f[free].ravel().copy()

    dof = 3 * nodes.shape[0]
    k = np.empty((dof, dof))
    for c in range(dof):
        xp, xm = x0.copy(), x0.copy()
        xp[nodes[c // 3], c % 3] += h
        xm[nodes[c // 3], c % 3] -= h
        k[:, c] = -(forces(xp) - forces(xm)) / (2 * h)
    m.tw_theta[:] = theta0
    return float(np.linalg.eigvalsh(0.5 * (k + k.T))[0])
