"""Numba kernels of the material frame: twist angles, twist springs and anisotropic bending (issue 22).

Design (after Bergou et al. 2008, "Discrete Elastic Rods", and Bergou et al. 2010, "Discrete
Viscous Threads"). The centreline stays the chain of point masses x_i; each segment k (edge
e_k = x_{k+1} - x_k, unit tangent t_k) carries an orthonormal *material frame* (t_k, m1_k, m2_k),
m1_k along the section's first axis d1. It is stored, as in DER, as one scalar per segment on top
of a *reference frame*:

* the reference director r_k (unit, normal to t_k) is transported in **time** by parallel transport:
  when t_k turns during a step, r_k turns with it by the minimal rotation taking the old tangent to
  the new one (Bergou 2010; the space-parallel Bishop frame of Bergou 2008 would make every frame
  depend on all edges before it and the Jacobian dense). The frames therefore cost O(n) and stay
  local; they are state (``tan``, ``ref``), carried from step to step.
* the twist angle theta_k [rad] turns the material frame about t_k away from the reference:
  m1_k = cos theta_k r_k + sin theta_k (t_k x r_k), m2_k = t_k x m1_k. theta_k is a degree of
  freedom with the rotational inertia of the segment about its axis, I_k = rho J_p l0 [kg m^2]
  (J_p = I1 + I2, the section's polar moment), and an angular velocity omega_k [rad/s].
* at node i between edges a (incoming) and b (outgoing) the *reference twist* psi_i is the signed
  angle about t_b from the space-parallel transport of r_a onto edge b to r_b; it is kept
  continuous in time (unwrapped against its last value, ``mref``), so a clamp may roll through any
  number of turns. The discrete twist is m_i = theta_b - theta_a + psi_i (Bergou 2008, sec. 4.2).
* a clamp is a virtual edge: tangent the clamp direction d, director the clamp's section axis
  (the held end's ``normal``, turned with the gripper), twist angle 0. So a clamp holds the twist
  (the twist spring at the clamp node, stiffness 2 G J / l0 for its half Voronoi length, like the
  bending clamp spring 2 E I / l0), a pin or a free end does not (no spring: theta of the end segment
  is free).

Energies (k_t = G J / l0 at interior nodes, the bending constant k_b = E I / l0 as today):

* twist: E_t = sum_i 1/2 k_t,i m_i^2;
* bending: the turning-angle vector phi_i = beta_i (t_a x t_b)/|t_a x t_b| (|phi| = beta, the
  variable of today's isotropic energy 1/2 k_b beta^2) resolved in the material frames of both
  edges (DER averages the two, Bergou 2008 eq. 3): kappa_1 = phi . m1, kappa_2 = phi . m2 and
  E_b = sum_i 1/4 sum_{k in (a, b)} (k1 kappa_1,k^2 + k2 kappa_2,k^2), k1 = E I1 / l0, k2 = E I2 / l0.
  Since phi is normal to both tangents, kappa_1^2 + kappa_2^2 = beta^2 for either frame, so
  E_b = 1/2 kbar beta^2 + Delta/4 sum_k (kappa_1,k^2 - kappa_2,k^2) with kbar = (k1 + k2)/2 and
  Delta = (k1 - k2)/2: the isotropic part is today's bending spring (``k_bend`` holds kbar), this
  module adds the anisotropic part, which vanishes for round and tube sections.

Derivatives. With the reference frames transported in time, a variation of the edges turns each
frame without spin about its tangent, so (Bergou 2008/2010) d psi_i / d e_a = kb_i / (2 |e_a|),
d psi_i / d e_b = kb_i / (2 |e_b|) with the curvature binormal kb_i = 2 t_a x t_b / (1 + t_a . t_b),
and d(phi . m)/dx = m^T dphi/dx (the frame's own turn contributes phi . dm = -(m . dt)(phi . t) = 0).
These are exact at the state where the frames were last transported (the start of the step) and
the usual DER reduction within a step. Forces on the nodes and the clamp moments (twist moment
about the clamp axis included) are these gradients. The position Jacobian adds to today's exact
isotropic bending Hessian the Gauss-Newton part of the anisotropic bending,
Delta/2 sum_k (J1_k^T J1_k - J2_k^T J2_k) with J_j = m_j^T dphi/dx (exact about a straight cable,
where together with the isotropic part it is 1/2 sum_k (k1 J1^T J1 + k2 J2^T J2), positive
semi-definite); the terms proportional to the bending and twist stresses (and the twist-bending
coupling of the positions) are left to Newton's iterations (see :mod:`~bullet_dlo.core.kernels.steppers`).

Time integration: every method integrates the twist with the positions (:mod:`~bullet_dlo.core.kernels.twist_coupled`:
the implicit methods in one Newton system, in contact too, Gauss-Legendre in its collocation system, the explicit
methods through their stages); a contact step with a free body in its solve advances the twist angles after the
positions by an implicit Euler sub-step with the new positions held (a staggered, Gauss-Seidel coupling, first
order), solved by Newton on a tridiagonal system (:func:`twist_step`). The twist modes are stiff (omega ~ (1/l0) sqrt(G J / (rho J_p)),
the torsion wave speed over a segment), so the sub-step is implicit for every method; it is
unconditionally stable and damps twist waves the step cannot resolve (quasi-static twist at large
steps, the regime of Bergou 2008 sec. 7). Damping acts on twist with the meaning it has on the other
modes: drag -c I_k omega_k (a spinning segment decays as exp(-c t)) and Kelvin-Voigt twist dampers
G J tau / l0 on dm/dt.

State: the twist state is a :class:`TwistState` (theta, omega, the reference frames, the reference twists and
a built flag), carried by :class:`~bullet_dlo.core.model.CableState` and advanced by the steppers with the
positions; the parameters are the model's (:class:`~bullet_dlo.core.model.ModelArrays`, read only) and the
held ends' section axes and clamp springs are control (:class:`~bullet_dlo.core.model.CableControl`). The
kernels see the three through one flat argument, :class:`~bullet_dlo.core.model.KernelArrays` (fields
``tw_<name>``, the same array objects). A state whose ``flag[0]`` is 0 (a new one) is built from the positions
at its first use: reference frames by space-parallel transport from the first clamp's section axis, twist
angles in static equilibrium with the held ends.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.jit import njit


class TwistArrays(NamedTuple):
    """Material-frame parameters, control and state of a twisting cable as the kernels see them (SI); empty
    arrays without twist.

    The kernels' arrays carry these as flat fields ``tw_<name>`` (:class:`~bullet_dlo.core.model.KernelArrays`):
    k_twist .. drag from the model and the control (the clamp springs in force), theta .. mref and flag from
    the :class:`TwistState`, normal and clamp from the control.

    k_twist: twist spring constants [N m/rad], (n,) (index 0 / n-1: the clamp springs, 0 unless that
    end is clamped); c_twist: Kelvin-Voigt twist dampers k_twist tau [N m s/rad], (n,);
    k_aniso: anisotropic bending constant Delta = (k1 - k2)/2 [N m/rad^2] per bending node, (n,);
    inertia: rotational inertia of each segment about its axis [kg m^2], (n-1,);
    drag: twist drag c I_k [N m s/rad], (n-1,);
    theta: twist angles [rad], (n-1,); omega: their rates [rad/s], (n-1,);
    ref: reference directors (unit), (n-1, 3); tan: the tangents they were last transported to, (n-1, 3);
    mref: reference twist at each node at the last transport (unwrapped) [rad], (n,);
    normal: the clamps' section axis d1 at the three held-end sample times, (3, 2, 3) (shared with the
    holder plan, which writes it); clamp: the clamps' section axis the force kernels use now, (2, 3);
    flag: (1,) int, 0 = the state is to be built from the positions at its next use;
    prev: the twist angles [rad] and rates [rad/s] before the last implicit step (BDF2's history), (2, n-1).
    """

    k_twist: np.ndarray
    c_twist: np.ndarray
    k_aniso: np.ndarray
    inertia: np.ndarray
    drag: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    ref: np.ndarray
    tan: np.ndarray
    mref: np.ndarray
    normal: np.ndarray
    clamp: np.ndarray
    flag: np.ndarray
    prev: np.ndarray


class TwistState(NamedTuple):
    """The material frame's state, advanced with the positions (SI); empty arrays without twist.

    theta: twist angles [rad], (n-1,); omega: their rates [rad/s], (n-1,); ref: reference directors (unit),
    (n-1, 3); tan: the tangents they were last transported to (unit), (n-1, 3); mref: reference twist at each
    node at the last transport (unwrapped) [rad], (n,); flag: (1,) int, 0 = to be built from the positions at
    its next use (a new state), 1 = built; prev: theta and omega before the last implicit step, (2, n-1) (BDF2's
    history, read only when the step is told it has one).
    """

    theta: np.ndarray
    omega: np.ndarray
    ref: np.ndarray
    tan: np.ndarray
    mref: np.ndarray
    flag: np.ndarray
    prev: np.ndarray

    def copy(self) -> "TwistState":
        """An independent copy (same values)."""
        return TwistState(*(a.copy() for a in self))


def make_twist_state(n: int, enabled: bool = True) -> TwistState:
    """A new twist state of an n-node cable, built at first use (``enabled`` False: the empty state of a
    cable without a material frame)."""
    s = n - 1 if enabled else 0
    return TwistState(np.zeros(s), np.zeros(s), np.zeros((s, 3)), np.zeros((s, 3)), np.zeros(n if enabled else 0),
                      np.zeros(1, dtype=np.int64), np.zeros((2, s)))


TWIST_PARAMETERS = ("k_twist", "c_twist", "k_aniso", "inertia", "drag")  # the model's fields of TwistArrays
TWIST_AXES = ("normal", "clamp")  # the control's (held ends' section axes)


def no_twist() -> TwistArrays:
    """The empty :class:`TwistArrays` of a cable without a material frame."""
    e1, e2 = np.zeros(0), np.zeros((0, 3))
    return TwistArrays(e1, e1, e1, e1, e1, e1, e1, e2, e2, e1, np.zeros((0, 2, 3)), np.zeros((2, 3)),
                       np.zeros(1, dtype=np.int64), np.zeros((2, 0)))


def make_twist(k_twist: np.ndarray, c_twist: np.ndarray, k_aniso: np.ndarray, inertia: np.ndarray,
               drag: np.ndarray) -> TwistArrays:
    """:class:`TwistArrays` with the given parameters and a zeroed state to be built at first use."""
    n = k_twist.shape[0]
    return TwistArrays(k_twist, c_twist, k_aniso, inertia, drag, np.zeros(n - 1), np.zeros(n - 1),
                       np.zeros((n - 1, 3)), np.zeros((n - 1, 3)), np.zeros(n), np.zeros((3, 2, 3)),
                       np.zeros((2, 3)), np.zeros(1, dtype=np.int64), np.zeros((2, n - 1)))


def twist_fields(tw: TwistArrays) -> dict[str, np.ndarray]:
    """The ``tw_<name>`` fields of the model arrays for ``tw``."""
    return {f"tw_{k}": v for k, v in tw._asdict().items()}


def twist_view(m: NamedTuple) -> TwistArrays:
    """The :class:`TwistArrays` of model arrays ``m`` (the same array objects)."""
    return TwistArrays(*(getattr(m, f"tw_{k}") for k in TwistArrays._fields))


# ----- small vector helpers ---------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def has_twist(m):
    """Whether the model arrays ``m`` carry a material frame."""
    return m.tw_k_twist.shape[0] > 0


@njit(cache=True, error_model="numpy", inline="always")
def _wrap(a):
    """Angle a [rad] wrapped into (-pi, pi]."""
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@njit(cache=True, error_model="numpy", inline="always")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy", inline="always")
def add_cross_matrix(mat, scale, v):
    """mat (3, 3) += scale [v]x, the cross-product matrix of v (3,): [v]x y = v x y."""
    mat[0, 1] -= scale * v[2]
    mat[0, 2] += scale * v[1]
    mat[1, 0] += scale * v[2]
    mat[1, 2] -= scale * v[0]
    mat[2, 0] -= scale * v[1]
    mat[2, 1] += scale * v[0]


@njit(cache=True, error_model="numpy", inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def _transport(u, t1, t2, out):
    """out <- u parallel-transported from unit tangent t1 to unit tangent t2 (minimal rotation), then
    made unit and normal to t2 (guards round-off drift). u must be normal to t1."""
    c = _dot(t1, t2)
    bx = t1[1] * t2[2] - t1[2] * t2[1]
    by = t1[2] * t2[0] - t1[0] * t2[2]
    bz = t1[0] * t2[1] - t1[1] * t2[0]
    bu = bx * u[0] + by * u[1] + bz * u[2]
    f = bu / (1.0 + c) if c > -1.0 + 1e-12 else 0.0
    o0 = c * u[0] + (by * u[2] - bz * u[1]) + f * bx
    o1 = c * u[1] + (bz * u[0] - bx * u[2]) + f * by
    o2 = c * u[2] + (bx * u[1] - by * u[0]) + f * bz
    d = o0 * t2[0] + o1 * t2[1] + o2 * t2[2]
    o0 -= d * t2[0]
    o1 -= d * t2[1]
    o2 -= d * t2[2]
    norm = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    out[0], out[1], out[2] = o0 / norm, o1 / norm, o2 / norm


transport = _transport  # the public name (callers outside the kernels)


@njit(cache=True, error_model="numpy", inline="always")
def scatter_edge(f, k, g0, g1, g2):
    """f[k] += g, f[k + 1] -= g: a gradient g = dE/de_k [N] of edge k = x_{k+1} - x_k as forces -dE/dx on its two
    nodes (f (n, 3); in this order, so sums stay bit-identical to the loops written out)."""
    f[k, 0] += g0
    f[k, 1] += g1
    f[k, 2] += g2
    f[k + 1, 0] -= g0
    f[k + 1, 1] -= g1
    f[k + 1, 2] -= g2


@njit(cache=True, error_model="numpy", inline="always")
def _unit_edge(x, k, out):
    """out <- unit tangent of edge k; returns its length [m]."""
    dx, dy, dz = x[k + 1, 0] - x[k, 0], x[k + 1, 1] - x[k, 1], x[k + 1, 2] - x[k, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    out[0], out[1], out[2] = dx / length, dy / length, dz / length
    return length


# ----- node geometry ------------------------------------------------------------------------------
# The per-node kernels work in scalars: no array view (``g[0]``, ``m.tw_ref[k]``) and no KernelArrays
# argument inside a per-node loop. Each view or array argument costs Numba an NRT incref/decref pair (an
# atomic call each); a node function taking ``m`` (27 arrays) paid ~70 of them per call, 8x the arithmetic
# (node twist at n = 80: 58 -> 7 us per sweep, bit-identical; see demos/twist_cost.py).
@njit(cache=True, error_model="numpy", inline="always")
def _transport_s(u0, u1, u2, a0, a1, a2, b0, b1, b2):
    """:func:`_transport` in scalars: u parallel-transported from unit tangent a to unit tangent b, made unit
    and normal to b; returns its three components (the same operations in the same order)."""
    c = a0 * b0 + a1 * b1 + a2 * b2
    bx = a1 * b2 - a2 * b1
    by = a2 * b0 - a0 * b2
    bz = a0 * b1 - a1 * b0
    bu = bx * u0 + by * u1 + bz * u2
    f = bu / (1.0 + c) if c > -1.0 + 1e-12 else 0.0
    o0 = c * u0 + (by * u2 - bz * u1) + f * bx
    o1 = c * u1 + (bz * u0 - bx * u2) + f * by
    o2 = c * u2 + (bx * u1 - by * u0) + f * bz
    d = o0 * b0 + o1 * b1 + o2 * b2
    o0 -= d * b0
    o1 -= d * b1
    o2 -= d * b2
    norm = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
    return o0 / norm, o1 / norm, o2 / norm


@njit(cache=True, error_model="numpy", inline="always")
def edge_frame(x, dirs, theta, ref, tan, clamp, k):
    """Edge k's (length [m], unit tangent (3 scalars), reference director carried onto it (3 scalars), twist
    angle [rad]); k = -1 and k = n - 1 are the clamps' virtual edges (length 1, tangent the clamp direction
    ``dirs[e]``, director the clamp's section axis ``clamp[e]`` re-orthonormalised, twist angle 0)."""
    n1 = x.shape[0] - 1
    if k < 0 or k >= n1:
        e = 0 if k < 0 else 1
        t0, t1, t2 = dirs[e, 0], dirs[e, 1], dirs[e, 2]
        r0, r1, r2 = _transport_s(clamp[e, 0], clamp[e, 1], clamp[e, 2], t0, t1, t2, t0, t1, t2)
        return 1.0, t0, t1, t2, r0, r1, r2, 0.0
    dx, dy, dz = x[k + 1, 0] - x[k, 0], x[k + 1, 1] - x[k, 1], x[k + 1, 2] - x[k, 2]
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    t0, t1, t2 = dx / length, dy / length, dz / length
    r0, r1, r2 = _transport_s(ref[k, 0], ref[k, 1], ref[k, 2], tan[k, 0], tan[k, 1], tan[k, 2], t0, t1, t2)
    return length, t0, t1, t2, r0, r1, r2, theta[k]


@njit(cache=True, error_model="numpy", inline="always")
def _psi(fa, fb):
    """Reference twist at the node between edges a and b (frames ``fa``, ``fb`` from :func:`edge_frame`): the
    signed angle about t_b from r_a carried onto edge b to r_b [rad], not unwrapped."""
    la, ta0, ta1, ta2, ra0, ra1, ra2, th_a = fa
    lb, tb0, tb1, tb2, rb0, rb1, rb2, th_b = fb
    p0, p1, p2 = _transport_s(ra0, ra1, ra2, ta0, ta1, ta2, tb0, tb1, tb2)
    c0 = p1 * rb2 - p2 * rb1
    c1 = p2 * rb0 - p0 * rb2
    c2 = p0 * rb1 - p1 * rb0
    return math.atan2(c0 * tb0 + c1 * tb1 + c2 * tb2, p0 * rb0 + p1 * rb1 + p2 * rb2)


@njit(cache=True, error_model="numpy", inline="always")
def twist_of_frames(fa, fb, mref_i):
    """:func:`node_twist` from the frames of the node's two edges (:func:`edge_frame`; a loop over the nodes
    carries edge b's frame on as the next node's edge a, so each edge frame is computed once per sweep) and the
    node's last reference twist mref_i [rad]."""
    la, ta0, ta1, ta2, ra0, ra1, ra2, th_a = fa
    lb, tb0, tb1, tb2, rb0, rb1, rb2, th_b = fb
    psi = _psi(fa, fb)
    twist = th_b - th_a + mref_i + _wrap(psi - mref_i)
    c = ta0 * tb0 + ta1 * tb1 + ta2 * tb2
    k0 = ta1 * tb2 - ta2 * tb1
    k1 = ta2 * tb0 - ta0 * tb2
    k2 = ta0 * tb1 - ta1 * tb0
    return twist, la, lb, 2.0 * k0 / (1.0 + c), 2.0 * k1 / (1.0 + c), 2.0 * k2 / (1.0 + c)


@njit(cache=True, error_model="numpy", inline="always")
def geometry_twist(fa, fb, mref_i):
    """(m_i twist [rad], |e_a| [m], |e_b| [m], curvature binormal kb (3 scalars)) from the frames of the node's
    two edges, as :func:`geometry_of_frames` computes them (the same operations and roundings: twist =
    th_b - th_a + (mref_i + wrap(psi - mref_i)); :func:`twist_of_frames` adds in another order), without the
    material axes and curvatures: what the twist of any section and a round or tube section's forces need."""
    la, ta0, ta1, ta2, ra0, ra1, ra2, th_a = fa
    lb, tb0, tb1, tb2, rb0, rb1, rb2, th_b = fb
    psi = _psi(fa, fb)
    mr = mref_i + _wrap(psi - mref_i)
    twist = th_b - th_a + mr
    c = ta0 * tb0 + ta1 * tb1 + ta2 * tb2
    k0 = ta1 * tb2 - ta2 * tb1
    k1 = ta2 * tb0 - ta0 * tb2
    k2 = ta0 * tb1 - ta1 * tb0
    return twist, la, lb, 2.0 * k0 / (1.0 + c), 2.0 * k1 / (1.0 + c), 2.0 * k2 / (1.0 + c)


@njit(cache=True, error_model="numpy", inline="always")
def node_twist(x, dirs, theta, ref, tan, clamp, mref, i):
    """The part of :func:`node_geometry` a round or tube section needs, in scalars: (m_i twist [rad], |e_a| [m],
    |e_b| [m], curvature binormal kb = 2 t_a x t_b / (1 + t_a . t_b) (3 scalars)). Arrays: x [m] (n, 3), dirs the
    clamp directions (2, 3), theta [rad] (n-1,), the reference frames ref, tan (n-1, 3), the clamps' section axes
    clamp (2, 3), the reference twists mref [rad] (n,) (the ``tw_`` fields of the kernel arrays)."""
    return twist_of_frames(edge_frame(x, dirs, theta, ref, tan, clamp, i - 1),
                           edge_frame(x, dirs, theta, ref, tan, clamp, i), mref[i])


# Scratch rows of g (12, 3): 0 t_a, 1 r_a, 2 t_b, 3 r_b, 4 m1_a, 5 m2_a, 6 m1_b, 7 m2_b, 8 phi,
# 9 kb (curvature binormal), 10 transported r_a, 11 spare.
@njit(cache=True, error_model="numpy")
def node_geometry(x, dirs, theta, ref, tan, clamp, mref, i, g):
    """Frames, twist and curvature at node i into scratch ``g`` (see the row map above; rows 10-11 not written).

    Arrays as :func:`node_twist`; theta: twist angles to use [rad], (n-1,). Returns (m_i twist [rad], |e_a| [m],
    |e_b| [m], ratio = beta/sin(beta), alpha = (sin - beta cos)/sin^3, c = cos(beta)); a clamp's virtual edge
    has length 1 (its direction is a unit vector, as in the bending kernels) and twist angle 0.
    """
    return geometry_of_frames(edge_frame(x, dirs, theta, ref, tan, clamp, i - 1),
                              edge_frame(x, dirs, theta, ref, tan, clamp, i), mref[i], g)


@njit(cache=True, error_model="numpy")
def geometry_of_frames(fa, fb, mref_i, g):
    """:func:`node_geometry` from the frames of the node's two edges (:func:`edge_frame`) and its last reference
    twist mref_i [rad]."""
    la, ta0, ta1, ta2, ra0, ra1, ra2, th_a = fa
    lb, tb0, tb1, tb2, rb0, rb1, rb2, th_b = fb
    psi = _psi(fa, fb)
    g[0, 0], g[0, 1], g[0, 2] = ta0, ta1, ta2
    g[1, 0], g[1, 1], g[1, 2] = ra0, ra1, ra2
    g[2, 0], g[2, 1], g[2, 2] = tb0, tb1, tb2
    g[3, 0], g[3, 1], g[3, 2] = rb0, rb1, rb2
    # reference twist unwrapped against mref
    mr = mref_i + _wrap(psi - mref_i)
    twist = th_b - th_a + mr
    # material frames: m1 = cos th r + sin th (t x r), m2 = t x m1
    ca, sa = math.cos(th_a), math.sin(th_a)
    m0 = ca * ra0 + sa * (ta1 * ra2 - ta2 * ra1)
    m1 = ca * ra1 + sa * (ta2 * ra0 - ta0 * ra2)
    m2 = ca * ra2 + sa * (ta0 * ra1 - ta1 * ra0)
    g[4, 0], g[4, 1], g[4, 2] = m0, m1, m2
    g[5, 0], g[5, 1], g[5, 2] = ta1 * m2 - ta2 * m1, ta2 * m0 - ta0 * m2, ta0 * m1 - ta1 * m0
    cb, sb = math.cos(th_b), math.sin(th_b)
    m0 = cb * rb0 + sb * (tb1 * rb2 - tb2 * rb1)
    m1 = cb * rb1 + sb * (tb2 * rb0 - tb0 * rb2)
    m2 = cb * rb2 + sb * (tb0 * rb1 - tb1 * rb0)
    g[6, 0], g[6, 1], g[6, 2] = m0, m1, m2
    g[7, 0], g[7, 1], g[7, 2] = tb1 * m2 - tb2 * m1, tb2 * m0 - tb0 * m2, tb0 * m1 - tb1 * m0
    # turning-angle vector phi = beta (ta x tb)/sin(beta) and curvature binormal 2 ta x tb/(1 + ta.tb)
    c = ta0 * tb0 + ta1 * tb1 + ta2 * tb2
    k0 = ta1 * tb2 - ta2 * tb1
    k1 = ta2 * tb0 - ta0 * tb2
    k2 = ta0 * tb1 - ta1 * tb0
    s = math.sqrt(k0 * k0 + k1 * k1 + k2 * k2)
    beta = math.atan2(s, c)
    if beta < 1e-3:
        b2 = beta * beta
        ratio = 1.0 + b2 / 6.0
        alpha = 1.0 / 3.0 + 2.0 * b2 / 15.0
    else:
        ratio = beta / s
        alpha = (s - beta * c) / (s * s * s)
    g[8, 0], g[8, 1], g[8, 2] = ratio * k0, ratio * k1, ratio * k2
    g[9, 0], g[9, 1], g[9, 2] = 2.0 * k0 / (1.0 + c), 2.0 * k1 / (1.0 + c), 2.0 * k2 / (1.0 + c)
    return twist, la, lb, ratio, alpha, c


@njit(cache=True, error_model="numpy", inline="always")
def _add_cross_matrix_s(mat, scale, v0, v1, v2):
    """:func:`add_cross_matrix` with v given as three scalars."""
    mat[0, 1] -= scale * v2
    mat[0, 2] += scale * v1
    mat[1, 0] += scale * v2
    mat[1, 2] -= scale * v0
    mat[2, 0] -= scale * v1
    mat[2, 1] += scale * v0


@njit(cache=True, error_model="numpy")
def phi_jacobians(g, la, lb, ratio, alpha, c, pa, pb):
    """Plain derivatives dphi/da, dphi/db (3, 3) of the turning-angle vector into pa, pb (from
    :func:`node_geometry`'s scratch g): dphi/da = -alpha chi ga^T - (r/la)([w]x + chi u^T),
    dphi/db = -alpha chi gb^T + (r/lb)([u]x - chi w^T), u = t_a, w = t_b, chi = u x w,
    ga = (w - c u)/la, gb = (u - c w)/lb, r = beta/sin(beta)."""
    u0, u1, u2 = g[0, 0], g[0, 1], g[0, 2]
    w0, w1, w2 = g[2, 0], g[2, 1], g[2, 2]
    chi0 = u1 * w2 - u2 * w1
    chi1 = u2 * w0 - u0 * w2
    chi2 = u0 * w1 - u1 * w0
    for r in range(3):
        chi_r = chi0 if r == 0 else (chi1 if r == 1 else chi2)
        for col in range(3):
            ga = (g[2, col] - c * g[0, col]) / la
            gb = (g[0, col] - c * g[2, col]) / lb
            pa[r, col] = -alpha * chi_r * ga - (ratio / la) * chi_r * g[0, col]
            pb[r, col] = -alpha * chi_r * gb - (ratio / lb) * chi_r * g[2, col]
    _add_cross_matrix_s(pa, -ratio / la, w0, w1, w2)
    _add_cross_matrix_s(pb, ratio / lb, u0, u1, u2)


@njit(cache=True, error_model="numpy", inline="always")
def _curvatures(g):
    """Material curvatures (phi . m1, phi . m2) in the frames of edge a and edge b."""
    p0, p1, p2 = g[8, 0], g[8, 1], g[8, 2]
    return (p0 * g[4, 0] + p1 * g[4, 1] + p2 * g[4, 2], p0 * g[5, 0] + p1 * g[5, 1] + p2 * g[5, 2],
            p0 * g[6, 0] + p1 * g[6, 1] + p2 * g[6, 2], p0 * g[7, 0] + p1 * g[7, 1] + p2 * g[7, 2])


# ----- state --------------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def twist_ready(m, x, dirs):
    """Build the twist state from the positions x [m] if ``flag`` asks for it (else nothing).

    Reference frames: space-parallel transport along the chain from the first clamp's section axis
    (the first end's ``normal``; turned into the first edge), so every reference twist starts at 0
    except at a second clamp; twist angles: static equilibrium with the clamps (:func:`twist_solve`),
    zero rates.
    """
    if m.tw_flag[0] != 0:
        return
    m.tw_flag[0] = 1
    n = x.shape[0]
    m.tw_clamp[:, :] = m.tw_normal[0]
    t = np.empty(3)
    d0 = np.empty(3)
    d0[:] = dirs[0]
    prev_t = d0
    prev_r = np.empty(3)
    _transport(m.tw_clamp[0], d0, d0, prev_r)
    for k in range(n - 1):
        _unit_edge(x, k, t)
        _transport(prev_r, prev_t, t, m.tw_ref[k])
        m.tw_tan[k, :] = t
        prev_t = m.tw_tan[k]
        prev_r = m.tw_ref[k]
    m.tw_theta[:] = 0.0
    m.tw_omega[:] = 0.0
    m.tw_mref[:] = 0.0
    g = np.empty((12, 3))
    for i in range(n):  # reference twists of the built frames (0 but at a second clamp)
        m.tw_mref[i] = node_geometry(x, dirs, m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref, i, g)[0]
    if m.tw_k_twist[0] != 0.0 or m.tw_k_twist[n - 1] != 0.0:
        twist_solve(m, x, dirs, 1.0, False, m.tw_mref)


@njit(cache=True, error_model="numpy")
def grip_section(m, x, dirs, end):
    """Make the clamp of ``end`` (0 first, 1 last) hold the section as it is now, for a clamp closing on
    the cable (a gripper's grasp): its section axis d1 becomes the end segment's material axis m1 carried
    by parallel transport onto the clamp direction ``dirs[end]`` (unit), and the clamp node's reference
    twist is set so that its twist is 0 (closing a gripper does not twist the cable). Writes the axis into
    ``tw_clamp`` and every sample of ``tw_normal`` of that end and returns it (3,), world frame; the
    caller sets the clamp's twist springs (``tw_k_twist`` etc. at the end node)."""
    twist_ready(m, x, dirs)
    n = x.shape[0]
    k = 0 if end == 0 else n - 2
    t, r, b, m1, out = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    _unit_edge(x, k, t)
    _transport(m.tw_ref[k], m.tw_tan[k], t, r)
    _cross(t, r, b)
    c, s = math.cos(m.tw_theta[k]), math.sin(m.tw_theta[k])
    for j in range(3):
        m1[j] = c * r[j] + s * b[j]
    d = np.empty(3)
    d[:] = dirs[end]
    _transport(m1, t, d, out)
    m.tw_clamp[end, :] = out
    for sample in range(m.tw_normal.shape[0]):
        m.tw_normal[sample, end, :] = out
    # twist m_i = theta_b - theta_a + mref_i is 0 with the clamp edge's theta 0 (see node_geometry)
    m.tw_mref[0 if end == 0 else n - 1] = -m.tw_theta[0] if end == 0 else m.tw_theta[n - 2]
    return out


@njit(cache=True, error_model="numpy")
def set_clamp(m, k):
    """Make the clamps' section axis of held-end sample k (0: t, 1: t + h/2, 2: t + h) the current one."""
    if has_twist(m):
        m.tw_clamp[:, :] = m.tw_normal[k]


@njit(cache=True, error_model="numpy")
def update_frames(m, x, dirs):
    """Transport the reference frames to the tangents of x (time-parallel) and store the new
    (unwrapped) reference twists; returns nothing. Call once per step, after the positions moved."""
    n = x.shape[0]
    ref, tan, theta, clamp, mref = m.tw_ref, m.tw_tan, m.tw_theta, m.tw_clamp, m.tw_mref
    for k in range(n - 1):
        dx, dy, dz = x[k + 1, 0] - x[k, 0], x[k + 1, 1] - x[k, 1], x[k + 1, 2] - x[k, 2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        t0, t1, t2 = dx / length, dy / length, dz / length
        r0, r1, r2 = _transport_s(ref[k, 0], ref[k, 1], ref[k, 2], tan[k, 0], tan[k, 1], tan[k, 2], t0, t1, t2)
        ref[k, 0], ref[k, 1], ref[k, 2] = r0, r1, r2
        tan[k, 0], tan[k, 1], tan[k, 2] = t0, t1, t2
    reference_twists(x, dirs, theta, ref, tan, clamp, mref)


@njit(cache=True, error_model="numpy", inline="always")
def reference_twists(x, dirs, theta, ref, tan, clamp, mref):
    """The second half of :func:`update_frames`: mref <- the (unwrapped) reference twists of the frames ref, tan
    (already transported to the tangents of x). The coupled implicit step calls it alone when its last residual
    transported the frames to the end-of-step tangents already."""
    n = x.shape[0]
    fb = edge_frame(x, dirs, theta, ref, tan, clamp, -1)
    for i in range(n):
        fa = fb  # edge i-1's frame, carried on from the last node
        fb = edge_frame(x, dirs, theta, ref, tan, clamp, i)
        th_b = theta[i] if i < n - 1 else 0.0
        th_a = theta[i - 1] if i > 0 else 0.0
        mref[i] = twist_of_frames(fa, fb, mref[i])[0] - (th_b - th_a)


# ----- energy, forces, Jacobian, clamp moments ------------------------------------------------------
@njit(cache=True, error_model="numpy")
def twist_energy(m, x, dirs):
    """Twist energy plus the anisotropic part of the bending energy [J] at the current twist angles.

    One sweep over the nodes carrying each edge's frame on to the next node, the full node geometry only where
    the section is anisotropic (the same values as :func:`node_geometry` node by node: 16 -> 4 us at n = 80)."""
    twist_ready(m, x, dirs)
    n = x.shape[0]
    g = np.empty((12, 3))
    e = 0.0
    ktw, kan, theta = m.tw_k_twist, m.tw_k_aniso, m.tw_theta
    ref, tan, clamp, mref = m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    fb = edge_frame(x, dirs, theta, ref, tan, clamp, -1)
    for i in range(n):
        fa = fb  # edge i-1's frame, carried on from the last node
        fb = edge_frame(x, dirs, theta, ref, tan, clamp, i)
        kt, dl = ktw[i], kan[i]
        if kt == 0.0 and dl == 0.0:
            continue
        if dl != 0.0:
            twist = geometry_of_frames(fa, fb, mref[i], g)[0]
        else:
            twist = geometry_twist(fa, fb, mref[i])[0]
        e += 0.5 * kt * twist * twist
        if dl != 0.0:
            p1a, p2a, p1b, p2b = _curvatures(g)
            e += 0.25 * dl * (p1a * p1a - p2a * p2a + p1b * p1b - p2b * p2b)
    return e


@njit(cache=True, error_model="numpy")
def twist_kinetic(m):
    """Kinetic energy of the segments' spin [J]."""
    e = 0.0
    for k in range(m.tw_omega.shape[0]):
        e += 0.5 * m.tw_inertia[k] * m.tw_omega[k] * m.tw_omega[k]
    return e


@njit(cache=True, error_model="numpy")
def _node_edge_gradients(g, twist, la, lb, ratio, alpha, c, dl, kt, ga, gb, pa, pb):
    """dE/de_a, dE/de_b [N] of node i's twist and anisotropic bending energies into ga, gb (3,)."""
    ft = kt * twist
    for j in range(3):
        ga[j] = ft * g[9, j] / (2.0 * la)
        gb[j] = ft * g[9, j] / (2.0 * lb)
    if dl != 0.0:
        p1a, p2a, p1b, p2b = _curvatures(g)
        q0 = 0.5 * dl * (p1a * g[4, 0] - p2a * g[5, 0] + p1b * g[6, 0] - p2b * g[7, 0])
        q1 = 0.5 * dl * (p1a * g[4, 1] - p2a * g[5, 1] + p1b * g[6, 1] - p2b * g[7, 1])
        q2 = 0.5 * dl * (p1a * g[4, 2] - p2a * g[5, 2] + p1b * g[6, 2] - p2b * g[7, 2])
        phi_jacobians(g, la, lb, ratio, alpha, c, pa, pb)
        for j in range(3):
            ga[j] += pa[0, j] * q0 + pa[1, j] * q1 + pa[2, j] * q2
            gb[j] += pb[0, j] * q0 + pb[1, j] * q1 + pb[2, j] * q2


@njit(cache=True, error_model="numpy")
def add_twist_forces(m, x, dirs, out):
    """out += -dE/dx [N] of the twist and anisotropic bending energies (twist angles held), (n, 3).

    Edge frames carried from node to node as in :func:`twist_energy`; a round or tube section's node takes
    -dE/de_a = -k_t m_i kb/(2|e_a|) (and the same on e_b) from :func:`geometry_twist`, the values
    :func:`_node_edge_gradients` gives without anisotropy."""
    twist_ready(m, x, dirs)
    n = x.shape[0]
    g = np.empty((12, 3))
    ga, gb = np.empty(3), np.empty(3)
    pa, pb = np.empty((3, 3)), np.empty((3, 3))
    ktw, kan, theta = m.tw_k_twist, m.tw_k_aniso, m.tw_theta
    ref, tan, clamp, mref = m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    fb = edge_frame(x, dirs, theta, ref, tan, clamp, -1)
    for i in range(n):
        fa = fb
        fb = edge_frame(x, dirs, theta, ref, tan, clamp, i)
        kt, dl = ktw[i], kan[i]
        if kt == 0.0 and dl == 0.0:
            continue
        if dl != 0.0:
            twist, la, lb, ratio, alpha, c = geometry_of_frames(fa, fb, mref[i], g)
            _node_edge_gradients(g, twist, la, lb, ratio, alpha, c, dl, kt, ga, gb, pa, pb)
            ga0, ga1, ga2, gb0, gb1, gb2 = ga[0], ga[1], ga[2], gb[0], gb[1], gb[2]
        else:
            twist, la, lb, kb0, kb1, kb2 = geometry_twist(fa, fb, mref[i])
            ft = kt * twist
            ga0, ga1, ga2 = ft * kb0 / (2.0 * la), ft * kb1 / (2.0 * la), ft * kb2 / (2.0 * la)
            gb0, gb1, gb2 = ft * kb0 / (2.0 * lb), ft * kb1 / (2.0 * lb), ft * kb2 / (2.0 * lb)
        if i > 0:  # e_a = x_i - x_{i-1}
            scatter_edge(out, i - 1, ga0, ga1, ga2)
        if i < n - 1:  # e_b = x_{i+1} - x_i
            scatter_edge(out, i, gb0, gb1, gb2)


@njit(cache=True, error_model="numpy")
def add_twist_jacobian(m, x, dirs, jac):
    """jac += the Gauss-Newton part of -d2E/dx2 of the anisotropic bending [N/m] (block-banded
    (n, 5, 3, 3), as :func:`~bullet_dlo.core.kernels.forces.force_jacobian`): -Delta/2 sum_k
    (J1_k^T J1_k - J2_k^T J2_k), J_j = m_j^T dphi/d(a, b). No-op for round and tube sections."""
    twist_ready(m, x, dirs)
    n = x.shape[0]
    g = np.empty((12, 3))
    pa, pb = np.empty((3, 3)), np.empty((3, 3))
    jrow = np.empty((4, 6))
    hb = np.empty((6, 6))
    kan, theta, ref, tan, clamp, mref = m.tw_k_aniso, m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    for i in range(n):
        dl = kan[i]
        if dl == 0.0:
            continue
        twist, la, lb, ratio, alpha, c = node_geometry(x, dirs, theta, ref, tan, clamp, mref, i, g)
        phi_jacobians(g, la, lb, ratio, alpha, c, pa, pb)
        aniso_node_hessian(g, dl, pa, pb, jrow, hb)
        scatter_node_hessian(jac, i, n, hb)


@njit(cache=True, error_model="numpy", inline="always")
def aniso_node_hessian(g, dl, pa, pb, jrow, hb):
    """The Gauss-Newton part of node i's anisotropic bending Hessian over (e_a, e_b): jrow (4, 6) <- J_j =
    m_j^T dphi/d(a, b) for the rows m1_a, m2_a, m1_b, m2_b (frames from :func:`node_geometry`'s g, pa, pb from
    :func:`phi_jacobians`); hb (6, 6) <- Delta/2 sum_k (J1_k^T J1_k - J2_k^T J2_k) [N m] (dl = Delta)."""
    for r in range(4):
        d0, d1, d2 = g[4 + r, 0], g[4 + r, 1], g[4 + r, 2]
        for col in range(3):
            jrow[r, col] = d0 * pa[0, col] + d1 * pa[1, col] + d2 * pa[2, col]
            jrow[r, 3 + col] = d0 * pb[0, col] + d1 * pb[1, col] + d2 * pb[2, col]
    for r in range(6):
        for col in range(6):
            hb[r, col] = 0.5 * dl * (jrow[0, r] * jrow[0, col] - jrow[1, r] * jrow[1, col]
                                     + jrow[2, r] * jrow[2, col] - jrow[3, r] * jrow[3, col])


@njit(cache=True, error_model="numpy", inline="always")  # called per node
def scatter_node_hessian(jac, i, n, hb):
    """jac -= the node Hessian hb (6, 6) over (e_a, e_b) mapped onto nodes i-1, i, i+1 (clamp edges fixed):
    a = x_i - x_{i-1}, b = x_{i+1} - x_i, by the chain rule jac[p, q-p+2] -= H_pq; at a clamp (i = 0 or
    n - 1) only the free edge's nodes move. Used by the bending and the twist Jacobians."""
    for r in range(3):
        for col in range(3):
            haa, hab = hb[r, col], hb[r, 3 + col]
            hba, hbb = hb[3 + r, col], hb[3 + r, 3 + col]
            if i == 0:
                jac[0, 2, r, col] -= hbb
                jac[0, 3, r, col] += hbb
                jac[1, 1, r, col] += hbb
                jac[1, 2, r, col] -= hbb
            elif i == n - 1:
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
def twist_clamp_torque(m, x, dirs, end):
    """Moment [N m] the twist springs and the anisotropic bending exert on the clamp at ``end`` (0 first,
    1 last), world frame: the part today's :func:`~bullet_dlo.core.kernels.forces.clamp_torque` (isotropic
    bending) does not hold. About the clamp axis d: +k_t m_0 (first) or -k_t m_{n-1} (last), the
    torsion torque, minus Delta kappa_1 kappa_2 of the clamp's own frame; normal to d: -d x dE/dd."""
    out = np.zeros(3)
    n = x.shape[0]
    i = 0 if end == 0 else n - 1
    kt, dl = m.tw_k_twist[i], m.tw_k_aniso[i]
    if kt == 0.0 and dl == 0.0:
        return out
    twist_ready(m, x, dirs)
    g = np.empty((12, 3))
    ga, gb = np.empty(3), np.empty(3)
    pa, pb = np.empty((3, 3)), np.empty((3, 3))
    twist, la, lb, ratio, alpha, c = node_geometry(x, dirs, m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref, i, g)
    _node_edge_gradients(g, twist, la, lb, ratio, alpha, c, dl, kt, ga, gb, pa, pb)
    d = g[0] if end == 0 else g[2]
    gd = ga if end == 0 else gb  # dE/dd (the clamp direction plays edge a at the first end, b at the last)
    spin = kt * twist if end == 0 else -kt * twist
    if dl != 0.0:
        p1a, p2a, p1b, p2b = _curvatures(g)
        spin -= dl * (p1a * p2a if end == 0 else p1b * p2b)
    out[0] = -(d[1] * gd[2] - d[2] * gd[1]) + spin * d[0]
    out[1] = -(d[2] * gd[0] - d[0] * gd[2]) + spin * d[1]
    out[2] = -(d[0] * gd[1] - d[1] * gd[0]) + spin * d[2]
    return out


@njit(cache=True, error_model="numpy", inline="always")
def flat_dampers(m):
    """Whether the Kelvin-Voigt bending dampers of ``m`` need :func:`damper_tensors`: a material frame with an
    anisotropic section (some k_aniso != 0) and internal damping on bending (some c_bend > 0). The frame's arrays,
    not ``has_twist``: the coupled twisting step passes them without the twist springs (``_frameless``)."""
    aniso = False
    for i in range(m.tw_k_aniso.shape[0]):
        if m.tw_k_aniso[i] != 0.0:
            aniso = True
            break
    if not aniso:
        return False
    for i in range(m.c_bend.shape[0]):
        if m.c_bend[i] > 0.0:
            return True
    return False


@njit(cache=True, error_model="numpy")
def damper_tensors(m, x, dirs, out):
    """out (n, 3, 3) <- each node's Kelvin-Voigt bending damper C_i [N m s/rad^2] on the turning angle's rate
    phi_dot (its Rayleigh term 1/2 phi_dot^T C_i phi_dot): tau times the Gauss-Newton Hessian of the node's bending
    energy in phi, C_i = c_b I + tau Delta/2 sum_k (m1_k m1_k^T - m2_k m2_k^T) over the frames of its two edges
    (tau = c_b / k_b), which is tau/2 sum_k (k1 m1_k m1_k^T + k2 m2_k m2_k^T + kbar t_k t_k^T): each bending plane
    damped by its own stiffness, so mode k of either plane decays as exp(-tau omega_k^2 t / 2). (c_b I alone, the
    round section's damper, damped a flat strip's weak plane with the mean stiffness: 3200 times too much on a
    40 x 0.5 mm strip, which crept back instead of ringing.) The frames' own rates are left out, as
    :func:`add_twist_forces` leaves out their turn: phi . dm/dt, second order in the curvature."""
    if has_twist(m):  # (without the springs, the coupled step's view: its frames are built)
        twist_ready(m, x, dirs)
    g = np.empty((12, 3))
    for i in range(x.shape[0]):
        damper_tensor(m, x, dirs, i, g, out[i])


@njit(cache=True, error_model="numpy")
def damper_tensor(m, x, dirs, i, g, out):
    """out (3, 3) <- node i's damper C_i of :func:`damper_tensors` (its frames already built: ``twist_ready``);
    g (12, 3): scratch."""
    cb = m.c_bend[i]
    for r in range(3):
        for col in range(3):
            out[r, col] = cb if r == col else 0.0
    dl = m.tw_k_aniso[i]
    if cb == 0.0 or dl == 0.0 or m.k_bend[i] == 0.0:
        return
    node_geometry(x, dirs, m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref, i, g)
    w = 0.5 * dl * cb / m.k_bend[i]
    for r in range(3):
        for col in range(3):
            out[r, col] += w * (g[4, r] * g[4, col] - g[5, r] * g[5, col] + g[6, r] * g[6, col] - g[7, r] * g[7, col])


# ----- the twist sub-step ---------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def theta_gradient(m, x, dirs, theta, grad, hdiag):
    """grad <- dE/dtheta [N m] at twist angles ``theta`` (positions x held); hdiag <- the anisotropic
    part of d2E/dtheta2 (diagonal), filtered to >= 0 (keeps the Newton matrix positive definite)."""
    n = x.shape[0]
    g = np.empty((12, 3))
    grad[:] = 0.0
    hdiag[:] = 0.0
    ktw, kan, ref, tan, clamp, mref = m.tw_k_twist, m.tw_k_aniso, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    for i in range(n):
        kt, dl = ktw[i], kan[i]
        if kt == 0.0 and dl == 0.0:
            continue
        twist = node_geometry(x, dirs, theta, ref, tan, clamp, mref, i, g)[0]
        if i > 0:  # dm_i/dtheta_{i-1} = -1
            grad[i - 1] -= kt * twist
        if i < n - 1:
            grad[i] += kt * twist
        if dl != 0.0:
            p1a, p2a, p1b, p2b = _curvatures(g)
            if i > 0:  # d/dtheta (k1 p1^2 + k2 p2^2)/4 -> Delta p1 p2; second derivative Delta (p2^2 - p1^2)
                grad[i - 1] += dl * p1a * p2a
                hdiag[i - 1] += max(dl * (p2a * p2a - p1a * p1a), 0.0)
            if i < n - 1:
                grad[i] += dl * p1b * p2b
                hdiag[i] += max(dl * (p2b * p2b - p1b * p1b), 0.0)


@njit(cache=True, error_model="numpy")
def twist_solve(m, x, dirs, h, dynamic, dref):
    """Advance the twist angles by one implicit Euler step h [s] with the positions x held
    (``dynamic``), or put them in static equilibrium (not ``dynamic``; h unused). Newton on the
    tridiagonal system; linear (one iteration) for round and tube sections. Returns Newton iterations.

    Dynamic: I (w' - w) + h (dE/dtheta(theta + h w') + c_d w' + dR/dw') = 0 with the Kelvin-Voigt rate
    dm_i/dt = w'_b - w'_a + dref_i, dref [rad/s] (n,) the rate of the reference twist over the step
    (the positions' and the clamps' share of the twist rate).
    """
    n = x.shape[0]
    ns = n - 1
    w_new = m.tw_omega.copy()
    theta_try = np.empty(ns)
    grad = np.empty(ns)
    hd = np.empty(ns)
    diag = np.empty(ns)
    off = np.empty(ns)
    rhs = np.empty(ns)
    aniso = np.max(np.abs(m.tw_k_aniso)) > 0.0
    its = 0
    scale = 0.0
    for it in range(30):
        its = it + 1
        for k in range(ns):
            theta_try[k] = m.tw_theta[k] + (h * w_new[k] if dynamic else w_new[k])
        theta_gradient(m, x, dirs, theta_try, grad, hd)
        for k in range(ns):
            kt_a, kt_b = m.tw_k_twist[k], m.tw_k_twist[k + 1]
            if dynamic:
                ct_a, ct_b = m.tw_c_twist[k], m.tw_c_twist[k + 1]
                # Kelvin-Voigt: rates of the twists at node k (edges k-1, k) and k+1 (edges k, k+1)
                wa = w_new[k - 1] if k > 0 else 0.0
                wb = w_new[k + 1] if k < ns - 1 else 0.0
                rate_a = w_new[k] - wa + dref[k]
                rate_b = wb - w_new[k] + dref[k + 1]
                kv = ct_a * rate_a - ct_b * rate_b
                rhs[k] = -(m.tw_inertia[k] * (w_new[k] - m.tw_omega[k]) + h * (grad[k] + m.tw_drag[k] * w_new[k] + kv))
                diag[k] = m.tw_inertia[k] + h * m.tw_drag[k] + h * (ct_a + ct_b) + h * h * (kt_a + kt_b + hd[k])
                off[k] = -(h * ct_b + h * h * kt_b) if k < ns - 1 else 0.0
            else:
                rhs[k] = -grad[k]
                diag[k] = kt_a + kt_b + hd[k]
                off[k] = -kt_b if k < ns - 1 else 0.0
        res = np.max(np.abs(rhs))
        if it == 0:
            scale = res
        if res <= 1e-12 * scale or res == 0.0:
            its = it
            break
        # Thomas algorithm (symmetric positive definite tridiagonal: no pivoting)
        for k in range(1, ns):
            f = off[k - 1] / diag[k - 1]
            diag[k] -= f * off[k - 1]
            rhs[k] -= f * rhs[k - 1]
        rhs[ns - 1] /= diag[ns - 1]
        for k in range(ns - 2, -1, -1):
            rhs[k] = (rhs[k] - off[k] * rhs[k + 1]) / diag[k]
        for k in range(ns):
            w_new[k] += rhs[k]
        if not aniso:  # linear in theta: one Newton step is the solution
            break
    for k in range(ns):
        if dynamic:
            m.tw_theta[k] += h * w_new[k]
            m.tw_omega[k] = w_new[k]
        else:
            m.tw_theta[k] += w_new[k]
    return its


@njit(cache=True, error_model="numpy")
def twist_step(m, x, dirs, h):
    """The twist part of a step of length h [s], after the positions x [m] reached the end of the step
    (clamp directions ``dirs`` and section axes ``m.tw_normal[2]`` at t + h): transport the frames, then
    the implicit twist sub-step (:func:`twist_solve`). The Kelvin-Voigt twist rate counts the change of the
    reference twist over the step, (new - old)/h, as a known part of dm/dt."""
    dref = m.tw_mref.copy()
    m.tw_clamp[:, :] = m.tw_normal[2]
    update_frames(m, x, dirs)
    for i in range(dref.shape[0]):
        dref[i] = (m.tw_mref[i] - dref[i]) / h
    return twist_solve(m, x, dirs, h, True, dref)
