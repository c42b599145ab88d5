"""Linear stability analysis: predicted critical time steps and damping bounds.

Linearising the cable about a state (default: straight, at rest, ends held as the model
says) gives M x'' + C x' + K x = 0 on the free degrees of freedom, with C = c M + tau K:
drag at the rate c = :attr:`CableSpec.mass_damping_rate` [1/s] and Kelvin-Voigt internal
damping with retardation time tau = ``internal_damping`` [s] (exact about a straight
unstressed cable; about a stressed one the geometric stiffness is left out of tau K). The
modes decouple: mode k (omega_k^2 an eigenvalue of M^-1 K) has the damping rate
gamma_k = c + tau omega_k^2 and eigenvalues lambda = -gamma_k/2 +- sqrt(gamma_k^2/4 - omega_k^2).
Internal damping makes the stiff modes overdamped with a fast real eigenvalue near
-tau omega^2, so it *lowers* the explicit methods' critical steps (about 2 / (tau omega_max^2)).
A fixed-step method is stable when every mode is:

* explicit Euler:   |1 + h lambda| <= 1          ->  h <= -2 Re(lambda) / |lambda|^2
                    (h <= gamma / omega^2 for an underdamped mode: no damping, no stability)
* symplectic Euler: amplification [[1 - h^2 w^2, h(1 - h g)], [-h w^2, 1 - h g]]
                    ->  h <= (-gamma + sqrt(gamma^2 + 4 omega^2)) / omega^2  and  h <= 2 / gamma
                    (2 / omega_max without damping)
* RK4:              |1 + z + z^2/2 + z^3/6 + z^4/24| <= 1 along the ray z = h lambda
                    (2 sqrt(2) / omega_max without damping)
* implicit Euler, BDF2, implicit midpoint: A-stable, no limit for the linear problem.

A cable with a material frame (issue 22) has two more kinds of modes. Anisotropic bending: the stiff
axis's bending modes (E I2 > E I1 for a strip) are in :func:`stiffness_spectrum`, since the force
Jacobian carries the anisotropic bending (exact about a straight cable), so :func:`critical_dt` covers
them. Twist: n - 1 torsional modes, a chain of segment inertias I = rho J_p l0 and springs G J / l0, up to
omega_t = (2 / l0) sqrt(G J / (rho J_p)) (:func:`twist_frequency`; for a round section the torsion
wave speed sqrt(G / rho) over half a segment, typically 10-100x the highest bending frequency). The
implicit methods solve the twist with the positions (A-stable: no critical step; at steps h >> 1/omega_t
the twist is left quasi-static, which is what a rod with a material frame does at those time scales); the
explicit methods carry it through their stages, so :func:`critical_dt` adds the twist chain's modes
(:func:`twist_spectrum`, damped by drag at c like the other modes and by Kelvin-Voigt twist dampers at
tau omega^2). They never set the limit: omega_t / omega_stretch = sqrt(G J / (E J_p)) <= 1 / sqrt(2 (1 + nu))
(J <= J_p), so the stretch modes stay the fastest.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigvals_banded

from bullet_dlo.core.integrators import get_integrator
from bullet_dlo.core.kernels.forces import force_jacobian
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec


def stiffness_spectrum(model: CableModel, state: CableState | None = None) -> np.ndarray:
    """Eigenvalues omega^2 [1/s^2] of M^-1 K on the free DOFs, ascending, shape (3 n_free,).

    K = -dF/dx (exact, undamped) evaluated at ``state`` (default: the model's initial state).
    """
    st = state or model.initial_state()
    a = model.kernel_arrays()
    n = model.n
    jac = np.zeros((n, 5, 3, 3))
    force_jacobian(a, st.x, model.holder_plan().start_dir, False, jac)
    free = np.flatnonzero(~a.held)
    if free.size == 0:
        return np.zeros(0)
    # Symmetric scaled stiffness S = M^-1/2 K M^-1/2 on free DOFs, in LAPACK upper band storage.
    # Free nodes are contiguous (only the two ends can be held), so the band structure survives.
    first_free = free[0]
    nf = free.size
    half = 8
    ab = np.zeros((half + 1, 3 * nf))
    inv_sqrt_m = 1.0 / np.sqrt(a.mass)
    for li in range(nf):
        i = first_free + li
        for o in range(5):
            j = i + o - 2
            if j < i or j < first_free or j >= first_free + nf:
                continue
            block = -jac[i, o] * inv_sqrt_m[i] * inv_sqrt_m[j]
            lj = j - first_free
            for r in range(3):
                for c in range(3):
                    row, col = 3 * li + r, 3 * lj + c
                    if col >= row:
                        ab[half + row - col, col] = block[r, c]
    return np.sort(eigvals_banded(ab, lower=False))


def twist_spectrum(model: CableModel) -> np.ndarray:
    """Eigenvalues omega^2 [1/s^2] of the twist chain of a cable with a material frame (segment inertias I_k,
    springs k_t at the nodes, a clamp's spring at a clamped end), ascending, (n - 1,); empty without a frame."""
    a = model.kernel_arrays()
    kt, inertia = a.tw_k_twist, a.tw_inertia
    if kt.shape[0] == 0:
        return np.zeros(0)
    ns = inertia.shape[0]
    k = np.diag(kt[:ns] + kt[1:ns + 1]) - np.diag(kt[1:ns], 1) - np.diag(kt[1:ns], -1)
    s = 1.0 / np.sqrt(inertia)
    return np.sort(np.linalg.eigvalsh(s[:, None] * k * s[None, :]))


def twist_frequency(spec: CableSpec) -> float:
    """Highest twist-mode angular frequency [rad/s] of a cable with a material frame:
    (2 / l0) sqrt(G J / (rho J_p)) (the twist chain's top mode: segment inertia rho J_p l0, springs G J / l0)."""
    return 2.0 / spec.rest_length * math.sqrt(spec.torsional_rigidity / (spec.density * spec.polar_moment))


def _rk4_limit_on_ray(direction: complex) -> float:
    """Largest s with |R(s * direction)| <= 1 for all s' <= s, |direction| = 1, RK4."""
    def growth(s: np.ndarray) -> np.ndarray:
        z = s * direction
        return np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)

    s = np.linspace(1e-6, 4.0, 4001)
    bad = np.flatnonzero(growth(s) > 1.0 + 1e-12)
    if bad.size == 0:
        return math.inf
    lo, hi = (s[bad[0] - 1] if bad[0] > 0 else 0.0), s[bad[0]]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if growth(np.array([mid]))[0] > 1.0 + 1e-12:
            hi = mid
        else:
            lo = mid
    return lo


def critical_dt_from_modes(method: str, omega2: np.ndarray, gamma: float, tau: float = 0.0) -> float | None:
    """Largest stable step [s] for modes omega^2 [1/s^2], drag rate gamma [1/s] and internal
    damping tau [s] (mode k damped at gamma + tau omega_k^2).

    Returns None for unconditionally stable (implicit) methods and 0.0 when no positive
    step is stable (explicit Euler without damping).
    """
    integ = get_integrator(method)
    if not integ.explicit:
        return None
    w2 = np.maximum(np.asarray(omega2, dtype=float), 0.0)
    g = float(gamma) + float(tau) * w2  # damping rate of each mode [1/s]
    limits = [math.inf]
    if float(gamma) > 0:
        limits.append(2.0 / float(gamma))  # the damping alone (omega -> 0 mode) for all three methods
    if integ.name == "symplectic_euler":
        pos = w2 > 0
        w2p, gp = w2[pos], g[pos]
        if w2p.size:
            limits.append(float(np.min((-gp + np.sqrt(gp * gp + 4.0 * w2p)) / w2p)))
            limits.append(float(np.min(2.0 / np.maximum(gp, 1e-300))))
        return min(limits)
    # explicit Euler / RK4 act on the first-order eigenvalues lambda
    disc = np.sqrt((g * g / 4.0 - w2).astype(complex))
    lams = np.concatenate([-g / 2 + disc, -g / 2 - disc])
    lams = lams[np.abs(lams) > 0]
    if integ.name == "explicit_euler":
        limits.append(float(np.min(-2.0 * lams.real / np.abs(lams) ** 2)))
        return max(0.0, min(limits))
    # RK4: scan the distinct ray directions (to 1e-6 rad), each with its largest |lambda|
    dirs = lams / np.abs(lams)
    mags = np.abs(lams)
    keys = np.round(np.angle(dirs), 6 if tau > 0 else 9)
    for key in np.unique(keys):
        sel = keys == key
        s_max = _rk4_limit_on_ray(complex(dirs[sel][0]))
        limits.append(s_max / float(np.max(mags[sel])))
    return min(limits)


def critical_dt(model: CableModel, integrator: str, state: CableState | None = None) -> float | None:
    """Predicted largest stable fixed step [s] of ``integrator`` for ``model``.

    From the linearisation about ``state`` (default: the initial straight state at rest),
    damping included. None for unconditionally stable implicit methods.
    """
    if not get_integrator(integrator).explicit:
        return None
    spec = model.spec
    modes = np.concatenate([stiffness_spectrum(model, state), twist_spectrum(model)])
    return critical_dt_from_modes(integrator, modes, spec.mass_damping_rate, spec.internal_damping)


@dataclass(frozen=True)
class DampingBounds:
    """Damping numbers that matter for explicit MSD simulation (all per average mass m = M/n).

    omega_max: highest angular frequency [rad/s]; k_d_critical_mode: k_d that critically
    damps the highest mode, 2 m omega_max [N s/m]; k_d_critical_spring: 2 sqrt(k_s m), the
    critical damping of one segment spring with one mass [N s/m]; damping_ratio: zeta of the
    highest mode at the spec's k_d; k_d_min_explicit_euler: smallest k_d that makes explicit
    Euler stable at step dt (gamma >= dt omega_max^2) [N s/m]; k_d_max_explicit: largest k_d
    for which an explicit method stays stable at step dt (dt <= 2/gamma) [N s/m].
    damping_ratio counts every damping term: gamma / (2 omega_max) + tau omega_max / 2;
    internal_damping_max_explicit: largest internal_damping tau [s] whose fast overdamped
    eigenvalue (about -tau omega_max^2) keeps an explicit method stable at step dt (2 / (dt omega_max^2)).
    """

    omega_max: float
    k_d_critical_mode: float
    k_d_critical_spring: float
    damping_ratio: float
    k_d_min_explicit_euler: float
    k_d_max_explicit: float
    internal_damping_max_explicit: float


def damping_bounds(model: CableModel, dt: float) -> DampingBounds:
    """Damping bounds for ``model`` at step ``dt`` [s] (see :class:`DampingBounds`)."""
    spec = model.spec
    w_max = math.sqrt(max(float(stiffness_spectrum(model)[-1]), 0.0))
    m_avg = spec.mass / spec.n_masses
    gamma = spec.mass_damping_rate
    return DampingBounds(
        omega_max=w_max,
        k_d_critical_mode=2.0 * m_avg * w_max,
        k_d_critical_spring=2.0 * math.sqrt(spec.k_stretch * m_avg),
        damping_ratio=gamma / (2.0 * w_max) + spec.internal_damping * w_max / 2.0 if w_max > 0 else math.inf,
        k_d_min_explicit_euler=dt * w_max**2 * m_avg,
        k_d_max_explicit=2.0 * m_avg / dt,
        internal_damping_max_explicit=2.0 / (dt * w_max**2) if w_max > 0 else math.inf,
    )


def measured_critical_dt(model: CableModel, integrator: str, duration: float = 0.2, *,
                         state: CableState | None = None, guess: float | None = None,
                         rel_tol: float = 0.01) -> float:
    """Largest step [s] at which a run of ``duration`` stays stable, found by bisection.

    Brackets the boundary around ``guess`` (default: the predicted critical step, or 1 ms)
    and bisects in log space to ``rel_tol``. The answer depends on the run's duration and
    start state: a slowly growing mode may need a long run to show.
    """
    from bullet_dlo.core.engine import simulate

    def stable(dt: float) -> bool:
        return simulate(model, integrator, dt, duration, state=state, max_records=3).stable

    g = guess or critical_dt(model, integrator) or 1e-3
    lo, hi = g / 1.7, g * 2.3  # asymmetric, so no bisection point lands on the prediction itself
    while not stable(lo):
        lo, hi = lo / 4.0, lo
        if lo < 1e-12:
            return 0.0
    while stable(hi):
        lo, hi = hi, hi * 4.0
        if hi > 10.0:
            return math.inf
    while hi / lo > 1.0 + rel_tol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo
