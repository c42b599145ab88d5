"""Forces against finite differences of the energy, Jacobian against finite differences of
the forces, and the energy kernel against a plain-NumPy transcription of the model."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.core.kernels import forces
from bullet_dlo.core.kernels.banded import (
    HALF,
    assemble_system,
    band_matrix_to_dense,
    band_solve,
    band_substitute,
)
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec


def reference_energy(x, spec: CableSpec, k_bend, d_first, d_last):
    """Model energy written directly from the formulas (no shared code with the kernels)."""
    seg = np.diff(x, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    e = 0.5 * spec.k_stretch * np.sum((lengths - spec.rest_length) ** 2)
    tangents = np.vstack([d_first, seg, d_last])  # clamp directions bracket the segments
    for i in range(x.shape[0]):
        if k_bend[i] == 0.0:
            continue
        li, lj = tangents[i], tangents[i + 1]
        beta = np.arctan2(np.linalg.norm(np.cross(lj, li)), np.dot(lj, li))
        e += 0.5 * k_bend[i] * beta**2
    return e


def _setup(n=7, ends=("clamped", "clamped"), noise=0.006, seed=0):
    spec = CableSpec.lv2017(n_masses=n)
    model = CableModel.straight(spec, ends=ends)
    rng = np.random.default_rng(seed)
    x = model.x0 + rng.normal(scale=noise, size=model.x0.shape)
    d1 = np.array([1.0, 0.3, -0.2]); d1 /= np.linalg.norm(d1)
    d2 = np.array([0.8, -0.4, 0.3]); d2 /= np.linalg.norm(d2)
    return spec, model.kernel_arrays(), x, d1, d2


def dirs(d1, d2):
    """Clamp directions as the kernels take them, (2, 3)."""
    return np.stack([d1, d2])


def finite_difference(fn, x, eps=1e-7):
    """Central differences of fn (array -> array or scalar) with respect to every entry of x."""
    cols = []
    for i in range(x.shape[0]):
        for j in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, j] += eps
            xm[i, j] -= eps
            cols.append(np.ravel((fn(xp) - fn(xm)) / (2 * eps)))
    return np.array(cols).T


def _forces(x, a, d1, d2):
    f = np.zeros_like(x)
    forces.internal_forces(a, x, dirs(d1, d2), f)
    return f


@pytest.mark.parametrize("ends", [("clamped", "clamped"), ("free", "free"), ("pinned", "clamped")])
def test_energy_matches_reference(ends):
    spec, a, x, d1, d2 = _setup(ends=ends)
    e = forces.internal_energy(a, x, dirs(d1, d2))
    assert e == pytest.approx(reference_energy(x, spec, a.k_bend, d1, d2), rel=1e-12)
    assert e > 0


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("ends", [("clamped", "clamped"), ("free", "free")])
def test_forces_are_minus_energy_gradient(seed, ends):
    spec, a, x, d1, d2 = _setup(ends=ends, seed=seed)
    f = _forces(x, a, d1, d2)
    fd = -finite_difference(lambda y: reference_energy(y, spec, a.k_bend, d1, d2), x).reshape(x.shape)
    assert np.max(np.abs(f - fd)) < 1e-6 * np.max(np.abs(f))


@pytest.mark.parametrize("noise", [0.0, 1e-4, 6e-3])
def test_jacobian_matches_force_differences(noise):
    spec, a, x, d1, d2 = _setup(noise=noise)
    if noise == 0.0:  # exactly straight: the bending terms must stay finite (theta -> 0 limit)
        d1 = d2 = np.array([1.0, 0.0, 0.0])
    jac = np.zeros((x.shape[0], 5, 3, 3))
    forces.force_jacobian(a, x, dirs(d1, d2), False, jac)
    dense = forces.jacobian_blocks_to_dense(jac)
    fd = finite_difference(lambda y: _forces(y, a, d1, d2), x)
    assert np.all(np.isfinite(dense))
    assert np.max(np.abs(dense - fd)) < 1e-6 * np.max(np.abs(dense))
    assert np.allclose(dense, dense.T, atol=1e-9 * np.abs(dense).max())  # conservative forces


def test_definite_jacobian_is_negative_semidefinite_under_compression():
    spec, a, x, d1, d2 = _setup(noise=0.0)
    x = x * np.array([0.9, 1.0, 1.0]) + np.array([0.0, 0.0, 0.05])  # compress every segment by 10 %
    jac = np.zeros((x.shape[0], 5, 3, 3))
    d = np.array([1.0, 0.0, 0.0])
    forces.force_jacobian(a, x, dirs(d, d), False, jac)
    exact = np.linalg.eigvalsh(forces.jacobian_blocks_to_dense(jac))
    forces.force_jacobian(a, x, dirs(d, d), True, jac)
    filtered = np.linalg.eigvalsh(forces.jacobian_blocks_to_dense(jac))
    assert exact.max() > 1.0  # the exact Jacobian has unstable (buckling) directions
    assert filtered.max() < 1e-6 * abs(filtered.min())


def test_internal_forces_balance_without_clamps():
    _, a, x, d1, d2 = _setup(ends=("free", "free"))
    f = _forces(x, a, d1, d2)
    assert np.allclose(f.sum(axis=0), 0.0, atol=1e-9 * np.abs(f).max())
    torque = np.cross(x, f).sum(axis=0)  # no external torque either: rotation invariance
    assert np.allclose(torque, 0.0, atol=1e-9 * np.abs(f).max())


def test_clamp_torque_is_minus_energy_rotation_derivative():
    _, a, x, d1, d2 = _setup()
    tau = forces.clamp_torque(a, x, np.zeros_like(x), dirs(d1, d2), 0)
    eps = 1e-7
    for axis in range(3):
        w = np.zeros(3)
        w[axis] = eps

        def rotated(d, w):
            return d + np.cross(w, d)

        ep = forces.internal_energy(a, x, dirs(rotated(d1, w), d2))
        em = forces.internal_energy(a, x, dirs(rotated(d1, -w), d2))
        assert tau[axis] == pytest.approx(-(ep - em) / (2 * eps), rel=1e-5, abs=1e-9)


@pytest.mark.parametrize("end", [0, 1])
def test_clamp_moment_includes_its_kelvin_voigt_damper(end):
    """Angular momentum balance of the damping terms for a planar motion (x-z plane).

    A rigid rotation of cable and clamp about the plane's normal changes no turning-angle rate,
    so the Rayleigh function is invariant under it: the damping forces' moment about y plus the
    damping moment on the clamp must vanish. Without the clamp damper's moment (only the spring's,
    as before) the balance is off by the damper's whole moment.
    """
    spec = CableSpec.lv2017(n_masses=7, internal_damping=0.01)
    model = CableModel.straight(spec, ends=("clamped", "clamped"))
    a = model.kernel_arrays()
    rng = np.random.default_rng(3)
    x = model.x0.copy()
    x[:, 2] += 0.01 * np.sin(np.linspace(0.0, 3.0, len(x)))  # bent in the x-z plane
    v = rng.normal(scale=0.05, size=x.shape)
    v[:, 1] = 0.0  # planar velocities
    d = np.stack([np.array([1.0, 0.0, 0.2]) / np.hypot(1.0, 0.2), np.array([1.0, 0.0, -0.3]) / np.hypot(1.0, 0.3)])
    f_damp = np.zeros_like(x)
    forces.internal_damping_forces(a, x, v, d, f_damp)
    nodes_moment = np.cross(x, f_damp).sum(axis=0)[1]
    clamp_moment = (forces.clamp_torque(a, x, v, d, end) - forces.clamp_torque(a, x, np.zeros_like(v), d, end))[1]
    other = 1 - end  # the other clamp's damper takes its share too
    other_moment = (forces.clamp_torque(a, x, v, d, other) - forces.clamp_torque(a, x, np.zeros_like(v), d, other))[1]
    assert abs(clamp_moment) > 1e-3 * abs(nodes_moment) > 0.0  # not vacuous
    scale = np.abs(np.cross(x, f_damp)[:, 1]).sum()  # the size of the terms that cancel
    assert nodes_moment + clamp_moment + other_moment == pytest.approx(0.0, abs=1e-9 * scale)


def test_banded_solve_matches_dense(rng):
    n = 12
    spec, a, x, d1, d2 = _setup(n=n)
    jac = np.zeros((n, 5, 3, 3))
    forces.force_jacobian(a, x, dirs(d1, d2), True, jac)
    held = np.zeros(n, dtype=bool)
    held[0] = held[-1] = True
    m = a._replace(damp=a.damp + 0.1, held=held)
    band = np.zeros((3 * n, 2 * HALF + 1))
    assemble_system(m, jac, 1.0, 1e-6, 1e-3, band)
    dense = band_matrix_to_dense(band)
    rhs = rng.normal(size=3 * n)
    rhs[:3] = rhs[-3:] = 0.0
    y = rhs.copy()
    band_solve(band, y)
    assert np.allclose(dense @ y, rhs, atol=1e-10 * np.abs(rhs).max())
    assert np.allclose(y, np.linalg.solve(dense, rhs))
    for _ in range(3):  # the eliminated band's factors solve other right-hand sides (a chord iteration's)
        rhs = rng.normal(size=3 * n)
        rhs[:3] = rhs[-3:] = 0.0
        y = rhs.copy()
        band_substitute(band, y)
        assert np.allclose(dense @ y, rhs, atol=1e-10 * np.abs(rhs).max())
