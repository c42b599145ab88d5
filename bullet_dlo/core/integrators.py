"""Time integrators behind one interface (Numba kernels + a small registry).

Every method advances (x, v) by one fixed step h given the model arrays, the held-end
samples at t, t+h/2 and t+h, and optional external forces. Methods:

=====================  =====  ========================================================
name                   order  character
=====================  =====  ========================================================
``explicit_euler``     1      forward Euler; adds energy, needs damping *and* tiny steps
``symplectic_euler``   1      v then x (Gazebo, Isaac Sim, Lv, Bullet); stable for h < ~2/omega_max
``rk4``                4      classic Runge-Kutta; stable for h < ~2.8/omega_max
``implicit_euler``     1      linearly implicit backward Euler, one banded O(n) solve; L-stable,
                              damps stiff (and, at large h, slow) modes
``bdf2``               2      backward differentiation, Newton on a banded system; L-stable,
                              damps stiff modes but keeps the slow dynamics
``implicit_midpoint``  2      symplectic and A-stable, Newton; no numerical damping at all
=====================  =====  ========================================================

Held nodes are kinematic: after every step they sit exactly at the prescribed pose.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from bullet_dlo.core.kernels.banded import HALF, assemble_system, band_solve
from bullet_dlo.core.kernels.forces import force_jacobian, internal_energy, total_forces
from bullet_dlo.core.validate import ParameterError

EXPLICIT_EULER, SYMPLECTIC_EULER, RK4, IMPLICIT_EULER, BDF2, IMPLICIT_MIDPOINT = range(6)


@dataclass(frozen=True)
class Integrator:
    """Description of a time integration method (the kernels are selected by ``code``)."""

    name: str
    code: int
    order: int
    explicit: bool
    summary: str


INTEGRATORS: dict[str, Integrator] = {
    i.name: i
    for i in (
        Integrator("explicit_euler", EXPLICIT_EULER, 1, True, "forward Euler"),
        Integrator("symplectic_euler", SYMPLECTIC_EULER, 1, True, "semi-implicit Euler (velocity first)"),
        Integrator("rk4", RK4, 4, True, "classic 4th-order Runge-Kutta"),
        Integrator("implicit_euler", IMPLICIT_EULER, 1, False, "linearly implicit backward Euler"),
        Integrator("bdf2", BDF2, 2, False, "2nd-order backward differentiation (Newton)"),
        Integrator("implicit_midpoint", IMPLICIT_MIDPOINT, 2, False, "implicit midpoint rule (Newton)"),
    )
}


def get_integrator(name: str) -> Integrator:
    """Look up an integrator by name; unknown names raise ParameterError listing the choices."""
    if isinstance(name, Integrator):
        return name
    key = str(name).lower()
    if key not in INTEGRATORS:
        raise ParameterError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {name!r}")
    return INTEGRATORS[key]


@dataclass(frozen=True)
class NewtonOptions:
    """Newton settings for implicit methods.

    max_iter: Newton iterations per step at most (``max_iter=1`` makes ``implicit_euler`` the
    pure linearly implicit method); tol: convergence when the momentum residual is below
    tol * (momentum change of the step + gravity impulse) plus the round-off floor. None picks
    the method's default: 1e-3 for ``implicit_euler`` (its first-order error dwarfs a finer
    solve, so a second iteration runs only when the linearisation visibly failed) and 1e-6
    for the second-order methods; definite: filter the compressive stretch Hessian so the
    system stays positive definite.
    """

    max_iter: int = 8
    tol: float | None = None
    definite: bool = True

    def tolerance(self, integrator: str) -> float:
        """The residual tolerance used for ``integrator``."""
        if self.tol is not None:
            return self.tol
        return 1e-3 if get_integrator(integrator).name == "implicit_euler" else 1e-6


# ----- helpers -------------------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _set_held(x, v, held, pos, vel):
    """Put held nodes at the prescribed positions/velocities (pos, vel: (2, 3))."""
    n = x.shape[0]
    if held[0]:
        x[0, :] = pos[0]
        v[0, :] = vel[0]
    if held[n - 1]:
        x[n - 1, :] = pos[1]
        v[n - 1, :] = vel[1]


@njit(cache=True, error_model="numpy")
def _accel(x, v, m, dirs, f_ext, f, a):
    """a <- M^-1 F(x, v) with clamp directions dirs (2, 3)."""
    total_forces(x, v, m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity, dirs[0], dirs[1], f_ext, f)
    for i in range(x.shape[0]):
        for j in range(3):
            a[i, j] = f[i, j] / m.mass[i]


# ----- explicit methods -----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _explicit_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W):
    f, a = W[0], W[1]
    _accel(x, v, m, hold_dir[0], f_ext, f, a)
    x += h * v
    v += h * a
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


@njit(cache=True, error_model="numpy")
def _symplectic_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W):
    f, a = W[0], W[1]
    _accel(x, v, m, hold_dir[0], f_ext, f, a)
    v += h * a
    x += h * v
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


@njit(cache=True, error_model="numpy")
def _rk4_stage(x, v, kx_prev, kv_prev, c, h, m, pos, vel, dirs, f_ext, f, xs, vs, kx, kv):
    """Stage state (x, v) + c h (kx_prev, kv_prev), held ends at (pos, vel); its slopes into kx, kv."""
    for i in range(x.shape[0]):
        for j in range(3):
            xs[i, j] = x[i, j] + c * h * kx_prev[i, j]
            vs[i, j] = v[i, j] + c * h * kv_prev[i, j]
    _set_held(xs, vs, m.held, pos, vel)
    kx[:, :] = vs
    _accel(xs, vs, m, dirs, f_ext, f, kv)


@njit(cache=True, error_model="numpy")
def _rk4(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W):
    f, xs, vs = W[0], W[1], W[2]
    k1x, k1v, k2x, k2v, k3x, k3v, k4x, k4v = W[3], W[4], W[5], W[6], W[7], W[8], W[9], W[10]
    _rk4_stage(x, v, k1x, k1v, 0.0, h, m, hold_pos[0], hold_vel[0], hold_dir[0], f_ext, f, xs, vs, k1x, k1v)
    _rk4_stage(x, v, k1x, k1v, 0.5, h, m, hold_pos[1], hold_vel[1], hold_dir[1], f_ext, f, xs, vs, k2x, k2v)
    _rk4_stage(x, v, k2x, k2v, 0.5, h, m, hold_pos[1], hold_vel[1], hold_dir[1], f_ext, f, xs, vs, k3x, k3v)
    _rk4_stage(x, v, k3x, k3v, 1.0, h, m, hold_pos[2], hold_vel[2], hold_dir[2], f_ext, f, xs, vs, k4x, k4v)
    for i in range(x.shape[0]):
        for j in range(3):
            x[i, j] += (h / 6.0) * (k1x[i, j] + 2.0 * k2x[i, j] + 2.0 * k3x[i, j] + k4x[i, j])
            v[i, j] += (h / 6.0) * (k1v[i, j] + 2.0 * k2v[i, j] + 2.0 * k3v[i, j] + k4v[i, j])
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


# ----- implicit methods -----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def _residual(vn, xe0, cx, ve0, cv, av, hf, m, pos_e, vel_e, dirs, f_ext, xe, ve, f, r):
    """r <- hf F(X, V) - M (v' - av) on free nodes (0 on held), X = xe0 + cx v', V = ve0 + cv v'.

    Returns max |r| [N s].
    """
    n = vn.shape[0]
    for i in range(n):
        for j in range(3):
            xe[i, j] = xe0[i, j] + cx * vn[i, j]
            ve[i, j] = ve0[i, j] + cv * vn[i, j]
    _set_held(xe, ve, m.held, pos_e, vel_e)
    total_forces(xe, ve, m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity,
                 dirs[0], dirs[1], f_ext, f)
    worst = 0.0
    for i in range(n):
        for j in range(3):
            val = 0.0 if m.held[i] else hf * f[i, j] - m.mass[i] * (vn[i, j] - av[i, j])
            r[3 * i + j] = val
            if not abs(val) <= worst:  # also catches NaN
                worst = abs(val)
    return worst


@njit(cache=True, error_model="numpy")
def _merit(vn, xe, ve, av, cx, cv, hf, m, dirs, f_ext):
    """Incremental potential whose gradient in v' is (cx/hf) * residual [J].

    Phi = (cx/hf) 1/2 |v' - av|_M^2 + E_el(X) - (M g + f_ext) . X + (cx/cv) 1/2 |V|_C^2,
    evaluated at the X, V left in xe, ve by the last residual call.
    """
    phi = internal_energy(xe, m.k_stretch, m.rest_length, m.k_bend, dirs[0], dirs[1])
    for i in range(vn.shape[0]):
        for j in range(3):
            dv = vn[i, j] - av[i, j]
            phi += 0.5 * (cx / hf) * m.mass[i] * dv * dv
            phi -= (m.mass[i] * m.gravity[j] + f_ext[i, j]) * xe[i, j]
            phi += 0.5 * (cx / cv) * m.damp[i] * ve[i, j] * ve[i, j]
    return phi


@njit(cache=True, error_model="numpy")
def _implicit(kind, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext, max_iter, tol, definite, W):
    """Newton with line search on the end-of-step velocity v' (implicit Euler, BDF2, midpoint).

    Each method evaluates forces at X = xe0 + cx v', V = ve0 + cv v' and solves
    M (v' - av) = hf F(X, V). That is the stationarity condition of an incremental
    potential (see ``_merit``), so a step that lowers the residual or the potential is
    accepted and otherwise halved: no blow-up from a poor linearisation. The Newton matrix
    M - hf cx dF/dx + hf cv C is block-banded (O(n) solve). The first iteration of implicit
    Euler is the classical linearly implicit (Baraff-Witkin) step; later iterations run only
    when its residual is above tolerance (large held-end jumps, strong nonlinearity).
    Returns (iterations, converged).
    """
    n = x.shape[0]
    held = m.held
    dirs = hold_dir[2]
    pos_e = hold_pos[2].copy()
    vel_e = hold_vel[2].copy()
    xe0, av, ve0 = W[0], W[1], W[2]
    if kind == BDF2 and has_prev:
        for i in range(n):
            for j in range(3):
                xe0[i, j] = (4.0 * x[i, j] - xp[i, j]) / 3.0
                av[i, j] = (4.0 * v[i, j] - vp[i, j]) / 3.0
                ve0[i, j] = 0.0
        cx, cv, hf = 2.0 * h / 3.0, 1.0, 2.0 * h / 3.0
    elif kind == IMPLICIT_MIDPOINT:
        for i in range(n):
            for j in range(3):
                xe0[i, j] = x[i, j] + 0.25 * h * v[i, j]
                av[i, j] = v[i, j]
                ve0[i, j] = 0.5 * v[i, j]
        cx, cv, hf = 0.25 * h, 0.5, h
        dirs = hold_dir[1]
        pos_e[0] = 0.5 * (x[0] + hold_pos[2, 0])
        pos_e[1] = 0.5 * (x[n - 1] + hold_pos[2, 1])
        vel_e[0] = 0.5 * (v[0] + hold_vel[2, 0])
        vel_e[1] = 0.5 * (v[n - 1] + hold_vel[2, 1])
    else:  # implicit Euler (and the first BDF2 step)
        xe0[:, :] = x
        av[:, :] = v
        ve0[:, :] = 0.0
        cx, cv, hf = h, 1.0, h
    vn, xe, ve, f, v_try = W[3], W[4], W[5], W[6], W[7]
    vn[:, :] = v
    if held[0]:
        vn[0] = hold_vel[2, 0]
    if held[n - 1]:
        vn[n - 1] = hold_vel[2, 1]
    r = W[8].reshape(3 * n)
    r_try = W[9].reshape(3 * n)
    jac = W[10:25].reshape((n, 5, 3, 3))
    band = W[25:25 + 2 * HALF + 1].reshape((3 * n, 2 * HALF + 1))
    # Residual scale: momentum gravity and external forces give in one step, and round-off
    # floor of stiff spring forces (k eps |x|) below which no iteration can go.
    g_norm = np.sqrt(np.sum(m.gravity ** 2))
    xscale = 0.0
    for i in range(n):
        for j in range(3):
            xscale = max(xscale, abs(x[i, j]))
    r_scale = hf * (np.max(m.mass) * g_norm + np.max(np.abs(f_ext))) + 1e-300
    r_floor = 10.0 * 2.2e-16 * hf * (np.max(m.k_stretch) * (xscale + np.max(m.rest_length)))
    rnorm = _residual(vn, xe0, cx, ve0, cv, av, hf, m, pos_e, vel_e, dirs, f_ext, xe, ve, f, r)
    it = 0
    converged = False
    while it < max_iter:
        it += 1
        force_jacobian(xe, m.k_stretch, m.rest_length, m.k_bend, dirs[0], dirs[1], definite, jac)
        assemble_system(jac, m.mass, m.damp, hf * cx, hf * cv, held, band)
        band_solve(band, r)  # r becomes the Newton direction dv
        phi0 = np.nan
        alpha = 1.0
        accepted = False
        for _ in range(12):
            for i in range(n):
                for j in range(3):
                    v_try[i, j] = vn[i, j] + alpha * r[3 * i + j]
            rn_try = _residual(v_try, xe0, cx, ve0, cv, av, hf, m, pos_e, vel_e, dirs, f_ext, xe, ve, f, r_try)
            if rn_try < rnorm or rn_try <= tol * r_scale + r_floor:
                accepted = True
                break
            if phi0 != phi0:  # merit at the current iterate, computed once when first needed
                _residual(vn, xe0, cx, ve0, cv, av, hf, m, pos_e, vel_e, dirs, f_ext, xe, ve, f, r_try)
                phi0 = _merit(vn, xe, ve, av, cx, cv, hf, m, dirs, f_ext)
                _residual(v_try, xe0, cx, ve0, cv, av, hf, m, pos_e, vel_e, dirs, f_ext, xe, ve, f, r_try)
            if _merit(v_try, xe, ve, av, cx, cv, hf, m, dirs, f_ext) <= phi0:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break  # stagnated: keep the current iterate (reported as not converged)
        vn[:, :] = v_try
        r[:] = r_try
        rnorm = rn_try
        # residual tolerance relative to the momentum change of this step
        dmom = 0.0
        for i in range(n):
            if held[i]:
                continue
            for j in range(3):
                dmom = max(dmom, m.mass[i] * abs(vn[i, j] - av[i, j]))
        if rnorm <= tol * (r_scale + dmom) + r_floor:
            converged = True
            break
    # position update consistent with each method
    for i in range(n):
        for j in range(3):
            if kind == IMPLICIT_MIDPOINT:
                x[i, j] += 0.5 * h * (v[i, j] + vn[i, j])
            elif kind == BDF2 and has_prev:
                x[i, j] = xe0[i, j] + cx * vn[i, j]
            else:
                x[i, j] += h * vn[i, j]
    v[:, :] = vn
    _set_held(x, v, held, hold_pos[2], hold_vel[2])
    return it, converged


WORK_SLOTS = 25 + 2 * HALF + 1  # (n, 3) slots of the integrator workspace


def workspace(n: int) -> np.ndarray:
    """Scratch memory for :func:`step_kernel` (so that no step allocates), shape (WORK_SLOTS, n, 3)."""
    return np.zeros((WORK_SLOTS, n, 3))


@njit(cache=True, error_model="numpy")
def step_kernel(code, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext, max_iter, tol, definite, W):
    """Advance (x, v) in place by one step h [s] with method ``code``.

    For BDF2 the caller passes the previous state (xp, vp) and ``has_prev``; the kernel
    does not update them. hold_*: held-end samples at (t, t+h/2, t+h), shape (3, 2, 3).
    W: workspace from :func:`workspace`. Returns (Newton iterations, converged); explicit
    methods return (0, True).
    """
    if code == EXPLICIT_EULER:
        _explicit_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W)
    elif code == SYMPLECTIC_EULER:
        _symplectic_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W)
    elif code == RK4:
        _rk4(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext, W)
    else:
        return _implicit(code, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext,
                         max_iter, tol, definite, W)
    return 0, True
