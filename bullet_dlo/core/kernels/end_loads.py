"""Clamp moments of every recorded state of a run, in one Numba call (used by the core engine)."""
from __future__ import annotations

import numpy as np
from numba import njit

from bullet_dlo.core.kernels.forces import clamp_torque
from bullet_dlo.core.kernels.holders import HeldSamples, sample_holders


@njit(cache=True, error_model="numpy")
def clamp_moment_history(m, plan, t, x, v, out):
    """Torque [N m] the cable exerts on each clamp at every recorded row, (rows, 2, 3) into ``out``.

    m: ModelArrays; plan: HolderPlan; t: recorded times [s], (rows,); x, v: recorded positions [m]
    and velocities [m/s], (rows, n, 3). The clamp directions are the held ends' at each time ``t``
    (as :func:`~bullet_dlo.core.kernels.forces.clamp_torque` takes them: spring and Kelvin-Voigt
    parts, zero for an end that is not clamped); a non-finite row gives non-finite moments.
    """
    samples = HeldSamples(np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)), np.empty((3, 2, 3)))
    for r in range(t.shape[0]):
        sample_holders(plan, t[r], 0.0, samples)
        for e in range(2):
            out[r, e, :] = clamp_torque(m, x[r], v[r], samples.dir[0], e)
