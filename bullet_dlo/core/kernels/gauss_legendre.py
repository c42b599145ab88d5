"""Two-stage Gauss-Legendre collocation (implicit Runge-Kutta, order 4) for the cable: one step, in place.

The method (Butcher tableau, c = 1/2 -+ sqrt(3)/6, b = (1/2, 1/2))::

    A = [[1/4,              1/4 - sqrt(3)/6],
         [1/4 + sqrt(3)/6,  1/4            ]]

is 4th order, A-stable (its stability function is the (2, 2) Pade approximant of exp, |R(i w h)| = 1:
no numerical damping of an undamped linear mode, no blow-up at any h omega) and symplectic. Its phase
error on a linear mode, 2 atan((w h / 2) / (1 - (w h)^2 / 12)) against w h, is 4th order in h.

For the cable's second-order system x' = v, M v' = F(x, v) the unknowns are the two stage velocities
V_1, V_2 (n, 3) each; the stage positions follow from them, X_s = x + h sum_q a_sq V_q, and the stage
accelerations K = A^-1 (V - v) / h. The stage equations, in momentum units [N s] like the other
implicit methods' residual,

    R_s = h F(X_s, V_s) - M sum_q (A^-1)_sq (V_q - v) = 0,    s = 1, 2,

are solved by a simplified Newton method (the same force Jacobians as the other implicit methods: dF/dx of
the elastic forces, dF/dv of the dampers and the drag; the dampers' x-dependence is not differentiated, as
there). The exact Jacobian of the stage system is

    dR_s/dV_q = h^2 a_sq dF/dx(X_s) + h delta_sq dF/dv(X_s, V_s) - M (A^-1)_sq;

with K = dF/dx and D = dF/dv taken once, at the mean of the two stage states, it is
-(A^-1 (x) M - h^2 A (x) K - h I (x) D), and A's eigenvectors T (A = T diag(lam, conj lam) T^-1, lam =
1/4 + i sqrt(3)/12) split it into one complex system per eigenvalue, C = M / lam - h^2 lam K - h D of the 3n
node unknowns, whose conjugate is the other's (Butcher's transformation, as in Radau5 and other implicit
Runge-Kutta codes): the Newton direction is dV_s = 2 Re(T_s0 C^-1 (T^-1 R)_0), one complex banded system of
scalar half-width 8 instead of the real 6n one of half-width 17 (at n = 12 its factorisation took 17.6 of a
48 us step). C's Hermitian part is positive definite where the other methods' matrix is (Re 1/lam = 3,
Re lam = 1/4), so it is factorised without pivoting. The factors are kept for the next iterations while each
cuts the residual at least 4x (:data:`CONTRACTION`), else made again at the current iterate; factors that do not
lower the residual at all are replaced at once. Where fresh factors of C do not lower it within four halvings
(their one Jacobian is no descent direction there: the first step from a released stiff cantilever, whose
stage states differ most) or leave more than a quarter of it (a cable buckling at 60 Hz: 16.7 iterations a step
against 12.9, three solves at the cap), the rest of the step takes the exact real Jacobian of the stage system,
node-major (node i's unknowns: stage 1 xyz, stage 2 xyz), banded with a scalar half-width of 6 * 2 + 5 = 17,
factorised without pivoting too (the symmetric part of A^-1 is 3 I). Before 2026-12-08 every step took that exact
matrix (S2, n = 12, 5 ms: 48 us a step, 4.6 iterations, against 33 us and 5.9 iterations now).
Convergence rules as in :func:`~bullet_dlo.core.kernels.steppers.newton`: a step is accepted when it
lowers the residual (halved up to 12 times, else the iteration stops and the step is reported as not
converged; there is no incremental potential to fall back on), converged when the residual is below
tol * (gravity impulse + momentum change of the step) + the round-off floor of the stiff springs.
Then x' = x + h (V_1 + V_2) / 2 and v' = v + h (K_1 + K_2) / 2 = v + sqrt(3) (V_2 - V_1).

Held nodes follow their prescribed poses at the stage times t + c_s h, interpolated from the step's
three samples (t, t + h/2, t + h: position, velocity, acceleration) by quintic Hermite polynomials on
the half step holding the stage (error O(h^6) in position); clamp directions by normalised linear
interpolation between the same samples (exact for fixed clamps; O(h^2) for turning ones). Scratch
arrays are allocated per step (about 1 us; kept out of the shared Workspace so that the other
methods' kernels do not carry them).
"""
from __future__ import annotations

import math

import numpy as np

from bullet_dlo.core.kernels.banded import HALF
from bullet_dlo.core.kernels.drag import add_drag_jacobian
from bullet_dlo.core.kernels.forces import BAND, add_damping_jacobian, force_jacobian, total_forces
from bullet_dlo.core.kernels.jit import njit

SQRT3 = math.sqrt(3.0)
C1 = 0.5 - SQRT3 / 6.0  # stage times as fractions of h
C2 = 0.5 + SQRT3 / 6.0
A11 = 0.25
A12 = 0.25 - SQRT3 / 6.0
A21 = 0.25 + SQRT3 / 6.0
A22 = 0.25
# A^-1 = 12 [[a22, -a12], [-a21, a11]] (det A = 1/12)
AI11 = 3.0
AI12 = 2.0 * SQRT3 - 3.0
AI21 = -3.0 - 2.0 * SQRT3
AI22 = 3.0
_LAMS, _VECS = np.linalg.eig(np.array([[A11, A12], [A21, A22]]))
LAM = complex(_LAMS[0])  # an eigenvalue of A, 1/4 +- i sqrt(3)/12 (the other is its conjugate)
_T = np.array([_VECS[:, 0], np.conj(_VECS[:, 0])]).T  # its eigenvector and the conjugate's: T
T0, T1 = complex(_T[0, 0]), complex(_T[1, 0])  # the first eigenvector's stage components
U0, U1 = (complex(u) for u in np.linalg.inv(_T)[0])  # the first row of T^-1
GL_HALF = 6 * BAND + 5  # scalar half-bandwidth of the exact real stage system: 17
CONTRACTION = 0.25  # a simplified Newton iteration must cut the residual at least this much, else a fresh Jacobian


@njit(cache=True, error_model="numpy")
def _hermite(p0, v0, a0, p1, v1, a1, span, u):
    """Quintic Hermite interpolant on an interval of length ``span`` [s] at u in [0, 1]: position [m] and
    velocity [m/s] from the end values p, v, a (scalars)."""
    u2 = u * u
    u3 = u2 * u
    u4 = u3 * u
    u5 = u4 * u
    h0 = 1.0 - 10.0 * u3 + 15.0 * u4 - 6.0 * u5
    h1 = u - 6.0 * u3 + 8.0 * u4 - 3.0 * u5
    h2 = 0.5 * (u2 - 3.0 * u3 + 3.0 * u4 - u5)
    h3 = 0.5 * (u3 - 2.0 * u4 + u5)
    h4 = -4.0 * u3 + 7.0 * u4 - 3.0 * u5
    h5 = 10.0 * u3 - 15.0 * u4 + 6.0 * u5
    d0 = -30.0 * u2 + 60.0 * u3 - 30.0 * u4
    d1 = 1.0 - 18.0 * u2 + 32.0 * u3 - 15.0 * u4
    d2 = 0.5 * (2.0 * u - 9.0 * u2 + 12.0 * u3 - 5.0 * u4)
    d3 = 0.5 * (3.0 * u2 - 8.0 * u3 + 5.0 * u4)
    d4 = -12.0 * u2 + 28.0 * u3 - 15.0 * u4
    d5 = 30.0 * u2 - 60.0 * u3 + 30.0 * u4
    s2 = span * span
    pos = p0 * h0 + v0 * span * h1 + a0 * s2 * h2 + a1 * s2 * h3 + v1 * span * h4 + p1 * h5
    vel = (p0 * d0 + v0 * span * d1 + a0 * s2 * d2 + a1 * s2 * d3 + v1 * span * d4 + p1 * d5) / span
    return pos, vel


@njit(cache=True, error_model="numpy")
def stage_holders(samples, c, h, pos, vel, dirs):
    """Held-end pose at t + c h (0 <= c <= 1) from the step's samples at t, t + h/2, t + h into pos [m],
    vel [m/s], dirs (unit), each (2, 3). A sample pair at rest (equal positions, zero velocities and
    accelerations) gives the pose exactly."""
    k0 = 0 if c <= 0.5 else 1
    u = (c - 0.5 * k0) / 0.5
    span = 0.5 * h
    for e in range(2):
        p0, p1 = samples.pos[k0, e], samples.pos[k0 + 1, e]
        v0, v1 = samples.vel[k0, e], samples.vel[k0 + 1, e]
        a0, a1 = samples.acc[k0, e], samples.acc[k0 + 1, e]
        rest = True
        for j in range(3):
            if p0[j] != p1[j] or v0[j] != 0.0 or v1[j] != 0.0 or a0[j] != 0.0 or a1[j] != 0.0:
                rest = False
        for j in range(3):
            if rest or span == 0.0:
                pos[e, j] = p0[j]
                vel[e, j] = v0[j]
            else:
                pos[e, j], vel[e, j] = _hermite(p0[j], v0[j], a0[j], p1[j], v1[j], a1[j], span, u)
        d0, d1 = samples.dir[k0, e], samples.dir[k0 + 1, e]
        norm = 0.0
        for j in range(3):
            dirs[e, j] = (1.0 - u) * d0[j] + u * d1[j]
            norm += dirs[e, j] * dirs[e, j]
        norm = math.sqrt(norm)
        if norm > 0.0:
            for j in range(3):
                dirs[e, j] /= norm


@njit(cache=True, error_model="numpy")
def _stage_states(m, x, h, vs, xs, vstage, hpos, hvel):
    """Stage positions X_s = x + h sum_q a_sq V_q and velocities V_s (held nodes at their stage poses)."""
    n = x.shape[0]
    for i in range(n):
        for j in range(3):
            xs[0, i, j] = x[i, j] + h * (A11 * vs[0, i, j] + A12 * vs[1, i, j])
            xs[1, i, j] = x[i, j] + h * (A21 * vs[0, i, j] + A22 * vs[1, i, j])
            vstage[0, i, j] = vs[0, i, j]
            vstage[1, i, j] = vs[1, i, j]
    for s in range(2):
        for e in range(2):
            i = 0 if e == 0 else n - 1
            if m.held[i]:
                for j in range(3):
                    xs[s, i, j] = hpos[s, e, j]
                    vstage[s, i, j] = hvel[s, e, j]


@njit(cache=True, error_model="numpy")
def _gl_residual(m, x, v, h, vs, xs, vstage, f, hpos, hvel, hdir, r):
    """r <- R_s (see the module docstring) [N s] on free nodes (0 on held), node-major (6n,); returns max |r|.
    Leaves the stage states in xs, vstage and their forces in f (2, n, 3)."""
    n = x.shape[0]
    _stage_states(m, x, h, vs, xs, vstage, hpos, hvel)
    total_forces(m, xs[0], vstage[0], hdir[0], f[0])
    total_forces(m, xs[1], vstage[1], hdir[1], f[1])
    worst = 0.0
    for i in range(n):
        for j in range(3):
            if m.held[i]:
                r[6 * i + j] = 0.0
                r[6 * i + 3 + j] = 0.0
                continue
            d0 = vs[0, i, j] - v[i, j]
            d1 = vs[1, i, j] - v[i, j]
            r0 = h * f[0, i, j] - m.mass[i] * (AI11 * d0 + AI12 * d1)
            r1 = h * f[1, i, j] - m.mass[i] * (AI21 * d0 + AI22 * d1)
            r[6 * i + j] = r0
            r[6 * i + 3 + j] = r1
            if not abs(r0) <= worst:  # also catches NaN
                worst = abs(r0)
            if not abs(r1) <= worst:
                worst = abs(r1)
    return worst


@njit(cache=True, error_model="numpy")
def _gl_matrix(m, h, xs, vstage, hdir, definite, jx, jv, band):
    """band <- -dR/dV (the Newton matrix of the stage system), node-major, half-width GL_HALF; held nodes as
    identity rows and columns. jx, jv: scratch (2, n, 5, 3, 3) for dF/dx and dF/dv at each stage."""
    n = xs.shape[1]
    held = m.held
    for s in range(2):
        force_jacobian(m, xs[s], hdir[s], definite, jx[s])
        jv[s, :, :, :, :] = 0.0
        add_damping_jacobian(m, xs[s], hdir[s], 1.0, jv[s])
        add_drag_jacobian(m, xs[s], vstage[s], 1.0, jv[s])
    band[:, :] = 0.0
    hh = h * h
    for i in range(n):
        for s in range(2):
            row0 = 6 * i + 3 * s
            if held[i]:
                for r in range(3):
                    band[row0 + r, GL_HALF] = 1.0
                continue
            for o in range(2 * BAND + 1):
                j = i + o - BAND
                if j < 0 or j >= n or held[j]:
                    continue
                for q in range(2):
                    a_sq = (A11 if q == 0 else A12) if s == 0 else (A21 if q == 0 else A22)
                    col0 = 6 * j + 3 * q
                    for r in range(3):
                        for c in range(3):
                            val = -hh * a_sq * jx[s, i, o, r, c]
                            if s == q:
                                val -= h * jv[s, i, o, r, c]
                            band[row0 + r, col0 + c - row0 - r + GL_HALF] += val
            for q in range(2):
                ai = (AI11 if q == 0 else AI12) if s == 0 else (AI21 if q == 0 else AI22)
                col0 = 6 * i + 3 * q
                for r in range(3):
                    dv = m.mass[i] * ai + (h * m.damp[i] if s == q else 0.0)
                    band[row0 + r, col0 + r - row0 - r + GL_HALF] += dv


@njit(cache=True, error_model="numpy")
def _gl_transformed_matrix(m, h, xs, vstage, hdir, definite, xm, vm, dm, jx, jv, band):
    """band <- C = M / lam - h^2 lam K - h D (module doc; complex, (3n, 2 HALF + 1)), K and D at the mean of the
    two stage states xs, vstage (and of the held ends' stage directions hdir); held nodes as identity rows and
    columns. xm, vm (n, 3), dm (2, 3), jx, jv (n, 5, 3, 3): scratch."""
    n = xs.shape[1]
    held = m.held
    for i in range(n):
        for j in range(3):
            xm[i, j] = 0.5 * (xs[0, i, j] + xs[1, i, j])
            vm[i, j] = 0.5 * (vstage[0, i, j] + vstage[1, i, j])
    for e in range(2):
        norm = 0.0
        for j in range(3):
            dm[e, j] = hdir[0, e, j] + hdir[1, e, j]
            norm += dm[e, j] * dm[e, j]
        norm = math.sqrt(norm)
        if norm > 0.0:
            for j in range(3):
                dm[e, j] /= norm
    force_jacobian(m, xm, dm, definite, jx)
    jv[:, :, :, :] = 0.0
    add_damping_jacobian(m, xm, dm, 1.0, jv)
    add_drag_jacobian(m, xm, vm, 1.0, jv)
    band[:, :] = 0.0
    ck = -h * h * LAM
    for i in range(n):
        if held[i]:
            for r in range(3):
                band[3 * i + r, HALF] = 1.0
            continue
        for o in range(2 * BAND + 1):
            j = i + o - BAND
            if j < 0 or j >= n or held[j]:
                continue
            for r in range(3):
                for c in range(3):
                    band[3 * i + r, 3 * j + c - 3 * i - r + HALF] = ck * jx[i, o, r, c] - h * jv[i, o, r, c]
        for r in range(3):
            band[3 * i + r, HALF] += m.mass[i] / LAM + h * m.damp[i]


@njit(cache=True, error_model="numpy")
def _gl_direction(band, r, w, dv):
    """dv <- the Newton direction (6n,) for the stage residual r (6n,, node-major) with the factors of C in band
    (module doc): w = (T^-1 R)_0 (3n, complex scratch), C^-1 w, dV_s = 2 Re(T_s0 C^-1 w)."""
    n = w.shape[0] // 3
    for i in range(n):
        for j in range(3):
            w[3 * i + j] = U0 * r[6 * i + j] + U1 * r[6 * i + 3 + j]
    gl_band_substitute(band, w, HALF)
    for i in range(n):
        for j in range(3):
            y = w[3 * i + j]
            dv[6 * i + j] = 2.0 * (T0 * y).real
            dv[6 * i + 3 + j] = 2.0 * (T1 * y).real


@njit(cache=True, error_model="numpy")
def gl_band_factor(band, half):
    """LU-factorise a general band matrix of half-width ``half`` stored as band[r, c - r + half] in place
    (Gaussian elimination without pivoting; the multipliers are kept below the diagonal). Returns min |pivot|."""
    size = band.shape[0]
    min_pivot = np.inf
    for k in range(size):
        piv = band[k, half]
        if abs(piv) < min_pivot:
            min_pivot = abs(piv)
        last = min(k + half, size - 1)
        for i in range(k + 1, last + 1):
            f = band[i, k - i + half] / piv
            band[i, k - i + half] = f
            if f == 0.0:
                continue
            for j in range(k + 1, last + 1):
                band[i, j - i + half] -= f * band[k, j - k + half]
    return min_pivot


@njit(cache=True, error_model="numpy")
def gl_band_substitute(band, rhs, half):
    """Solve L U y = rhs in place with the factors of :func:`gl_band_factor`."""
    size = rhs.shape[0]
    for k in range(size):
        last = min(k + half, size - 1)
        for i in range(k + 1, last + 1):
            rhs[i] -= band[i, k - i + half] * rhs[k]
    for k in range(size - 1, -1, -1):
        acc = rhs[k]
        last = min(k + half, size - 1)
        for j in range(k + 1, last + 1):
            acc -= band[k, j - k + half] * rhs[j]
        rhs[k] = acc / band[k, half]


@njit(cache=True, error_model="numpy")
def gl_band_solve(band, rhs, half):
    """Solve band * y = rhs in place for a general band matrix of half-width ``half`` stored as
    band[r, c - r + half] (Gaussian elimination without pivoting; band destroyed). Returns min |pivot|."""
    min_pivot = gl_band_factor(band, half)
    gl_band_substitute(band, rhs, half)
    return min_pivot


@njit(cache=True, error_model="numpy")
def gauss_legendre_step(stepper, m, x, v, samples):
    """Advance (x, v) [m, m/s] in place by one 2-stage Gauss-Legendre step of ``stepper`` (h, Newton settings).

    samples: the held ends at t, t + h/2, t + h (:class:`~bullet_dlo.core.kernels.holders.HeldSamples`).
    Returns (Newton iterations, converged). Held nodes end at the pose of the t + h sample.
    """
    h = stepper.h
    n = x.shape[0]
    hpos = np.empty((2, 2, 3))
    hvel = np.empty((2, 2, 3))
    hdir = np.empty((2, 2, 3))
    stage_holders(samples, C1, h, hpos[0], hvel[0], hdir[0])
    stage_holders(samples, C2, h, hpos[1], hvel[1], hdir[1])
    vs = np.empty((2, n, 3))
    v_try = np.empty((2, n, 3))
    xs = np.empty((2, n, 3))
    vstage = np.empty((2, n, 3))
    f = np.empty((2, n, 3))
    r = np.empty(6 * n)
    r_try = np.empty(6 * n)
    dv = np.empty(6 * n)
    jx = np.empty((2, n, 2 * BAND + 1, 3, 3))  # (the transformed matrix uses the first stage's slot)
    jv = np.empty((2, n, 2 * BAND + 1, 3, 3))
    xm = np.empty((n, 3))
    vm = np.empty((n, 3))
    dm = np.empty((2, 3))
    band = np.empty((3 * n, 2 * HALF + 1), dtype=np.complex128)
    w = np.empty(3 * n, dtype=np.complex128)
    exact_band = np.empty((0, 2 * GL_HALF + 1))  # the exact real matrix, made where the transformed one fails
    # first iterate: the current velocities (held nodes at their stage velocities); a guess v + c_s h a from
    # the forces at x was tried: the stiff stretch modes make it worse (5.9 against 4.2 iterations, S2 n = 20, 5 ms)
    for s in range(2):
        for i in range(n):
            for j in range(3):
                vs[s, i, j] = v[i, j]
        for e in range(2):
            i = 0 if e == 0 else n - 1
            if m.held[i]:
                for j in range(3):
                    vs[s, i, j] = hvel[s, e, j]
    # residual scale and round-off floor, as in steppers.newton (hf = h)
    g_norm = math.sqrt(m.gravity[0] ** 2 + m.gravity[1] ** 2 + m.gravity[2] ** 2)
    xscale = 0.0
    mass_max = -np.inf
    fext_max = -np.inf
    for i in range(n):
        mass_max = max(mass_max, m.mass[i])
        for j in range(3):
            xscale = max(xscale, abs(x[i, j]))
            fext_max = max(fext_max, abs(m.f_ext[i, j]))
    k_max = -np.inf
    for i in range(m.k_stretch.shape[0]):
        k_max = max(k_max, m.k_stretch[i])
    rest_max = -np.inf
    for i in range(m.rest_length.shape[0]):
        rest_max = max(rest_max, m.rest_length[i])
    r_scale = h * (mass_max * g_norm + fext_max) + 1e-300
    r_floor = 10.0 * 2.2e-16 * h * (k_max * (xscale + rest_max))
    tol = stepper.tol
    rnorm = _gl_residual(m, x, v, h, vs, xs, vstage, f, hpos, hvel, hdir, r)
    it = 0
    converged = False
    refresh = True  # factorise the Jacobian at the current iterate in this iteration
    exact = False  # the exact real matrix instead of the transformed one (for the rest of the step)
    while it < stepper.max_iter:
        it += 1
        fresh = refresh  # is the factorised matrix the Jacobian at the current iterate?
        if refresh and exact:
            if exact_band.shape[0] == 0:
                exact_band = np.empty((6 * n, 2 * GL_HALF + 1))
            _gl_matrix(m, h, xs, vstage, hdir, stepper.definite, jx, jv, exact_band)
            gl_band_factor(exact_band, GL_HALF)
            refresh = False
        elif refresh:
            _gl_transformed_matrix(m, h, xs, vstage, hdir, stepper.definite, xm, vm, dm, jx[0], jv[0], band)
            gl_band_factor(band, HALF)
            refresh = False
        if exact:
            dv[:] = r
            gl_band_substitute(exact_band, dv, GL_HALF)
        else:
            _gl_direction(band, r, w, dv)  # the Newton direction dV (simplified: an older matrix)
        alpha = 1.0
        accepted = False
        rn_try = rnorm
        for _ in range(12 if fresh and exact else (4 if fresh else 1)):
            for s in range(2):
                for i in range(n):
                    for j in range(3):
                        v_try[s, i, j] = vs[s, i, j] + alpha * dv[6 * i + 3 * s + j]
            rn_try = _gl_residual(m, x, v, h, v_try, xs, vstage, f, hpos, hvel, hdir, r_try)
            if rn_try < rnorm or rn_try <= tol * r_scale + r_floor:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if fresh and exact:
                break  # stagnated with the exact Jacobian: keep the current iterate (reported as not converged)
            if fresh:  # the transformed matrix's one Jacobian is no descent direction here: the exact matrix
                exact = True
            # the old matrix no longer contracts: the stage states back at the iterate, then a fresh Jacobian
            rnorm = _gl_residual(m, x, v, h, vs, xs, vstage, f, hpos, hvel, hdir, r)
            refresh = True
            it -= 1  # a rejected simplified iteration is not counted
            continue
        refresh = rn_try > CONTRACTION * rnorm  # slow contraction: refresh the Jacobian next iteration
        if refresh and fresh and not exact:
            exact = True  # fresh factors of C contracted slowly: its one Jacobian does not serve this step
        vs[:, :, :] = v_try
        r[:] = r_try
        rnorm = rn_try
        dmom = 0.0  # momentum change of the step, max over free nodes and stages of m |V_s - v|
        for i in range(n):
            if m.held[i]:
                continue
            for s in range(2):
                for j in range(3):
                    dmom = max(dmom, m.mass[i] * abs(vs[s, i, j] - v[i, j]))
        if rnorm <= tol * (r_scale + dmom) + r_floor:
            converged = True
            break
    for i in range(n):
        for j in range(3):
            x[i, j] += 0.5 * h * (vs[0, i, j] + vs[1, i, j])
            v[i, j] += SQRT3 * (vs[1, i, j] - vs[0, i, j])
    for e in range(2):  # held nodes exactly at the end-of-step pose
        i = 0 if e == 0 else n - 1
        if m.held[i]:
            for j in range(3):
                x[i, j] = samples.pos[2, e, j]
                v[i, j] = samples.vel[2, e, j]
    return it, converged
