"""Kelvin-Voigt damping of a flat section: each bending plane damped by its own stiffness (issue 22, item 1).

``internal_damping`` tau [s] promises that mode k decays as exp(-tau omega_k^2 t / 2). A round section's bending
damper is tau k_b on the turning angle's rate; a flat one's must be tau times the node's bending stiffness in each
plane, tau/2 sum_k (k1 m1 m1^T + k2 m2 m2^T + kbar t t^T). Before, the flat section had the round damper with the
mean stiffness kbar = (k1 + k2) / 2: a steel strip 40 x 0.5 mm released from a bend through its thickness crept
back (its weak plane 3200 times over-damped) instead of ringing.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from bullet_dlo.core.engine import simulate
from test_damping import check_dampers  # tests/core/test_damping.py (pytest puts this folder on the path)

from bullet_dlo.core.kernels.forces import dissipation, internal_damping_forces
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

L, WIDTH, THICK, E, RHO = 0.5, 0.04, 0.0005, 2e11, 7850.0


def _strip(n: int, tau: float) -> CableSpec:
    return CableSpec(length=L, diameter=THICK, mass=RHO * WIDTH * THICK * L, youngs_modulus=E, section="rectangle",
                     width=WIDTH, thickness=THICK, n_masses=n, internal_damping=tau)


def _bent(tau=1e-3, n=8, seed=1, ends=("clamped", "free")):
    """A strip bent at random (frames built from the positions), its kernel arrays, clamp directions, the generator."""
    model = CableModel.straight(_strip(n, tau), ends=ends, gravity=(0.0, 0.0, 0.0))
    rng = np.random.default_rng(seed)
    x = model.x0 + 0.01 * rng.standard_normal(model.x0.shape)
    x[0] = model.x0[0]
    m, dirs = model.kernel_arrays(), model.holder_plan().start_dir
    return m, x, dirs, rng


def test_a_flat_sections_dampers_derive_from_its_dissipation_function_with_exact_jacobian():
    m, x, dirs, rng = _bent()
    check_dampers(m, x, rng.standard_normal(x.shape), dirs)


def test_a_flat_strip_translating_and_turning_in_its_plane_feels_no_internal_damping():
    """As the round section's dampers (tests/core/test_damping.py): a strip bent in a plane, moved rigidly in it."""
    m, x, dirs, _ = _bent(ends=("free", "free"))
    x[:, 2] = 0.5  # bent in the horizontal plane
    for omega in ([0.0, 0.0, 2.0], [0.0, 0.0, -0.7]):
        v = np.array([0.3, -0.1, 0.2]) + np.cross(np.array(omega), x)
        f = np.zeros_like(x)
        internal_damping_forces(m, x, v, dirs, f)
        scale = m.c_bend.max() * np.abs(v).max() / (L / 7)  # [N] a damper's force at a rate |v| / l0
        assert np.abs(f).max() < 1e-12 * scale and dissipation(m, x, v, dirs) < 1e-24 * scale**2, omega


def _decay(n: int, tau: float, axis: int, dt: float, duration: float) -> tuple[float, float]:
    """Amplitude decay rate [1/s] and angular frequency [rad/s] of the strip's tip released from a static bend along
    ``axis`` (1: across its width, the strong plane; 2: through its thickness, the weak one), no gravity."""
    spec = _strip(n, tau)
    model = CableModel.straight(spec, ends=("clamped", "free"), start=(0.0, 0.0, 0.0), gravity=(0.0, 0.0, 0.0))
    ei = E * WIDTH * THICK**3 / 12 if axis == 2 else E * THICK * WIDTH**3 / 12
    f = np.zeros((n, 3))
    f[-1, axis] = 1e-3 * 3.0 * ei / L**2  # a tip deflection of 1e-3 L
    start = solve_static(model, f_ext=f).state()
    res = simulate(model, "implicit_midpoint", dt, duration, state=start, record_every=1)
    a = res.x[:, -1, axis]
    peaks = [i for i in range(1, len(a) - 1) if abs(a[i]) >= abs(a[i - 1]) and abs(a[i]) > abs(a[i + 1])]
    rate = -np.polyfit(res.t[peaks], np.log(np.abs(a[peaks])), 1)[0]
    omega = math.pi / np.median(np.diff(res.t[peaks]))  # (peaks of |a|: half periods)
    return rate, omega


@pytest.mark.parametrize("axis, tau, dt, duration", [(2, 2e-3, 2e-3, 4.0), (1, 2e-5, 1e-4, 0.4)],
                         ids=["weak-plane", "strong-plane"])
def test_each_bending_plane_of_a_strip_decays_at_tau_omega_squared_over_two(axis, tau, dt, duration):
    """Steel strip 0.5 m x 40 mm x 0.5 mm, clamped-free, n 20: its first mode in the weak plane (1.6 Hz) and in the
    strong plane (130 Hz, 80 times faster) each decay at tau omega_1^2 / 2 of their own frequency (the undamped run's
    own decay, the integrator's, subtracted)."""
    rate, omega = _decay(20, tau, axis, dt, duration)
    rate0, _ = _decay(20, 0.0, axis, dt, duration)
    assert rate - rate0 == pytest.approx(tau * omega**2 / 2, rel=0.03)
