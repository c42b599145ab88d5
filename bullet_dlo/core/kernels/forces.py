"""Numba kernels: MSD cable energy, forces and the analytic force Jacobian.

The chain has n nodes x_i (shape (n, 3), m) and n-1 segments e_i = x_{i+1} - x_i.

* stretch springs:  E_s = 1/2 k_s,i (|e_i| - l0_i)^2
* bending springs at interior nodes: E_b = 1/2 k_b,i beta_i^2, beta_i the angle between
  e_{i-1} and e_i (atan2(|e_{i-1} x e_i|, e_{i-1} . e_i))
* clamp springs at a clamped end: the same bending energy between the clamp direction
  (held by the gripper) and the first (last) segment, stiffness ``k_bend[0]`` (``k_bend[-1]``);
  a stiffness of 0 means the end is not clamped.

Kernels take the model as :class:`bullet_dlo.core.model.ModelArrays` (``m``), positions x
[m] (n, 3), velocities v [m/s] (n, 3) and the clamp directions ``dirs`` (unit, (2, 3): first,
last end; used only where ``k_bend`` of that end is nonzero). They write into preallocated
outputs and never allocate per node, so the same code serves the core time loop, the static
solver and the per-step PyBullet coupling. A new force term goes into :func:`total_forces`
(and, if it depends on x, :func:`force_jacobian`), its parameters into ``ModelArrays``.

Jacobian storage: block-banded, ``jac[i, o] = dF_i / dx_{i+o-2}`` with shape (n, 5, 3, 3)
(bending couples nodes up to two apart). ``definite=True`` drops the compressive part of the
stretch Hessian (the usual filter that keeps M + h^2 K positive definite for implicit steps);
``definite=False`` gives the exact derivative.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

BAND = 2  # block half-bandwidth of the force Jacobian


@njit(cache=True, error_model="numpy", inline="always")
def _angle_terms(ax, ay, az, bx, by, bz):
    """Angle between vectors a and b and the pieces its derivatives need.

    Returns (theta, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, alpha) with u, w the unit
    vectors, c = cos, s = sin, ratio = theta/sin(theta) and alpha = (s - theta c)/s^3, both
    evaluated by series near theta = 0 where they are smooth but 0/0 numerically.
    """
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    ux, uy, uz = ax / la, ay / la, az / la
    wx, wy, wz = bx / lb, by / lb, bz / lb
    c = ux * wx + uy * wy + uz * wz
    cx = uy * wz - uz * wy
    cy = uz * wx - ux * wz
    cz = ux * wy - uy * wx
    s = math.sqrt(cx * cx + cy * cy + cz * cz)
    theta = math.atan2(s, c)
    if theta < 1e-3:
        t2 = theta * theta
        ratio = 1.0 + t2 / 6.0
        alpha = 1.0 / 3.0 + 2.0 * t2 / 15.0
    else:
        ratio = theta / s
        alpha = (s - theta * c) / (s * s * s)
    return theta, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, alpha


@njit(cache=True, error_model="numpy", inline="always")
def _node_edges(x, i, dirs):
    """Incoming edge a and outgoing edge b at node i; the clamp directions stand in at the ends."""
    n = x.shape[0]
    if i == 0:
        a0, a1, a2 = dirs[0, 0], dirs[0, 1], dirs[0, 2]
    else:
        a0, a1, a2 = x[i, 0] - x[i - 1, 0], x[i, 1] - x[i - 1, 1], x[i, 2] - x[i - 1, 2]
    if i == n - 1:
        b0, b1, b2 = dirs[1, 0], dirs[1, 1], dirs[1, 2]
    else:
        b0, b1, b2 = x[i + 1, 0] - x[i, 0], x[i + 1, 1] - x[i, 1], x[i + 1, 2] - x[i, 2]
    return a0, a1, a2, b0, b1, b2


@njit(cache=True, error_model="numpy")
def internal_energy(m, x, dirs):
    """Elastic energy of stretch, bending and clamp springs [J]."""
    n = x.shape[0]
    e = 0.0
    for i in range(n - 1):
        dx = x[i + 1, 0] - x[i, 0]
        dy = x[i + 1, 1] - x[i, 1]
        dz = x[i + 1, 2] - x[i, 2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz) - m.rest_length[i]
        e += 0.5 * m.k_stretch[i] * d * d
    for i in range(n):
        k = m.k_bend[i]
        if k == 0.0:
            continue
        a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
        theta = _angle_terms(a0, a1, a2, b0, b1, b2)[0]
        e += 0.5 * k * theta * theta
    return e


@njit(cache=True, error_model="numpy")
def mechanical_energy(m, x, v, dirs):
    """Kinetic + elastic + gravitational energy [J] (gravitational zero at the origin)."""
    e = internal_energy(m, x, dirs)
    for i in range(x.shape[0]):
        for j in range(3):
            e += 0.5 * m.mass[i] * v[i, j] * v[i, j] - m.mass[i] * m.gravity[j] * x[i, j]
    return e


@njit(cache=True, error_model="numpy")
def internal_forces(m, x, dirs, out):
    """Write the elastic forces -dE/dx [N], shape (n, 3), into ``out`` (overwritten)."""
    n = x.shape[0]
    out[:, :] = 0.0
    for i in range(n - 1):
        dx = x[i + 1, 0] - x[i, 0]
        dy = x[i + 1, 1] - x[i, 1]
        dz = x[i + 1, 2] - x[i, 2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        f = m.k_stretch[i] * (length - m.rest_length[i]) / length  # tension / length
        out[i, 0] += f * dx
        out[i, 1] += f * dy
        out[i, 2] += f * dz
        out[i + 1, 0] -= f * dx
        out[i + 1, 1] -= f * dy
        out[i + 1, 2] -= f * dz
    for i in range(n):
        k = m.k_bend[i]
        if k == 0.0:
            continue
        a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
        _, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, _ = _angle_terms(a0, a1, a2, b0, b1, b2)
        # dE/da = -k (theta/s) (w - c u)/|a| ; dE/db = -k (theta/s) (u - c w)/|b|
        ga = -k * ratio / la
        gb = -k * ratio / lb
        gax, gay, gaz = ga * (wx - c * ux), ga * (wy - c * uy), ga * (wz - c * uz)
        gbx, gby, gbz = gb * (ux - c * wx), gb * (uy - c * wy), gb * (uz - c * wz)
        # a = x_i - x_{i-1}, b = x_{i+1} - x_i ; F = -dE/dx
        if i > 0:  # a depends on x_{i-1} (-1) and x_i (+1)
            out[i - 1, 0] += gax
            out[i - 1, 1] += gay
            out[i - 1, 2] += gaz
            out[i, 0] -= gax
            out[i, 1] -= gay
            out[i, 2] -= gaz
        if i < n - 1:  # b depends on x_i (-1) and x_{i+1} (+1)
            out[i, 0] += gbx
            out[i, 1] += gby
            out[i, 2] += gbz
            out[i + 1, 0] -= gbx
            out[i + 1, 1] -= gby
            out[i + 1, 2] -= gbz


@njit(cache=True, error_model="numpy")
def clamp_torque(m, x, dirs, end):
    """Torque [N m] the cable exerts on the clamp at ``end`` (0 first, 1 last), world frame.

    The clamp spring pulls the clamp direction towards the adjacent segment with magnitude
    k * beta about the axis d x e (zero when the end is not clamped).
    """
    n = x.shape[0]
    out = np.zeros(3)
    if end == 0:
        k = m.k_bend[0]
        d = dirs[0]
        e0, e1, e2 = x[1, 0] - x[0, 0], x[1, 1] - x[0, 1], x[1, 2] - x[0, 2]
    else:
        k = m.k_bend[n - 1]
        d = -dirs[1]  # direction from the clamp into the cable
        e0, e1, e2 = x[n - 2, 0] - x[n - 1, 0], x[n - 2, 1] - x[n - 1, 1], x[n - 2, 2] - x[n - 1, 2]
    if k == 0.0:
        return out
    _, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, _ = _angle_terms(d[0], d[1], d[2], e0, e1, e2)
    # k * beta * (u x w)/|u x w| = k * (beta/s) * (u x w)
    out[0] = k * ratio * (uy * wz - uz * wy)
    out[1] = k * ratio * (uz * wx - ux * wz)
    out[2] = k * ratio * (ux * wy - uy * wx)
    return out


@njit(cache=True, error_model="numpy")
def force_jacobian(m, x, dirs, definite, jac):
    """Write dF/dx of the elastic forces [N/m] into ``jac`` (shape (n, 5, 3, 3), overwritten).

    Gravity and external forces add nothing; viscous damping enters as dF/dv = -diag(c)
    (see :func:`bullet_dlo.core.kernels.banded.assemble_system`).
    """
    n = x.shape[0]
    jac[:, :, :, :] = 0.0
    hs = np.empty((3, 3))
    d = np.empty(3)
    for i in range(n - 1):
        d[0] = x[i + 1, 0] - x[i, 0]
        d[1] = x[i + 1, 1] - x[i, 1]
        d[2] = x[i + 1, 2] - x[i, 2]
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        k = m.k_stretch[i]
        geo = 1.0 - m.rest_length[i] / length
        if definite and geo < 0.0:
            geo = 0.0
        for r in range(3):
            for col in range(3):
                dd = d[r] * d[col] / (length * length)
                hs[r, col] = k * (dd + geo * ((1.0 if r == col else 0.0) - dd))
        # e = x_{i+1} - x_i: Hessian blocks (i,i)=+H, (i,i+1)=-H, (i+1,i)=-H, (i+1,i+1)=+H
        for r in range(3):
            for col in range(3):
                hv = hs[r, col]
                jac[i, 2, r, col] -= hv
                jac[i, 3, r, col] += hv
                jac[i + 1, 1, r, col] += hv
                jac[i + 1, 2, r, col] -= hv
    hb = np.empty((6, 6))
    g = np.empty(12)
    for i in range(n):
        k = m.k_bend[i]
        if k == 0.0:
            continue
        a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
        _bend_hessian(a0, a1, a2, b0, b1, b2, k, g, hb)
        # a = x_i - x_{i-1}, b = x_{i+1} - x_i: chain rule onto the nodes (jac[p, q-p+2] -= H_pq)
        for r in range(3):
            for col in range(3):
                haa, hab = hb[r, col], hb[r, 3 + col]
                hba, hbb = hb[3 + r, col], hb[3 + r, 3 + col]
                if i == 0:  # clamp at the first end: only b moves (nodes 0, 1)
                    jac[0, 2, r, col] -= hbb
                    jac[0, 3, r, col] += hbb
                    jac[1, 1, r, col] += hbb
                    jac[1, 2, r, col] -= hbb
                elif i == n - 1:  # clamp at the last end: only a moves (nodes n-2, n-1)
                    jac[n - 2, 2, r, col] -= haa
                    jac[n - 2, 3, r, col] += haa
                    jac[n - 1, 1, r, col] += haa
                    jac[n - 1, 2, r, col] -= haa
                else:
                    jac[i - 1, 2, r, col] -= haa
                    jac[i - 1, 3, r, col] -= hab - haa
                    jac[i - 1, 4, r, col] += hab
                    jac[i, 1, r, col] -= hba - haa
                    jac[i, 2, r, col] -= haa - hab - hba + hbb
                    jac[i, 3, r, col] -= hab - hbb
                    jac[i + 1, 0, r, col] += hba
                    jac[i + 1, 1, r, col] -= hba - hbb
                    jac[i + 1, 2, r, col] -= hbb


@njit(cache=True, error_model="numpy")
def _bend_hessian(a0, a1, a2, b0, b1, b2, k, g, out):
    """Hessian of 1/2 k theta(a, b)^2 with respect to (a, b), shape (6, 6), into ``out`` (g: scratch (12,)).

    H = k [alpha grad(c) grad(c)^T - (theta/s) hess(c)], c = cos(theta), written so that
    every term stays finite at theta = 0 (straight cable).
    """
    _, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, alpha = _angle_terms(a0, a1, a2, b0, b1, b2)
    u = g[6:9]
    w = g[9:12]
    u[0], u[1], u[2] = ux, uy, uz
    w[0], w[1], w[2] = wx, wy, wz
    for r in range(3):
        g[r] = (w[r] - c * u[r]) / la
        g[3 + r] = (u[r] - c * w[r]) / lb
    iaa = 1.0 / (la * la)
    ibb = 1.0 / (lb * lb)
    iab = 1.0 / (la * lb)
    for r in range(3):
        for col in range(3):
            eye = 1.0 if r == col else 0.0
            uw = w[r] * u[col] + u[r] * w[col]
            caa = (-uw + 3.0 * c * u[r] * u[col] - c * eye) * iaa
            cbb = (-uw + 3.0 * c * w[r] * w[col] - c * eye) * ibb
            cab = (eye - w[r] * w[col] - u[r] * u[col] + c * u[r] * w[col]) * iab
            out[r, col] = k * (alpha * g[r] * g[col] - ratio * caa)
            out[3 + r, 3 + col] = k * (alpha * g[3 + r] * g[3 + col] - ratio * cbb)
            out[r, 3 + col] = k * (alpha * g[r] * g[3 + col] - ratio * cab)
            out[3 + col, r] = out[r, 3 + col]


@njit(cache=True, error_model="numpy")
def total_forces(m, x, v, dirs, out):
    """Elastic + gravity + viscous damping + external forces [N], shape (n, 3), into ``out``."""
    internal_forces(m, x, dirs, out)
    n = x.shape[0]
    for i in range(n):
        for j in range(3):
            out[i, j] += m.mass[i] * m.gravity[j] - m.damp[i] * v[i, j] + m.f_ext[i, j]


@njit(cache=True, error_model="numpy")
def max_strain(m, x):
    """Largest |l/l0 - 1| over segments (dimensionless)."""
    worst = 0.0
    for i in range(x.shape[0] - 1):
        dx = x[i + 1, 0] - x[i, 0]
        dy = x[i + 1, 1] - x[i, 1]
        dz = x[i + 1, 2] - x[i, 2]
        s = abs(math.sqrt(dx * dx + dy * dy + dz * dz) / m.rest_length[i] - 1.0)
        if not s <= worst:  # also propagates NaN
            worst = s
    return worst


def jacobian_blocks_to_dense(jac: np.ndarray) -> np.ndarray:
    """Expand a block-banded Jacobian (n, 5, 3, 3) into a dense (3n, 3n) matrix (tests)."""
    n = jac.shape[0]
    dense = np.zeros((3 * n, 3 * n))
    for i in range(n):
        for o in range(2 * BAND + 1):
            j = i + o - BAND
            if 0 <= j < n:
                dense[3 * i:3 * i + 3, 3 * j:3 * j + 3] = jac[i, o]
    return dense
