"""The implicit step of a cable with a material frame: positions and twist angles in one Newton system (issue 22).

Unknowns: the end-of-step velocities v' (n, 3) and twist rates w' (n-1,). The twist angles are integrated by the
same method as the positions, through the same affine map (:class:`~bullet_dlo.core.kernels.steppers.ImplicitMap`,
cx [s], cv [-], hf [s]): Theta = theta_base + cx w', W = w_base + cv w' with

* implicit Euler: theta_base = theta, w_avg = omega, w_base = 0;
* BDF2 (with history ``tw_prev``): theta_base = (4 theta - theta_prev)/3, w_avg = (4 omega - omega_prev)/3;
* implicit midpoint: theta_base = theta + h/4 omega, w_base = omega/2, w_avg = omega (forces at t + h/2),

and one residual for both (hf times the generalised forces at (X, Theta, V, W) minus the momentum change):

    r_x = hf F(X, Theta, V, W) - M (v' - v_avg),    r_theta = hf T(X, Theta, V, W) - I (w' - w_avg),

T = -dE/dtheta - c I W - the Kelvin-Voigt twist torque. The Kelvin-Voigt twist dampers derive from the Rayleigh
function 1/2 c_t (dm/dt)^2 with the twist rate dm_i/dt = W_b - W_a + kb_i . (dV_a / 2|e_a| + dV_b / 2|e_b|) (the
reference twist's rate, Bergou 2008/2010) plus, at a clamp node, the clamp's own roll and turn over the step; they
act on the positions too (-c_t dm/dt d(dm/dt)/dV), so the damping matrix is symmetric.

The Newton matrix is M - hf cx dF/dq - hf cv dF/dq' over q = (x, theta). Its Gauss-Newton part is a symmetric band with the
unknowns interleaved (x_i then theta_i: 4 per node, the last theta slot an identity row), half-width 10 (each node's
rows end at column 4 i + 10, x_{i+2}; the solve works only inside that envelope). It is assembled from what the
last residual computed at the same state (the edges' frames, the nodes' lengths and binormals), so the matrix
repeats no geometry of a round section. Its blocks:

* x-x: the position Jacobian of :func:`~bullet_dlo.core.kernels.forces.force_jacobian` at Theta (isotropic
  bending exact, the anisotropic bending's Gauss-Newton part) plus the twist springs' Gauss-Newton part
  k_t g g^T (g = dm/dq: -kb/2|e_a|, kb/2|e_a| - kb/2|e_b|, kb/2|e_b| on x_{i-1}, x_i, x_{i+1}; -1, +1 on theta_a,
  theta_b) and the Kelvin-Voigt twist dampers (cv/cx) c_t g g^T;
* x-theta (the coupling): k_t g_x g_theta^T of the twist springs and Delta (kappa_2 J_1 + kappa_1 J_2) of the
  anisotropic bending (J_j = m_j^T dphi/dx), the exact derivatives of the bending forces in theta and, at the
  state where the frames were transported (the start of the step), of the twist torques in x;
* theta-theta: k_t (tridiagonal) and Delta (kappa_2^2 - kappa_1^2) (filtered to >= 0 with ``definite``).

These blocks are the exact matrix's base. Taken alone (the Gauss-Newton matrix) an anisotropic section's bending
enters as its own Gauss-Newton matrix instead, 1/2 sum_k (k1 grad kappa_1 grad kappa_1^T + k2 grad kappa_2 grad
kappa_2^T) over (x, theta) (:func:`_definite_bending`; without a rest shape): the blocks above are positive
semi-definite only about a straight cable, and the Gauss-Newton direction, taken where the exact matrix is
indefinite, must descend.

The exact Jacobian of this residual (:func:`_exact_node`) is there on request: besides the blocks above, the
stress terms s dgamma/dx of the twist (s = k_t m + c_t dm/dt, gamma = dm/dx as the residual computes it, kb/2|e|),
the twist gradient's part off the transported state (the reference frames' spin within the step,
(tan x t)/(1 + tan . t) per edge), the Kelvin-Voigt rate's position derivative, and the anisotropic bending's
curvature terms (the Hessian of q . phi, the material frames' turn and spin). It is not symmetric (the residual's
kb/2|e| is m's gradient only at the transported state), so it is stored as an upper and a lower band and
eliminated without pivoting (:func:`_band_lu_coupled`). The Newton iterations from the stepper's ``exact_from`` on
take it (:class:`~bullet_dlo.core.integrators.NewtonOptions`); by default (:data:`EXACT_AUTO`) all of them for an
anisotropic section, whose Gauss-Newton iterations converge slowly, and for a round or tube section none until a
Gauss-Newton iteration contracts poorly (:data:`CONTRACTION`; then the rest of the step): per iteration it costs
about 2x the Gauss-Newton matrix and solve at n = 80, and a quarter turn's step needs as many iterations with either
(3.0 -> 2.8 per step; docs/concepts/model.md). An iteration whose elimination meets a pivot <= 0 takes the Gauss-Newton
matrix; in contact, one whose direction finds no lower potential takes it for the rest of the step. With it
Newton converges quadratically in the twist as in the positions (the frameless Kelvin-Voigt
dampers' position terms, left out of :func:`~bullet_dlo.core.kernels.forces.add_damping_jacobian`, aside). Newton iterates to the stepper's tolerance
with the line search of :func:`~bullet_dlo.core.kernels.steppers.newton` on the incremental potential (kinetic and
dissipative terms of the twist included), so the coupled step has the method's order (2 for BDF2 and implicit midpoint).
By default (``NewtonOptions.reuse_matrix``) the step builds and factors one matrix and takes its factors again in the
iterations after while each leaves at most :data:`CHORD_CONTRACTION` of the residual (chord iterations, as stiff ODE
codes do; a fresh matrix where one does not), and BDF2 starts Newton from velocities extrapolated from the last two
steps: the matrix and its elimination cost 1.5-2x a residual, so a step pays for one instead of 2.5-3.

In contact (:func:`coupled_contact`, called by :func:`~bullet_dlo.core.kernels.contact.contact_step` when no free
body is in the solve) the same system takes the contact and grip forces on the position rows, their stiffness on
the position block of the Gauss-Newton matrix and their potential in the merit, with the contact Newton's rules
(potential decrease only, the friction caps an outer fixed point). BDF2 then keeps order 2 in contact
(frictionless rows: ``tests/bullet/test_twist_contact_order.py``; sliding friction is first order of its own). A flat
section's rows add their moments on the twist rows, their couples on the edges' nodes and their gap's and slip's
gradients in positions and twist to the Newton matrix (:func:`_add_section_moments`, :func:`_add_section_couples`,
:func:`_add_section_band`; docs/concepts/contact.md, "Flat sections").

Gauss-Legendre (:func:`coupled_gauss_legendre`) solves both stages' velocities and twist rates in one Newton system
(8 unknowns per node), each stage's forces and matrix (exact or Gauss-Newton, chosen as above) from :func:`_residual`
and :func:`_newton_matrix`;
the explicit methods (:func:`explicit_twist`) take their stages' forces and torques from :func:`_residual`. Both
advance the twist angle relative to the step's one-rotation transport of the reference frame at omega plus the
holonomy rate (:func:`_holonomy_rates`), so that the material frame keeps the method's order
(``tests/core/test_twist_gl_explicit_order.py``: order 4).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.banded import HALF
from bullet_dlo.core.kernels.drag import add_drag_jacobian, has_drag
from bullet_dlo.core.kernels.forces import (
    _bend_hessian,
    _node_edges,
    add_damping_jacobian,
    dissipation,
    force_jacobian,
    internal_energy,
    total_forces,
)
from bullet_dlo.core.kernels.gauss_legendre import (
    A11,
    A12,
    A21,
    A22,
    AI11,
    AI12,
    AI21,
    AI22,
    C1,
    C2,
    SQRT3,
    gl_band_factor,
    gl_band_substitute,
    stage_holders,
)
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.steppers import (
    BDF2,
    CHORD_CONTRACTION,
    HALF_T,
    IMPLICIT_MIDPOINT,
    ImplicitMap,
    extrapolate,
    _momentum_change,
    _set_held,
    _start_implicit,
)
from bullet_dlo.core.kernels.twist import (
    _curvatures,
    _node_edge_gradients,
    _transport_s,
    _wrap,
    aniso_node_hessian,
    edge_frame,
    geometry_of_frames,
    geometry_twist,
    twist_of_frames,
    phi_jacobians,
    reference_twists,
    scatter_edge,
    scatter_node_hessian,
    update_frames,
)

# the nodes from which the round section's passes by rows (_round_twist) pay for their extra loops and stores:
# BDF2 step at n = 10 and 20 1-3 % slower with them, at 40, 80, 160 5, 9, 10 % faster (demos/twist_cost.py)
ROUND_PASSES_FROM = 32


class Scratch(NamedTuple):
    """Scratch arrays of the coupled step (allocated once per step, :func:`make_scratch`): ga, gb (3,) edge
    gradients [N]; pa, pb (3, 3) dphi/d(edge) [1/m]; energy (1,) the material frame's energy at the last residual
    [J]; gv (11,): dm/dq of a node over its unknowns' local layout, cg (11,): gv times the node's stiffness;
    jrow (4, 6); hb (6, 6) node Hessian.

    What the last :func:`_residual` computed, for the Newton matrix at the same state (and, at the accepted
    iterate, the frames' transport at the end of the step), stored by rows (structure of arrays: the round
    section's passes over edges and nodes then run in SIMD lanes, see :func:`_round_twist`): edges (8, n+1)
    column k+1 edge k's length [m], unit tangent, reference director transported onto it and twist angle
    (:func:`~bullet_dlo.core.kernels.twist.edge_frame`'s values; columns 0 and n the clamps' virtual edges);
    geo (6, n) each node's |e_a|, |e_b| [m], curvature binormal kb (3) and twist stress s = k_t m + c_t dm/dt
    [N m] (written for the nodes with a twist spring or damper); xw (36, 6): the exact Jacobian's node scratch
    (:func:`_exact_node`); zw (8, 11) :func:`_scatter_exact`'s. Per step (the reference frames fixed within it,
    taken by the first residual, :func:`_prepare`): xs (3, n) X by rows; rt (6, n-1) the reference directors
    and tangents by rows; nd (12, n) the round pass's node scratch; flags (2,): prepared, and whether every
    node is round or tube without a twist damper (the vectorised passes) or not (the node loop)."""

    ga: np.ndarray
    gb: np.ndarray
    pa: np.ndarray
    pb: np.ndarray
    energy: np.ndarray
    gv: np.ndarray
    jrow: np.ndarray
    hb: np.ndarray
    cg: np.ndarray
    edges: np.ndarray
    geo: np.ndarray
    xw: np.ndarray
    zw: np.ndarray
    xs: np.ndarray
    rt: np.ndarray
    nd: np.ndarray
    flags: np.ndarray


def make_scratch(n: int) -> Scratch:
    """The :class:`Scratch` of an n-node cable."""
    return Scratch(np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 3)), np.zeros(1), np.empty(11),
                   np.empty((4, 6)), np.empty((6, 6)), np.empty(11), np.empty((8, n + 1)),
                   np.empty((6, n)), np.zeros((36, 6)), np.zeros((8, 11)), np.empty((3, n)),
                   np.empty((6, max(n - 1, 0))), np.empty((12, n)), np.zeros(2, dtype=np.int64))


@njit(cache=True, inline="always")
def _view(buf, o, rows, cols):
    """(the (rows, cols) view of buf from offset o, the offset after it)."""
    return buf[o:o + rows * cols].reshape((rows, cols)), o + rows * cols


@njit(cache=True)
def _make_scratch(n):
    """:func:`make_scratch` from the compiled step: its float arrays as views of one buffer (one allocation a step
    instead of 16, about 0.5 us of a 19 us twisting step at n = 10)."""
    ns = max(n - 1, 0)
    buf = np.empty(3 + 3 + 9 + 9 + 1 + 11 + 24 + 36 + 11 + 8 * (n + 1) + 6 * n + 216 + 88 + 3 * n + 6 * ns + 12 * n)
    ga, gb, energy, gv, cg = buf[0:3], buf[3:6], buf[6:7], buf[7:18], buf[18:29]
    pa, o = _view(buf, 29, 3, 3)
    pb, o = _view(buf, o, 3, 3)
    jrow, o = _view(buf, o, 4, 6)
    hb, o = _view(buf, o, 6, 6)
    edges, o = _view(buf, o, 8, n + 1)
    geo, o = _view(buf, o, 6, n)
    xw, o = _view(buf, o, 36, 6)
    zw, o = _view(buf, o, 8, 11)
    xs, o = _view(buf, o, 3, n)
    rt, o = _view(buf, o, 6, ns)
    nd, o = _view(buf, o, 12, n)
    energy[:] = 0.0
    xw[:, :] = 0.0
    zw[:, :] = 0.0
    return Scratch(ga, gb, pa, pb, energy, gv, jrow, hb, cg, edges, geo, xw, zw, xs, rt, nd,
                   np.zeros(2, dtype=np.int64))


@njit(cache=True, error_model="numpy")
def _frameless(m):
    """The kernel arrays ``m`` without the material frame (the same arrays, an empty ``tw_k_twist``): the force,
    energy and Jacobian kernels then skip the twist terms, which the coupled step computes once per node itself."""
    return _model.KernelArrays(m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity, m.f_ext, m.held,
                               m.c_stretch, m.c_bend, np.zeros(0), m.tw_c_twist, m.tw_k_aniso, m.tw_inertia,
                               m.tw_drag, m.tw_theta, m.tw_omega, m.tw_ref, m.tw_tan, m.tw_mref, m.tw_normal,
                               m.tw_clamp, m.tw_flag, m.tw_prev, m.drag_k, m.drag_face, m.rest_angle)


@njit(cache=True, error_model="numpy")
def band_solve_upper(band, rhs, half, group=1):
    """Solve A y = rhs in place for a symmetric band matrix A given by its upper band ``band[r, c - r]``
    (0 <= c - r <= half), shape (size, half + 1); rhs (size,) becomes y. Elimination without pivoting (A is
    dominated by its positive diagonal); ``band`` is destroyed. Returns min |pivot|.

    group: the unknowns come in groups of ``group`` consecutive rows whose entries all end at the same column,
    the group's first row + half (the coupled step's layout: the 4 unknowns of a node couple to nodes up to two
    ahead, (x_i, theta_i) to x_{i+2}: column 4 i + 10). Elimination fills only within that envelope, so row k's
    work stops there: the same operations on the entries in it as with group = 1, and none on the zeros beyond
    (the theta row of a node has 7 entries right of the diagonal instead of 10).

    The coupled layout itself (group 4, half 10) takes :func:`_band_solve_coupled`: the same operations in the
    same order, its loops over each whole group's constant offsets (17.4 -> 9.1 us per solve at n = 80)."""
    if group == 4 and half == HALF_T:
        return _band_solve_coupled(band, rhs)
    min_pivot = _eliminate_rows(band, rhs, 0, group, half, np.inf)
    _back_substitute_rows(band, rhs, 0, group, half)
    return min_pivot


@njit(cache=True, error_model="numpy")
def _eliminate_rows(band, rhs, start, group, half, min_pivot):
    """The elimination of :func:`band_solve_upper` over rows start .. size - 1 (each row's work ending at its
    group's envelope, clipped at the matrix's edge); returns min(min_pivot, the |pivots| met)."""
    size = rhs.shape[0]
    for k in range(start, size):
        piv = band[k, 0]
        if abs(piv) < min_pivot:
            min_pivot = abs(piv)
        last = min(k - k % group + half, size - 1)
        for i in range(k + 1, last + 1):
            f = band[k, i - k] / piv
            if f == 0.0:
                continue
            for j in range(i, last + 1):
                band[i, j - i] -= f * band[k, j - k]
            rhs[i] -= f * rhs[k]
    return min_pivot


@njit(cache=True, error_model="numpy")
def _back_substitute_rows(band, rhs, stop, group, half):
    """The back substitution of :func:`band_solve_upper` over rows size - 1 down to stop."""
    size = rhs.shape[0]
    for k in range(size - 1, stop - 1, -1):
        acc = rhs[k]
        last = min(k - k % group + half, size - 1)
        for j in range(k + 1, last + 1):
            acc -= band[k, j - k] * rhs[j]
        rhs[k] = acc / band[k, 0]


@njit(cache=True, error_model="numpy")
def _band_solve_coupled(band, rhs):
    """:func:`band_solve_upper` with group 4, half-width 10 (HALF_T): each whole group of 4 rows (rows
    4 g .. 4 g + 3, all ending at column 4 g + 10 <= size - 1) eliminated and back-substituted with its offsets
    from 4 g (loop bounds known to the compiler; the general loop's operations in its order, so bit-identical),
    the last groups (ending at the matrix's edge) by the general loop."""
    size = rhs.shape[0]
    min_pivot = np.inf
    full = (size - HALF_T - 1) // 4 + 1 if size > HALF_T else 0  # groups whose envelope ends inside the matrix
    for gr in range(full):
        b = 4 * gr
        for r in range(4):
            k = b + r
            piv = band[k, 0]
            if abs(piv) < min_pivot:
                min_pivot = abs(piv)
            for ii in range(r + 1, HALF_T + 1):
                f = band[k, ii - r] / piv
                if f == 0.0:
                    continue
                for jj in range(ii, HALF_T + 1):
                    band[b + ii, jj - ii] -= f * band[k, jj - r]
                rhs[b + ii] -= f * rhs[k]
    min_pivot = _eliminate_rows(band, rhs, 4 * full, 4, HALF_T, min_pivot)  # the last groups: the general loop
    _back_substitute_rows(band, rhs, 4 * full, 4, HALF_T)
    for gr in range(full - 1, -1, -1):
        b = 4 * gr
        for r in range(3, -1, -1):
            k = b + r
            acc = rhs[k]
            for jj in range(r + 1, HALF_T + 1):
                acc -= band[k, jj - r] * rhs[b + jj]
            rhs[k] = acc / band[k, 0]
    return min_pivot


@njit(cache=True, error_model="numpy", inline="always")
def _add_sym(band, a, b, val):
    """A[a, b] += val and A[b, a] += val (a != b) in upper band storage; A[a, a] += val when a == b."""
    if a <= b:
        band[a, b - a] += val
    else:
        band[b, a - b] += val


@njit(cache=True, error_model="numpy")
def _clamp_rate(m, xe, samples, frac, h, i):
    """Rate [rad/s] of the twist at clamp node i (0 or n-1) at t + frac h from the clamp's own roll and turn
    (positions xe held): the derivative of the quadratic through its three samples psi_0, psi_1/2, psi_1 at
    t, t + h/2, t + h, ((4 frac - 3) psi_0 + (4 - 8 frac) psi_1/2 + (4 frac - 1) psi_1)/h, second order: at t + h
    (frac 1: implicit Euler, BDF2) (psi_0 - 4 psi_1/2 + 3 psi_1)/h, at t + h/2 (frac 1/2: implicit midpoint)
    (psi_1 - psi_0)/h, at a Gauss-Legendre stage's time c_s h. The clamp node reads only its own end's row of the
    section axes and directions, so each sample's (2, 3) arrays stand in for ``tw_clamp`` and ``dirs``; each twist
    is :func:`node_geometry`'s (its bits), from the two edge frames alone."""
    th, ref, tan, mref, nrm = m.tw_theta, m.tw_ref, m.tw_tan, m.tw_mref, m.tw_normal
    p0 = geometry_twist(edge_frame(xe, samples.dir[0], th, ref, tan, nrm[0], i - 1),
                        edge_frame(xe, samples.dir[0], th, ref, tan, nrm[0], i), mref[i])[0]
    p1 = geometry_twist(edge_frame(xe, samples.dir[1], th, ref, tan, nrm[1], i - 1),
                        edge_frame(xe, samples.dir[1], th, ref, tan, nrm[1], i), mref[i])[0]
    p2 = geometry_twist(edge_frame(xe, samples.dir[2], th, ref, tan, nrm[2], i - 1),
                        edge_frame(xe, samples.dir[2], th, ref, tan, nrm[2], i), mref[i])[0]
    return ((4.0 * frac - 3.0) * p0 + (4.0 - 8.0 * frac) * p1 + (4.0 * frac - 1.0) * p2) / h


@njit(cache=True, error_model="numpy", inline="always")
def _store_edge(edges, col, fr):
    """edges[:, col] <- the 8 values of an :func:`~bullet_dlo.core.kernels.twist.edge_frame`."""
    edges[0, col], edges[1, col], edges[2, col], edges[3, col] = fr[0], fr[1], fr[2], fr[3]
    edges[4, col], edges[5, col], edges[6, col], edges[7, col] = fr[4], fr[5], fr[6], fr[7]


@njit(cache=True, error_model="numpy", inline="always")
def _prepare(ref, tan, kan, ctw, rt, flags):
    """The per-step part of the scratch (the reference frames are fixed within a step): whether every node takes
    :func:`_round_twist` (no anisotropy kan, no twist damper ctw, at least ROUND_PASSES_FROM nodes) into flags[1],
    then the reference directors ref and tangents tan by rows into rt; flags[0] <- 1. (Arrays, not the tuples:
    a call passing the kernel arrays and the scratch cost ~0.5 us of reference counting under Numba's own pipeline.)"""
    fast = 1 if kan.shape[0] >= ROUND_PASSES_FROM else 0
    for i in range(kan.shape[0]):
        if kan[i] != 0.0 or ctw[i] != 0.0:
            fast = 0
    if fast:
        for k in range(ref.shape[0]):
            for j in range(3):
                rt[j, k] = ref[k, j]
                rt[3 + j, k] = tan[k, j]
    flags[1] = fast
    flags[0] = 1


@njit(cache=True, error_model="numpy", inline="always")
def _edges_by_rows(x, dirs, theta, clamp, E, xs, R, ri, ti, rc):
    """E <- :func:`~bullet_dlo.core.kernels.twist.edge_frame`'s values of every edge of positions x by rows (column
    k + 1 edge k; columns 0 and n the clamps' virtual edges; the same operations per value), edge k's director
    transported from the reference director R[ri:ri+3, k+rc] on the reference tangent R[ti:ti+3, k+rc] (R may be
    E itself: each column is read before it is written); xs <- x by rows."""
    n = x.shape[0]
    ns = n - 1
    for i in range(n):
        xs[0, i], xs[1, i], xs[2, i] = x[i, 0], x[i, 1], x[i, 2]
    _store_edge(E, 0, edge_frame(x, dirs, theta, xs, xs, clamp, -1))  # (reference frames not read for these)
    _store_edge(E, n, edge_frame(x, dirs, theta, xs, xs, clamp, ns))
    for k in range(ns):
        c = k + rc
        u0, u1, u2, a0, a1, a2 = R[ri, c], R[ri + 1, c], R[ri + 2, c], R[ti, c], R[ti + 1, c], R[ti + 2, c]
        dx, dy, dz = xs[0, k + 1] - xs[0, k], xs[1, k + 1] - xs[1, k], xs[2, k + 1] - xs[2, k]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        t0, t1, t2 = dx / length, dy / length, dz / length
        r0, r1, r2 = _transport_s(u0, u1, u2, a0, a1, a2, t0, t1, t2)
        E[0, k + 1], E[1, k + 1], E[2, k + 1], E[3, k + 1] = length, t0, t1, t2
        E[4, k + 1], E[5, k + 1], E[6, k + 1] = r0, r1, r2
    for k in range(ns):  # (a loop of its own: with it the loop above is not vectorised, 0.42 -> 1.6 us at n = 80)
        E[7, k + 1] = theta[k]


@njit(cache=True, error_model="numpy", inline="always")
def _psi_args(E, i):
    """The two arguments of :func:`~bullet_dlo.core.kernels.twist._psi`'s atan2 (its operations) at node i from
    edge rows E (:class:`Scratch`'s edges: edge a in column i, edge b in column i + 1)."""
    ta0, ta1, ta2, ra0, ra1, ra2 = E[1, i], E[2, i], E[3, i], E[4, i], E[5, i], E[6, i]
    tb0, tb1, tb2, rb0, rb1, rb2 = E[1, i + 1], E[2, i + 1], E[3, i + 1], E[4, i + 1], E[5, i + 1], E[6, i + 1]
    p0, p1, p2 = _transport_s(ra0, ra1, ra2, ta0, ta1, ta2, tb0, tb1, tb2)
    c0 = p1 * rb2 - p2 * rb1
    c1 = p2 * rb0 - p0 * rb2
    c2 = p0 * rb1 - p1 * rb0
    return c0 * tb0 + c1 * tb1 + c2 * tb2, p0 * rb0 + p1 * rb1 + p2 * rb2


@njit(cache=True, error_model="numpy")
def _round_twist(xe, dirs, th, clamp, mref, ktw, f, tq, rate, E, geo, xs, rt, nd):
    """The twist part of :func:`_residual` for round and tube sections without twist dampers (every node; see
    :func:`_prepare`): f += the twist springs' forces, tq += their torques, rate <- 0, E and geo (the scratch's edges
    and geo; xs, rt, nd its rows of X, the reference frames and node scratch) as the node loop writes them; returns the twist energy [J]. The same operations in the same order per value as the
    node loop (:func:`~bullet_dlo.core.kernels.twist.edge_frame`, :func:`~bullet_dlo.core.kernels.twist._psi`,
    :func:`~bullet_dlo.core.kernels.twist.twist_of_frames`), so bit-identical, but split into passes over rows
    of arrays (edges, node geometry, the atan2s, twist and gradients) whose divisions and square roots the
    compiler runs 4 or 8 at a time; the sums (forces, torques, energy) in a last pass in node order."""
    n = xe.shape[0]
    ns = n - 1
    _edges_by_rows(xe, dirs, th, clamp, E, xs, rt, 0, 3, 0)  # transported from the step's reference frames
    for i in range(n):  # _psi's atan2 arguments and twist_of_frames' binormal at node i (edges a = i-1, b = i)
        nd[0, i], nd[1, i] = _psi_args(E, i)
        ta0, ta1, ta2, tb0, tb1, tb2 = E[1, i], E[2, i], E[3, i], E[1, i + 1], E[2, i + 1], E[3, i + 1]
        c = ta0 * tb0 + ta1 * tb1 + ta2 * tb2
        k0 = ta1 * tb2 - ta2 * tb1
        k1 = ta2 * tb0 - ta0 * tb2
        k2 = ta0 * tb1 - ta1 * tb0
        geo[0, i], geo[1, i] = E[0, i], E[0, i + 1]
        geo[2, i], geo[3, i], geo[4, i] = 2.0 * k0 / (1.0 + c), 2.0 * k1 / (1.0 + c), 2.0 * k2 / (1.0 + c)
    for i in range(n):  # (a library call each: not vectorised)
        nd[0, i] = math.atan2(nd[0, i], nd[1, i])
    for i in range(n):  # twist, stress, energy term and edge gradients
        mr = mref[i]
        twist = E[7, i + 1] - E[7, i] + mr + _wrap(nd[0, i] - mr)
        kt = ktw[i]
        s = kt * twist
        geo[5, i] = s
        nd[1, i] = 0.5 * kt * twist * twist
        la, lb, kb0, kb1, kb2 = geo[0, i], geo[1, i], geo[2, i], geo[3, i], geo[4, i]
        nd[2, i], nd[3, i], nd[4, i] = s * kb0 / (2.0 * la), s * kb1 / (2.0 * la), s * kb2 / (2.0 * la)
        nd[5, i], nd[6, i], nd[7, i] = s * kb0 / (2.0 * lb), s * kb1 / (2.0 * lb), s * kb2 / (2.0 * lb)
    energy = 0.0
    for i in range(n):  # the sums, in node order
        rate[i] = 0.0
        if ktw[i] == 0.0:
            continue
        energy += nd[1, i]
        if i > 0:  # e_a = x_i - x_{i-1}
            scatter_edge(f, i - 1, nd[2, i], nd[3, i], nd[4, i])
        if i < ns:  # e_b = x_{i+1} - x_i
            scatter_edge(f, i, nd[5, i], nd[6, i], nd[7, i])
        s = geo[5, i]
        if i > 0:  # dm_i/dtheta_a = -1
            tq[i - 1] += s
        if i < ns:
            tq[i] -= s
    return energy


@njit(cache=True, error_model="numpy")
def _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc):
    """r <- the coupled residual [N s; N m s] at (v', w') = (vn, wn), interleaved (4 per node); returns its max
    with the twist rows divided by the segment's rest length (force units).

    Leaves X, V in ws.x_stage, ws.v_stage, Theta in ``m.tw_theta`` (the force kernels read it there), W in
    ``wv``, the twist torques T [N m] in ``tq`` and the twist rates dm/dt of the nodes with a twist damper in
    ``rate`` (read by :func:`_merit`)."""
    n = vn.shape[0]
    ns = n - 1
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    xe, ve, f = ws.x_stage, ws.v_stage, ws.force
    xb, vb, va = ws.x_base, ws.v_base, ws.v_avg
    # the arrays the per-node loops read, taken out of the tuples once (see twist.py, "node geometry")
    held, mass, rest = m.held, m.mass, m.rest_length
    ktw, kan, ctw, drag, inertia = m.tw_k_twist, m.tw_k_aniso, m.tw_c_twist, m.tw_drag, m.tw_inertia
    ref, tan, clamp, mref = m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    dirs = imp.dirs
    for i in range(n):
        for j in range(3):
            xe[i, j] = xb[i, j] + cx * vn[i, j]
            ve[i, j] = vb[i, j] + cv * vn[i, j]
    _set_held(held, xe, ve, imp.pos_end, imp.vel_end)
    th = m.tw_theta
    for k in range(ns):
        th[k] = tb[k] + cx * wn[k]
        wv[k] = wb[k] + cv * wn[k]
    total_forces(mp, xe, ve, dirs, f)  # without the material frame's terms (added below)
    ga, gb, pa, pb = sc.ga, sc.gb, sc.pa, sc.pb
    for k in range(ns):
        tq[k] = -drag[k] * wv[k]
    edges, geo = sc.edges, sc.geo
    if sc.flags[0] == 0:
        _prepare(ref, tan, kan, ctw, sc.rt, sc.flags)
    if sc.flags[1] != 0:  # round and tube sections without twist dampers: the vectorised passes
        energy = _round_twist(xe, dirs, th, clamp, mref, ktw, f, tq, rate, edges, geo, sc.xs, sc.rt, sc.nd)
    else:
        energy = 0.0
        fb = edge_frame(xe, dirs, th, ref, tan, clamp, -1)
        _store_edge(edges, 0, fb)
        for i in range(n):
            fa = fb  # edge i-1's frame, carried on from the last node (each edge frame computed once)
            fb = edge_frame(xe, dirs, th, ref, tan, clamp, i)
            _store_edge(edges, i + 1, fb)  # kept for the Newton matrix and the frames' transport at the end
            kt, dl, ct = ktw[i], kan[i], ctw[i]
            rate[i] = 0.0
            if kt == 0.0 and dl == 0.0 and ct == 0.0:
                continue
            if dl != 0.0:
                twist, la, lb, ratio, alpha, c = geometry_of_frames(fa, fb, mref[i], g)
                kb0, kb1, kb2 = g[9, 0], g[9, 1], g[9, 2]
            else:  # round and tube sections: twist and binormal only
                twist, la, lb, kb0, kb1, kb2 = twist_of_frames(fa, fb, mref[i])
                ratio, alpha, c = 1.0, 0.0, 1.0  # (unused without anisotropy)
            geo[0, i], geo[1, i], geo[2, i], geo[3, i], geo[4, i] = la, lb, kb0, kb1, kb2
            s = kt * twist
            if ct != 0.0:
                rt = (wv[i] if i < ns else 0.0) - (wv[i - 1] if i > 0 else 0.0)
                if i > 0:
                    rt += (kb0 * (ve[i, 0] - ve[i - 1, 0]) + kb1 * (ve[i, 1] - ve[i - 1, 1])
                           + kb2 * (ve[i, 2] - ve[i - 1, 2])) / (2.0 * la)
                else:
                    rt += _clamp_rate(m, xe, samples, frac, h, i)
                if i < ns:
                    rt += (kb0 * (ve[i + 1, 0] - ve[i, 0]) + kb1 * (ve[i + 1, 1] - ve[i, 1])
                           + kb2 * (ve[i + 1, 2] - ve[i, 2])) / (2.0 * lb)
                else:
                    rt += _clamp_rate(m, xe, samples, frac, h, i)
                rate[i] = rt
                s += ct * rt
            geo[5, i] = s
            energy += 0.5 * kt * twist * twist
            # forces on the positions: -dE/dx of the twist spring and damper (stress s) and the anisotropic bending
            if dl != 0.0:
                p1a, p2a, p1b, p2b = _curvatures(g)
                energy += 0.25 * dl * (p1a * p1a - p2a * p2a + p1b * p1b - p2b * p2b)
                _node_edge_gradients(g, s, la, lb, ratio, alpha, c, dl, 1.0, ga, gb, pa, pb)
                ga0, ga1, ga2, gb0, gb1, gb2 = ga[0], ga[1], ga[2], gb[0], gb[1], gb[2]
            else:  # (as _node_edge_gradients computes them without anisotropy)
                ga0, ga1, ga2 = s * kb0 / (2.0 * la), s * kb1 / (2.0 * la), s * kb2 / (2.0 * la)
                gb0, gb1, gb2 = s * kb0 / (2.0 * lb), s * kb1 / (2.0 * lb), s * kb2 / (2.0 * lb)
            if i > 0:  # e_a = x_i - x_{i-1}
                scatter_edge(f, i - 1, ga0, ga1, ga2)
            if i < ns:  # e_b = x_{i+1} - x_i
                scatter_edge(f, i, gb0, gb1, gb2)
            if i > 0:  # dm_i/dtheta_a = -1
                tq[i - 1] += s
            if i < ns:
                tq[i] -= s
            if dl != 0.0:
                p1a, p2a, p1b, p2b = _curvatures(g)
                if i > 0:
                    tq[i - 1] -= dl * p1a * p2a
                if i < ns:
                    tq[i] -= dl * p1b * p2b
    worst = 0.0
    for i in range(n):
        for j in range(3):
            val = 0.0 if held[i] else hf * f[i, j] - mass[i] * (vn[i, j] - va[i, j])
            r[4 * i + j] = val
            if not abs(val) <= worst:  # also catches NaN
                worst = abs(val)
    for k in range(ns):
        val = hf * tq[k] - inertia[k] * (wn[k] - wa[k])
        r[4 * k + 3] = val
        scaled = abs(val) / rest[k]
        if not scaled <= worst:
            worst = scaled
    r[4 * ns + 3] = 0.0
    sc.energy[0] = energy
    return worst


@njit(cache=True, error_model="numpy")
def _merit(m, mp, imp, ws, wa, vn, wn, wv, rate, sc):
    """Incremental potential of the coupled step [J] (its gradient in (v', w') is -(cx/hf) times the residual)
    at the X, V, Theta, W, rates left by the last :func:`_residual` call."""
    xe, ve = ws.x_stage, ws.v_stage
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    drag, ctw, inertia = m.tw_drag, m.tw_c_twist, m.tw_inertia
    mass, grav, fext, va = m.mass, m.gravity, m.f_ext, ws.v_avg
    rd = dissipation(mp, xe, ve, imp.dirs)
    for k in range(wn.shape[0]):
        rd += 0.5 * drag[k] * wv[k] * wv[k]
    for i in range(rate.shape[0]):
        rd += 0.5 * ctw[i] * rate[i] * rate[i]
    phi = internal_energy(mp, xe, imp.dirs) + sc.energy[0] + (cx / cv) * rd
    for i in range(vn.shape[0]):
        for j in range(3):
            dv = vn[i, j] - va[i, j]
            phi += 0.5 * (cx / hf) * mass[i] * dv * dv
            phi -= (mass[i] * grav[j] + fext[i, j]) * xe[i, j]
    for k in range(wn.shape[0]):
        dw = wn[k] - wa[k]
        phi += 0.5 * (cx / hf) * inertia[k] * dw * dw
    return phi


# _FIRST[p, q]: whether g g^T's entry (p, q) of a node's local layout (below) is (coef g_p) g_q rather than
# (coef g_q) g_p: p comes first in the enumeration x_{i-1,j}, x_{i,j}, x_{i+1,j} for j = 0..2, then theta_{i-1},
# theta_i (its rank there: _RANK), the order of the first version of the loop, kept so that the band is
# bit-identical (floating-point products commute, so only which factor takes coef matters)
_RANK = np.array([0, 3, 6, 9, 1, 4, 7, 10, 2, 5, 8])
_FIRST = np.array([[_RANK[p] <= _RANK[q] for q in range(11)] for p in range(11)])


@njit(cache=True, error_model="numpy", inline="always")
def _present(p, pa, pi, pb, ta, tb):
    """Whether local unknown p (0-10, see :func:`_add_twist_ggt`) of a node is an unknown of the system."""
    a = p // 4
    if p % 4 == 3:
        return ta if a == 0 else tb
    return pa if a == 0 else (pi if a == 1 else pb)


@njit(cache=True, error_model="numpy")
def _add_twist_ggt(band, base, coef, qa0, qa1, qa2, qb0, qb1, qb2, pa, pi, pb, ta, tb, gv, cg):
    """band += coef g g^T (upper band) for one node's twist, g = dm_i/dq over the local layout base + l
    (x_{i-1} l = 0-2, theta_{i-1} 3, x_i 4-6, theta_i 7, x_{i+1} 8-10): -kb/2|e_a|, -1, kb/2|e_a| - kb/2|e_b|,
    +1, kb/2|e_b| (a clamp's virtual edge: the x_i entry without its term). pa, pi, pb: whether x_{i-1}, x_i,
    x_{i+1} are unknowns (not held, inside the chain); ta, tb: theta_{i-1}, theta_i. qa = kb/2|e_a|, qb = kb/2|e_b|
    (3 scalars each). gv, cg (11,): scratch.
    Each product's factor order is _FIRST's. A node with all 11 unknowns (all but the two or three next to each
    held end) takes the loop without presence tests (half the time)."""
    for j in range(3):
        qa = qa0 if j == 0 else (qa1 if j == 1 else qa2)
        qb = qb0 if j == 0 else (qb1 if j == 1 else qb2)
        gv[j] = -qa
        gv[4 + j] = (qa if ta else 0.0) - (qb if tb else 0.0)
        gv[8 + j] = qb
    gv[3] = -1.0
    gv[7] = 1.0
    for q in range(11):
        cg[q] = coef * gv[q]
    if pa and pi and pb and ta and tb:
        for p in range(11):
            for q in range(p, 11):
                band[base + p, q - p] += cg[p] * gv[q] if _FIRST[p, q] else cg[q] * gv[p]
        return
    for p in range(11):
        if not _present(p, pa, pi, pb, ta, tb):
            continue
        for q in range(p, 11):
            if _present(q, pa, pi, pb, ta, tb):
                band[base + p, q - p] += cg[p] * gv[q] if _FIRST[p, q] else cg[q] * gv[p]


@njit(cache=True, error_model="numpy", inline="always")
def _kept_frame(edges, k):
    """:func:`~bullet_dlo.core.kernels.twist.edge_frame` of edge k (-1 .. n-1, the clamps' virtual edges
    included) at the last residual's state, as that residual computed it (``edges``, :class:`Scratch`)."""
    c = k + 1
    return (edges[0, c], edges[1, c], edges[2, c], edges[3, c], edges[4, c], edges[5, c], edges[6, c], edges[7, c])


# ----- the exact Jacobian's terms beyond Gauss-Newton ----------------------------------------------------------
# Scratch rows of sc.xw (44, 6): 0-7 X (8, 6) the node's extra d Gamma / d(e_a, e_b) over rows (e_a, e_b, theta_a,
# theta_b); 8-13 D gamma (6, 6); 14-16 Y (3, 6); 17-19 K_a P_a / ((1+c) l_a) | K_b P_b / ((1+c) l_b); 20-22 H_uu |
# H_ww; 23-25 H_uw | spare; 26 h_a | h_b (transport spins); 27 the spin vector sv (6); 28 d rate (6); 29 gamma 0-5;
# 30 q | chi; 31 w x q | q x u; 32 F_u | F_w; 33-34 P H t | t^T H P (blocks aa, bb); 35 the same for ab.
@njit(cache=True, error_model="numpy", inline="always")
def _spin_row(W, row, off, t0, t1, t2, u0, u1, u2):
    """W[row, off:off+3] <- (u x t)/(1 + u . t): the spin 1-form of the reference director transported in time
    from tangent u (``tan``) to t, d(spin)/dt = -that (Bergou 2010's time-parallel frame, off its transported
    state)."""
    d = 1.0 + u0 * t0 + u1 * t1 + u2 * t2
    W[row, off] = (u1 * t2 - u2 * t1) / d
    W[row, off + 1] = (u2 * t0 - u0 * t2) / d
    W[row, off + 2] = (u0 * t1 - u1 * t0) / d


@njit(cache=True, error_model="numpy")
def _exact_node(g, la, lb, ratio, alpha, c, kt, dl, s, ct, has_a, has_b, tan, i, ve, wts, sdirs, pa, pb, W):
    """W[0:8] <- the terms of d Gamma / d(e_a, e_b) (Gamma = dE/d(e_a, e_b, theta_a, theta_b) as the residual
    computes it, stress s = k_t m + c_t dm/dt) that the Gauss-Newton matrix leaves out (its columns over theta are
    exact already):

    * twist: k_t gamma sv^T (m's gradient off the transported state: the reference frames' spin, sv =
      (h_a/l_a, -h_b/l_b), h = tan x t / (1 + tan . t)) + c_t gamma (d rate/de)^T + s D gamma (gamma = (kb/2l_a,
      kb/2l_b, -1, +1), D gamma its derivative in the edges);
    * anisotropic bending: [dphi/de]^T (the frames' turn and spin in dq) + the Hessian of q . phi at fixed q
      (q = Delta/2 sum_k (kappa_1 m_1 - kappa_2 m_2)), and on the theta rows the spin in d kappa/de.

    g: the node geometry (rows 0 t_a, 2 t_b, 9 kb; 4-8 frames and phi when dl != 0); has_a, has_b: whether edge
    a, b is a segment (not a clamp's virtual edge); ve: V [m/s] (n, 3); wts (3,): the clamp rate's weights on the
    three samples, sdirs the samples' clamp directions (3, 2, 3); pa, pb: dphi/de (dl != 0)."""
    for r in range(8):
        for col in range(6):
            W[r, col] = 0.0
    ta0, ta1, ta2 = g[0, 0], g[0, 1], g[0, 2]
    tb0, tb1, tb2 = g[2, 0], g[2, 1], g[2, 2]
    kb0, kb1, kb2 = g[9, 0], g[9, 1], g[9, 2]
    for j in range(6):
        W[26, j] = 0.0
    if has_a:
        _spin_row(W, 26, 0, ta0, ta1, ta2, tan[i - 1, 0], tan[i - 1, 1], tan[i - 1, 2])
    if has_b:
        _spin_row(W, 26, 3, tb0, tb1, tb2, tan[i, 0], tan[i, 1], tan[i, 2])
    for j in range(3):
        W[29, j] = g[9, j] / (2.0 * la)
        W[29, 3 + j] = g[9, j] / (2.0 * lb)
        W[27, j] = W[26, j] / la
        W[27, 3 + j] = -W[26, 3 + j] / lb
    # K_a = dkb/dt_a = (-2[t_b]x - kb t_b^T)/(1+c), K_b = dkb/dt_b = (2[t_a]x - kb t_a^T)/(1+c); rows 17-19 <- K P / l
    for r in range(3):
        kr = kb0 if r == 0 else (kb1 if r == 1 else kb2)
        for col in range(3):
            W[17 + r, col] = -kr * g[2, col]
            W[17 + r, 3 + col] = -kr * g[0, col]
    W[17, 1] += 2.0 * tb2
    W[17, 2] -= 2.0 * tb1
    W[18, 0] -= 2.0 * tb2
    W[18, 2] += 2.0 * tb0
    W[19, 0] += 2.0 * tb1
    W[19, 1] -= 2.0 * tb0
    W[17, 4] -= 2.0 * ta2
    W[17, 5] += 2.0 * ta1
    W[18, 3] += 2.0 * ta2
    W[18, 5] -= 2.0 * ta0
    W[19, 3] -= 2.0 * ta1
    W[19, 4] += 2.0 * ta0
    for r in range(3):
        sa = W[17 + r, 0] * ta0 + W[17 + r, 1] * ta1 + W[17 + r, 2] * ta2
        sb = W[17 + r, 3] * tb0 + W[17 + r, 4] * tb1 + W[17 + r, 5] * tb2
        for col in range(3):
            W[17 + r, col] = (W[17 + r, col] - sa * g[0, col]) / ((1.0 + c) * la)
            W[17 + r, 3 + col] = (W[17 + r, 3 + col] - sb * g[2, col]) / ((1.0 + c) * lb)
    # D gamma: d(kb/2l_a)/de_a = K_a P_a/(2 l_a^2 (1+c)) - kb t_a^T/(2 l_a^2), d(kb/2l_a)/de_b = K_b P_b/(2 l_a l_b (1+c)),
    # and the same for kb/2l_b
    for r in range(3):
        for col in range(3):
            W[8 + r, col] = W[17 + r, col] / (2.0 * la) - g[9, r] * g[0, col] / (2.0 * la * la)
            W[8 + r, 3 + col] = W[17 + r, 3 + col] / (2.0 * la)
            W[11 + r, col] = W[17 + r, col] / (2.0 * lb)
            W[11 + r, 3 + col] = W[17 + r, 3 + col] / (2.0 * lb) - g[9, r] * g[2, col] / (2.0 * lb * lb)
    for col in range(6):
        W[28, col] = 0.0
    if ct != 0.0:  # d rate/de: the positions' share kb/2l . dV (interior edges), the clamp rate's (virtual edges)
        for e in range(2):
            if (has_a if e == 0 else has_b):
                p, q = (i - 1, i) if e == 0 else (i, i + 1)
                dv0, dv1, dv2 = ve[q, 0] - ve[p, 0], ve[q, 1] - ve[p, 1], ve[q, 2] - ve[p, 2]
                for col in range(6):
                    W[28, col] += dv0 * W[8 + 3 * e, col] + dv1 * W[9 + 3 * e, col] + dv2 * W[10 + 3 * e, col]
            else:  # sum_k w_k kb_k / (2 l) over the other (free) edge; the spins cancel (sum_k w_k = 0)
                end = e
                lo = lb if e == 0 else la
                off = 3 if e == 0 else 0
                for k in range(3):
                    wk = wts[k]
                    if wk == 0.0:
                        continue
                    d0, d1, d2 = sdirs[k, end, 0], sdirs[k, end, 1], sdirs[k, end, 2]
                    if e == 0:
                        a0, a1, a2, b0, b1, b2 = d0, d1, d2, tb0, tb1, tb2
                    else:
                        a0, a1, a2, b0, b1, b2 = ta0, ta1, ta2, d0, d1, d2
                    den = (1.0 + a0 * b0 + a1 * b1 + a2 * b2) * lo
                    W[28, off] += wk * (a1 * b2 - a2 * b1) / den
                    W[28, off + 1] += wk * (a2 * b0 - a0 * b2) / den
                    W[28, off + 2] += wk * (a0 * b1 - a1 * b0) / den
    for r in range(8):
        gr = W[29, r] if r < 6 else (-1.0 if r == 6 else 1.0)
        for col in range(6):
            W[r, col] += gr * (kt * W[27, col] + ct * W[28, col])
    for r in range(6):
        for col in range(6):
            W[r, col] += s * W[8 + r, col]
    if dl == 0.0:
        return
    p0, p1, p2 = g[8, 0], g[8, 1], g[8, 2]
    k1a = p0 * g[4, 0] + p1 * g[4, 1] + p2 * g[4, 2]
    k2a = p0 * g[5, 0] + p1 * g[5, 1] + p2 * g[5, 2]
    k1b = p0 * g[6, 0] + p1 * g[6, 1] + p2 * g[6, 2]
    k2b = p0 * g[7, 0] + p1 * g[7, 1] + p2 * g[7, 2]
    hdl = 0.5 * dl
    # Y = dq/de beyond Gauss-Newton: sum_d sign_d (d (phi^T Dd) + kappa_d Dd), Dm1 = -(t m1^T + m2 h^T)/l,
    # Dm2 = (-t m2^T + m1 h^T)/l, phi^T Dm1 = -kappa_2 h^T/l, phi^T Dm2 = kappa_1 h^T/l (phi normal to t)
    for j in range(3):
        for col in range(3):
            ya, yb = 0.0, 0.0
            if has_a:
                ha = W[26, col]
                ya = (g[4, j] * (-k2a * ha / la) - g[5, j] * (k1a * ha / la)
                      + k1a * (-(g[0, j] * g[4, col] + g[5, j] * ha) / la)
                      - k2a * ((-g[0, j] * g[5, col] + g[4, j] * ha) / la))
            if has_b:
                hb = W[26, 3 + col]
                yb = (g[6, j] * (-k2b * hb / lb) - g[7, j] * (k1b * hb / lb)
                      + k1b * (-(g[2, j] * g[6, col] + g[7, j] * hb) / lb)
                      - k2b * ((-g[2, j] * g[7, col] + g[6, j] * hb) / lb))
            W[14 + j, col] = hdl * ya
            W[14 + j, 3 + col] = hdl * yb
    for r in range(3):
        for col in range(6):
            W[r, col] += pa[0, r] * W[14, col] + pa[1, r] * W[15, col] + pa[2, r] * W[16, col]
            W[3 + r, col] += pb[0, r] * W[14, col] + pb[1, r] * W[15, col] + pb[2, r] * W[16, col]
    # the Hessian of f = q . phi at fixed q, phi = r(c) (u x w): F_u = r' Q w + r (w x q), F_w = r' Q u + r (q x u)
    # (Q = q . (u x w), r' = -alpha), its second derivatives in u, w, mapped onto the edges (u = e_a/|e_a|, ...)
    for j in range(3):
        W[30, j] = hdl * (k1a * g[4, j] - k2a * g[5, j] + k1b * g[6, j] - k2b * g[7, j])
    q0, q1, q2 = W[30, 0], W[30, 1], W[30, 2]
    x0, x1, x2 = ta1 * tb2 - ta2 * tb1, ta2 * tb0 - ta0 * tb2, ta0 * tb1 - ta1 * tb0
    qq = q0 * x0 + q1 * x1 + q2 * x2
    beta = math.atan2(math.sqrt(x0 * x0 + x1 * x1 + x2 * x2), c)
    if beta < 0.05:  # r'' = d2(beta/sin beta)/dc2, its series (the closed form cancels to ~1e-16/beta^4)
        b2 = beta * beta
        r2 = 4.0 / 15.0 + b2 * (6.0 / 35.0 + b2 * (13.0 / 210.0 + b2 * (1153.0 / 69300.0)))
    else:
        sn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        r2 = (beta * sn * sn + 3.0 * c * (beta * c - sn)) / (sn * sn * sn * sn * sn)
    r1 = -alpha
    W[31, 0], W[31, 1], W[31, 2] = tb1 * q2 - tb2 * q1, tb2 * q0 - tb0 * q2, tb0 * q1 - tb1 * q0  # w x q
    W[31, 3], W[31, 4], W[31, 5] = q1 * ta2 - q2 * ta1, q2 * ta0 - q0 * ta2, q0 * ta1 - q1 * ta0  # q x u
    for j in range(3):
        W[32, j] = r1 * qq * g[2, j] + ratio * W[31, j]
        W[32, 3 + j] = r1 * qq * g[0, j] + ratio * W[31, 3 + j]
    for r in range(3):
        for col in range(3):
            W[20 + r, col] = r2 * qq * g[2, r] * g[2, col] + r1 * (g[2, r] * W[31, col] + W[31, r] * g[2, col])
            W[20 + r, 3 + col] = (r2 * qq * g[0, r] * g[0, col]
                                  + r1 * (g[0, r] * W[31, 3 + col] + W[31, 3 + r] * g[0, col]))
            W[23 + r, col] = r2 * qq * g[2, r] * g[0, col] + r1 * (g[2, r] * W[31, 3 + col] + W[31, r] * g[0, col])
        W[23 + r, r] += r1 * qq
    W[23, 1] += ratio * q2
    W[23, 2] -= ratio * q1
    W[24, 0] -= ratio * q2
    W[24, 2] += ratio * q0
    W[25, 0] += ratio * q1
    W[25, 1] -= ratio * q0
    # P H P = H - t (t^T H) - (H t) t^T + t (t^T H t) t^T (P = I - t t^T); rows 33 H t, 34 t^T H (aa | bb), 35 (ab)
    for r in range(3):
        W[33, r] = W[20 + r, 0] * ta0 + W[20 + r, 1] * ta1 + W[20 + r, 2] * ta2
        W[34, r] = W[20, r] * ta0 + W[21, r] * ta1 + W[22, r] * ta2
        W[33, 3 + r] = W[20 + r, 3] * tb0 + W[20 + r, 4] * tb1 + W[20 + r, 5] * tb2
        W[34, 3 + r] = W[20, 3 + r] * tb0 + W[21, 3 + r] * tb1 + W[22, 3 + r] * tb2
        W[35, r] = W[23 + r, 0] * tb0 + W[23 + r, 1] * tb1 + W[23 + r, 2] * tb2  # H_uw w
        W[35, 3 + r] = W[23, r] * ta0 + W[24, r] * ta1 + W[25, r] * ta2  # u^T H_uw
    saa = W[33, 0] * ta0 + W[33, 1] * ta1 + W[33, 2] * ta2
    sbb = W[33, 3] * tb0 + W[33, 4] * tb1 + W[33, 5] * tb2
    sab = W[35, 0] * ta0 + W[35, 1] * ta1 + W[35, 2] * ta2
    uf = W[32, 0] * ta0 + W[32, 1] * ta1 + W[32, 2] * ta2
    wf = W[32, 3] * tb0 + W[32, 4] * tb1 + W[32, 5] * tb2
    for r in range(3):
        ur, wr = g[0, r], g[2, r]
        pfu_r = W[32, r] - uf * ur  # (P_u F_u)_r
        pfw_r = W[32, 3 + r] - wf * wr
        for col in range(3):
            uc, wc = g[0, col], g[2, col]
            pu = (1.0 if r == col else 0.0) - ur * uc
            pw = (1.0 if r == col else 0.0) - wr * wc
            pfu_c = W[32, col] - uf * uc
            pfw_c = W[32, 3 + col] - wf * wc
            haa = W[20 + r, col] - ur * W[34, col] - W[33, r] * uc + ur * saa * uc
            hbb = W[20 + r, 3 + col] - wr * W[34, 3 + col] - W[33, 3 + r] * wc + wr * sbb * wc
            hab = W[23 + r, col] - ur * W[35, 3 + col] - W[35, r] * wc + ur * sab * wc
            W[r, col] += (haa - uf * pu - ur * pfu_c - pfu_r * uc) / (la * la)
            W[3 + r, 3 + col] += (hbb - wf * pw - wr * pfw_c - pfw_r * wc) / (lb * lb)
            W[r, 3 + col] += hab / (la * lb)
            W[3 + col, r] += hab / (la * lb)
    for j in range(3):
        W[6, j] += dl * (k1a * k1a - k2a * k2a) * W[26, j] / la
        W[7, 3 + j] += dl * (k1b * k1b - k2b * k2b) * W[26, 3 + j] / lb


@njit(cache=True, error_model="numpy")
def _scatter_exact(band, lower, upx, W, Z, kc, i, ns, held):
    """A += kc E^T X E for node i's extra terms X = W[0:8] (rows e_a, e_b, theta_a, theta_b; columns e_a, e_b),
    E the map of the local unknowns (x_{i-1} 0-2, theta_{i-1} 3, x_i 4-6, theta_i 7, x_{i+1} 8-10) onto them
    (e_a = x_i - x_{i-1}, e_b = x_{i+1} - x_i; a clamp's virtual edge is fixed): the diagonal into ``band``, the
    entries above it into ``upx``, below it into ``lower`` (by columns, lower[q, p - q] = A[p, q]); held nodes'
    unknowns left out. Z (8, 11): scratch, X E."""
    ea, eb = i > 0, i < ns
    pa, pi, pb = ea and not held[i - 1], not held[i], eb and not held[i + 1]
    for yr in range(8):
        for j in range(3):
            xa = W[yr, j] if ea else 0.0
            xb = W[yr, 3 + j] if eb else 0.0
            Z[yr, j] = -xa
            Z[yr, 4 + j] = xa - xb
            Z[yr, 8 + j] = xb
    base = 4 * (i - 1)
    for lr in range(11):
        if not _present(lr, pa, pi, pb, ea, eb):
            continue
        node, comp = lr // 4, lr % 4
        p = base + lr
        for lc in range(11):
            if lc % 4 == 3 or not _present(lc, pa, pi, pb, ea, eb):
                continue
            if comp == 3:
                val = Z[6, lc] if node == 0 else Z[7, lc]
            else:
                za = Z[comp, lc] if ea else 0.0
                zb = Z[3 + comp, lc] if eb else 0.0
                val = -za if node == 0 else (za - zb if node == 1 else zb)
            if val == 0.0:
                continue
            q = base + lc
            if p == q:
                band[p, 0] += kc * val
            elif p < q:
                upx[p, q - p] += kc * val
            else:
                lower[q, p - q] += kc * val


@njit(cache=True, error_model="numpy")
def _band_lu_coupled(band, lower, rhs):
    """Solve A y = rhs in place for a band matrix A of the coupled layout (group 4, half-width HALF_T) given by its
    upper band ``band[r, c - r]`` and its lower band by columns ``lower[c, r - c]``: elimination without pivoting
    within the envelope of :func:`band_solve_upper` (the exact Newton matrix is not symmetric). Both arrays are
    destroyed; returns the smallest pivot (signed: <= 0 or NaN means the elimination is not to be trusted)."""
    size = rhs.shape[0]
    min_pivot = np.inf
    for k in range(size):
        piv = band[k, 0]
        if not piv >= min_pivot:
            min_pivot = piv
        last = min(k - k % 4 + HALF_T, size - 1)
        for i in range(k + 1, last + 1):
            f = lower[k, i - k] / piv
            if f == 0.0:
                continue
            for j in range(k + 1, i):
                lower[j, i - j] -= f * band[k, j - k]
            for j in range(i, last + 1):
                band[i, j - i] -= f * band[k, j - k]
            rhs[i] -= f * rhs[k]
    _back_substitute_rows(band, rhs, 0, 4, HALF_T)
    return min_pivot


@njit(cache=True, error_model="numpy")
def _definite_bending(x, dirs, i, kbar, jrow, hb, hiso, g12):
    """hb (6, 6, over node i's edges a, b) += the isotropic bending's Gauss-Newton part minus its exact Hessian
    (the one the position Jacobian holds), kbar/2 sum_k (J1_k^T J1_k + J2_k^T J2_k) - d2(kbar beta^2 / 2) (jrow:
    the rows J_j of :func:`~bullet_dlo.core.kernels.twist.aniso_node_hessian`; hiso, g12: scratch): with the
    anisotropic part's Delta/2 sum_k (J1_k^T J1_k - J2_k^T J2_k) the bending's Gauss-Newton matrix 1/2 sum_k (k1
    J1_k^T J1_k + k2 J2_k^T J2_k), positive semi-definite. The exact isotropic Hessian with the anisotropic part's
    Gauss-Newton terms is that only about a straight cable: a bent strip's can be indefinite, and so were the
    Gauss-Newton directions taken where the exact matrix was (they ascended)."""
    a0, a1, a2, b0, b1, b2 = _node_edges(x, i, dirs)
    _bend_hessian(a0, a1, a2, b0, b1, b2, kbar, g12, hiso)
    for r in range(6):
        for col in range(6):
            gn = jrow[0, r] * jrow[0, col] + jrow[1, r] * jrow[1, col] + jrow[2, r] * jrow[2, col] \
                + jrow[3, r] * jrow[3, col]
            hb[r, col] += 0.5 * kbar * gn - hiso[r, col]


@njit(cache=True, error_model="numpy")
def _newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, frac, h):
    """band <- the coupled Newton matrix (upper band, interleaved layout) at the X, V, Theta of the last residual:
    its Gauss-Newton part (symmetric); with ``exact`` the exact Jacobian instead (:func:`_exact_node`'s terms
    added), not symmetric: upper band in ``band``, lower band by columns in ``lower`` (``upx``: scratch of
    band's shape). samples, frac, h: as :func:`_residual` took them (the clamp rate's derivative)."""
    n = ws.x_stage.shape[0]
    ns = n - 1
    xe = ws.x_stage
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    jac = ws.jacobian
    force_jacobian(mp, xe, imp.dirs, stepper.definite, jac)
    add_damping_jacobian(mp, xe, imp.dirs, cv / cx, jac)
    if has_drag(mp):  # (checked here: a no-op call passing the arrays cost ~0.3 us, Numba's pipeline)
        add_drag_jacobian(mp, xe, ws.v_stage, cv / cx, jac)
    kc = hf * cx
    held, mass, damp = m.held, m.mass, m.damp
    ktw, kan, ctw, drag, inertia = m.tw_k_twist, m.tw_k_aniso, m.tw_c_twist, m.tw_drag, m.tw_inertia
    th, ref, tan, clamp, mref = m.tw_theta, m.tw_ref, m.tw_tan, m.tw_clamp, m.tw_mref
    dirs = imp.dirs
    gv, pa, pb, jrow, hb, cg = sc.gv, sc.pa, sc.pb, sc.jrow, sc.hb, sc.cg
    edges, geo = sc.edges, sc.geo
    band[:, :] = 0.0
    W = sc.xw
    hiso, gb12 = np.empty((6, 6)), np.empty(12)  # (scratch of _definite_bending)
    if exact:
        lower[:, :] = 0.0
        upx[:, :] = 0.0
        # d(clamp rate)/d(sample): the weights of _clamp_rate
        wt = np.array(((4.0 * frac - 3.0) / h, (4.0 - 8.0 * frac) / h, (4.0 * frac - 1.0) / h))
    else:
        wt = np.zeros(3)
    nd = sc.nd
    fast = sc.flags[1] != 0
    if fast:  # every node round: the twist gradient's kb/2|e| from the residual's geometry, by rows (vectorised)
        for i in range(n):
            la, lb, kb0, kb1, kb2 = geo[0, i], geo[1, i], geo[2, i], geo[3, i], geo[4, i]
            nd[0, i], nd[1, i], nd[2, i] = kb0 / (2.0 * la), kb1 / (2.0 * la), kb2 / (2.0 * la)
            nd[3, i], nd[4, i], nd[5, i] = kb0 / (2.0 * lb), kb1 / (2.0 * lb), kb2 / (2.0 * lb)
    for i in range(n):
        kt, dl, ct = ktw[i], kan[i], ctw[i]
        if kt == 0.0 and dl == 0.0 and ct == 0.0:
            continue
        if dl != 0.0:  # the frames from the residual's edges (the same values edge_frame gives at this state)
            twist, la, lb, ratio, alpha, c = geometry_of_frames(_kept_frame(edges, i - 1), _kept_frame(edges, i),
                                                                mref[i], g)
            kb0, kb1, kb2 = g[9, 0], g[9, 1], g[9, 2]
        else:  # round and tube sections: the residual's lengths and binormal at this state
            la, lb, kb0, kb1, kb2 = geo[0, i], geo[1, i], geo[2, i], geo[3, i], geo[4, i]
            ratio, alpha, c = 1.0, 0.0, 1.0
        # g = dm/dq over the node's unknowns in the local layout l = q - 4(i-1) (x_{i-1} 0-2, theta_{i-1} 3, x_i
        # 4-6, theta_i 7, x_{i+1} 8-10), added as coef g g^T into the band's rows of the present unknowns
        coef = kc * (kt + (cv / cx) * ct)
        if coef != 0.0:
            if fast:  # (the pass above)
                qa0, qa1, qa2, qb0, qb1, qb2 = nd[0, i], nd[1, i], nd[2, i], nd[3, i], nd[4, i], nd[5, i]
            else:
                qa0, qa1, qa2 = kb0 / (2.0 * la), kb1 / (2.0 * la), kb2 / (2.0 * la)
                qb0, qb1, qb2 = kb0 / (2.0 * lb), kb1 / (2.0 * lb), kb2 / (2.0 * lb)
            _add_twist_ggt(band, 4 * (i - 1), coef, qa0, qa1, qa2, qb0, qb1, qb2, i > 0 and not held[i - 1],
                           not held[i], i < ns and not held[i + 1], i > 0, i < ns, gv, cg)
        if dl != 0.0:
            phi_jacobians(g, la, lb, ratio, alpha, c, pa, pb)
        if exact:
            if dl == 0.0:  # the tangents (the residual's edges; a clamp's direction) and binormal into g
                for j in range(3):
                    g[0, j] = edges[1 + j, i] if i > 0 else dirs[0, j]
                    g[2, j] = edges[1 + j, i + 1] if i < ns else dirs[1, j]
                g[9, 0], g[9, 1], g[9, 2] = kb0, kb1, kb2
                c = g[0, 0] * g[2, 0] + g[0, 1] * g[2, 1] + g[0, 2] * g[2, 2]
            _exact_node(g, la, lb, ratio, alpha, c, kt, dl, geo[5, i], ct, i > 0, i < ns, tan, i, ws.v_stage,
                        wt, samples.dir, pa, pb, W)
            _scatter_exact(band, lower, upx, W, sc.zw, kc, i, ns, held)
        if dl == 0.0:
            continue
        p1a, p2a, p1b, p2b = _curvatures(g)
        # x-x: the Gauss-Newton part of the anisotropic bending, Delta/2 sum_k (J1_k^T J1_k - J2_k^T J2_k); for the
        # Gauss-Newton matrix the whole bending's instead (_definite_bending: positive semi-definite)
        aniso_node_hessian(g, dl, pa, pb, jrow, hb)
        kbar = mp.k_bend[i]
        gauss_newton = not exact and kbar > 0.0 and mp.rest_angle.shape[0] == 0  # (a rest shape: as before)
        if gauss_newton:
            _definite_bending(xe, dirs, i, kbar, jrow, hb, hiso, gb12)
        scatter_node_hessian(jac, i, n, hb)
        # x-theta: d2E/dtheta_k dx = Delta (kappa_2 J_1 + kappa_1 J_2); theta-theta: Delta (kappa_2^2 - kappa_1^2)
        for e in range(2):
            if (e == 0 and i == 0) or (e == 1 and i == ns):
                continue  # a clamp's virtual edge has no twist angle
            k = i - 1 if e == 0 else i
            k1, k2 = (p1a, p2a) if e == 0 else (p1b, p2b)
            ti = 4 * k + 3
            # exact: d2E/dtheta dx = Delta (kappa_2 J1 + kappa_1 J2); Gauss-Newton: 1/2 (k1 kappa_2 J1 - k2 kappa_1 J2)
            wa1 = 0.5 * (kbar + dl) if gauss_newton else dl
            wa2 = 0.5 * (dl - kbar) if gauss_newton else dl
            for j in range(3):  # chain rule: a = x_i - x_{i-1}, b = x_{i+1} - x_i (clamp edges fixed)
                ca = (wa1 * k2 * jrow[2 * e, j] + wa2 * k1 * jrow[2 * e + 1, j]) if i > 0 else 0.0
                cb = (wa1 * k2 * jrow[2 * e, 3 + j] + wa2 * k1 * jrow[2 * e + 1, 3 + j]) if i < ns else 0.0
                if i > 0 and not held[i - 1]:
                    _add_sym(band, ti, 4 * (i - 1) + j, kc * (-ca))
                if not held[i]:
                    _add_sym(band, ti, 4 * i + j, kc * (ca - cb))
                if i < ns and not held[i + 1]:
                    _add_sym(band, ti, 4 * (i + 1) + j, kc * cb)
            hd = dl * (k2 * k2 - k1 * k1)
            if gauss_newton:  # 1/2 (k1 kappa_2^2 + k2 kappa_1^2)
                hd = 0.5 * ((kbar + dl) * k2 * k2 + (kbar - dl) * k1 * k1)
            elif stepper.definite and hd < 0.0:
                hd = 0.0
            band[ti, 0] += kc * hd
    for i in range(n):  # x-x blocks (upper triangle) from the position Jacobian
        if held[i]:
            continue
        row = 4 * i
        for r in range(3):  # the node's own block: its upper triangle
            for c in range(r, 3):
                band[row + r, c - r] -= kc * jac[i, 2, r, c]
        for o in range(3, 5):  # the next two nodes' blocks, whole
            p = i + o - 2
            if p >= n or held[p]:
                continue
            off = 4 * (o - 2)
            for r in range(3):
                for c in range(3):
                    band[row + r, off + c - r] -= kc * jac[i, o, r, c]
    for i in range(n):
        for r in range(3):
            if held[i]:
                band[4 * i + r, 0] = 1.0
            else:
                band[4 * i + r, 0] += mass[i] + hf * cv * damp[i]
    for k in range(ns):
        band[4 * k + 3, 0] += inertia[k] + hf * cv * drag[k]
    band[4 * ns + 3, 0] = 1.0
    if exact:  # lower <- the symmetric part's mirror plus the lower extra terms; band += the upper ones
        for k in range(band.shape[0]):
            for d in range(1, HALF_T + 1):
                lower[k, d] += band[k, d]
                band[k, d] += upx[k, d]


@njit(cache=True, error_model="numpy")
def _round_reference_twists(x, dirs, theta, clamp, mref, E, xs, nd):
    """:func:`~bullet_dlo.core.kernels.twist.reference_twists` at the end of a step whose last residual's frames
    (E, the scratch's edges) are the new reference frames, by rows as :func:`_round_twist` (the same operations per
    value, so bit-identical): each edge's frame transported from itself onto the tangent of x, the nodes'
    reference twists. Overwrites E and the scratch's rows xs, nd."""
    n = x.shape[0]
    _edges_by_rows(x, dirs, theta, clamp, E, xs, E, 4, 1, 1)  # each edge's frame transported from itself
    for i in range(n):  # _psi's atan2 arguments
        nd[0, i], nd[1, i] = _psi_args(E, i)
    for i in range(n):
        nd[0, i] = math.atan2(nd[0, i], nd[1, i])
    for i in range(n):  # twist_of_frames' twist minus (th_b - th_a)
        mr = mref[i]
        dth = E[7, i + 1] - E[7, i]
        mref[i] = dth + mr + _wrap(nd[0, i] - mr) - dth


@njit(cache=True, error_model="numpy")
def _bases(method, m, h, has_prev):
    """The twist's part of the implicit map (module docstring): the step's start (theta0, omega0) and theta_base,
    w_base, w_avg, each (n-1,); BDF2 then stores (theta0, omega0) as the history of the next step."""
    ns = m.tw_theta.shape[0]
    theta0 = m.tw_theta.copy()
    omega0 = m.tw_omega.copy()
    tb, wb, wa = np.empty(ns), np.empty(ns), np.empty(ns)
    if method == BDF2 and has_prev:
        for k in range(ns):
            tb[k] = (4.0 * theta0[k] - m.tw_prev[0, k]) / 3.0
            wa[k] = (4.0 * omega0[k] - m.tw_prev[1, k]) / 3.0
            wb[k] = 0.0
    elif method == IMPLICIT_MIDPOINT:
        for k in range(ns):
            tb[k] = theta0[k] + 0.25 * h * omega0[k]
            wa[k] = omega0[k]
            wb[k] = 0.5 * omega0[k]
    else:
        for k in range(ns):
            tb[k] = theta0[k]
            wa[k] = omega0[k]
            wb[k] = 0.0
    if method == BDF2:
        m.tw_prev[0, :] = theta0
        m.tw_prev[1, :] = omega0
    return theta0, omega0, tb, wb, wa


@njit(cache=True, error_model="numpy")
def _scales(m, x, hf, theta0):
    """Newton's residual scale and round-off floor of the coupled step [N s] (see
    :func:`~bullet_dlo.core.kernels.steppers.newton`; the floor counts the twist springs too)."""
    g_norm = np.sqrt(np.sum(m.gravity ** 2))
    xscale = 0.0
    for i in range(x.shape[0]):
        for j in range(3):
            xscale = max(xscale, abs(x[i, j]))
    lmin = np.min(m.rest_length)
    r_scale = hf * (np.max(m.mass) * g_norm + np.max(np.abs(m.f_ext))) + 1e-300
    r_floor = 10.0 * 2.2e-16 * hf * (np.max(m.k_stretch) * (xscale + np.max(m.rest_length))
                                     + np.max(m.tw_k_twist) * (np.max(np.abs(theta0)) + np.max(np.abs(m.tw_mref))
                                                               + 1.0) / lmin)
    return r_scale, r_floor


@njit(cache=True, error_model="numpy", inline="always")
def _change(m, ws, vn, wn, wa):
    """The momentum change of the step, positions and twist (the twist's per rest length) [N s]."""
    dmom = _momentum_change(m, ws, vn)
    for k in range(wn.shape[0]):
        dmom = max(dmom, m.tw_inertia[k] * abs(wn[k] - wa[k]) / m.rest_length[k])
    return dmom


@njit(cache=True, error_model="numpy")
def _finish(method, m, x, v, samples, ws, has_prev, h, cx, theta0, omega0, tb, wn, kept, sc):
    """The end of a coupled step from its solution (v', w') = (ws.v_new, wn): x, v, the twist angles and rates
    in place, then the reference frames transported to the new tangents (from the last residual's edges when it
    was taken at the solution, ``kept``, and the step is not the midpoint rule's)."""
    n = x.shape[0]
    ns = n - 1
    mid = method == IMPLICIT_MIDPOINT
    vn = ws.v_new
    for i in range(n):
        for j in range(3):
            if method == IMPLICIT_MIDPOINT:
                x[i, j] += 0.5 * h * (v[i, j] + vn[i, j])
            elif method == BDF2 and has_prev:
                x[i, j] = ws.x_base[i, j] + cx * vn[i, j]
            else:
                x[i, j] += h * vn[i, j]
    v[:, :] = vn
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])
    for k in range(ns):
        if method == IMPLICIT_MIDPOINT:
            m.tw_theta[k] = theta0[k] + 0.5 * h * (omega0[k] + wn[k])
        elif method == BDF2 and has_prev:
            m.tw_theta[k] = tb[k] + cx * wn[k]
        else:
            m.tw_theta[k] = theta0[k] + h * wn[k]
        m.tw_omega[k] = wn[k]
    m.tw_clamp[:, :] = m.tw_normal[2]
    if kept and not mid:  # X of the last residual is the new x: its edges' transported frames are the new ones
        ref, tan, edges = m.tw_ref, m.tw_tan, sc.edges
        for k in range(ns):
            tan[k, 0], tan[k, 1], tan[k, 2] = edges[1, k + 1], edges[2, k + 1], edges[3, k + 1]
            ref[k, 0], ref[k, 1], ref[k, 2] = edges[4, k + 1], edges[5, k + 1], edges[6, k + 1]
        if sc.flags[1] != 0:  # (the same values by rows)
            _round_reference_twists(x, samples.dir[2], m.tw_theta, m.tw_clamp, m.tw_mref, edges, sc.xs, sc.nd)
        else:
            reference_twists(x, samples.dir[2], m.tw_theta, ref, tan, m.tw_clamp, m.tw_mref)
    else:
        update_frames(m, x, samples.dir[2])


@njit(cache=True, error_model="numpy")
def coupled_implicit(stepper, m, x, v, samples, ws, has_prev):
    """One implicit step (implicit Euler, BDF2 or implicit midpoint) of a cable with a material frame: positions,
    velocities, twist angles and rates advanced together in place (see the module docstring); the reference
    frames then transported to the new tangents. The clamps' section axes in ``m.tw_clamp`` must be those of
    the method's evaluation time (as :func:`~bullet_dlo.core.kernels.steppers.advance` sets them).

    With ``stepper.reuse`` the step factors its Newton matrix once and takes the same factors in the iterations
    after (chord iterations) while each leaves at most
    :data:`~bullet_dlo.core.kernels.steppers.CHORD_CONTRACTION` of the residual, and BDF2 starts from the velocities
    extrapolated from the last two steps (:func:`~bullet_dlo.core.kernels.steppers.extrapolate`; the frameless step
    alike): where the matrix costs more than the residual (a twisting step at n = 10: 3.2 + 1.6 us against 2.3
    us), the second iteration then costs a residual and a substitution. The solution is Newton's to the same
    tolerance; nothing is kept between steps. Returns (Newton iterations, converged)."""
    method, h = stepper.method, stepper.h
    n = x.shape[0]
    ns = n - 1
    imp = _start_implicit(method, m, x, v, h, samples, ws, has_prev)
    cx, hf = imp.cx, imp.hf
    theta0, omega0, tb, wb, wa = _bases(method, m, h, has_prev)
    g = np.empty((12, 3))
    frac = 0.5 if method == IMPLICIT_MIDPOINT else 1.0  # the residual's time in the step
    size = 4 * n
    band, lower, upx = ws.tw_band, ws.tw_lower, ws.tw_upper
    buf = np.empty(3 * size + 4 * ns + n)  # (one allocation for the step's vectors)
    r, r_try, r_keep = buf[:size], buf[size:2 * size], buf[2 * size:3 * size]
    o = 3 * size
    wn, w_try, wv, tq = buf[o:o + ns], buf[o + ns:o + 2 * ns], buf[o + 2 * ns:o + 3 * ns], buf[o + 3 * ns:o + 4 * ns]
    rate = buf[o + 4 * ns:]
    wn[:] = omega0
    rate[:] = 0.0
    sc = _make_scratch(n)
    mp = _frameless(m)
    vn, v_try = ws.v_new, ws.v_try
    tol = stepper.tol
    r_scale, r_floor = _scales(m, x, hf, theta0)
    if stepper.reuse and method == BDF2 and has_prev:  # (vn holds v: _start_implicit)
        extrapolate(m.held, ws.v_avg, vn)
        for k in range(ns):  # the twist rates alike (wa = (4 omega - omega_prev) / 3)
            wn[k] = 3.0 * wa[k] - 2.0 * omega0[k]
    it = 0
    converged = False
    rnorm = _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)
    kept = True  # the last residual was at the current iterate (sc.edges: its frames)
    first_exact = _first_exact(stepper, m)
    slow = False  # a Gauss-Newton iteration of this step contracted poorly (see _contracted)
    factored = NOT_FACTORED  # what band (and lower) hold: this step's last fresh matrix's factors, or nothing
    while it < stepper.max_iter:
        it += 1
        chord = factored != NOT_FACTORED
        if chord:  # the factors of this step's last fresh matrix
            r_keep[:] = r
            _factored_direction(band, lower, factored == EXACT_FACTORS, r)
        else:
            # the exact Jacobian from iteration first_exact on, or once the Gauss-Newton matrix contracts poorly;
            # where its elimination meets a pivot <= 0 (the matrix indefinite, e.g. beyond a twist buckling
            # threshold at a large step) the Gauss-Newton matrix instead
            exact = it >= first_exact or slow
            if exact:
                _newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, frac, h)
                exact = _exact_direction(band, lower, r, r_try)
            if not exact:
                _newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, frac, h)
                band_solve_upper(band, r, HALF_T, 4)  # r becomes the Newton direction
            ws.matrices[0] += 1.0
            if stepper.reuse:
                factored = EXACT_FACTORS if exact else GAUSS_NEWTON_FACTORS
        phi0 = np.nan
        alpha = 1.0
        accepted = False
        rn_try = 0.0
        for _ in range(12):
            _trial(vn, wn, r, alpha, v_try, w_try, n, ns)
            rn_try = _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, v_try, w_try, wv, rate, tq, r_try, g, sc)
            kept = False
            if rn_try < rnorm or rn_try <= tol * r_scale + r_floor:
                accepted = True
                break
            if chord:  # a chord direction is taken whole or not at all
                break
            if phi0 != phi0:  # merit at the current iterate, computed once when first needed
                _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r_try, g, sc)
                phi0 = _merit(m, mp, imp, ws, wa, vn, wn, wv, rate, sc)
                _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, v_try, w_try, wv, rate, tq, r_try, g, sc)
            if _merit(m, mp, imp, ws, wa, v_try, w_try, wv, rate, sc) <= phi0:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if chord:  # the old factors failed here: a fresh matrix at the same iterate (not counted)
                factored = NOT_FACTORED
                r[:] = r_keep
                it -= 1
                continue
            break  # stagnated: keep the current iterate (reported as not converged)
        vn[:, :] = v_try
        wn[:] = w_try
        kept = True  # (the last residual, at v_try, w_try)
        r[:] = r_try
        if chord:
            if rn_try > CHORD_CONTRACTION * rnorm:
                factored = NOT_FACTORED  # a fresh matrix next
        elif not _contracted(rn_try, rnorm, alpha):
            factored = NOT_FACTORED
            slow = True
        rnorm = rn_try
        if rnorm <= tol * (r_scale + _change(m, ws, vn, wn, wa)) + r_floor:
            converged = True
            break
    _finish(method, m, x, v, samples, ws, has_prev, h, cx, theta0, omega0, tb, wn, kept, sc)
    return it, converged


NOT_FACTORED, GAUSS_NEWTON_FACTORS, EXACT_FACTORS = range(3)
"""What the coupled step's band holds between its iterations (:func:`coupled_implicit`)."""


@njit(cache=True, error_model="numpy")
def _factored_direction(band, lower, exact, r):
    """r (a residual) becomes the Newton direction of a matrix already eliminated by :func:`band_solve_upper` (group
    4, half-width HALF_T; ``exact`` False: symmetric, its multipliers in the upper band) or by
    :func:`_band_lu_coupled` (``exact`` True: the multipliers in ``lower``): the same forward elimination on r
    and back substitution, without the matrix's O(n half^2) elimination."""
    size = r.shape[0]
    mult = lower if exact else band
    for k in range(size):
        piv = band[k, 0]
        last = min(k - k % 4 + HALF_T, size - 1)
        for i in range(k + 1, last + 1):
            r[i] -= mult[k, i - k] / piv * r[k]
    _back_substitute_rows(band, r, 0, 4, HALF_T)


EXACT_AUTO = 1001
"""``exact_from`` of the automatic choice (:class:`~bullet_dlo.core.integrators.NewtonOptions`' default): the exact
Jacobian from the first iteration for a cable with anisotropic bending (the Gauss-Newton matrix leaves out its
curvature terms, of order the bend times E I_strong / l0: a PET ribbon 20 x 0.3 mm, n 81, falling from a clamp
rolled 0.7 rad at 1 kHz failed 86 of 270 steps with it and blew up at 0.27 s; exact from the second iteration, 28
of 2000 steps failed and at 240 Hz it blew up; from the first, none of 2000), else only after a poor contraction."""
CONTRACTION = 0.25
"""The residual share [-] a Gauss-Newton iteration of the coupled twisting step must leave at most, with a full
step, for the next iteration to keep the Gauss-Newton matrix. It leaves out the twist's stress terms, which matter
for a cable twisted by turns or at a long step: there its iterations contract slowly and the exact Jacobian takes
over for the rest of the step (the study's cable, n 40, its clamp turned 3 times in 1 s at 60 Hz, BDF2: 72 of 90
steps failed with the Gauss-Newton matrix alone)."""


@njit(cache=True, error_model="numpy", inline="always")
def _first_exact(stepper, m):
    """The Newton iteration (1-based) from which the coupled step takes the exact Jacobian: the stepper's
    ``exact_from``, or with :data:`EXACT_AUTO` 1 for a cable with anisotropic bending and never otherwise."""
    if stepper.exact_from != EXACT_AUTO:
        return stepper.exact_from
    for i in range(m.tw_k_aniso.shape[0]):
        if m.tw_k_aniso[i] != 0.0:
            return 1
    return EXACT_AUTO


@njit(cache=True, error_model="numpy", inline="always")
def _exact_direction(band, lower, r, keep):
    """r (the residual) becomes the Newton direction of the exact matrix (upper ``band``, ``lower`` band by columns,
    both destroyed); where its elimination meets a pivot <= 0 (the matrix indefinite, e.g. beyond a twist buckling
    threshold at a large step) r is left as it was and False is returned: the caller takes Gauss-Newton's.
    ``keep``: scratch of r's shape."""
    keep[:] = r
    if _band_lu_coupled(band, lower, r) > 0.0:
        return True
    r[:] = keep
    return False


@njit(cache=True, error_model="numpy", inline="always")
def _contracted(r_new, r_old, alpha):
    """Whether an accepted Newton iteration contracted well: a full step (alpha 1) that left at most
    :data:`CONTRACTION` of the residual's max r_old (r_new after it)."""
    return alpha == 1.0 and r_new <= CONTRACTION * r_old


# ----- the contact step's Newton with the twist (contact.contact_step without free bodies) ----------------
@njit(cache=True, error_model="numpy")
def _add_contacts(m, imp, ws, r, c, sc, wv):
    """r += hf times the contact set ``c``'s forces at the X, Theta, V, W of the last :func:`_residual` (ws.x_stage,
    ws.v_stage, the frames in sc.edges, the twist rates ``wv``; into c.node_force, c.f_n, c.f_t) on the free nodes'
    position rows, and a flat section's contact moments on the twist rows (:func:`_add_section_moments`) and
    couples on its edges' nodes (:func:`_add_section_couples`); returns
    the residual's max as :func:`_residual` measures it (twist rows per rest length)."""
    n = ws.x_stage.shape[0]
    fc = c.node_force
    _contact.set_support(c, sc.edges, wv, m.tw_ref, m.tw_tan)
    _contact.contact_forces(c, ws.x_stage, ws.v_stage, fc)
    _add_section_moments(c, imp.hf, n - 1, r)
    _add_section_couples(c, sc.edges, fc)
    worst = 0.0
    for i in range(n):
        for j in range(3):
            if not m.held[i]:
                r[4 * i + j] += imp.hf * fc[i, j]
            if not abs(r[4 * i + j]) <= worst:
                worst = abs(r[4 * i + j])
    for k in range(n - 1):
        scaled = abs(r[4 * k + 3]) / m.rest_length[k]
        if not scaled <= worst:
            worst = scaled
    return worst


@njit(cache=True, error_model="numpy")
def _add_section_moments(c, hf, ns, r):
    """The twist rows r[4 e + 3] += hf times a flat section's contact moments [N m] about each of the row's edges e,
    -f_n ds/dtheta_e + f_t . dm/dtheta_e: the generalised forces of the normal force f_n [N] on the gap
    g = n . (p - c) - s and of the friction force f_t [N] on the slip, which counts the touching point's move m,
    s (theta - theta0) (n x t) (:func:`~bullet_dlo.core.kernels.contact.set_support`)."""
    if c.section[0] <= 0.0:
        return
    for k in range(c.count[0]):
        if c.support[k, 0] <= 0.0:
            continue
        fn = c.f_n[k]
        e0, e1 = _contact.row_edges(c.node[k, 0], c.node[k, 1], ns)
        for slot in range(2):
            e = e0 if slot == 0 else e1
            if e < 0:
                continue
            q = 12 + 3 * slot
            moment = (-fn * c.support[k, 2 + slot] + c.f_t[k, 0] * c.support[k, q]
                      + c.f_t[k, 1] * c.support[k, q + 1] + c.f_t[k, 2] * c.support[k, q + 2])
            r[4 * e + 3] += hf * moment


@njit(cache=True, error_model="numpy")
def _add_section_couples(c, E, fc):
    """fc [N] += the couples a flat section's contact forces put on its edges' nodes (+-, no net force) as the
    section turns with the edges' tangents (edge frames ``E``, :class:`Scratch` edges): the normal force's -f_n
    ds/dx (it acts at the touching point, off the centre line; ds/dx from
    :func:`~bullet_dlo.core.kernels.contact.set_support`) and the friction's f_t . dm/dx, m = s (theta - theta0)
    (n x t) the touching point's move: on the far node of edge e, (theta - theta0) ((f_t . n x t) ds/dx + s
    (f_t x n)_perp / length), minus that on the near one."""
    if c.section[0] <= 0.0:
        return
    ns = E.shape[1] - 2
    for k in range(c.count[0]):
        if c.support[k, 0] <= 0.0:
            continue
        n0, n1, n2 = c.normal[k, 0], c.normal[k, 1], c.normal[k, 2]
        f0, f1, f2 = c.f_t[k, 0], c.f_t[k, 1], c.f_t[k, 2]
        fxn0, fxn1, fxn2 = f1 * n2 - f2 * n1, f2 * n0 - f0 * n2, f0 * n1 - f1 * n0  # f_t x n
        e0, e1 = _contact.row_edges(c.node[k, 0], c.node[k, 1], ns)
        for slot in range(2):
            e = e0 if slot == 0 else e1
            if e < 0:
                continue
            col = e + 1
            t0, t1, t2 = E[1, col], E[2, col], E[3, col]
            turn = E[7, col] - c.support[k, 9 + slot]
            fnt = fxn0 * t0 + fxn1 * t1 + fxn2 * t2  # f_t . (n x t)
            lever = turn * c.support[k, 24 + slot] / E[0, col]
            for j in range(3):
                tj = t0 if j == 0 else (t1 if j == 1 else t2)
                fj = fxn0 if j == 0 else (fxn1 if j == 1 else fxn2)
                grad = c.support[k, 18 + 3 * slot + j]
                push = -c.f_n[k] * grad + turn * fnt * grad + lever * (fj - fnt * tj)
                fc[e + 1, j] += push
                fc[e, j] -= push


@njit(cache=True, error_model="numpy", inline="always")
def _add_band_entry(band, lower, exact, p, q, val):
    """The symmetric pair of entries (p, q), (q, p) of the coupled layout += val (:func:`_add_sym`), with ``exact``
    the mirror in the lower band too (stored at the same places; p == q: the upper band only)."""
    _add_sym(band, p, q, val)
    if exact and p != q:
        _add_sym(lower, p, q, val)


@njit(cache=True, error_model="numpy", inline="always")
def _skew(n0, n1, n2, i, j):
    """Entry (i, j) of the cross-product matrix [n]_x (n x q = [n]_x q)."""
    if i == j:
        return 0.0
    if i == 0:
        return -n2 if j == 1 else n1
    if i == 1:
        return n2 if j == 0 else -n0
    return -n1 if j == 0 else n0


@njit(cache=True, error_model="numpy")
def _slip_gradient(c, k, E, e0, e1, base, full, axis):
    """full (3, 11) <- the gradient of penalty row k's slip over :func:`_add_section_band`'s local unknowns: the
    anchored point's weights (1 - s_a) I, s_a I on the row's nodes and the section's touching point's move m = s
    (theta - theta0) (n x t) (:func:`~bullet_dlo.core.kernels.contact.set_support`) in its edges' twist angles and
    nodes, dm/dx_{e+1} = -dm/dx_e = (theta - theta0) ((n x t) ds/dx^T + s [n]_x (I - t t^T) / length), the
    derivative :func:`_add_section_couples` applies to the friction force; axis (3, 11) <- its node-weight part
    alone (the frameless block's). ``E``: the edges' frames (:class:`Scratch` edges)."""
    full[:, :] = 0.0
    axis[:, :] = 0.0
    sa = c.anchor[k, 3]
    for side in range(2):  # (a row on one node: both weights there)
        local = 3 * (c.node[k, side] - base)
        w = 1.0 - sa if side == 0 else sa
        for j in range(3):
            full[j, local + j] += w
            axis[j, local + j] += w
    n0, n1, n2 = c.normal[k, 0], c.normal[k, 1], c.normal[k, 2]
    for slot in range(2):
        e = e0 if slot == 0 else e1
        if e < 0:
            continue
        col = e + 1
        t0, t1, t2 = E[1, col], E[2, col], E[3, col]
        turn = E[7, col] - c.support[k, 9 + slot]
        lever = turn * c.support[k, 24 + slot] / E[0, col]
        for i in range(3):
            xi = (n1 * t2 - n2 * t1) if i == 0 else ((n2 * t0 - n0 * t2) if i == 1 else (n0 * t1 - n1 * t0))  # n x t
            full[i, 9 + slot] = c.support[k, 12 + 3 * slot + i]
            for j in range(3):
                tj = t0 if j == 0 else (t1 if j == 1 else t2)
                d = turn * xi * c.support[k, 18 + 3 * slot + j] + lever * (_skew(n0, n1, n2, i, j) - xi * tj)
                full[i, 3 * (e + 1 - base) + j] += d
                full[i, 3 * (e - base) + j] -= d


@njit(cache=True, error_model="numpy")
def _add_section_band(c, held, x, E, kx, kv, band, lower, exact):
    """A flat section's contact terms in the coupled Newton matrix, kx (-dF/dq) + kv (-dF/dq') beyond the frameless
    position block's: for a row pressing (g < 0) with gap gradient G (w_a n, w_b n on its nodes, -+ ds/dx on its
    edges' nodes, -ds/dtheta on its edges' twist angles; :func:`~bullet_dlo.core.kernels.contact.set_support`),
    (kx k_n + kv c_n) (G G^T - (w n)(w n)^T) and the curvature of s in the twist, kx k_n |g| d2s/dtheta^2 (with
    ``exact`` as it is; else where it is >= 0: the Gauss-Newton matrix stays positive definite); for its friction
    spring K (:func:`~bullet_dlo.core.kernels.contact._row_blocks`, 3 x 3) with slip gradient T
    (:func:`_slip_gradient`: the anchored point's weights on its nodes, the touching point's move in its edges' twist
    angles and nodes), T^T K T - A^T K A (A: the weights alone, the frameless block's). The curvature of s in the
    positions and the second derivatives of the move are left out (Gauss-Newton). ``E``: the edges' frames at x
    (:class:`Scratch` edges)."""
    if c.section[0] <= 0.0:
        return
    ns = x.shape[0] - 1
    full = np.empty(11)  # G over the row's local unknowns: x of nodes a - 1, a, a + 1, then theta of edges e0, e1
    axis = np.empty(11)  # its (w n) part (the frameless block has it)
    slip, slip_axis = np.empty((3, 11)), np.empty((3, 11))  # T and A over the same unknowns
    k_slip, k_axis = np.empty((3, 11)), np.empty((3, 11))  # K T, K A
    blk = np.empty((2, 3, 3))
    u = np.empty(3)
    for k in range(c.count[0]):
        if c.support[k, 0] <= 0.0:
            continue
        e0, e1 = _contact.row_edges(c.node[k, 0], c.node[k, 1], ns)
        base = c.node[k, 0] - 1
        _contact._row_blocks(c, k, x, kx, kv, u, blk)
        _slip_gradient(c, k, E, e0, e1, base, slip, slip_axis)
        for i in range(3):
            for p in range(11):
                k_slip[i, p] = blk[1, i, 0] * slip[0, p] + blk[1, i, 1] * slip[1, p] + blk[1, i, 2] * slip[2, p]
                k_axis[i, p] = (blk[1, i, 0] * slip_axis[0, p] + blk[1, i, 1] * slip_axis[1, p]
                                + blk[1, i, 2] * slip_axis[2, p])
        for p in range(11):
            if not _section_unknown(p, base, e0, e1, held):
                continue
            for q in range(p, 11):
                if not _section_unknown(q, base, e0, e1, held):
                    continue
                val = 0.0
                for i in range(3):
                    val += slip[i, p] * k_slip[i, q] - slip_axis[i, p] * k_axis[i, q]
                if val != 0.0:
                    _add_band_entry(band, lower, exact, _section_index(p, base, e0, e1),
                                    _section_index(q, base, e0, e1), val)
        g = _contact._gap(c, k, x)
        if not g < 0.0:
            continue
        stiff = kx * c.k_n[k] + kv * c.c_n[k]
        full[:] = 0.0
        axis[:] = 0.0
        for slot in range(2):  # (a row on one node with two weights adds both: the same local entries)
            node = c.node[k, slot]
            w = c.weight[k, slot]
            for j in range(3):
                full[3 * (node - base) + j] += w * c.normal[k, j]
                axis[3 * (node - base) + j] += w * c.normal[k, j]
        for slot in range(2):
            e = e0 if slot == 0 else e1
            if e < 0:
                continue
            full[9 + slot] = -c.support[k, 2 + slot]
            for j in range(3):
                full[3 * (e + 1 - base) + j] -= c.support[k, 18 + 3 * slot + j]
                full[3 * (e - base) + j] += c.support[k, 18 + 3 * slot + j]
            curv = kx * c.k_n[k] * (-g) * c.support[k, 4 + slot]
            if exact or curv > 0.0:
                _add_band_entry(band, lower, exact, 4 * e + 3, 4 * e + 3, curv)
        for p in range(11):
            if full[p] == 0.0 or not _section_unknown(p, base, e0, e1, held):
                continue
            for q in range(p, 11):
                if full[q] == 0.0 or not _section_unknown(q, base, e0, e1, held):
                    continue
                val = stiff * (full[p] * full[q] - axis[p] * axis[q])
                if val != 0.0:
                    _add_band_entry(band, lower, exact, _section_index(p, base, e0, e1),
                                    _section_index(q, base, e0, e1), val)


@njit(cache=True, error_model="numpy", inline="always")
def _section_index(p, base, e0, e1):
    """The coupled layout's index of :func:`_add_section_band`'s local unknown p (x of node base + p // 3, component
    p % 3, for p < 9; else theta of edge e0 or e1)."""
    if p < 9:
        return 4 * (base + p // 3) + p % 3
    return 4 * (e0 if p == 9 else e1) + 3


@njit(cache=True, error_model="numpy", inline="always")
def _section_unknown(p, base, e0, e1, held):
    """Whether :func:`_add_section_band`'s local unknown p is one of the solve's (a free node's position, a twist
    angle of an edge the row has)."""
    if p < 9:
        node = base + p // 3
        return 0 <= node < held.shape[0] and not held[node]
    return (e0 if p == 9 else e1) >= 0


@njit(cache=True, error_model="numpy")
def _add_contact_band(c, held, x, E, kx, kv, cb, band, lower, exact):
    """band (the coupled layout's upper band) += the contact set's kx (-dF/dx) + kv (-dF/dv) at x on the position
    block: :func:`~bullet_dlo.core.kernels.contact.add_contact_jacobian` into ``cb`` (the frameless layout's full
    band, scratch) and its upper triangle moved over (x_i, component r -> row 4 i + r; the rows couple nodes at
    most two apart, within the coupled envelope); with ``exact`` its mirror into the exact matrix's lower band by
    columns (``lower``, see :func:`_band_lu_coupled`) too; then a flat section's terms (:func:`_add_section_band`,
    ``E`` the edges' frames at x)."""
    cb[:, :] = 0.0
    _contact.add_contact_jacobian(c, held, x, kx, kv, cb)
    size = cb.shape[0]
    for a in range(size):
        ra = 4 * (a // 3) + a % 3
        for d in range(HALF, 2 * HALF + 1):
            val = cb[a, d]
            if val == 0.0:
                continue
            b = a + d - HALF
            off = 4 * (b // 3) + b % 3 - ra
            if b < size and off <= HALF_T:
                band[ra, off] += val
                if exact and off > 0:
                    lower[ra, off] += val
    _add_section_band(c, held, x, E, kx, kv, band, lower, exact)


# An exact contact matrix whose elimination meets a pivot <= 0 is assembled again with its diagonal times 1 +
# FIRST_SHIFT, 10 FIRST_SHIFT, ... (SHIFTS tries in all, the first unshifted; Marquardt's scaling: the step turns
# towards each unknown's own Newton step), and Gauss-Newton's only after that: at the frictional impact of a
# tilted ribbon (n 41, 1 kHz) the exact matrix is indefinite and Gauss-Newton's steps contract poorly (30
# iterations at alpha 1/32 - 1/4, the step failed); a 1.1x diagonal converges it (docs/concepts/contact.md).
SHIFTS = 5
FIRST_SHIFT = 1e-3


@njit(cache=True, error_model="numpy", inline="always")
def _scale_diagonal(band, factor):
    """The diagonal of the upper ``band`` (column 0) times ``factor``."""
    for i in range(band.shape[0]):
        band[i, 0] *= factor


@njit(cache=True, error_model="numpy", inline="always")
def _trial(vn, wn, r, alpha, v_try, w_try, n, ns):
    """The line search's trial velocities [m/s] of the n nodes and twist rates [rad/s] of the ns segments: (vn, wn)
    + alpha times the Newton direction r (4 per node: 3 velocity components, then the twist rate of the segment
    from it)."""
    for i in range(n):
        for j in range(3):
            v_try[i, j] = vn[i, j] + alpha * r[4 * i + j]
    for k in range(ns):
        w_try[k] = wn[k] + alpha * r[4 * k + 3]


@njit(cache=True, error_model="numpy")
def coupled_contact(stepper, method, m, x, v, samples, ws, has_prev, c, cap_tol=1e-3, max_passes=10):
    """One implicit step (``method``: implicit Euler or BDF2) of a cable with a material frame in contact (the
    contact set ``c``, no free body in the solve), positions and twist in one Newton system: the coupled residual
    of :func:`coupled_implicit` with the contact and grip forces added on the positions (a flat section's also on
    the twist), their stiffness in the Newton matrix (:func:`_add_contact_band`: the rows' springs through their gap
    and slip gradients, without those gradients' own derivatives) beside the exact or Gauss-Newton matrix of the
    rest, their potential in the merit; accepted on a potential decrease only and the friction caps an outer fixed
    point, as :func:`~bullet_dlo.core.kernels.steppers.newton` does with contacts (without its friction active set,
    which only solves with free bodies use), relaxed where a row's cap overshoots
    (:func:`~bullet_dlo.core.kernels.contact.relax_caps`); a solve that ends more than
    :data:`~bullet_dlo.core.kernels.contact.RETRY_RATIO` times gravity's impulse from convergence is taken again from
    the caps of :func:`~bullet_dlo.core.kernels.contact.bounded_caps`, the closer of the two kept (as ``newton``
    does). An exact matrix that is indefinite is scaled on its diagonal before Gauss-Newton's is taken
    (:data:`SHIFTS`). Advances x, v and the twist state in place and leaves the contact forces at the solution in
    ``c`` and the position rows of its residual in ws.residual (the stall guard's measure).
    Returns (Newton iterations, converged)."""
    h = stepper.h
    n = x.shape[0]
    ns = n - 1
    imp = _start_implicit(method, m, x, v, h, samples, ws, has_prev)
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    theta0, omega0, tb, wb, wa = _bases(method, m, h, has_prev)
    g = np.empty((12, 3))
    frac = 1.0  # implicit Euler, BDF2: the residual at t + h
    size = 4 * n
    band = np.empty((size, HALF_T + 1))
    lower, upx = np.empty((size, HALF_T + 1)), np.empty((size, HALF_T + 1))
    cb = np.empty((3 * n, 2 * HALF + 1))
    r, r_try = np.empty(size), np.empty(size)
    wn, w_try, wv, rate, tq = omega0.copy(), np.empty(ns), np.empty(ns), np.zeros(n), np.empty(ns)
    sc = _make_scratch(n)
    mp = _frameless(m)
    vn, v_try = ws.v_new, ws.v_try
    r_scale, r_floor = _scales(m, x, hf, theta0)
    g_norm = np.sqrt(0.0 + m.gravity[0] * m.gravity[0] + m.gravity[1] * m.gravity[1] + m.gravity[2] * m.gravity[2])
    phi_scale = 0.0  # the potential's scale (round-off allowance of the line search)
    for i in range(n):
        phi_scale += m.mass[i] * g_norm * (abs(x[i, 0]) + abs(x[i, 1]) + abs(x[i, 2]) + 1.0)
    nc = c.count[0]
    max_iter = max(stepper.max_iter, _contact.MIN_CONTACT_ITER)
    caps_new = np.empty(max(nc, 1))
    history = np.zeros((max(nc, 1), 2))  # (relax_caps)
    first_exact = _first_exact(stepper, m)
    # a solve that ends beyond RETRY_RATIO times gravity's impulse from convergence is solved again from friction
    # limits bounded by the step's inertia (contact.bounded_caps), the closer kept: as steppers.newton does
    v_start, w_start = vn.copy(), wn.copy()
    v_first, w_first, cap_first = vn.copy(), wn.copy(), np.empty(max(nc, 1))
    r_first = np.inf
    its = 0
    rnorm = 0.0
    converged = False
    for attempt in range(2):
        if attempt == 1:
            if converged:
                break
            for i in range(n):  # (r: the residual at the first solve's iterate, _contact_newton's return)
                for j in range(3):
                    ws.residual[3 * i + j] = r[4 * i + j]
            if _contact.stall_ratio(m, ws, hf) <= _contact.RETRY_RATIO:
                break
            v_first[:, :] = vn
            w_first[:] = wn
            cap_first[:nc] = c.cap[:nc]
            r_first = rnorm
            vn[:, :] = v_start
            wn[:] = w_start
            history[:, :] = 0.0
        _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)  # X at the predictor
        _contact.set_support(c, sc.edges, wv, m.tw_ref, m.tw_tan)  # (a flat section's reach at the predictor: caps)
        if attempt == 0:
            _contact.elastic_caps(c, ws.x_stage, c.cap)  # caps from its penetration
        else:
            _contact.bounded_caps(c, x, ws.x_stage, m.mass, m.held, cx, hf, c.cap)
        rnorm = _add_contacts(m, imp, ws, r, c, sc, wv)
        it, converged, rnorm = _contact_newton(stepper, m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv,
                                              rate, tq, r, r_try, v_try, w_try, g, sc, band, lower, upx, cb, c,
                                              caps_new, history, rnorm, max_iter, first_exact, cap_tol, max_passes,
                                              r_scale, r_floor, phi_scale)
        its += it
    kept_first = r_first < np.inf and not converged and rnorm >= r_first
    if kept_first:  # the first solve was closer: kept
        vn[:, :] = v_first
        wn[:] = w_first
        c.cap[:nc] = cap_first[:nc]
    c.lock[:nc] = 0
    if kept_first:  # forces, c.f_n, c.f_t and the frames at the kept iterate (else _contact_newton left them)
        _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)
        _add_contacts(m, imp, ws, r, c, sc, wv)
    for i in range(n):
        for j in range(3):
            ws.residual[3 * i + j] = r[4 * i + j]
    kept = bool(1)  # the last residual is at the solution (a runtime True: a literal compiles _finish twice)
    _finish(method, m, x, v, samples, ws, has_prev, h, cx, theta0, omega0, tb, wn, kept, sc)
    return its, converged


@njit(cache=True, error_model="numpy")
def _contact_newton(stepper, m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, r_try, v_try,
                    w_try, g, sc, band, lower, upx, cb, c, caps_new, history, rnorm, max_iter, first_exact, cap_tol,
                    max_passes, r_scale, r_floor, phi_scale):
    """:func:`coupled_contact`'s Newton iterations from (vn, wn), whose residual r and its max ``rnorm`` were taken
    with the caps in use, the caps an outer fixed point; (vn, wn) left at the last accepted iterate, r, the scratch
    and the contact forces its (however the solve ended). Returns (Newton iterations, converged, that residual's
    max)."""
    n = vn.shape[0]
    ns = n - 1
    nc = c.count[0]
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    tol = stepper.tol
    fresh = True  # r, rnorm, the scratch and the contact forces are those of (vn, wn) with the caps in use
    it = 0
    passes = 0
    converged = False
    slow = False  # a Gauss-Newton iteration contracted poorly: the exact Jacobian from then on (as coupled_implicit)
    descent = False  # an exact direction found no lower potential: the Gauss-Newton matrix for the rest of the step
    c.lock[:nc] = 0
    while True:
        if not fresh:
            _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)
            rnorm = _add_contacts(m, imp, ws, r, c, sc, wv)
        fresh = False
        if it > 0 and rnorm <= tol * (r_scale + _change(m, ws, vn, wn, wa)) + r_floor:
            if _contact.caps_settled(c, ws.x_stage, caps_new, cap_tol) or passes >= max_passes or it >= max_iter:
                converged = True
                break
            passes += 1
            _contact.relax_caps(c, caps_new, history, passes)
            continue
        if it >= max_iter:
            break
        it += 1
        phi0 = (_merit(m, mp, imp, ws, wa, vn, wn, wv, rate, sc)
                + _contact.contact_potential(c, ws.x_stage, ws.v_stage, cx / cv))
        exact = (it >= first_exact or slow) and not descent
        if exact:
            shift = 0.0  # an indefinite exact matrix (at an impact) is taken again with its diagonal scaled up
            solved = False
            for _ in range(SHIFTS):
                _newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, frac, h)
                _add_contact_band(c, m.held, ws.x_stage, sc.edges, hf * cx, hf * cv, cb, band, lower, exact)
                _scale_diagonal(band, 1.0 + shift)
                solved = _exact_direction(band, lower, r, r_try)
                if solved:
                    break
                shift = FIRST_SHIFT if shift == 0.0 else 10.0 * shift
            exact = solved
        if not exact:
            _newton_matrix(stepper, m, mp, imp, ws, band, g, sc, exact, lower, upx, samples, frac, h)
            _add_contact_band(c, m.held, ws.x_stage, sc.edges, hf * cx, hf * cv, cb, band, lower, exact)
            band_solve_upper(band, r, HALF_T, 4)  # r becomes the Newton direction
        alpha = 1.0
        accepted = False
        rn_try = 0.0
        for _ in range(30):
            _trial(vn, wn, r, alpha, v_try, w_try, n, ns)
            _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, v_try, w_try, wv, rate, tq, r_try, g, sc)
            rn_try = _add_contacts(m, imp, ws, r_try, c, sc, wv)
            phi = (_merit(m, mp, imp, ws, wa, v_try, w_try, wv, rate, sc)
                   + _contact.contact_potential(c, ws.x_stage, ws.v_stage, cx / cv))
            if phi <= phi0 + 1e-13 * (abs(phi0) + phi_scale):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if exact:  # (the exact matrix is not symmetric: its direction need not descend) Gauss-Newton's from here,
                descent = True  # the residual at the current iterate taken again (fresh is False)
                continue
            # r holds the Newton direction, the scratch and the contact forces the last trial's: those of (vn, wn)
            _residual(m, mp, imp, ws, samples, frac, h, tb, wb, wa, vn, wn, wv, rate, tq, r, g, sc)
            rnorm = _add_contacts(m, imp, ws, r, c, sc, wv)
            break
        vn[:, :] = v_try
        wn[:] = w_try
        r[:] = r_try
        slow = slow or not _contracted(rn_try, rnorm, alpha)
        rnorm = rn_try
        fresh = True
    return it, converged, rnorm


# The kernel arrays' type (model.py imports the kernels, so the module object is bound here; Numba resolves
# ``_model.KernelArrays`` when it compiles).
from bullet_dlo.core import model as _model  # noqa: E402
from bullet_dlo.core.kernels import contact as _contact  # noqa: E402  (the contact terms of coupled_contact)


# ----- Gauss-Legendre with the twist in its collocation system ------------------------------------------------
GLT_HALF = 8 * 2 + 7  # scalar half-width of the stage system, 8 unknowns per node (2 stages x (x_i, theta_i)): 23


@njit(cache=True, error_model="numpy", inline="always")
def _gl_index(a, s):
    """The stage system's index of the coupled layout's unknown a (4 i + c) at stage s: 8 i + 4 s + c."""
    return 8 * (a // 4) + 4 * s + a % 4


@njit(cache=True, error_model="numpy")
def _stage_axes(m, dirs, c, out):
    """out (2, 3) <- the clamps' section axes at t + c h: the quadratic through the three samples of ``tw_normal``
    (t, t + h/2, t + h), its component along the stage's clamp direction ``dirs`` removed, normalised."""
    l0, l1, l2 = 2.0 * (c - 0.5) * (c - 1.0), -4.0 * c * (c - 1.0), 2.0 * c * (c - 0.5)
    nrm = m.tw_normal
    for e in range(2):
        dot = 0.0
        for j in range(3):
            out[e, j] = l0 * nrm[0, e, j] + l1 * nrm[1, e, j] + l2 * nrm[2, e, j]
            dot += out[e, j] * dirs[e, j]
        norm = 0.0
        for j in range(3):
            out[e, j] -= dot * dirs[e, j]
            norm += out[e, j] * out[e, j]
        norm = math.sqrt(norm)
        if norm > 0.0:
            for j in range(3):
                out[e, j] /= norm


@njit(cache=True, error_model="numpy")
def _holonomy_rates(m, x, h, vs, hpos, hvel, xs, hol):
    """Stage positions xs (2, n, 3) [m] (held nodes at their stage poses) and hol (2, n-1) [rad/s]: the rate at each
    stage of the angle between an edge's reference director carried by parallel transport in time and the one the
    step transports by a single minimal rotation from the step's tangent t0 (``tw_tan``) to the stage's t,
    t0 . (t x dt/dt) / (1 + t0 . t) (the solid angle the tangent sweeps; O(h^2) over a step: the twist angle
    relative to the minimal rotation advances by omega + this)."""
    n = x.shape[0]
    tan = m.tw_tan
    for s in range(2):
        a0 = A11 if s == 0 else A21
        a1 = A12 if s == 0 else A22
        for i in range(n):
            for j in range(3):
                xs[s, i, j] = x[i, j] + h * (a0 * vs[0, i, j] + a1 * vs[1, i, j])
        vel = np.empty((n, 3))
        vel[:, :] = vs[s]
        for e in range(2):
            i = 0 if e == 0 else n - 1
            if m.held[i]:
                for j in range(3):
                    xs[s, i, j] = hpos[s, e, j]
                    vel[i, j] = hvel[s, e, j]
        for k in range(n - 1):
            d0, d1, d2 = xs[s, k + 1, 0] - xs[s, k, 0], xs[s, k + 1, 1] - xs[s, k, 1], xs[s, k + 1, 2] - xs[s, k, 2]
            length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            t0, t1, t2 = d0 / length, d1 / length, d2 / length
            u0, u1, u2 = vel[k + 1, 0] - vel[k, 0], vel[k + 1, 1] - vel[k, 1], vel[k + 1, 2] - vel[k, 2]
            c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
            s0, s1, s2 = tan[k, 0], tan[k, 1], tan[k, 2]
            hol[s, k] = (s0 * c0 + s1 * c1 + s2 * c2) / (length * (1.0 + s0 * t0 + s1 * t1 + s2 * t2))


@njit(cache=True, error_model="numpy")
def _gl_stage(m, mp, x, theta0, h, s, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv, rate, tq, r4, g, sc):
    """Evaluate stage s (0, 1) by :func:`_residual` with the map X = x_base + h a_ss V_s, x_base = x + h a_so V_o
    (o the other stage), Theta = theta_base + h a_ss W_s, theta_base = theta0 + h a_so (W_o + hol_o) + h a_ss hol_s:
    leaves the generalised forces F [N] in ws.force and T [N m] in ``tq`` (vs (2, n, 3) stage velocities, wsr
    (2, n-1) stage twist rates, hol their holonomy rates, :func:`_holonomy_rates`)."""
    n = x.shape[0]
    ns = n - 1
    o = 1 - s
    a_so = A12 if s == 0 else A21
    a_ss = A11 if s == 0 else A22
    for i in range(n):
        for j in range(3):
            ws.x_base[i, j] = x[i, j] + h * a_so * vs[o, i, j]
            ws.v_base[i, j] = 0.0
            ws.v_avg[i, j] = vs[s, i, j]
    tb = np.empty(ns)
    wa = np.empty(ns)
    for k in range(ns):
        tb[k] = theta0[k] + h * a_so * (wsr[o, k] + hol[o, k]) + h * a_ss * hol[s, k]
        wa[k] = wsr[s, k]
    imp = ImplicitMap(h * a_ss, 1.0, h, hpos[s], hvel[s], hdir[s])
    m.tw_clamp[:, :] = haxes[s]
    _residual(m, mp, imp, ws, samples, C1 if s == 0 else C2, h, tb, np.zeros(ns), wa, vs[s], wsr[s], wv, rate, tq, r4,
              g, sc)
    return imp


@njit(cache=True, error_model="numpy")
def _gl_twist_residual(m, mp, x, v, theta0, omega0, h, vs, wsr, hol, xs, ws, samples, hpos, hvel, hdir, haxes,
                       fs, tqs, wv, rate, r4, g, sc, r):
    """r (8n,) <- the stage equations R_s = h F_s - M sum_q (A^-1)_sq (U_q - u) [N s; N m s] of positions and twist
    (interleaved: node i's stage-0 x, theta_i, then stage-1's); 0 on held nodes and the last theta slot. Returns
    max |r| with the twist rows per rest length (as :func:`_residual`). Leaves the stage forces in fs, tqs."""
    n = x.shape[0]
    ns = n - 1
    _holonomy_rates(m, x, h, vs, hpos, hvel, xs, hol)
    for s in range(2):
        _gl_stage(m, mp, x, theta0, h, s, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv, rate, tqs[s], r4, g,
                  sc)
        fs[s, :, :] = ws.force
    worst = 0.0
    for i in range(n):
        for s in range(2):
            ai0 = AI11 if s == 0 else AI21
            ai1 = AI12 if s == 0 else AI22
            for j in range(3):
                val = 0.0
                if not m.held[i]:
                    val = h * fs[s, i, j] - m.mass[i] * (ai0 * (vs[0, i, j] - v[i, j]) + ai1 * (vs[1, i, j] - v[i, j]))
                r[8 * i + 4 * s + j] = val
                if not abs(val) <= worst:
                    worst = abs(val)
            val = 0.0
            if i < ns:
                val = h * tqs[s, i] - m.tw_inertia[i] * (ai0 * (wsr[0, i] - omega0[i]) + ai1 * (wsr[1, i] - omega0[i]))
                scaled = abs(val) / m.rest_length[i]
                if not scaled <= worst:
                    worst = scaled
            r[8 * i + 4 * s + 3] = val
    return worst


@njit(cache=True, error_model="numpy")
def _gl_twist_matrix(stepper, m, mp, x, theta0, h, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv, rate,
                     tq, r4, g, sc, exact, cb0, cb1, lower0, lower1, upx, band):
    """band (8n, 2 GLT_HALF + 1) <- -dR/dU of the stage equations (general band, band[r, c - r + GLT_HALF]), from
    each stage's matrix of the coupled step (:func:`_newton_matrix`, interleaved layout; Gauss-Newton, or with
    ``exact`` the exact Jacobian, its lower band by columns in lower0 / lower1): K_s = dF/dq and C_s = dF/dq' at
    stage s from two of them (cx 1, cv 0 and 1, hf 1), then -dR_s/dU_q = -h^2 a_sq K_s - h delta_sq C_s +
    M (A^-1)_sq. The holonomy rates' derivatives are left out (they are O(h) against the kept terms). Held nodes
    and the last theta slot: identity rows."""
    n = x.shape[0]
    ns = n - 1
    size4 = 4 * n
    band[:, :] = 0.0  # (hol: the holonomy rates of the last residual, taken at vs, wsr)
    for s in range(2):
        _gl_stage(m, mp, x, theta0, h, s, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv, rate, tq, r4, g, sc)
        imp0 = ImplicitMap(1.0, 0.0, 1.0, hpos[s], hvel[s], hdir[s])
        _newton_matrix(stepper, m, mp, imp0, ws, cb0, g, sc, exact, lower0, upx, samples, C1 if s == 0 else C2, h)
        imp1 = ImplicitMap(1.0, 1.0, 1.0, hpos[s], hvel[s], hdir[s])
        _newton_matrix(stepper, m, mp, imp1, ws, cb1, g, sc, exact, lower1, upx, samples, C1 if s == 0 else C2, h)
        for a in range(size4):
            fixed_a = (a % 4 != 3 and m.held[a // 4]) or a == size4 - 1
            if fixed_a:
                continue
            diag_m = m.mass[a // 4] if a % 4 != 3 else m.tw_inertia[a // 4]
            for d in range(HALF_T + 1):
                b = a + d
                if b >= size4:
                    break
                fixed_b = (b % 4 != 3 and m.held[b // 4]) or b == size4 - 1
                if fixed_b:
                    continue
                kneg = cb0[a, d] - (diag_m if d == 0 else 0.0)  # -K_s (a, b)
                cneg = cb1[a, d] - cb0[a, d]  # -C_s (a, b)
                for q in range(2):
                    a_sq = (A11 if q == 0 else A12) if s == 0 else (A21 if q == 0 else A22)
                    val = h * h * a_sq * kneg + (h * cneg if s == q else 0.0)
                    row, col = _gl_index(a, s), _gl_index(b, q)
                    band[row, col - row + GLT_HALF] += val
                    if d > 0:  # (b, a): the same entry, or the exact matrix's lower band
                        if exact:
                            val = h * h * a_sq * lower0[a, d] + (h * (lower1[a, d] - lower0[a, d]) if s == q else 0.0)
                        row, col = _gl_index(b, s), _gl_index(a, q)
                        band[row, col - row + GLT_HALF] += val
    for a in range(size4):
        fixed_a = (a % 4 != 3 and m.held[a // 4]) or a == size4 - 1
        for s in range(2):
            row = _gl_index(a, s)
            if fixed_a:
                band[row, GLT_HALF] = 1.0
                continue
            diag_m = m.mass[a // 4] if a % 4 != 3 else m.tw_inertia[a // 4]
            for q in range(2):
                ai = (AI11 if q == 0 else AI12) if s == 0 else (AI21 if q == 0 else AI22)
                col = _gl_index(a, q)
                band[row, col - row + GLT_HALF] += diag_m * ai


@njit(cache=True, error_model="numpy")
def coupled_gauss_legendre(stepper, m, x, v, samples, ws):
    """One 2-stage Gauss-Legendre step of a cable with a material frame: the stage velocities V_s and twist rates
    W_s solved together in one Newton system (the collocation equations of positions and twist,
    :func:`_gl_twist_residual`), x, v, theta, omega advanced in place, then the reference frames transported to the
    new tangents. Held ends at their stage poses (:func:`~bullet_dlo.core.kernels.gauss_legendre.stage_holders`),
    the clamps' section axes at the stage times by :func:`_stage_axes`. The twist angle relative to the step's
    minimal-rotation transport advances by omega plus the holonomy rate (:func:`_holonomy_rates`), integrated by the
    same collocation. Newton on the stage matrix (:func:`_gl_twist_matrix`), exact or Gauss-Newton as
    :func:`coupled_implicit` chooses (:func:`_first_exact`, :func:`_contracted`; Gauss-Newton's for the rest of the
    step where the exact one meets a zero pivot or its direction no decrease), and a line search on the residual
    (12 halvings); converged as :func:`coupled_implicit`. Returns (iterations, converged)."""
    h = stepper.h
    n = x.shape[0]
    ns = n - 1
    hpos = np.empty((2, 2, 3))
    hvel = np.empty((2, 2, 3))
    hdir = np.empty((2, 2, 3))
    haxes = np.empty((2, 2, 3))
    stage_holders(samples, C1, h, hpos[0], hvel[0], hdir[0])
    stage_holders(samples, C2, h, hpos[1], hvel[1], hdir[1])
    _stage_axes(m, hdir[0], C1, haxes[0])
    _stage_axes(m, hdir[1], C2, haxes[1])
    theta0 = m.tw_theta.copy()
    omega0 = m.tw_omega.copy()
    vs, v_try = np.empty((2, n, 3)), np.empty((2, n, 3))
    wsr, w_try = np.empty((2, ns)), np.empty((2, ns))
    for s in range(2):
        vs[s, :, :] = v
        for e in range(2):
            i = 0 if e == 0 else n - 1
            if m.held[i]:
                vs[s, i, :] = hvel[s, e]
        wsr[s, :] = omega0
    hol = np.empty((2, ns))
    xs = np.empty((2, n, 3))
    fs = np.empty((2, n, 3))
    tqs = np.empty((2, ns))
    tq = np.empty(ns)
    wv = np.empty(ns)
    rate = np.zeros(n)
    r4 = np.empty(4 * n)
    g = np.empty((12, 3))
    sc = _make_scratch(n)
    mp = _frameless(m)
    size = 8 * n
    r, r_try, du = np.empty(size), np.empty(size), np.empty(size)
    cb0, cb1 = np.empty((4 * n, HALF_T + 1)), np.empty((4 * n, HALF_T + 1))
    lower0, lower1 = np.empty((4 * n, HALF_T + 1)), np.empty((4 * n, HALF_T + 1))
    upx = np.empty((4 * n, HALF_T + 1))
    band = np.empty((size, 2 * GLT_HALF + 1))
    r_scale, r_floor = _scales(m, x, h, theta0)
    tol = stepper.tol
    rnorm = _gl_twist_residual(m, mp, x, v, theta0, omega0, h, vs, wsr, hol, xs, ws, samples, hpos, hvel, hdir,
                               haxes, fs, tqs, wv, rate, r4, g, sc, r)
    it = 0
    converged = False
    first_exact = _first_exact(stepper, m)
    slow = False  # a Gauss-Newton iteration of this step contracted poorly (see _contracted)
    gauss_newton = False  # the exact matrix failed this step (a zero pivot, or its direction found no decrease)
    while it < stepper.max_iter:
        it += 1
        # the stage matrices exact as coupled_implicit chooses them; Gauss-Newton's where the exact one failed
        exact = (it >= first_exact or slow) and not gauss_newton
        _gl_twist_matrix(stepper, m, mp, x, theta0, h, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv, rate,
                         tq, r4, g, sc, exact, cb0, cb1, lower0, lower1, upx, band)
        pivot = gl_band_factor(band, GLT_HALF)
        if exact and not pivot > 0.0:  # (also NaN)
            gauss_newton = True
            exact = not gauss_newton  # (a runtime False: a literal compiles _newton_matrix anew)
            _gl_twist_matrix(stepper, m, mp, x, theta0, h, vs, wsr, hol, ws, samples, hpos, hvel, hdir, haxes, wv,
                             rate, tq, r4, g, sc, exact, cb0, cb1, lower0, lower1, upx, band)
            gl_band_factor(band, GLT_HALF)
        du[:] = r
        gl_band_substitute(band, du, GLT_HALF)
        alpha = 1.0
        accepted = False
        rn_try = rnorm
        for _ in range(12):
            for s in range(2):
                for i in range(n):
                    for j in range(3):
                        v_try[s, i, j] = vs[s, i, j] + alpha * du[8 * i + 4 * s + j]
                for k in range(ns):
                    w_try[s, k] = wsr[s, k] + alpha * du[8 * k + 4 * s + 3]
            rn_try = _gl_twist_residual(m, mp, x, v, theta0, omega0, h, v_try, w_try, hol, xs, ws, samples, hpos,
                                        hvel, hdir, haxes, fs, tqs, wv, rate, r4, g, sc, r_try)
            if rn_try < rnorm or rn_try <= tol * r_scale + r_floor:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if exact:  # the exact direction found no decrease: Gauss-Newton's for the rest of the step
                gauss_newton = True
                continue
            break
        vs[:, :, :] = v_try
        wsr[:, :] = w_try
        r[:] = r_try
        slow = slow or not _contracted(rn_try, rnorm, alpha)
        rnorm = rn_try
        dmom = 0.0  # the momentum change of the step over both stages (the twist's per rest length)
        for i in range(n):
            for s in range(2):
                if not m.held[i]:
                    for j in range(3):
                        dmom = max(dmom, m.mass[i] * abs(vs[s, i, j] - v[i, j]))
                if i < ns:
                    dmom = max(dmom, m.tw_inertia[i] * abs(wsr[s, i] - omega0[i]) / m.rest_length[i])
        if rnorm <= tol * (r_scale + dmom) + r_floor:
            converged = True
            break
    _holonomy_rates(m, x, h, vs, hpos, hvel, xs, hol)  # at the solution
    for i in range(n):
        for j in range(3):
            x[i, j] += 0.5 * h * (vs[0, i, j] + vs[1, i, j])
            v[i, j] += SQRT3 * (vs[1, i, j] - vs[0, i, j])
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])
    for k in range(ns):
        m.tw_theta[k] = theta0[k] + 0.5 * h * (wsr[0, k] + hol[0, k] + wsr[1, k] + hol[1, k])
        m.tw_omega[k] = omega0[k] + SQRT3 * (wsr[1, k] - wsr[0, k])
    m.tw_clamp[:, :] = m.tw_normal[2]
    update_frames(m, x, samples.dir[2])
    return it, converged


# ----- the explicit methods with the twist as state -----------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _explicit_forces(m, mp, xe, ve, th, w, k, h, samples, ws, tq, wv, rate, r4, g, sc):
    """Generalised forces at the state (xe [m], th [rad], ve [m/s], w [rad/s]) with the held ends and clamps at
    sample k (0: t, 1: t + h/2, 2: t + h): F [N] into ws.force (n, 3), T [N m] into tq (n-1,), by :func:`_residual`
    (map X = (xe - ve) + ve, Theta = (th - w) + w). xe, ve: the held nodes' rows are set to the sample's pose."""
    n = xe.shape[0]
    ns = n - 1
    _set_held(m.held, xe, ve, samples.pos[k], samples.vel[k])
    for i in range(n):
        for j in range(3):
            ws.x_base[i, j] = xe[i, j] - ve[i, j]
            ws.v_base[i, j] = 0.0
            ws.v_avg[i, j] = ve[i, j]
    tb = np.empty(ns)
    for q in range(ns):
        tb[q] = th[q] - w[q]
    imp = ImplicitMap(1.0, 1.0, 1.0, samples.pos[k], samples.vel[k], samples.dir[k])
    m.tw_clamp[:, :] = m.tw_normal[k]
    _residual(m, mp, imp, ws, samples, 0.5 * k, h, tb, np.zeros(ns), w, ve, w, wv, rate, tq, r4, g, sc)


@njit(cache=True, error_model="numpy")
def _holonomy_rate(m, xe, ve, out):
    """out (n-1,) <- the holonomy rate of each edge at the state (xe, ve) (see :func:`_holonomy_rates`) [rad/s]."""
    tan = m.tw_tan
    for k in range(xe.shape[0] - 1):
        d0, d1, d2 = xe[k + 1, 0] - xe[k, 0], xe[k + 1, 1] - xe[k, 1], xe[k + 1, 2] - xe[k, 2]
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        t0, t1, t2 = d0 / length, d1 / length, d2 / length
        u0, u1, u2 = ve[k + 1, 0] - ve[k, 0], ve[k + 1, 1] - ve[k, 1], ve[k + 1, 2] - ve[k, 2]
        c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
        s0, s1, s2 = tan[k, 0], tan[k, 1], tan[k, 2]
        out[k] = (s0 * c0 + s1 * c1 + s2 * c2) / (length * (1.0 + s0 * t0 + s1 * t1 + s2 * t2))


@njit(cache=True, error_model="numpy")
def explicit_twist(stepper, m, x, v, samples, ws, method):
    """One step of an explicit method (``method``: 0 explicit Euler, 1 symplectic Euler, 2 RK4) of a cable with a
    material frame, the twist angles and rates state of the same method: theta' = omega + the holonomy rate
    (:func:`_holonomy_rate`, 0 at the step's start), I omega' = T, with the positions' forces F and the twist
    torques T of the coupled implicit step (:func:`_residual`: twist springs, anisotropic bending, Kelvin-Voigt
    twist dampers on both). x, v, theta, omega advanced in place, then the reference frames transported to the new
    tangents. Returns (0, True)."""
    h = stepper.h
    n = x.shape[0]
    ns = n - 1
    theta0 = m.tw_theta.copy()
    omega0 = m.tw_omega.copy()
    tq, wv, rate, r4 = np.empty(ns), np.empty(ns), np.zeros(n), np.empty(4 * n)
    g = np.empty((12, 3))
    sc = _make_scratch(n)
    mp = _frameless(m)
    xe, ve = np.empty((n, 3)), np.empty((n, 3))
    th, w, hol = np.empty(ns), np.empty(ns), np.empty(ns)
    if method == 2:  # RK4: the stages carry (x, v, theta, omega); slopes kx, kv (workspace), kt, kw
        kx, kv = ws.kx, ws.kv
        kt, kw = np.zeros((4, ns)), np.zeros((4, ns))  # zeroed: stage 0 adds 0 x kt[0] (0 x a stray NaN is NaN)
        for stage in range(4):
            c = 0.0 if stage == 0 else (1.0 if stage == 3 else 0.5)
            prev = max(stage - 1, 0)
            k = (stage + 1) // 2
            for i in range(n):
                for j in range(3):
                    xe[i, j] = x[i, j] + c * h * kx[prev, i, j]
                    ve[i, j] = v[i, j] + c * h * kv[prev, i, j]
            for q in range(ns):
                th[q] = theta0[q] + c * h * kt[prev, q]
                w[q] = omega0[q] + c * h * kw[prev, q]
            _explicit_forces(m, mp, xe, ve, th, w, k, h, samples, ws, tq, wv, rate, r4, g, sc)
            _holonomy_rate(m, xe, ve, hol)
            for i in range(n):
                for j in range(3):
                    kx[stage, i, j] = ve[i, j]
                    kv[stage, i, j] = ws.force[i, j] / m.mass[i]
            for q in range(ns):
                kt[stage, q] = w[q] + hol[q]
                kw[stage, q] = tq[q] / m.tw_inertia[q]
        for i in range(n):
            for j in range(3):
                x[i, j] += (h / 6.0) * (kx[0, i, j] + 2.0 * kx[1, i, j] + 2.0 * kx[2, i, j] + kx[3, i, j])
                v[i, j] += (h / 6.0) * (kv[0, i, j] + 2.0 * kv[1, i, j] + 2.0 * kv[2, i, j] + kv[3, i, j])
        for q in range(ns):
            m.tw_theta[q] = theta0[q] + (h / 6.0) * (kt[0, q] + 2.0 * kt[1, q] + 2.0 * kt[2, q] + kt[3, q])
            m.tw_omega[q] = omega0[q] + (h / 6.0) * (kw[0, q] + 2.0 * kw[1, q] + 2.0 * kw[2, q] + kw[3, q])
    else:  # explicit / symplectic Euler: forces at the start (the holonomy rate is 0 there)
        xe[:, :] = x
        ve[:, :] = v
        # sample 0 as an int64, as the RK4 stages pass it (a literal 0 compiled the kernel a second time)
        _explicit_forces(m, mp, xe, ve, theta0, omega0, np.int64(0), h, samples, ws, tq, wv, rate, r4, g, sc)
        for i in range(n):
            for j in range(3):
                a = ws.force[i, j] / m.mass[i]
                if method == 1:
                    v[i, j] += h * a
                    x[i, j] += h * v[i, j]
                else:
                    x[i, j] += h * v[i, j]
                    v[i, j] += h * a
        for q in range(ns):
            w_new = omega0[q] + h * tq[q] / m.tw_inertia[q]
            m.tw_theta[q] = theta0[q] + h * (w_new if method == 1 else omega0[q])
            m.tw_omega[q] = w_new
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])
    m.tw_clamp[:, :] = m.tw_normal[2]
    update_frames(m, x, samples.dir[2])
    return 0, True
