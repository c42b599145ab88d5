"""Numba step kernels: one fixed step of each time integrator, in place.

Every method advances positions x [m] and velocities v [m/s], both (n, 3), by one step h
given the model (:class:`~bullet_dlo.core.model.KernelArrays`: parameters, control, twist state) and the
held-end samples at t,
t + h/2 and t + h (:class:`~bullet_dlo.core.kernels.holders.HeldSamples`). Scratch memory is
a :class:`Workspace` allocated once by :func:`make_workspace`, so no step allocates. Held
nodes are kinematic: after every step they sit exactly at the prescribed pose. The method
table (names, orders, defaults) is :mod:`bullet_dlo.core.integrators`.

A cable with a material frame (``KernelArrays.tw``, :mod:`bullet_dlo.core.kernels.twist`) takes its
implicit steps with positions and twist angles in one Newton system, the twist integrated by the same
method (:func:`~bullet_dlo.core.kernels.twist_coupled.coupled_implicit`; the clamps' section axes at the
method's evaluation time), so the step keeps the method's order; the contact step of
:mod:`~bullet_dlo.core.kernels.contact` too (:func:`~bullet_dlo.core.kernels.twist_coupled.coupled_contact`).
Gauss-Legendre solves the stage twist rates in its collocation system
(:func:`~bullet_dlo.core.kernels.twist_coupled.coupled_gauss_legendre`) and the explicit methods carry the twist
angles and rates through their stages (:func:`~bullet_dlo.core.kernels.twist_coupled.explicit_twist`). Only a
contact step with a free body in its solve advances the positions with the twist angles held, then the twist
angles by an implicit Euler sub-step (:func:`~bullet_dlo.core.kernels.twist.twist_step`, staggered, first order).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.banded import HALF, assemble_system, band_solve, band_substitute
from bullet_dlo.core.kernels.drag import has_drag
from bullet_dlo.core.kernels.gauss_legendre import gauss_legendre_step
from bullet_dlo.core.kernels.forces import (
    add_damping_jacobian,
    add_drag_jacobian,
    dissipation,
    force_jacobian,
    internal_energy,
    total_forces,
)
from bullet_dlo.core.kernels.jit import njit
from bullet_dlo.core.kernels.twist import has_twist, set_clamp, twist_ready

EXPLICIT_EULER, SYMPLECTIC_EULER, RK4, IMPLICIT_EULER, BDF2, IMPLICIT_MIDPOINT, GAUSS_LEGENDRE = range(7)
RK4_C = (0.0, 0.5, 0.5, 1.0)
"""RK4's stage times as fractions of the step (each stage's state is (x, v) + c h (previous slopes))."""


class Stepper(NamedTuple):
    """How to take a step: method code (above), step h [s], and the Newton settings of the
    implicit methods: at most ``max_iter`` iterations, residual tolerance ``tol`` (relative, see
    :class:`~bullet_dlo.core.integrators.NewtonOptions`), ``definite`` stiffness filter, the iteration
    ``exact_from`` from which the coupled twisting step takes its exact Jacobian, and whether that step reuses
    its factored Newton matrix within a step (``reuse``)."""

    method: int
    h: float
    max_iter: int
    tol: float
    definite: bool
    exact_from: int
    reuse: bool


class Workspace(NamedTuple):
    """Scratch arrays of the step kernels (and BDF2's history), allocated once per cable.

    force [N], accel [m/s^2]: forces and accelerations at a stage, (n, 3);
    x_stage [m], v_stage [m/s]: the state a stage (RK4) or Newton iterate evaluates forces at, (n, 3);
    kx [m/s], kv [m/s^2]: RK4 slopes of the four stages, (4, n, 3);
    x_base [m], v_base [m/s], v_avg [m/s]: the implicit method's affine map from the end-of-step
    velocity v' to the evaluation state, X = x_base + cx v', V = v_base + cv v', and the
    velocity its momentum balance starts from, M (v' - v_avg) = hf F(X, V), (n, 3);
    v_new, v_try [m/s]: Newton iterate of v' and the line-search trial, (n, 3);
    residual, residual_try [N s]: momentum residuals of both, (3n,); residual_kept [N s]: the residual a chord
    iteration started from (kept in case its direction fails), (3n,);
    jacobian [N/m]: block-banded dF/dx, (n, 5, 3, 3); band: Newton matrix, (3n, 2*HALF+1);
    x_prev [m], v_prev [m/s]: state before the last step (BDF2), (n, 3);
    tw_band, tw_lower, tw_upper: the coupled twisting step's Newton matrix (upper band, lower band by columns, the
    exact matrix's extra upper entries) and, once eliminated, its factors, (4n, HALF_T + 1);
    matrices [-]: how many Newton matrices the implicit steps without contact have built and factored, a running
    count, in slot 0; then the key of the factors ``band`` keeps for later frameless steps (slot 1: whether it
    does, 2-4: the hf, cx, cv they were built with, from :data:`KEPT` on the held nodes, 1.0 held), (KEPT + n,).
    """

    force: np.ndarray
    accel: np.ndarray
    x_stage: np.ndarray
    v_stage: np.ndarray
    kx: np.ndarray
    kv: np.ndarray
    x_base: np.ndarray
    v_base: np.ndarray
    v_avg: np.ndarray
    v_new: np.ndarray
    v_try: np.ndarray
    residual: np.ndarray
    residual_try: np.ndarray
    residual_kept: np.ndarray
    jacobian: np.ndarray
    band: np.ndarray
    x_prev: np.ndarray
    v_prev: np.ndarray
    tw_band: np.ndarray
    tw_lower: np.ndarray
    tw_upper: np.ndarray
    matrices: np.ndarray


HALF_T = 10
"""Scalar half-bandwidth of the coupled twisting step's interleaved (x_i, theta_i) layout (twist_coupled)."""
KEPT = 5
"""Slots of ``Workspace.matrices`` before its held-node key (the count and the kept factors' key)."""
QUIET_START = 10.0
"""A frameless step takes an earlier step's factors only where its first residual is within this many times the
convergence threshold (module :func:`newton`): a settled or slowly loaded cable. Taken at every step, a moving
cable's chord iterations stopped just under the tolerance where Newton lands far below it: a falling cable with
drag lost its first order at 100 Hz and undamped swings at 60 Hz were stopped as energy growth (2026-12-06)."""


def make_workspace(n: int) -> Workspace:
    """Zeroed scratch arrays for an n-node cable."""
    shapes = {"kx": (4, n, 3), "kv": (4, n, 3), "residual": (3 * n,), "residual_try": (3 * n,),
              "residual_kept": (3 * n,), "jacobian": (n, 5, 3, 3), "band": (3 * n, 2 * HALF + 1),
              "tw_band": (4 * n, HALF_T + 1), "tw_lower": (4 * n, HALF_T + 1), "tw_upper": (4 * n, HALF_T + 1),
              "matrices": (KEPT + n,)}
    return Workspace(*(np.zeros(shapes.get(name, (n, 3))) for name in Workspace._fields))


# ----- helpers -------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def _set_held(held, x, v, pos, vel):
    """Put held nodes at the prescribed positions [m] and velocities [m/s] (pos, vel: (2, 3))."""
    n = x.shape[0]
    if held[0]:
        x[0, :] = pos[0]
        v[0, :] = vel[0]
    if held[n - 1]:
        x[n - 1, :] = pos[1]
        v[n - 1, :] = vel[1]
    _last_use = held, x, v, pos, vel  # (a last use after the branches: tests/llvm_loops.py)


@njit(cache=True, error_model="numpy")
def _accel(m, x, v, dirs, f, a):
    """a <- M^-1 F(x, v) [m/s^2] with clamp directions dirs (2, 3); f receives F [N]."""
    total_forces(m, x, v, dirs, f)
    for i in range(x.shape[0]):
        for j in range(3):
            a[i, j] = f[i, j] / m.mass[i]


# ----- explicit methods -----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _explicit_euler(m, x, v, h, samples, ws):
    _accel(m, x, v, samples.dir[0], ws.force, ws.accel)
    x += h * v
    v += h * ws.accel
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])


@njit(cache=True, error_model="numpy")
def _symplectic_euler(m, x, v, h, samples, ws):
    _accel(m, x, v, samples.dir[0], ws.force, ws.accel)
    v += h * ws.accel
    x += h * v
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])


@njit(cache=True, error_model="numpy")
def _rk4_stage(m, x, v, h, samples, ws, stage, c):
    """Slopes of RK4 stage ``stage`` (0..3) into ws.kx[stage], ws.kv[stage].

    The stage state is (x, v) + c h (slopes of the previous stage) with the held ends at the
    stage's time sample (t, t + h/2, t + h/2, t + h); stage 0 has c = 0.
    """
    prev = max(stage - 1, 0)
    k = (stage + 1) // 2
    set_clamp(m, k)
    xs, vs = ws.x_stage, ws.v_stage
    for i in range(x.shape[0]):
        for j in range(3):
            xs[i, j] = x[i, j] + c * h * ws.kx[prev, i, j]
            vs[i, j] = v[i, j] + c * h * ws.kv[prev, i, j]
    _set_held(m.held, xs, vs, samples.pos[k], samples.vel[k])
    ws.kx[stage] = vs
    _accel(m, xs, vs, samples.dir[k], ws.force, ws.kv[stage])


@njit(cache=True, error_model="numpy")
def _rk4(m, x, v, h, samples, ws):
    for stage in range(4):  # a loop, not four calls: literal stage numbers compiled _rk4_stage four times
        _rk4_stage(m, x, v, h, samples, ws, stage, RK4_C[stage])
    kx, kv = ws.kx, ws.kv
    for i in range(x.shape[0]):
        for j in range(3):
            x[i, j] += (h / 6.0) * (kx[0, i, j] + 2.0 * kx[1, i, j] + 2.0 * kx[2, i, j] + kx[3, i, j])
            v[i, j] += (h / 6.0) * (kv[0, i, j] + 2.0 * kv[1, i, j] + 2.0 * kv[2, i, j] + kv[3, i, j])
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])


# ----- implicit methods -----------------------------------------------------------------------
class ImplicitMap(NamedTuple):
    """Where an implicit method evaluates forces, given the end-of-step velocity v'.

    X = x_base + cx v', V = v_base + cv v' (cx [s], cv [-]; arrays in the Workspace), momentum
    balance M (v' - v_avg) = hf F(X, V) (hf [s]); held ends at pos_end [m], vel_end [m/s] and
    clamp directions dirs, each (2, 3), at the evaluation time.
    """

    cx: float
    cv: float
    hf: float
    pos_end: np.ndarray
    vel_end: np.ndarray
    dirs: np.ndarray


@njit(cache=True, error_model="numpy")
def _implicit_map(method, x, v, h, samples, ws, has_prev):
    """Fill ws.x_base, v_base, v_avg for ``method`` and return its :class:`ImplicitMap`.

    BDF2 (with history): X = (4x - x_prev)/3 + 2h/3 v'; implicit midpoint: X = x + h/4 (v + v'),
    V = (v + v')/2 at t + h/2; implicit Euler (and BDF2's first step): X = x + h v'.
    BDF2 then stores (x, v) as the history of the next step.
    """
    n = x.shape[0]
    xb, vb, va = ws.x_base, ws.v_base, ws.v_avg
    if method == BDF2 and has_prev:
        for i in range(n):
            for j in range(3):
                xb[i, j] = (4.0 * x[i, j] - ws.x_prev[i, j]) / 3.0
                va[i, j] = (4.0 * v[i, j] - ws.v_prev[i, j]) / 3.0
                vb[i, j] = 0.0
        imp = ImplicitMap(2.0 * h / 3.0, 1.0, 2.0 * h / 3.0, samples.pos[2], samples.vel[2], samples.dir[2])
    elif method == IMPLICIT_MIDPOINT:
        for i in range(n):
            for j in range(3):
                xb[i, j] = x[i, j] + 0.25 * h * v[i, j]
                va[i, j] = v[i, j]
                vb[i, j] = 0.5 * v[i, j]
        pos_mid = np.empty((2, 3))
        vel_mid = np.empty((2, 3))
        pos_mid[0] = 0.5 * (x[0] + samples.pos[2, 0])
        pos_mid[1] = 0.5 * (x[n - 1] + samples.pos[2, 1])
        vel_mid[0] = 0.5 * (v[0] + samples.vel[2, 0])
        vel_mid[1] = 0.5 * (v[n - 1] + samples.vel[2, 1])
        imp = ImplicitMap(0.25 * h, 0.5, h, pos_mid, vel_mid, samples.dir[1])
    else:
        xb[:, :] = x
        va[:, :] = v
        vb[:, :] = 0.0
        imp = ImplicitMap(h, 1.0, h, samples.pos[2], samples.vel[2], samples.dir[2])
    if method == BDF2:
        ws.x_prev[:, :] = x
        ws.v_prev[:, :] = v
    return imp


@njit(cache=True, error_model="numpy")
def _residual(m, imp, ws, vn, r, c=None):
    """r <- hf F(X, V) - M (v' - v_avg) [N s] on free nodes (0 on held), v' = vn; returns max |r|.

    With a contact set ``c`` (:class:`~bullet_dlo.core.kernels.contact.Contacts`) its forces at X, V
    (in c.node_force, and c.f_n, c.f_t) are added on the free nodes. Leaves X, V in ws.x_stage,
    ws.v_stage (read by :func:`_merit`).
    """
    worst = _cable_residual(m, imp, ws, vn, r)
    if c is None:
        return worst
    return _contact_residual(m, imp, ws, r, c)


@njit(cache=True, error_model="numpy", inline="always")  # inlined in Newton's cable-only loop (a call passing m
def _cable_residual(m, imp, ws, vn, r):                   # and ws cost ~0.5-1 us under Numba's own pipeline)
    """:func:`_residual` without contacts."""
    n = vn.shape[0]
    xe, ve, f = ws.x_stage, ws.v_stage, ws.force
    for i in range(n):
        for j in range(3):
            xe[i, j] = ws.x_base[i, j] + imp.cx * vn[i, j]
            ve[i, j] = ws.v_base[i, j] + imp.cv * vn[i, j]
    _set_held(m.held, xe, ve, imp.pos_end, imp.vel_end)
    total_forces(m, xe, ve, imp.dirs, f)
    worst = 0.0
    for i in range(n):
        for j in range(3):
            val = 0.0 if m.held[i] else imp.hf * f[i, j] - m.mass[i] * (vn[i, j] - ws.v_avg[i, j])
            r[3 * i + j] = val
            if not abs(val) <= worst:  # also catches NaN
                worst = abs(val)
    _last_use = m, imp, ws, vn, r  # (a last use after the branches: tests/llvm_loops.py)
    return worst


@njit(cache=True, error_model="numpy", inline="always")
def _contact_residual(m, imp, ws, r, c):
    """r += hf times the contact set ``c``'s forces at the X, V in ws.x_stage, ws.v_stage (into c.node_force,
    c.f_n, c.f_t) on the free nodes, r holding the rest of :func:`_residual` there; returns max |r|."""
    n = r.shape[0] // 3
    fc = c.node_force
    _contact.contact_forces(c, ws.x_stage, ws.v_stage, fc)
    worst = 0.0
    for i in range(n):
        for j in range(3):
            if not m.held[i]:
                r[3 * i + j] += imp.hf * fc[i, j]
            if not abs(r[3 * i + j]) <= worst:
                worst = abs(r[3 * i + j])
    _last_use = m, imp, ws, r, c  # (a last use after the branches: tests/llvm_loops.py)
    return worst


@njit(cache=True, error_model="numpy")
def _merit(m, imp, ws, vn, c=None):
    """Incremental potential whose gradient in v' is (cx/hf) * residual [J].

    Phi = (cx/hf) 1/2 |v' - v_avg|_M^2 + E_el(X) - (M g + f_ext) . X + (cx/cv) R(X, V), with R
    the Rayleigh dissipation of all damping terms (drag 1/2 |V|_C^2 and Kelvin-Voigt, quadratic in V;
    its X-dependence is not differentiated), plus the contact set ``c``'s potential when given, at
    the X, V left in ws.x_stage, ws.v_stage by the last residual call.
    """
    xe, ve = ws.x_stage, ws.v_stage
    cx, cv, hf = imp.cx, imp.cv, imp.hf
    phi = internal_energy(m, xe, imp.dirs) + (cx / cv) * dissipation(m, xe, ve, imp.dirs)
    for i in range(vn.shape[0]):
        for j in range(3):
            dv = vn[i, j] - ws.v_avg[i, j]
            phi += 0.5 * (cx / hf) * m.mass[i] * dv * dv
            phi -= (m.mass[i] * m.gravity[j] + m.f_ext[i, j]) * xe[i, j]
    if c is None:
        return phi
    return phi + _contact.contact_potential(c, xe, ve, cx / cv)


@njit(cache=True, error_model="numpy", inline="always")  # (a call passing m and ws: ~0.5 us under Numba's own pipeline)
def _momentum_change(m, ws, vn):
    """max over free nodes of m |v' - v_avg| [N s]: the scale of the residual tolerance."""
    dmom = 0.0
    for i in range(vn.shape[0]):
        if m.held[i]:
            continue
        for j in range(3):
            dmom = max(dmom, m.mass[i] * abs(vn[i, j] - ws.v_avg[i, j]))
    return dmom


@njit(cache=True, error_model="numpy")
def _newton_matrix(stepper, m, imp, ws, c=None):
    """ws.band <- the Newton matrix M - hf cx dF/dx - hf cv dF/dv (+ the contact set c's terms), block-banded."""
    _cable_matrix(stepper, m, imp, ws)
    if c is not None:
        _contact.add_contact_jacobian(c, m.held, ws.x_stage, imp.hf * imp.cx, imp.hf * imp.cv, ws.band)


@njit(cache=True, error_model="numpy", inline="always")  # inlined in Newton's cable-only loop
def _cable_matrix(stepper, m, imp, ws):
    """:func:`_newton_matrix` without contacts."""
    force_jacobian(m, ws.x_stage, imp.dirs, stepper.definite, ws.jacobian)
    add_damping_jacobian(m, ws.x_stage, imp.dirs, imp.cv / imp.cx, ws.jacobian)  # dF/dx + (cv/cx) dF/dv
    if has_drag(m):  # quadratic drag (checked here: a no-op call passing m cost ~0.5 us, Numba's pipeline)
        add_drag_jacobian(m, ws.x_stage, ws.v_stage, imp.cv / imp.cx, ws.jacobian)
    assemble_system(m, ws.jacobian, 1.0, imp.hf * imp.cx, imp.hf * imp.cv, ws.band)


CHORD_CONTRACTION = 0.1
"""The residual share [-] a Newton iteration must leave at most for the next to take the same factors (a chord
iteration, ``NewtonOptions.reuse_matrix``): a chord converges only linearly, so at a quarter a twisting step far from
its solution ran out of iterations (the study's cable turned three times in 1 s at 60 Hz: 6 of 90 steps); at a tenth
none did. Out of contact the frameless step keeps its last factors for the steps after (:func:`_kept`), and a step
that starts nearly converged (:data:`QUIET_START`) takes them: a settled cable then builds no matrix at all."""


@njit(cache=True, error_model="numpy", inline="always")
def extrapolate(held, v_avg, vn):
    """BDF2's first Newton iterate, in place: the free nodes' velocities vn (the current ones on entry) extrapolated
    linearly from the last two steps, v' = 2 v - v_prev (v_prev = 4 v - 3 v_avg, as BDF2's v_avg = (4 v - v_prev)
    / 3); held nodes keep their prescribed end-of-step velocities."""
    for i in range(vn.shape[0]):
        if not held[i]:
            for j in range(3):
                vn[i, j] = 3.0 * v_avg[i, j] - 2.0 * vn[i, j]


@njit(cache=True, error_model="numpy", inline="always")
def _kept(m, imp, ws):
    """Whether ws.band holds factors of an earlier step's matrix built with this step's hf, cx, cv and held nodes."""
    k = ws.matrices
    if k[1] != 1.0 or k[2] != imp.hf or k[3] != imp.cx or k[4] != imp.cv:
        return False
    for i in range(m.held.shape[0]):
        if k[KEPT + i] != (1.0 if m.held[i] else 0.0):
            return False
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _keep(m, imp, ws, kept):
    """Book the factors just left in ws.band (kept: whether a later step may take them)."""
    k = ws.matrices
    k[1] = 1.0 if kept else 0.0
    k[2], k[3], k[4] = imp.hf, imp.cx, imp.cv
    for i in range(m.held.shape[0]):
        k[KEPT + i] = 1.0 if m.held[i] else 0.0


@njit(cache=True, error_model="numpy")
def newton(stepper, m, x, imp, ws, c=None, cap_tol=1e-3, max_passes=10, bd=None):
    """Newton with line search on v' (in ws.v_new, started from the current velocity): the one
    solve of every implicit step, with the optional contact and grip terms of a contact set ``c``
    and then the free bodies ``bd`` solved with it (:class:`~bullet_dlo.core.kernels.contact.Bodies`,
    required with ``c``; kept out of ``c`` so that the contact kernels called several times per
    iteration do not pass its arrays).

    The system M (v' - v_avg) = hf F(X, V) (+ contact forces) is the stationarity condition of an
    incremental potential (see :func:`_merit`), so a line search on it cannot blow up from a poor
    linearisation. The Newton matrix M - hf cx dF/dx - hf cv dF/dv is block-banded (O(n) solve).

    Without contacts (``c`` None; Numba compiles that case without the contact code) a trial step
    is accepted when it lowers the residual or the potential, else halved (12 times at most); the
    first iteration of implicit Euler is the classical linearly implicit (Baraff-Witkin) step and
    later ones run only when its residual is above tolerance. With contacts only a potential
    decrease (with a round-off allowance) accepts a step (accepting residual decrease lets Newton
    cycle between stick and slide; 30 halvings at most), and the friction caps are an outer fixed
    point: re-taken from the converged X until they change by less than ``cap_tol`` (relative) or
    after ``max_passes`` passes (without free bodies each row's cap moves part way where it overshoots:
    :func:`~bullet_dlo.core.kernels.contact.relax_caps`); a solve without free bodies that ends more than
    :data:`~bullet_dlo.core.kernels.contact.RETRY_RATIO` times gravity's impulse in a step from convergence is taken
    again from the same start with the caps started from what stops each row within the step
    (:func:`~bullet_dlo.core.kernels.contact.bounded_caps`), and the closer of the two kept. Returns (iterations,
    converged).
    """
    n = x.shape[0]
    vn, v_try, r, r_try = ws.v_new, ws.v_try, ws.residual, ws.residual_try
    tol = stepper.tol
    # Residual scale: momentum gravity and external forces give in one step, and round-off
    # floor of stiff spring forces (k eps |x|) below which no iteration can go.
    # (one pass of scalar loops: the same maxima and sums as numpy's reductions, without their temporaries)
    g_norm = np.sqrt(0.0 + m.gravity[0] * m.gravity[0] + m.gravity[1] * m.gravity[1] + m.gravity[2] * m.gravity[2])
    xscale = 0.0
    phi_scale = 0.0  # the potential's scale (round-off allowance of the contact line search)
    mass_max = -np.inf
    fext_max = -np.inf
    for i in range(n):
        mass_max = max(mass_max, m.mass[i])
        for j in range(3):
            xscale = max(xscale, abs(x[i, j]))
            fext_max = max(fext_max, abs(m.f_ext[i, j]))
        if c is not None:
            phi_scale += m.mass[i] * g_norm * (abs(x[i, 0]) + abs(x[i, 1]) + abs(x[i, 2]) + 1.0)
    k_max = -np.inf
    for i in range(m.k_stretch.shape[0]):
        k_max = max(k_max, m.k_stretch[i])
    rest_max = -np.inf
    for i in range(m.rest_length.shape[0]):
        rest_max = max(rest_max, m.rest_length[i])
    r_scale = imp.hf * (mass_max * g_norm + fext_max) + 1e-300
    r_floor = 10.0 * 2.2e-16 * imp.hf * (k_max * (xscale + rest_max))
    it = 0
    converged = False
    if c is None:
        rnorm = _cable_residual(m, imp, ws, vn, r)
        # ws.band holds this step's last fresh matrix, eliminated (a chord iteration's), or an earlier step's where
        # this step starts within QUIET_START of converged (a settled or slowly loaded cable; QUIET_START: why)
        factored = (stepper.reuse and stepper.max_iter > 1 and rnorm <= QUIET_START * (tol * r_scale + r_floor)
                    and _kept(m, imp, ws))
        while it < stepper.max_iter:
            it += 1
            chord = factored
            if chord:
                ws.residual_kept[:] = r
                band_substitute(ws.band, r)
            else:
                _cable_matrix(stepper, m, imp, ws)
                band_solve(ws.band, r)  # r becomes the Newton direction dv
                ws.matrices[0] += 1.0
                factored = stepper.reuse
                _keep(m, imp, ws, factored)
            phi0 = np.nan
            alpha = 1.0
            accepted = False
            for _ in range(12):
                for i in range(n):
                    for j in range(3):
                        v_try[i, j] = vn[i, j] + alpha * r[3 * i + j]
                rn_try = _cable_residual(m, imp, ws, v_try, r_try)
                if rn_try < rnorm or rn_try <= tol * r_scale + r_floor:
                    accepted = True
                    break
                if chord:  # a chord direction is taken whole or not at all
                    break
                if phi0 != phi0:  # merit at the current iterate, computed once when first needed
                    _residual(m, imp, ws, vn, r_try)
                    phi0 = _merit(m, imp, ws, vn)
                    _residual(m, imp, ws, v_try, r_try)
                if _merit(m, imp, ws, v_try) <= phi0:
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                if chord:  # the old factors failed here: a fresh matrix at the same iterate (not counted)
                    factored = False
                    r[:] = ws.residual_kept
                    it -= 1
                    continue
                break  # stagnated: keep the current iterate (reported as not converged)
            vn[:, :] = v_try
            r[:] = r_try
            if rn_try > CHORD_CONTRACTION * rnorm:
                factored = False  # contracted poorly: a fresh matrix next
            rnorm = rn_try
            # residual tolerance relative to the momentum change of this step
            if rnorm <= tol * (r_scale + _momentum_change(m, ws, vn)) + r_floor:
                converged = True
                break
        return it, converged
    ws.matrices[1] = 0.0  # (the contact solve writes ws.band)
    nc = c.count[0]
    # bd: free bodies solved with the cable (their velocities: bd.vel_new, started by the caller)
    nb = np.int64(0)  # (a literal 0 is typed Literal[int](0) first: _contact_solve was compiled for both)
    for s in range(bd.active.shape[0]):
        nb += 1 if bd.active[s] else 0
    v_start = vn.copy()
    # a cable-only solve that ends beyond RETRY_RATIO times gravity's impulse from convergence (kept, it kicked a node
    # off a table at 2.7 m/s; coils on themselves were stopped as energy growth) is solved again from friction limits
    # bounded by the step's inertia (contact.bounded_caps), the closer kept; not a nearer miss, where from those limits
    # draped cables slid below the capstan threshold and a coil settled elsewhere (docs/concepts/contact.md, "Edges")
    it, converged, rnorm = _contact_solve(stepper, m, x, imp, ws, c, bd, nb, bool(0), cap_tol, max_passes, phi_scale,
                                          r_scale, r_floor)
    taken = True  # ws.residual and the rows' forces are those of vn with the caps in use (_contact_solve's return)
    if not converged and nb == 0 and _contact.stall_ratio(m, ws, imp.hf) > _contact.RETRY_RATIO:
        v_first, cap_first, r_first = vn.copy(), c.cap[:nc].copy(), rnorm
        vn[:, :] = v_start
        it_again, converged, rnorm = _contact_solve(stepper, m, x, imp, ws, c, bd, nb, bool(1), cap_tol, max_passes,
                                                    phi_scale, r_scale, r_floor)
        it += it_again
        if not converged and rnorm >= r_first:
            vn[:, :] = v_first
            c.cap[:nc] = cap_first
            taken = False
    if not converged:
        for k in range(nc):  # a row locked in a regime (solves with free bodies): its forces are taken again unlocked
            if c.lock[k] != 0:
                taken = False
    c.lock[:nc] = 0  # (converged: every row was in its Coulomb regime, so the forces are the unlocked ones)
    if not converged and not taken:  # (converged: the last residual was taken at vn, bodies' rows at vel_new)
        if nb > 0:
            _contact.load_bodies(c, bd, imp.hf, bd.vel_new)
        _residual(m, imp, ws, vn, r, c)  # forces and c.f_n, c.f_t at the accepted iterate
    return it, converged


@njit(cache=True, error_model="numpy")
def _contact_solve(stepper, m, x, imp, ws, c, bd, nb, bounded, cap_tol, max_passes, phi_scale, r_scale, r_floor):
    """:func:`newton`'s contact solve of the step from x [m] (its start) from the iterate in ws.v_new (and the free
    bodies' in bd.vel_new, ``nb`` of them active): Newton iterations with the friction caps frozen, the caps then an
    outer fixed point started from the predictor's penetration (``bounded``: bounded by the step's inertia,
    ``contact.bounded_caps``). Returns (Newton iterations, converged, the residual's norm [N s] at the last accepted
    iterate); ws.v_new holds that iterate and ws.residual, ws.x_stage, ws.v_stage and the rows' forces are its, taken
    with the caps and locks in use (however the solve ended)."""
    n = ws.v_new.shape[0]
    vn, v_try, r, r_try = ws.v_new, ws.v_try, ws.residual, ws.residual_try
    tol = stepper.tol
    nc = c.count[0]
    max_iter = max(stepper.max_iter, _contact.MIN_CONTACT_ITER)
    caps_new = np.empty(max(nc, 1))
    history = np.zeros((max(nc, 1), 2))  # (contact.relax_caps)
    it = 0
    converged = False
    if nb > 0:
        _contact.load_bodies(c, bd, imp.hf, bd.vel_new)
    _residual(m, imp, ws, vn, r)  # X at the predictor: caps from its penetration
    if bounded:
        _contact.bounded_caps(c, x, ws.x_stage, m.mass, m.held, imp.cx, imp.hf, c.cap)
    else:
        _contact.elastic_caps(c, ws.x_stage, c.cap)
    rnorm = _contact_residual(m, imp, ws, r, c)  # the first residual: the same X, V and elastic forces
    # ``fresh``: r, rnorm, ws.x_stage, v_stage and the contact forces are those of vn with the caps in use (the
    # first residual, or an accepted trial's): the loop does not take them again (each residual and its
    # contact forces are a pure function of vn, the caps and the bodies' rows, so they would come out the same)
    fresh = True
    passes = 0
    c.lock[:nc] = 0
    # the friction's stick-first active set (contact.lock_rows) in solves with free bodies, where Newton on the Huber
    # potential was measured cycling (docs/concepts/contact.md, "Friction in Newton"); cable-only solves keep it
    locking = nb > 0
    while True:
        if locking and _contact.lock_rows(c, ws.x_stage) > 0:  # (ws.x_stage: vn's X)
            fresh = False  # a row's friction at vn changed (locked to stick from slide)
        if not fresh:
            rnorm = _residual(m, imp, ws, vn, r, c)
        fresh = False
        if nb > 0:
            _contact.body_residual(c, bd, imp.hf, bd.vel_new)
        if (it > 0 and rnorm <= tol * (r_scale + _momentum_change(m, ws, vn)) + r_floor
                and (nb == 0 or _contact.bodies_converged(bd, imp.hf, tol, r_floor))):
            if locking and _contact.unlock_inconsistent(c, ws.x_stage) > 0:
                continue  # a locked row is in the wrong regime at this solution: solve on with it switched
            if _contact.caps_settled(c, ws.x_stage, caps_new, cap_tol) or passes >= max_passes or it >= max_iter:
                converged = True
                break
            passes += 1
            if nb == 0:  # a row whose cap overshoots between passes moves part way (relax_caps): a cable resting
                _contact.relax_caps(c, caps_new, history, passes)  # over a box edge cycled between two caps of its
            else:  # wrap row for ever; with free bodies whole (relaxed, a 3 kg box tipping off the cable was stopped)
                c.cap[:nc] = caps_new[:nc]
            continue
        if it >= max_iter:
            break
        it += 1
        _newton_matrix(stepper, m, imp, ws, c)
        phi0 = _merit(m, imp, ws, vn, c)
        if nb > 0:  # the bodies' velocities are unknowns too: their block and coupling, by a Schur complement
            phi0 += _contact.body_potential(bd, imp.hf, bd.vel_new)
            _contact.coupled_solve(c, bd, m.held, ws.x_stage, imp.hf * imp.cx, imp.hf * imp.cv, imp.hf, ws.band,
                                    r)
        else:
            band_solve(ws.band, r)  # r becomes the Newton direction
        alpha = 1.0
        accepted = False
        for _ in range(30):
            for i in range(n):
                for j in range(3):
                    v_try[i, j] = vn[i, j] + alpha * r[3 * i + j]
            if nb > 0:
                for s in range(bd.active.shape[0]):
                    for j in range(6):
                        bd.vel_try[s, j] = bd.vel_new[s, j] + alpha * bd.step[s, j]
                _contact.load_bodies(c, bd, imp.hf, bd.vel_try)
            rn_try = _residual(m, imp, ws, v_try, r_try, c)
            phi = _merit(m, imp, ws, v_try, c)
            if nb > 0:
                phi += _contact.body_potential(bd, imp.hf, bd.vel_try)
            if phi <= phi0 + 1e-13 * (abs(phi0) + phi_scale):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:  # r holds the Newton direction, the contact forces the last trial's: both of vn again
            if nb > 0:
                _contact.load_bodies(c, bd, imp.hf, bd.vel_new)
            rnorm = _residual(m, imp, ws, vn, r, c)
            break
        vn[:, :] = v_try
        r[:] = r_try  # the residual at the accepted iterate (the merit after it wrote nothing)
        rnorm = rn_try
        fresh = True
        if nb > 0:
            bd.vel_new[:, :] = bd.vel_try
    return it, converged, rnorm


@njit(cache=True, error_model="numpy", inline="always")  # (m, ws: ~0.5-1 us a call, Numba's pipeline)
def _start_implicit(method, m, x, v, h, samples, ws, has_prev):
    """The implicit method's affine map (see :func:`_implicit_map`) and Newton's first iterate in
    ws.v_new: the current velocities, held ends at their end-of-step velocities."""
    imp = _implicit_map(method, x, v, h, samples, ws, has_prev)
    n = x.shape[0]
    vn = ws.v_new
    vn[:, :] = v
    if m.held[0]:
        vn[0] = samples.vel[2, 0]
    if m.held[n - 1]:
        vn[n - 1] = samples.vel[2, 1]
    _last_use = m, samples, ws  # (a last use after the branches: tests/llvm_loops.py)
    return imp


@njit(cache=True, error_model="numpy", inline="always")
def _implicit(stepper, m, x, v, samples, ws, has_prev):
    """Implicit Euler, BDF2 or implicit midpoint: solve for v', then update x consistently."""
    method, h = stepper.method, stepper.h
    n = x.shape[0]
    imp = _start_implicit(method, m, x, v, h, samples, ws, has_prev)
    vn = ws.v_new
    if stepper.reuse and method == BDF2 and has_prev:
        extrapolate(m.held, ws.v_avg, vn)
    its, converged = newton(stepper, m, x, imp, ws)
    for i in range(n):
        for j in range(3):
            if method == IMPLICIT_MIDPOINT:
                x[i, j] += 0.5 * h * (v[i, j] + vn[i, j])
            elif method == BDF2 and has_prev:
                x[i, j] = ws.x_base[i, j] + imp.cx * vn[i, j]
            else:
                x[i, j] += h * vn[i, j]
    v[:, :] = vn
    _set_held(m.held, x, v, samples.pos[2], samples.vel[2])
    _last_use = m, x, ws, imp, samples  # (a last use after the branches: tests/llvm_loops.py)
    return its, converged


@njit(cache=True, error_model="numpy")
def advance(stepper, m, x, v, samples, ws, has_prev):
    """Advance (x, v) in place by one step of ``stepper`` (a :class:`Stepper`).

    samples: held-end poses at t, t + h/2, t + h; ws: scratch from :func:`make_workspace`;
    has_prev: whether ws.x_prev, ws.v_prev hold the state before this one (BDF2 falls back to
    implicit Euler without it). Returns (Newton iterations, converged); explicit methods
    return (0, True).
    """
    method, h = stepper.method, stepper.h
    twisting = has_twist(m)
    if twisting:
        twist_ready(m, x, samples.dir[0])
        set_clamp(m, 2 if method in (IMPLICIT_EULER, BDF2) else (1 if method in (IMPLICIT_MIDPOINT, GAUSS_LEGENDRE)
                                                                 else 0))
        if method in (IMPLICIT_EULER, BDF2, IMPLICIT_MIDPOINT):  # positions and twist in one Newton system
            return _twist_coupled.coupled_implicit(stepper, m, x, v, samples, ws, has_prev)
        if method == GAUSS_LEGENDRE:  # the twist in the collocation system
            return _twist_coupled.coupled_gauss_legendre(stepper, m, x, v, samples, ws)
        # the explicit methods: the twist angles and rates state of the method
        return _twist_coupled.explicit_twist(stepper, m, x, v, samples, ws, method)
    its, converged = 0, True
    if method == EXPLICIT_EULER:
        _explicit_euler(m, x, v, h, samples, ws)
    elif method == SYMPLECTIC_EULER:
        _symplectic_euler(m, x, v, h, samples, ws)
    elif method == RK4:
        _rk4(m, x, v, h, samples, ws)
    elif method == GAUSS_LEGENDRE:
        its, converged = gauss_legendre_step(stepper, m, x, v, samples)
    else:
        its, converged = _implicit(stepper, m, x, v, samples, ws, has_prev)
    return its, converged


# The contact and grip terms of :func:`newton` (contact.py imports this module, so the module object
# is bound here, after every name contact.py takes from it is defined; Numba resolves
# ``_contact.<name>`` when it compiles).
from bullet_dlo.core.kernels import contact as _contact  # noqa: E402
from bullet_dlo.core.kernels import twist_coupled as _twist_coupled  # noqa: E402  (the coupled twisting step)
