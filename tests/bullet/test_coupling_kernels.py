"""The coupling kernels against closed forms: measured gripper poses extrapolated over a step."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from bullet_dlo.bullet.kernels import ExternalHolders, external_samples
from bullet_dlo.core.kernels.holders import empty_samples


def test_external_samples_extrapolate_at_constant_acceleration_and_spin_rate(rng):
    direction = rng.normal(size=(2, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    ext = ExternalHolders(active=np.array([False, True]), pos=rng.normal(size=(2, 3)), vel=rng.normal(size=(2, 3)),
                          acc=rng.normal(size=(2, 3)), omega=rng.normal(size=(2, 3)), alpha=rng.normal(size=(2, 3)),
                          dir=direction,
                          normal=np.zeros((2, 3)))
    samples = empty_samples()
    tau0, hs = 2e-3, 1e-3
    external_samples(ext, 1, tau0, hs, samples, np.zeros((0, 2, 3)))
    for k, tau in enumerate((tau0, tau0 + hs / 2, tau0 + hs)):
        assert np.allclose(samples.pos[k, 1], ext.pos[1] + tau * ext.vel[1] + 0.5 * tau**2 * ext.acc[1], atol=1e-15)
        assert np.allclose(samples.vel[k, 1], ext.vel[1] + tau * ext.acc[1]) and np.allclose(samples.acc[k, 1], ext.acc[1])
        turn = tau * ext.omega[1] + 0.5 * tau**2 * ext.alpha[1]  # a fixed axis: the angle of constant alpha
        assert np.allclose(samples.dir[k, 1], Rotation.from_rotvec(turn).apply(direction[1]), atol=1e-14)
    assert np.all(samples.pos[:, 0] == 0.0)  # the other end is left alone
