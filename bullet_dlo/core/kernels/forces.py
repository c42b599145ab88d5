"""Numba kernels: MSD cable energy, forces and the analytic force Jacobian.

The chain has n nodes x_i (shape (n, 3), m) and n-1 segments e_i = x_{i+1} - x_i.

* stretch springs:  E_s = 1/2 k_s,i (|e_i| - l0_i)^2
* bending springs at interior nodes: E_b = 1/2 k_b,i beta_i^2, beta_i the angle between
  e_{i-1} and e_i (atan2(|e_{i-1} x e_i|, e_{i-1} . e_i))
* clamp springs at a clamped end: the same bending energy between the clamp direction
  (held by the gripper) and the first (last) segment, stiffness ``k_bend[0]`` (``k_bend[-1]``);
  a stiffness of 0 means the end is not clamped.

Kernels take the model as :class:`bullet_dlo.core.model.KernelArrays` (``m``: the model's parameters with the
control's end conditions and the twist state), positions x
[m] (n, 3), velocities v [m/s] (n, 3) and the clamp directions ``dirs`` (unit, (2, 3): first,
last end; used only where ``k_bend`` of that end is nonzero). They write into preallocated
outputs and never allocate per node, so the same code serves the core time loop, the static
solver and the per-step PyBullet coupling. A new force term goes into :func:`total_forces`
(and, if it depends on x, :func:`force_jacobian`), its parameters into ``ModelArrays`` (and ``KernelArrays``).

Damping: drag -c_i v_i per node and Kelvin-Voigt dampers on stretch and bending
(:func:`internal_damping_forces`), all from the Rayleigh function :func:`dissipation`; their
velocity Jacobian is :func:`add_damping_jacobian` (KV) plus -diag(c) (drag).

Quadratic fluid drag (opt-in: ``ModelArrays.drag_k`` non-empty): :mod:`bullet_dlo.core.kernels.drag`
adds -c |v_n| v_n per segment to :func:`total_forces` and its cubic dissipation function to
:func:`dissipation`; its velocity Jacobian (:func:`~bullet_dlo.core.kernels.drag.add_drag_jacobian`,
which needs v) is added by the implicit steps next to :func:`add_damping_jacobian`.

Material frame (issue 22, opt-in: ``ModelArrays.tw`` non-empty): twist springs and the anisotropic
part of the bending energy of :mod:`bullet_dlo.core.kernels.twist` join the energy, the forces, the
Jacobian and the clamp moments; ``k_bend`` then holds the mean of the two bending constants.

Curved rest shape (opt-in: ``ModelArrays.rest_angle`` non-empty): :mod:`bullet_dlo.core.kernels.rest_shape`
turns each interior bending energy into 1/2 k_b (beta - beta0)^2 (energy, forces and the node's Hessian).

Jacobian storage: block-banded, ``jac[i, o] = dF_i / dx_{i+o-2}`` with shape (n, 5, 3, 3)
(bending couples nodes up to two apart). ``definite=True`` drops the compressive part of the
stretch Hessian (the usual filter that keeps M + h^2 K positive definite for implicit steps);
``definite=False`` gives the exact derivative.
"""
from __future__ import annotations

import math

import numpy as np

from bullet_dlo.core.kernels.drag import add_drag_forces, add_drag_jacobian, drag_dissipation, has_drag  # noqa: F401
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.rest_shape import add_rest_shape_forces, has_rest_shape, rest_shape_energy, rest_shape_hessian
from bullet_dlo.core.kernels.twist import (
    add_cross_matrix,
    add_twist_forces,
    add_twist_jacobian,
    damper_tensor,
    damper_tensors,
    flat_dampers,
    has_twist,
    scatter_edge,
    scatter_node_hessian,
    twist_clamp_torque,
    twist_energy,
    twist_kinetic,
    twist_ready,
)

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
    if has_twist(m):
        e += twist_energy(m, x, dirs)
    if has_rest_shape(m):  # curved rest shape (checked here: a no-op call passing m cost ~0.5 us, Numba's pipeline)
        e += rest_shape_energy(m, x)
    return e


@njit(cache=True, error_model="numpy")
def mechanical_energy(m, x, v, dirs):
    """Kinetic + elastic + gravitational energy [J] (gravitational zero at the origin)."""
    e = internal_energy(m, x, dirs)
    for i in range(x.shape[0]):
        for j in range(3):
            e += 0.5 * m.mass[i] * v[i, j] * v[i, j] - m.mass[i] * m.gravity[j] * x[i, j]
    if has_twist(m):
        e += twist_kinetic(m)
    return e


@njit(cache=True, error_model="numpy", inline="always")  # passing m: ~0.3-0.5 us a call (Numba's pipeline): only
def internal_forces(m, x, dirs, out):                      # the loop's arrays are passed on (inlined: dispatch free)
    """Write the elastic forces -dE/dx [N], shape (n, 3), into ``out`` (overwritten)."""
    _spring_forces(m.k_stretch, m.rest_length, m.k_bend, x, dirs, out)
    if has_twist(m):
        add_twist_forces(m, x, dirs, out)
    if has_rest_shape(m):  # curved rest shape (checked here: a no-op call passing m cost ~0.5 us, Numba's pipeline)
        add_rest_shape_forces(m, x, out)


@njit(cache=True, error_model="numpy")
def _spring_forces(k_stretch, rest_length, k_bend, x, dirs, out):
    """out <- the stretch, bending and clamp springs' forces [N] (n, 3) (:func:`internal_forces` without its
    twist and rest-shape terms)."""
    n = x.shape[0]
    out[:, :] = 0.0
    for i in range(n - 1):
        dx = x[i + 1, 0] - x[i, 0]
        dy = x[i + 1, 1] - x[i, 1]
        dz = x[i + 1, 2] - x[i, 2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        f = k_stretch[i] * (length - rest_length[i]) / length  # tension / length
        out[i, 0] += f * dx
        out[i, 1] += f * dy
        out[i, 2] += f * dz
        out[i + 1, 0] -= f * dx
        out[i + 1, 1] -= f * dy
        out[i + 1, 2] -= f * dz
    for i in range(n):
        k = k_bend[i]
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
            scatter_edge(out, i - 1, gax, gay, gaz)
        if i < n - 1:  # b depends on x_i (-1) and x_{i+1} (+1)
            scatter_edge(out, i, gbx, gby, gbz)


@njit(cache=True, error_model="numpy")
def clamp_torque(m, x, v, dirs, end):
    """Torque [N m] the cable exerts on the clamp at ``end`` (0 first, 1 last), world frame.

    The clamp spring pulls the clamp direction towards the adjacent segment with magnitude
    k * beta about the axis d x e; with internal damping its Kelvin-Voigt damper adds
    -d x (K_d^T c phi_dot) (see :func:`clamp_damping_torque`); a material frame adds the twist spring's
    moment (:func:`~bullet_dlo.core.kernels.twist.twist_clamp_torque`), which a fork (no bending spring)
    has too. Zero at a pinned or free end.
    """
    n = x.shape[0]
    out = np.zeros(3)
    if end == 0:
        i = 0
        d = dirs[0]
        e0, e1, e2 = x[1, 0] - x[0, 0], x[1, 1] - x[0, 1], x[1, 2] - x[0, 2]
    else:
        i = n - 1
        d = -dirs[1]  # direction from the clamp into the cable
        e0, e1, e2 = x[n - 2, 0] - x[n - 1, 0], x[n - 2, 1] - x[n - 1, 1], x[n - 2, 2] - x[n - 1, 2]
    k = m.k_bend[i]
    holds_roll = has_twist(m) and m.tw_k_twist[i] != 0.0
    if k == 0.0 and not holds_roll:
        return out
    if k != 0.0:
        _, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, _ = _angle_terms(d[0], d[1], d[2], e0, e1, e2)
        # k * beta * (u x w)/|u x w| = k * (beta/s) * (u x w)
        out[0] = k * ratio * (uy * wz - uz * wy)
        out[1] = k * ratio * (uz * wx - ux * wz)
        out[2] = k * ratio * (ux * wy - uy * wx)
        if _has_internal_damping(m):
            out += clamp_damping_torque(m, x, v, dirs, end)
    if has_twist(m):
        out += twist_clamp_torque(m, x, dirs, end)
    return out


@njit(cache=True, error_model="numpy")
def clamp_damping_torque(m, x, v, dirs, end):
    """Moment [N m] of the clamp's Kelvin-Voigt bending damper on the clamp at ``end``, world frame.

    The damper's Rayleigh term 1/2 c |phi_dot|^2 at the end node depends on the clamp direction d
    through K_d (phi_dot = K_a a_dot + K_b b_dot, d standing in for a at the first end and for b
    at the last). A rotation of the clamp by dalpha changes d by dalpha x d, so the moment on the
    clamp is -d x (K_d^T c phi_dot): what keeps the angular momentum of cable plus clamp balanced
    (the nodes' damping forces are computed with the clamp direction held fixed).
    """
    n = x.shape[0]
    out = np.zeros(3)
    i = 0 if end == 0 else n - 1
    if m.c_bend[i] == 0.0 or m.k_bend[i] == 0.0:
        return out
    g = np.empty((5, 3, 3))
    rate = np.empty(3)
    _bend_node_blocks(x, i, dirs, g)
    _bend_rate(x, v, i, g, rate)
    a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
    ka = np.empty((3, 3))
    kb = np.empty((3, 3))
    _bend_rate_blocks(a0, a1, a2, b0, b1, b2, ka, kb)  # K_d unmasked (the node blocks zero the clamp's)
    kd = ka if end == 0 else kb
    d = dirs[0] if end == 0 else dirs[1]
    c = m.c_bend[i]
    if flat_dampers(m):  # C_i phi_dot for a flat section (:func:`~bullet_dlo.core.kernels.twist.damper_tensors`)
        if has_twist(m):
            twist_ready(m, x, dirs)
        cten = np.empty((3, 3))
        damper_tensor(m, x, dirs, i, np.empty((12, 3)), cten)
        cr = np.empty(3)
        for r in range(3):
            cr[r] = cten[r, 0] * rate[0] + cten[r, 1] * rate[1] + cten[r, 2] * rate[2]
        rate[:] = cr
        c = 1.0
    q0 = c * (kd[0, 0] * rate[0] + kd[1, 0] * rate[1] + kd[2, 0] * rate[2])  # K_d^T c phi_dot
    q1 = c * (kd[0, 1] * rate[0] + kd[1, 1] * rate[1] + kd[2, 1] * rate[2])
    q2 = c * (kd[0, 2] * rate[0] + kd[1, 2] * rate[1] + kd[2, 2] * rate[2])
    out[0] = -(d[1] * q2 - d[2] * q1)
    out[1] = -(d[2] * q0 - d[0] * q2)
    out[2] = -(d[0] * q1 - d[1] * q0)
    return out


@njit(cache=True, error_model="numpy", inline="always")  # only the loop's arrays are passed (see internal_forces)
def force_jacobian(m, x, dirs, definite, jac):
    """Write dF/dx of the elastic forces [N/m] into ``jac`` (shape (n, 5, 3, 3), overwritten).

    Gravity and external forces add nothing; damping enters through dF/dv: -diag(c) for the
    drag (see :func:`bullet_dlo.core.kernels.banded.assemble_system`) and
    :func:`add_damping_jacobian` for the Kelvin-Voigt dampers.
    """
    _spring_jacobian(m.k_stretch, m.rest_length, m.k_bend, m.rest_angle, x, dirs, definite, jac)
    if has_twist(m):
        add_twist_jacobian(m, x, dirs, jac)


@njit(cache=True, error_model="numpy")
def _spring_jacobian(k_stretch, rest_length, k_bend, rest_angle, x, dirs, definite, jac):
    """jac <- dF/dx of the stretch, bending and clamp springs (with the rest angles' terms) (:func:`force_jacobian`
    without the twist terms)."""
    n = x.shape[0]
    jac[:, :, :, :] = 0.0
    for i in range(n - 1):
        d0 = x[i + 1, 0] - x[i, 0]
        d1 = x[i + 1, 1] - x[i, 1]
        d2 = x[i + 1, 2] - x[i, 2]
        d = (d0, d1, d2)  # (a tuple, not a scratch array: no allocation)
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        k = k_stretch[i]
        geo = 1.0 - rest_length[i] / length
        if definite and geo < 0.0:
            geo = 0.0
        # e = x_{i+1} - x_i: Hessian blocks (i,i)=+H, (i,i+1)=-H, (i+1,i)=-H, (i+1,i+1)=+H
        for r in range(3):
            for col in range(3):
                dd = d[r] * d[col] / (length * length)
                hv = k * (dd + geo * ((1.0 if r == col else 0.0) - dd))
                jac[i, 2, r, col] -= hv
                jac[i, 3, r, col] += hv
                jac[i + 1, 1, r, col] += hv
                jac[i + 1, 2, r, col] -= hv
    hb = np.empty((6, 6))
    g = np.empty(12)
    rest = rest_angle.shape[0] > 0  # (has_rest_shape) checked once: a call costs more than a short node
    for i in range(n):
        k = k_bend[i]
        if k == 0.0:
            continue
        a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
        _bend_hessian(a0, a1, a2, b0, b1, b2, k, g, hb)
        if rest:  # curved rest shape
            rest_shape_hessian(rest_angle, k_bend, x, i, definite, hb)
        scatter_node_hessian(jac, i, n, hb)


@njit(cache=True, error_model="numpy", inline="always")  # called per node: a call costs more than a short node
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


@njit(cache=True, error_model="numpy", inline="always")  # inlined (passing m: ~0.3 us a call, Numba's pipeline)
def total_forces(m, x, v, dirs, out):
    """Elastic + gravity + damping + external forces [N], shape (n, 3), into ``out``."""
    internal_forces(m, x, dirs, out)
    n = x.shape[0]
    for i in range(n):
        for j in range(3):
            out[i, j] += m.mass[i] * m.gravity[j] - m.damp[i] * v[i, j] + m.f_ext[i, j]
    if _has_internal_damping(m):
        internal_damping_forces(m, x, v, dirs, out)
    if has_drag(m):  # the quadratic drag law (opt-in)
        add_drag_forces(m, x, v, out)


# ----- Kelvin-Voigt internal damping ------------------------------------------------------------
# Both dampers derive from a Rayleigh dissipation function R(x, v), quadratic in v for fixed x:
#   stretch: 1/2 c_s,i (u_i . (v_{i+1} - v_i))^2         (strain rate of segment i times l0)
#   bending: 1/2 c_b,i |phi_dot_i|^2, phi_dot_i = Ka (v_i - v_{i-1}) + Kb (v_{i+1} - v_i)
# with phi = (theta/sin theta) (u x w) the turning-angle vector at node i (|phi| = theta, the
# variable of the bending energy 1/2 k_b theta^2) and phi_dot its co-rotational rate: the rate
# of phi minus the part the pair of edges' mean rotation (u x u' + w x w')/2 carries along. So
# F = -dR/dv is linear in v, dF/dv = -c G^T G is symmetric, and about a straight unstressed
# cable C = tau K exactly (Rayleigh damping: mode k decays at tau omega_k^2 / 2). Translation
# and rotation about any axis normal to the local tangents are not damped (zero net force and
# torque); a bent node spinning about its own tangent is indistinguishable, at the velocity level,
# from out-of-plane bending in a chain without twist, and is damped as such.
@njit(cache=True, error_model="numpy", inline="always")
def _has_internal_damping(m):
    # the first positive coefficient answers (np.max scanned both arrays on every force call)
    if m.c_stretch.shape[0] == 0:
        return False
    for i in range(m.c_stretch.shape[0]):
        if m.c_stretch[i] > 0.0:
            return True
    for i in range(m.c_bend.shape[0]):
        if m.c_bend[i] > 0.0:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _bend_rate_blocks(a0, a1, a2, b0, b1, b2, ka, kb):
    """Ka, Kb (3, 3) with phi_dot = Ka a_dot + Kb b_dot for the turning angle between edges a and b."""
    _, s, c, la, lb, ux, uy, uz, wx, wy, wz, ratio, alpha = _angle_terms(a0, a1, a2, b0, b1, b2)
    u = (ux, uy, uz)
    w = (wx, wy, wz)
    chi = (uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)  # u x w = s n
    for r in range(3):
        for col in range(3):
            ga = (w[col] - c * u[col]) / la  # d(cos theta)/da
            gb = (u[col] - c * w[col]) / lb
            ka[r, col] = -alpha * chi[r] * ga - (ratio / la) * chi[r] * u[col] + (0.5 * ratio / la) * u[r] * chi[col]
            kb[r, col] = -alpha * chi[r] * gb - (ratio / lb) * chi[r] * w[col] + (0.5 * ratio / lb) * w[r] * chi[col]
    # cross-product matrices: -(ratio/la) [w]x and +(ratio/lb) [u]x
    add_cross_matrix(ka, -ratio / la, w)
    add_cross_matrix(kb, ratio / lb, u)


@njit(cache=True, error_model="numpy", inline="always")
def _bend_node_blocks(x, i, dirs, g):
    """Blocks g[0:3] of phi_dot_i = sum_k g[k] v_{i-1+k} at node i (clamp directions held fixed).

    g: scratch (5, 3, 3); g[3], g[4] receive Ka, Kb.
    """
    n = x.shape[0]
    a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
    ka = g[3]
    kb = g[4]
    _bend_rate_blocks(a0, a1, a2, b0, b1, b2, ka, kb)
    if i == 0:  # the clamp direction stands in for a: a_dot = 0
        ka[:, :] = 0.0
    if i == n - 1:
        kb[:, :] = 0.0
    for r in range(3):
        for col in range(3):
            g[0, r, col] = -ka[r, col]
            g[1, r, col] = ka[r, col] - kb[r, col]
            g[2, r, col] = kb[r, col]


@njit(cache=True, error_model="numpy", inline="always")
def _bend_rate(x, v, i, g, rate):
    """rate <- phi_dot_i [rad/s] from the blocks g of node i (nodes outside the chain skipped)."""
    n = x.shape[0]
    rate[:] = 0.0
    for k in range(3):
        p = i - 1 + k
        if p < 0 or p >= n:
            continue
        for r in range(3):
            rate[r] += g[k, r, 0] * v[p, 0] + g[k, r, 1] * v[p, 1] + g[k, r, 2] * v[p, 2]


@njit(cache=True, error_model="numpy", inline="always")
def _stretch_rate(x, v, i):
    """Segment i's edge (dx, dy, dz) [m], length [m] and stretch rate d(length)/dt [m/s]."""
    dx = x[i + 1, 0] - x[i, 0]
    dy = x[i + 1, 1] - x[i, 1]
    dz = x[i + 1, 2] - x[i, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    rel = (dx * (v[i + 1, 0] - v[i, 0]) + dy * (v[i + 1, 1] - v[i, 1]) + dz * (v[i + 1, 2] - v[i, 2])) / length
    return dx, dy, dz, length, rel


@njit(cache=True, error_model="numpy", inline="always")  # only the dampers' arrays are passed (see internal_forces)
def internal_damping_forces(m, x, v, dirs, out):
    """Add the Kelvin-Voigt damping forces -dR/dv [N], (n, 3), to ``out`` (see the block comment)."""
    if flat_dampers(m):  # a flat section: each bending plane damped by its own stiffness
        _flat_damper_forces(m, x, v, dirs, out)
    else:
        _damper_forces(m.c_stretch, m.c_bend, x, v, dirs, out)


@njit(cache=True, error_model="numpy")
def _flat_damper_forces(m, x, v, dirs, out):
    """:func:`internal_damping_forces` of a flat section: the stretch dampers, and the bending dampers' forces
    -G^T C_i phi_dot with the tensors C_i of :func:`~bullet_dlo.core.kernels.twist.damper_tensors`."""
    n = x.shape[0]
    _damper_forces(m.c_stretch, np.zeros(n), x, v, dirs, out)
    cten = np.empty((n, 3, 3))
    damper_tensors(m, x, dirs, cten)
    g = np.empty((5, 3, 3))
    rate = np.empty(3)
    q = np.empty(3)
    for i in range(n):
        if m.c_bend[i] == 0.0:
            continue
        _bend_node_blocks(x, i, dirs, g)
        _bend_rate(x, v, i, g, rate)
        for r in range(3):
            q[r] = cten[i, r, 0] * rate[0] + cten[i, r, 1] * rate[1] + cten[i, r, 2] * rate[2]
        for k in range(3):
            p = i - 1 + k
            if p < 0 or p >= n:
                continue
            for col in range(3):
                out[p, col] -= g[k, 0, col] * q[0] + g[k, 1, col] * q[1] + g[k, 2, col] * q[2]


@njit(cache=True, error_model="numpy")
def _damper_forces(c_stretch, c_bend, x, v, dirs, out):
    """:func:`internal_damping_forces` from the damper constants [N s/m], [N m s/rad^2]."""
    n = x.shape[0]
    for i in range(n - 1):
        c_s = c_stretch[i]
        if c_s == 0.0:
            continue
        dx, dy, dz, length, rel = _stretch_rate(x, v, i)
        f = c_s * rel / length  # damper tension / length
        out[i, 0] += f * dx
        out[i, 1] += f * dy
        out[i, 2] += f * dz
        out[i + 1, 0] -= f * dx
        out[i + 1, 1] -= f * dy
        out[i + 1, 2] -= f * dz
    g = np.empty((5, 3, 3))
    rate = np.empty(3)
    for i in range(n):
        c_b = c_bend[i]
        if c_b == 0.0:
            continue
        _bend_node_blocks(x, i, dirs, g)
        _bend_rate(x, v, i, g, rate)
        for k in range(3):
            p = i - 1 + k
            if p < 0 or p >= n:
                continue
            for col in range(3):
                out[p, col] -= c_b * (g[k, 0, col] * rate[0] + g[k, 1, col] * rate[1] + g[k, 2, col] * rate[2])


@njit(cache=True, error_model="numpy")
def dissipation(m, x, v, dirs):
    """Rayleigh dissipation function R [W] of all damping terms: F_damping = -dR/dv.

    R = 1/2 sum c_i |v_i|^2 (drag) + the Kelvin-Voigt terms (the power they dissipate is 2 R) + the
    quadratic drag law's sum c_k |v_n|^3 / 3 (power 3 times that; :mod:`bullet_dlo.core.kernels.drag`).
    """
    n = x.shape[0]
    r_sum = drag_dissipation(m, x, v) if has_drag(m) else 0.0
    for i in range(n):
        for j in range(3):
            r_sum += 0.5 * m.damp[i] * v[i, j] * v[i, j]
    if not _has_internal_damping(m):
        return r_sum
    for i in range(n - 1):
        c_s = m.c_stretch[i]
        if c_s == 0.0:
            continue
        dx, dy, dz, length, rel = _stretch_rate(x, v, i)
        r_sum += 0.5 * c_s * rel * rel
    g = np.empty((5, 3, 3))
    rate = np.empty(3)
    flat = flat_dampers(m)
    cten = np.empty((n if flat else 0, 3, 3))
    if flat:
        damper_tensors(m, x, dirs, cten)
    for i in range(n):
        c_b = m.c_bend[i]
        if c_b == 0.0:
            continue
        _bend_node_blocks(x, i, dirs, g)
        _bend_rate(x, v, i, g, rate)
        if flat:  # 1/2 phi_dot^T C_i phi_dot
            for r in range(3):
                r_sum += 0.5 * rate[r] * (cten[i, r, 0] * rate[0] + cten[i, r, 1] * rate[1] + cten[i, r, 2] * rate[2])
        else:
            r_sum += 0.5 * c_b * (rate[0] * rate[0] + rate[1] * rate[1] + rate[2] * rate[2])
    return r_sum


@njit(cache=True, error_model="numpy", inline="always")  # the no-op test inline, only the dampers' arrays passed
def add_damping_jacobian(m, x, dirs, scale, jac):
    """jac += scale * dF/dv of the Kelvin-Voigt dampers [N s/m] (block-banded (n, 5, 3, 3)).

    Exact: dF/dv = -c_s u u^T per segment, -c_b G^T G per bending node (G: the three blocks
    of phi_dot, nodes up to two apart). The drag -diag(damp) is not included (see
    :func:`bullet_dlo.core.kernels.banded.assemble_system`). No-op without internal damping.
    """
    if _has_internal_damping(m):
        if flat_dampers(m):
            _flat_damper_jacobian(m, x, dirs, scale, jac)
        else:
            _damper_jacobian(m.c_stretch, m.c_bend, x, dirs, scale, jac)


@njit(cache=True, error_model="numpy")
def _flat_damper_jacobian(m, x, dirs, scale, jac):
    """:func:`add_damping_jacobian` of a flat section: the stretch dampers', and -G^T C_i G per bending node
    (:func:`~bullet_dlo.core.kernels.twist.damper_tensors`)."""
    n = x.shape[0]
    _damper_jacobian(m.c_stretch, np.zeros(n), x, dirs, scale, jac)
    cten = np.empty((n, 3, 3))
    damper_tensors(m, x, dirs, cten)
    g = np.empty((5, 3, 3))
    cg = np.empty((3, 3))
    for i in range(n):
        if m.c_bend[i] == 0.0:
            continue
        _bend_node_blocks(x, i, dirs, g)
        for q_k in range(3):
            q = i - 1 + q_k
            if q < 0 or q >= n:
                continue
            for r in range(3):  # cg <- C_i G_q
                for col in range(3):
                    cg[r, col] = (cten[i, r, 0] * g[q_k, 0, col] + cten[i, r, 1] * g[q_k, 1, col]
                                  + cten[i, r, 2] * g[q_k, 2, col])
            for k in range(3):
                p = i - 1 + k
                if p < 0 or p >= n:
                    continue
                o = q - p + BAND
                for r in range(3):
                    for col in range(3):
                        acc = g[k, 0, r] * cg[0, col] + g[k, 1, r] * cg[1, col] + g[k, 2, r] * cg[2, col]
                        jac[p, o, r, col] -= scale * acc


@njit(cache=True, error_model="numpy")
def _damper_jacobian(c_stretch, c_bend, x, dirs, scale, jac):
    """:func:`add_damping_jacobian` from the damper constants (with internal damping)."""
    n = x.shape[0]
    d = np.empty(3)
    for i in range(n - 1):
        c_s = c_stretch[i]
        if c_s == 0.0:
            continue
        d[0] = x[i + 1, 0] - x[i, 0]
        d[1] = x[i + 1, 1] - x[i, 1]
        d[2] = x[i + 1, 2] - x[i, 2]
        l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        for r in range(3):
            for col in range(3):
                hv = scale * c_s * d[r] * d[col] / l2
                jac[i, 2, r, col] -= hv
                jac[i, 3, r, col] += hv
                jac[i + 1, 1, r, col] += hv
                jac[i + 1, 2, r, col] -= hv
    g = np.empty((5, 3, 3))
    for i in range(n):
        c_b = c_bend[i]
        if c_b == 0.0:
            continue
        _bend_node_blocks(x, i, dirs, g)
        for k in range(3):
            p = i - 1 + k
            if p < 0 or p >= n:
                continue
            for q_k in range(3):
                q = i - 1 + q_k
                if q < 0 or q >= n:
                    continue
                o = q - p + BAND
                for r in range(3):
                    for col in range(3):
                        acc = g[k, 0, r] * g[q_k, 0, col] + g[k, 1, r] * g[q_k, 1, col] + g[k, 2, r] * g[q_k, 2, col]
                        jac[p, o, r, col] -= scale * c_b * acc


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
