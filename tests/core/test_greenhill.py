"""Greenhill's problem (issue 22): a straight clamped-clamped rod twisted about its axis buckles when the torque
reaches M_c = 8.9868 E I / L (clamped ends; Greenhill 1883, e.g. Timoshenko & Gere, Theory of Elastic
Stability, sec. 2.19: M_c L / (E I) = 2.8606 pi). Found as the twist angle at which the straight state's
stiffness (positions, with the twist angles in equilibrium: the condensed Hessian) loses definiteness."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.kernels.forces import clamp_torque, internal_energy, internal_forces
from bullet_dlo.core.kernels.twist import twist_solve, update_frames
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec

GREENHILL = 2.8606 * math.pi  # M_c L / (E I), clamped-clamped (8.9868)


def lowest_stiffness(spec: CableSpec, roll: float) -> tuple[float, float]:
    """Lowest eigenvalue [N/m] of the straight rod's stiffness with its last clamp rolled by ``roll`` [rad]
    (twist angles in equilibrium for every position: the static condensation), and the torque [N m] on it."""
    model = CableModel.straight(spec, ends=("clamped", "clamped"), gravity=(0, 0, 0))
    m, x0 = model.kernel_arrays(), model.initial_state().x
    dirs = model.holder_plan().start_dir
    internal_energy(m, x0, dirs)  # builds the material frame
    d1 = m.tw_normal[0, 1].copy()
    d2 = np.cross(dirs[1], d1)
    steps = math.ceil(roll / 0.5)
    for k in range(1, steps + 1):  # turned in steps below pi so the reference twist counts whole turns
        a = roll * k / steps
        m.tw_normal[:, 1] = m.tw_clamp[1] = math.cos(a) * d1 + math.sin(a) * d2
        update_frames(m, x0, dirs)
        twist_solve(m, x0, dirs, 1.0, False, m.tw_mref)
    theta0 = m.tw_theta.copy()
    n = spec.n_masses
    f = np.zeros_like(x0)

    def forces(x):
        m.tw_theta[:] = theta0
        twist_solve(m, x, dirs, 1.0, False, m.tw_mref)  # (envelope theorem: -dE/dx at the equilibrium twist)
        internal_forces(m, x, dirs, f)
        return f[1:-1].ravel().copy()

    h = 1e-7 * spec.length
    k = np.empty((3 * (n - 2), 3 * (n - 2)))
    for c in range(3 * (n - 2)):
        xp, xm = x0.copy(), x0.copy()
        xp[1 + c // 3, c % 3] += h
        xm[1 + c // 3, c % 3] -= h
        k[:, c] = -(forces(xp) - forces(xm)) / (2 * h)
    m.tw_theta[:] = theta0
    return float(np.linalg.eigvalsh(0.5 * (k + k.T))[0]), float(clamp_torque(m, x0, np.zeros_like(x0), dirs, 0)[0])


def critical_torque(n: int) -> float:
    """Greenhill's M_c L / (E I) of the n-mass rod, by bisection on the clamp's roll."""
    spec = CableSpec(length=1.0, diameter=0.01, mass=0.1, youngs_modulus=1e9, n_masses=n, twist=True)
    roll_c = GREENHILL * spec.bending_rigidity / spec.torsional_rigidity  # 11.7 rad at nu = 0.3
    lo, hi = 0.7 * roll_c, 1.3 * roll_c
    assert lowest_stiffness(spec, lo)[0] > 0 > lowest_stiffness(spec, hi)[0]
    while hi - lo > 1e-5 * roll_c:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if lowest_stiffness(spec, mid)[0] > 0 else (lo, mid)
    return lowest_stiffness(spec, hi)[1] * spec.length / spec.bending_rigidity


def test_twisted_rod_buckles_at_greenhills_torque():
    """Measured: M_c L / (E I) = 9.516 (n = 11), 9.119 (21, +1.5 %), 9.020 (41, +0.37 %): second order."""
    errors = {n: critical_torque(n) / GREENHILL - 1.0 for n in (11, 21, 41)}
    assert abs(errors[21]) < 0.02 and abs(errors[41]) < 0.005
    for coarse, fine in ((11, 21), (21, 41)):
        order = math.log(errors[coarse] / errors[fine]) / math.log((fine - 1) / (coarse - 1))
        assert 1.8 < order < 2.2, (errors, order)
