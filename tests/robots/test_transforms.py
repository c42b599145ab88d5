"""Rotations: every conversion checked against SciPy's Rotation and against its defining property."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bullet_dlo.robots.transforms import angle_between, cross3, quat_from_axes, quat_from_matrix, rotation


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


def test_quat_from_matrix_every_pivot():
    """Half turns about x, y, z and a quarter turn about z take Shepperd's four branches."""
    for rotvec in ([np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], [0, 0, np.pi / 2], [2.0, 1.0, -0.5]):
        rot = Rotation.from_rotvec(rotvec)
        q = quat_from_matrix(rot.as_matrix())
        assert angle_between(q, rot.as_quat()) == pytest.approx(0.0, abs=1e-7)


def test_cross3_is_np_cross_to_the_bit(rng):
    for a, b in rng.normal(size=(100, 2, 3)):
        assert np.array_equal(cross3(a, b), np.cross(a, b))
