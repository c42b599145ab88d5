"""The shapes' frames from their bodies' base states in one compiled call (``contact.set_frames``, also what
``ContactSet._set_pose`` calls for one shape without native reads), against what the Python step computed before:
PyBullet's quaternion matrix and NumPy's products, to the bit."""
from __future__ import annotations

import numpy as np
import pybullet as pb

from bullet_dlo.bullet.contact import set_frames


def test_frames_equal_pybullets_matrix_and_numpys_products_to_the_bit():
    rng = np.random.default_rng(7)
    k = 400
    q = rng.normal(size=(k, 4))
    q[:5] = [[0, 0, 0, 1], [1, 0, 0, 0], [0, 0, 1e-9, 1], [0.3, -0.2, 0.1, 2.0], [0, 0, 0, -1]]
    q /= np.linalg.norm(q, axis=1)[:, None]  # (Bullet's base states hold unit quaternions)
    bases = np.concatenate([rng.normal(size=(k, 3)), q, rng.normal(size=(k, 6))], axis=1)
    moved = rng.random(k) < 0.8
    lpos, lrot = rng.normal(size=(k, 3)), rng.normal(size=(k, 3, 3))
    free_slot = np.where(rng.random(k) < 0.5, 0, -1).astype(np.int64)
    diag = rng.random((k, 3))
    com, pos, rot, inertia = (np.full((k, 3), 7.0), np.full((k, 3), 7.0), np.full((k, 3, 3), 7.0),
                              np.full((k, 3, 3), 7.0))
    set_frames(bases, moved, lpos, lrot, free_slot, diag, com, pos, rot, inertia)
    for s in range(k):
        if not moved[s]:  # untouched
            assert (com[s] == 7).all() and (pos[s] == 7).all() and (rot[s] == 7).all() and (inertia[s] == 7).all()
            continue
        r = np.array(pb.getMatrixFromQuaternion(bases[s, 3:7].tolist())).reshape(3, 3)
        assert np.array_equal(com[s], bases[s, 0:3])
        assert np.array_equal(pos[s], bases[s, 0:3] + r @ lpos[s]), s
        assert np.array_equal(rot[s], r @ lrot[s]), s
        if free_slot[s] >= 0:
            assert np.array_equal(inertia[s], (r * diag[s]) @ r.T), s
        else:
            assert (inertia[s] == 7).all()
