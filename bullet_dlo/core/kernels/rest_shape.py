"""Numba kernels of a curved rest shape: a rest turning angle per bending node (opt-in).

Real cables keep a set: unloaded, they are not straight. In the isotropic chain the bending energy
of node i is 1/2 k_b,i beta_i^2 (:mod:`bullet_dlo.core.kernels.forces`); with a rest turning angle
beta0_i >= 0 [rad] it becomes

    E_b,i = 1/2 k_b,i (beta_i - beta0_i)^2 = 1/2 k_b,i beta_i^2 - k_b,i beta0_i beta_i + 1/2 k_b,i beta0_i^2,

so this module adds the last two terms (energy), the force k_b beta0 d(beta)/dx and the change of the
node's bending Hessian. A rest curvature kappa0(s) [1/m] gives beta0_i = kappa0(s_i) l0.

Meaning: the energy sees the magnitude of the turning only, not its plane. It is the limit of a
naturally curved elastic rod (Bergou et al. 2008: E = 1/2 sum k |kappa - kappa0|^2 with kappa, kappa0
in the material frame) whose section turns freely about the tangent (no twist stiffness), where
min over the section's roll of |kappa - R kappa0|^2 = (|kappa| - |kappa0|)^2. It needs no material
frame (and is meant for a cable without one); a cable rests curved, in whatever plane its ends and
gravity choose. A straight node (beta = 0) is an unstable equilibrium of this energy: its force
direction is undefined there, so below :data:`BETA_MIN` the rest term is left out.

Only interior nodes carry a rest angle: at a clamp the cable leaves the gripper along the clamp
direction (the clamp spring and :func:`~bullet_dlo.core.kernels.forces.clamp_torque` are unchanged);
``rest_angle[0]`` and ``rest_angle[-1]`` are ignored. ``ModelArrays.rest_angle`` empty: no rest shape
(and no kernel here touches anything).
"""
from __future__ import annotations

import math

from bullet_dlo.core.kernels.jit import njit

BETA_MIN = 1e-6  # [rad] below this turning angle the rest term's direction is undefined: left out


@njit(cache=True, error_model="numpy", inline="always")
def has_rest_shape(m):
    """Whether the model arrays ``m`` carry rest angles."""
    return m.rest_angle.shape[0] > 0


@njit(cache=True, error_model="numpy", inline="always")
def _turn(x, i):
    """Turning angle beta [rad] at interior node i and its gradient q (6,) in (a, b), a = x_i - x_{i-1},
    b = x_{i+1} - x_i: d(beta)/da = -(w - c u)/(s |a|), d(beta)/db = -(u - c w)/(s |b|) (u, w the unit
    edges, c and s the cosine and sine of beta); q is garbage below :data:`BETA_MIN`, where no caller uses it."""
    a0, a1, a2 = x[i, 0] - x[i - 1, 0], x[i, 1] - x[i - 1, 1], x[i, 2] - x[i - 1, 2]
    b0, b1, b2 = x[i + 1, 0] - x[i, 0], x[i + 1, 1] - x[i, 1], x[i + 1, 2] - x[i, 2]
    la = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    lb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    u = (a0 / la, a1 / la, a2 / la)
    w = (b0 / lb, b1 / lb, b2 / lb)
    c = u[0] * w[0] + u[1] * w[1] + u[2] * w[2]
    cx = u[1] * w[2] - u[2] * w[1]
    cy = u[2] * w[0] - u[0] * w[2]
    cz = u[0] * w[1] - u[1] * w[0]
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    q = (-(w[0] - c * u[0]) / (s * la), -(w[1] - c * u[1]) / (s * la), -(w[2] - c * u[2]) / (s * la),
         -(u[0] - c * w[0]) / (s * lb), -(u[1] - c * w[1]) / (s * lb), -(u[2] - c * w[2]) / (s * lb))
    return math.atan2(s, c), q


@njit(cache=True, error_model="numpy", inline="always")
def _rest_node(m, x, i):
    """Node i's rest angle b0 [rad] and bending constant k [N m], or (0, 0) when it carries no rest term."""
    if i == 0 or i == x.shape[0] - 1:
        return 0.0, 0.0
    return m.rest_angle[i], m.k_bend[i]


@njit(cache=True, error_model="numpy")
def rest_shape_energy(m, x):
    """Energy the rest angles add to the isotropic bending energy [J]: sum -k b0 beta + 1/2 k b0^2."""
    e = 0.0
    if not has_rest_shape(m):
        return e
    for i in range(1, x.shape[0] - 1):
        b0, k = _rest_node(m, x, i)
        if b0 == 0.0 or k == 0.0:
            continue
        e += k * b0 * (0.5 * b0 - _turn(x, i)[0])
    return e


@njit(cache=True, error_model="numpy")
def add_rest_shape_forces(m, x, out):
    """Add the rest angles' forces k b0 d(beta)/dx [N] into ``out`` (n, 3) (the rest energy is -k b0 beta)."""
    if not has_rest_shape(m):
        return
    for i in range(1, x.shape[0] - 1):
        b0, k = _rest_node(m, x, i)
        if b0 == 0.0 or k == 0.0:
            continue
        beta, q = _turn(x, i)
        if beta < BETA_MIN:
            continue
        g = k * b0
        for j in range(3):  # d(beta)/dx: -q_a at i - 1, q_a - q_b at i, q_b at i + 1
            out[i - 1, j] -= g * q[j]
            out[i, j] += g * (q[j] - q[3 + j])
            out[i + 1, j] += g * q[3 + j]


@njit(cache=True, error_model="numpy")
def rest_shape_hessian(rest_angle, k_bend, x, i, definite, hb):
    """Turn node i's bending Hessian ``hb`` (6, 6) in (a, b) of 1/2 k beta^2 into that of 1/2 k (beta - b0)^2
    (rest_angle [rad], k_bend [N m/rad^2]: the model's arrays, passed alone: a call passing m cost ~0.5 us under
    Numba's own pipeline).

    With q = grad(beta): H = k q q^T + k beta hess(beta), so the new one is k q q^T + (1 - b0/beta)
    (H - k q q^T). ``definite``: the factor is clipped at 0 (a node bent less than its rest angle
    would otherwise contribute a negative curvature; Newton's iterations supply the rest).
    """
    if rest_angle.shape[0] == 0 or i == 0 or i == x.shape[0] - 1:  # (no rest shape; the ends: see _rest_node)
        return
    b0, k = rest_angle[i], k_bend[i]
    if b0 == 0.0 or k == 0.0:
        return
    beta, q = _turn(x, i)
    if beta < BETA_MIN:
        return
    f = 1.0 - b0 / beta
    if definite and f < 0.0:
        f = 0.0
    for r in range(6):
        for col in range(6):
            kq = k * q[r] * q[col]
            hb[r, col] = kq + f * (hb[r, col] - kq)
