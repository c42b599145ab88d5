"""Numba kernels of the quadratic (Morison-type) fluid drag law (off unless ``ModelArrays.drag_k`` is set).

Per segment k (nodes k, k+1, length l0, velocity u = (v_k + v_{k+1}) / 2, the fluid at rest) the
surrounding fluid pushes with

    f_k = -c_k |u_n| u_n,      c_k = 1/2 rho_f C_d w l0  [kg/m],

u_n the velocity component normal to the segment:

* cross-flow (round and tube sections, and every cable without a material frame): u_n = P u with
  P = I - t t^T, t the segment's unit tangent (the independence principle: the axial component
  drives no pressure drag; skin friction along the axis is neglected);
* face normal (a rectangle, whose material frame gives the face normal n = d2, the thickness axis of
  :mod:`bullet_dlo.core.kernels.twist`): u_n = (u . n) n. Flow along the width (edge first) drives no
  drag, as it would on a flat plate of negligible thickness.

Each node of the segment gets f_k / 2. A cable without a frame acting as a planar strip (the
``planes`` model of :mod:`bullet_dlo.reality.beam`) takes the cross-flow law with the strip's width as
``drag_width``: in a planar run the cross-flow component is in the plane and normal to the tangent,
i.e. exactly the face normal of the strip whose weak plane that run is.

The law derives from the dissipation function R = sum_k c_k |u_n,k|^3 / 3 (F = -dR/dv; the power
dissipated is 3 R, not 2 R as for the linear dampers), which is what the implicit integrators'
line-search merit adds. The velocity Jacobian is exact and symmetric negative semi-definite:

* cross-flow: du_n/du = P, d(|u_n| u_n)/du = |u_n| P + u_n u_n^T / |u_n| ;
* face normal: d(|s| s n)/du = 2 |s| n n^T with s = u . n;

so d f_k / du = -c_k (...) and every node pair (i, j) of segment k has the block 1/4 of it.
The position dependence (through t, or n) is left out of the Newton matrix: it would make the
matrix non-symmetric (the band solver of :mod:`bullet_dlo.core.kernels.banded` factorises a symmetric
one), its size is c |u|^2 / l0 per metre of displacement, against bending stiffnesses E I / l0^3 many
orders larger on any cable (steel strip in air: 0.1 N/m against 7e4 N/m), and the residual Newton
drives to zero uses the exact force, so the converged step is the same; only Newton's rate would
notice.
"""
from __future__ import annotations

import math

import numpy as np

from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.twist import transport

BAND = 2  # block half-bandwidth of the force Jacobian (as in forces.py)


@njit(cache=True, error_model="numpy", inline="always")
def has_drag(m):
    """Whether the model arrays ``m`` carry the quadratic drag law."""
    return m.drag_k.shape[0] > 0


@njit(cache=True, error_model="numpy", inline="always")
def _use_face(m):
    """Face-normal law: asked for, and the material frame is built (before its first use the kernels
    see the cross-flow law; a frame is built before the first step's forces)."""
    return m.drag_face[0] != 0 and m.tw_k_twist.shape[0] > 0 and m.tw_flag[0] != 0


@njit(cache=True, error_model="numpy")
def _segment(m, x, v, k, face, t, nrm, un):
    """Segment k's normal velocity u_n into ``un`` (3,) and, with ``face``, the face normal into ``nrm``;
    t (3,) receives the unit tangent. Returns (|u_n| [m/s], s = u . n [m/s] (face) or 0)."""
    dx = x[k + 1, 0] - x[k, 0]
    dy = x[k + 1, 1] - x[k, 1]
    dz = x[k + 1, 2] - x[k, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    t[0], t[1], t[2] = dx / length, dy / length, dz / length
    u0 = 0.5 * (v[k, 0] + v[k + 1, 0])
    u1 = 0.5 * (v[k, 1] + v[k + 1, 1])
    u2 = 0.5 * (v[k, 2] + v[k + 1, 2])
    if face:
        r = np.empty(3)
        transport(m.tw_ref[k], m.tw_tan[k], t, r)  # reference director on the current tangent
        b0 = t[1] * r[2] - t[2] * r[1]
        b1 = t[2] * r[0] - t[0] * r[2]
        b2 = t[0] * r[1] - t[1] * r[0]
        c, s = math.cos(m.tw_theta[k]), math.sin(m.tw_theta[k])
        # m1 = c r + s (t x r); m2 = t x m1 = c (t x r) - s r  (t x (t x r) = -r)
        nrm[0] = c * b0 - s * r[0]
        nrm[1] = c * b1 - s * r[1]
        nrm[2] = c * b2 - s * r[2]
        sn = u0 * nrm[0] + u1 * nrm[1] + u2 * nrm[2]
        un[0], un[1], un[2] = sn * nrm[0], sn * nrm[1], sn * nrm[2]
        return abs(sn), sn
    ut = u0 * t[0] + u1 * t[1] + u2 * t[2]
    un[0] = u0 - ut * t[0]
    un[1] = u1 - ut * t[1]
    un[2] = u2 - ut * t[2]
    return math.sqrt(un[0] * un[0] + un[1] * un[1] + un[2] * un[2]), 0.0


@njit(cache=True, error_model="numpy")
def add_drag_forces(m, x, v, out):
    """Add the quadratic drag forces [N], (n, 3), to ``out`` (no-op without the law)."""
    if not has_drag(m):
        return
    face = _use_face(m)
    t, nrm, un = np.empty(3), np.empty(3), np.empty(3)
    for k in range(x.shape[0] - 1):
        mag, _ = _segment(m, x, v, k, face, t, nrm, un)
        h = -0.5 * m.drag_k[k] * mag  # half the segment's force per node
        for j in range(3):
            out[k, j] += h * un[j]
            out[k + 1, j] += h * un[j]


@njit(cache=True, error_model="numpy")
def drag_dissipation(m, x, v):
    """Dissipation function R = sum_k c_k |u_n,k|^3 / 3 [W] of the law (F = -dR/dv; power 3 R)."""
    if not has_drag(m):
        return 0.0
    face = _use_face(m)
    t, nrm, un = np.empty(3), np.empty(3), np.empty(3)
    r_sum = 0.0
    for k in range(x.shape[0] - 1):
        mag, _ = _segment(m, x, v, k, face, t, nrm, un)
        r_sum += m.drag_k[k] * mag * mag * mag / 3.0
    return r_sum


@njit(cache=True, error_model="numpy")
def drag_power(m, x, v):
    """Power the fluid takes from the cable, sum_k c_k |u_n,k|^3 [W] (>= 0)."""
    return 3.0 * drag_dissipation(m, x, v)


@njit(cache=True, error_model="numpy")
def add_drag_jacobian(m, x, v, scale, jac):
    """jac += scale * dF/dv of the drag law [N s/m] (block-banded (n, 5, 3, 3), positions held fixed).

    Exact in v (see the module docstring); symmetric negative semi-definite. No-op without the law.
    """
    if not has_drag(m):
        return
    face = _use_face(m)
    t, nrm, un = np.empty(3), np.empty(3), np.empty(3)
    blk = np.empty((3, 3))
    for k in range(x.shape[0] - 1):
        mag, _ = _segment(m, x, v, k, face, t, nrm, un)
        c = m.drag_k[k]
        if c == 0.0 or mag == 0.0:
            continue  # dF/dv is 0 at u_n = 0 (the law is quadratic)
        for r in range(3):
            for col in range(3):
                if face:
                    d = 2.0 * mag * nrm[r] * nrm[col]
                else:
                    p = (1.0 if r == col else 0.0) - t[r] * t[col]
                    d = mag * p + un[r] * un[col] / mag
                blk[r, col] = -0.25 * scale * c * d  # d f_i / d v_j = 1/2 * 1/2 * d f_k / d u
        # nodes k and k+1: blocks (k,k) o=BAND, (k,k+1) o=BAND+1, (k+1,k) o=BAND-1, (k+1,k+1) o=BAND
        for r in range(3):
            for col in range(3):
                jac[k, BAND, r, col] += blk[r, col]
                jac[k, BAND + 1, r, col] += blk[r, col]
                jac[k + 1, BAND - 1, r, col] += blk[r, col]
                jac[k + 1, BAND, r, col] += blk[r, col]
