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

from .forces import force_jacobian, total_forces
from .linalg import assemble_system, band_solve, HALF
from .params import ParameterError

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

    max_iter: iterations per step (``implicit_euler`` always does exactly one: it is the
    linearly implicit method); tol: convergence when max|dv| <= tol * max(|v|, v_floor);
    definite: filter the compressive stretch Hessian so the system stays positive definite.
    """

    max_iter: int = 8
    tol: float = 1e-9
    definite: bool = True


# ----- helpers -------------------------------------------------------------------------------
@njit(cache=True)
def _set_held(x, v, held, pos, vel):
    """Put held nodes at the prescribed positions/velocities (pos, vel: (2, 3))."""
    n = x.shape[0]
    if held[0]:
        x[0, :] = pos[0]
        v[0, :] = vel[0]
    if held[n - 1]:
        x[n - 1, :] = pos[1]
        v[n - 1, :] = vel[1]


@njit(cache=True)
def _accel(x, v, m, dirs, f_ext, f, a):
    """a <- M^-1 F(x, v) with clamp directions dirs (2, 3)."""
    total_forces(x, v, m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity, dirs[0], dirs[1], f_ext, f)
    for i in range(x.shape[0]):
        for j in range(3):
            a[i, j] = f[i, j] / m.mass[i]


# ----- explicit methods -----------------------------------------------------------------------
@njit(cache=True)
def _explicit_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext):
    f = np.empty_like(x)
    a = np.empty_like(x)
    _accel(x, v, m, hold_dir[0], f_ext, f, a)
    x += h * v
    v += h * a
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


@njit(cache=True)
def _symplectic_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext):
    f = np.empty_like(x)
    a = np.empty_like(x)
    _accel(x, v, m, hold_dir[0], f_ext, f, a)
    v += h * a
    x += h * v
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


@njit(cache=True)
def _rk4(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext):
    f = np.empty_like(x)
    k1v = np.empty_like(x)
    k2v = np.empty_like(x)
    k3v = np.empty_like(x)
    k4v = np.empty_like(x)
    xs = x.copy()
    vs = v.copy()
    _set_held(xs, vs, m.held, hold_pos[0], hold_vel[0])
    k1x = vs.copy()
    _accel(xs, vs, m, hold_dir[0], f_ext, f, k1v)
    xs = x + 0.5 * h * k1x
    vs = v + 0.5 * h * k1v
    _set_held(xs, vs, m.held, hold_pos[1], hold_vel[1])
    k2x = vs.copy()
    _accel(xs, vs, m, hold_dir[1], f_ext, f, k2v)
    xs = x + 0.5 * h * k2x
    vs = v + 0.5 * h * k2v
    _set_held(xs, vs, m.held, hold_pos[1], hold_vel[1])
    k3x = vs.copy()
    _accel(xs, vs, m, hold_dir[1], f_ext, f, k3v)
    xs = x + h * k3x
    vs = v + h * k3v
    _set_held(xs, vs, m.held, hold_pos[2], hold_vel[2])
    k4x = vs.copy()
    _accel(xs, vs, m, hold_dir[2], f_ext, f, k4v)
    x += (h / 6.0) * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
    v += (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    _set_held(x, v, m.held, hold_pos[2], hold_vel[2])


# ----- implicit methods -----------------------------------------------------------------------
@njit(cache=True)
def _implicit(kind, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext, max_iter, tol, definite):
    """Newton on the end-of-step velocity v' for implicit Euler, BDF2 or implicit midpoint.

    Each method evaluates forces at X = xe0 + cx v', V = ve0 + cv v' and solves
    M (v' - av) = hf F(X, V); the Newton matrix M - hf cx dF/dx + hf cv C is block-banded.
    Returns (iterations, converged).
    """
    n = x.shape[0]
    held = m.held
    dirs = hold_dir[2]
    pos_e = hold_pos[2].copy()
    vel_e = hold_vel[2].copy()
    if kind == BDF2 and has_prev:
        xe0 = (4.0 * x - xp) / 3.0
        av = (4.0 * v - vp) / 3.0
        ve0 = np.zeros_like(v)
        cx, cv, hf = 2.0 * h / 3.0, 1.0, 2.0 * h / 3.0
    elif kind == IMPLICIT_MIDPOINT:
        xe0 = x + 0.25 * h * v
        av = v.copy()
        ve0 = 0.5 * v
        cx, cv, hf = 0.25 * h, 0.5, h
        dirs = hold_dir[1]
        pos_e[0] = 0.5 * (x[0] + hold_pos[2, 0])
        pos_e[1] = 0.5 * (x[n - 1] + hold_pos[2, 1])
        vel_e[0] = 0.5 * (v[0] + hold_vel[2, 0])
        vel_e[1] = 0.5 * (v[n - 1] + hold_vel[2, 1])
    else:  # implicit Euler (and the first BDF2 step)
        xe0 = x.copy()
        av = v.copy()
        ve0 = np.zeros_like(v)
        cx, cv, hf = h, 1.0, h
    iters = max_iter if kind != IMPLICIT_EULER else 1
    vn = v.copy()
    if held[0]:
        vn[0] = hold_vel[2, 0]
    if held[n - 1]:
        vn[n - 1] = hold_vel[2, 1]
    xe = np.empty_like(x)
    ve = np.empty_like(v)
    f = np.empty_like(x)
    jac = np.empty((n, 5, 3, 3))
    band = np.empty((3 * n, 2 * HALF + 1))
    rhs = np.empty(3 * n)
    converged = False
    it = 0
    while it < iters:
        it += 1
        for i in range(n):
            for j in range(3):
                xe[i, j] = xe0[i, j] + cx * vn[i, j]
                ve[i, j] = ve0[i, j] + cv * vn[i, j]
        _set_held(xe, ve, held, pos_e, vel_e)
        total_forces(xe, ve, m.mass, m.damp, m.k_stretch, m.rest_length, m.k_bend, m.gravity,
                     dirs[0], dirs[1], f_ext, f)
        for i in range(n):
            for j in range(3):
                rhs[3 * i + j] = 0.0 if held[i] else hf * f[i, j] - m.mass[i] * (vn[i, j] - av[i, j])
        force_jacobian(xe, m.k_stretch, m.rest_length, m.k_bend, dirs[0], dirs[1], definite, jac)
        assemble_system(jac, m.mass, m.damp, hf * cx, hf * cv, held, band)
        band_solve(band, rhs)
        step_size = 0.0
        vscale = 1e-9
        for i in range(n):
            for j in range(3):
                vn[i, j] += rhs[3 * i + j]
                step_size = max(step_size, abs(rhs[3 * i + j]))
                vscale = max(vscale, abs(vn[i, j]))
        if not (step_size == step_size):  # NaN: give up, the detector will report it
            break
        if step_size <= tol * vscale:
            converged = True
            break
    # position update consistent with each method
    if kind == IMPLICIT_MIDPOINT:
        x += 0.5 * h * (v + vn)
    elif kind == BDF2 and has_prev:
        x[:, :] = xe0 + cx * vn
    else:
        x += h * vn
    v[:, :] = vn
    _set_held(x, v, held, hold_pos[2], hold_vel[2])
    return it, converged or kind == IMPLICIT_EULER


@njit(cache=True)
def step_kernel(code, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext, max_iter, tol, definite):
    """Advance (x, v) in place by one step h [s] with method ``code``.

    For BDF2 the caller passes the previous state (xp, vp) and ``has_prev``; the kernel
    does not update them. hold_*: held-end samples at (t, t+h/2, t+h), shape (3, 2, 3).
    Returns (Newton iterations, converged); explicit methods return (0, True).
    """
    if code == EXPLICIT_EULER:
        _explicit_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext)
    elif code == SYMPLECTIC_EULER:
        _symplectic_euler(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext)
    elif code == RK4:
        _rk4(x, v, h, m, hold_pos, hold_vel, hold_dir, f_ext)
    else:
        return _implicit(code, x, v, xp, vp, has_prev, h, m, hold_pos, hold_vel, hold_dir, f_ext,
                         max_iter, tol, definite)
    return 0, True
