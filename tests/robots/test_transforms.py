"""Rotations: every conversion checked against SciPy's Rotation and against its defining property."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.robots.transforms import angle_between, quat_from_axes, quat_from_matrix, quat_z_onto, rotation


def test_rotation_matches_scipy_and_normalises(rng):
    for q in rng.normal(size=(50, 4)):
        expected = Rotation.from_quat(q).as_matrix()  # SciPy normalises too
        assert np.allclose(rotation(q), expected, atol=1e-12)
        assert np.allclose(rotation(3.0 * q), expected, atol=1e-12)


def test_quat_from_matrix_round_trip():
    for rot in Rotation.random(20, random_state=1).as_matrix():
        assert np.allclose(rotation(quat_from_matrix(rot)), rot, atol=1e-12)


def test_quat_from_axes_keeps_z_and_orthogonalises_x():
    q = quat_from_axes((1.0, 0.0, 0.5), (0.0, 0.0, -2.0))
    m = rotation(q)
    assert np.allclose(m[:, 2], [0.0, 0.0, -1.0], atol=1e-15)
    assert np.allclose(m[:, 0], [1.0, 0.0, 0.0], atol=1e-15)  # x's component along z removed
    assert np.allclose(m[:, 1], np.cross(m[:, 2], m[:, 0]), atol=1e-15)  # right-handed
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)


def test_angle_between():
    a = Rotation.from_euler("z", 0.3).as_quat()
    b = Rotation.from_euler("z", -0.4).as_quat()
    assert angle_between(a, b) == pytest.approx(0.7, abs=1e-12)
    assert angle_between(a, -a) == pytest.approx(0.0, abs=1e-7)  # q and -q are one orientation
    assert angle_between([0, 0, 0, 1], [1, 0, 0, 0]) == pytest.approx(np.pi, abs=1e-12)


@pytest.mark.parametrize("d", [(0.3, -0.2, 0.9), (1.0, 0.0, 0.0), (0.0, 0.0, 2.0), (0.0, 0.0, -1.0),
                               (-1e-3, 2e-3, -5e-3)])
def test_quat_z_onto_takes_z_to_the_direction(d):
    m = rotation(quat_z_onto(d))
    assert np.allclose(m[:, 2], np.asarray(d) / np.linalg.norm(d), atol=1e-12)
    assert np.allclose(m.T @ m, np.eye(3), atol=1e-12)


def test_quat_z_onto_zero_vector_is_identity():
    assert quat_z_onto((0.0, 0.0, 0.0)) == [0.0, 0.0, 0.0, 1.0]
