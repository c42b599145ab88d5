"""A Panda keeps its flange poses and Jacobians along a joint path: a beam fit predicts the same recordings many
times, and the kinematics along a recording (one pose reset and query per row) cost more than the strip's run.
Kept answers are the computed ones, returned as copies; another path is computed anew; one call sets all joints."""
from __future__ import annotations

import numpy as np

from bullet_dlo.reality.panda import N_JOINTS, Panda


def test_a_path_is_computed_once_and_its_answers_are_the_computed_ones(monkeypatch):
    q = np.random.default_rng(0).uniform(-1.0, 1.0, (20, N_JOINTS))
    with Panda() as panda:
        fresh = [panda.jacobian(row) for row in q], [panda.flange_pose(row) for row in q]
        calls = []
        single = panda.jacobian
        monkeypatch.setattr(panda, "jacobian", lambda row: (calls.append(1), single(row))[1])
        first = panda.jacobians(q)
        np.testing.assert_array_equal(first, np.array(fresh[0]))
        first[:] = 0.0  # a caller's copy: the kept answer is untouched
        np.testing.assert_array_equal(panda.jacobians(q), np.array(fresh[0]))
        assert len(calls) == len(q)
        panda.jacobians(q[:5] + 0.1)
        assert len(calls) == len(q) + 5
        pos, rot = panda.flange_path(q)
        np.testing.assert_array_equal(pos, np.array([p for p, _ in fresh[1]]))
        np.testing.assert_array_equal(rot, np.array([r for _, r in fresh[1]]))
