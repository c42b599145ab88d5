"""Numerical damping and ringing of a fitted model's integrator, against the physical damping it identifies.

Linearised about the static shape, the model's modes decouple (see :mod:`bullet_dlo.core.stability`):
mode k has angular frequency omega_k (from :func:`~bullet_dlo.core.stability.stiffness_spectrum`)
and the physical eigenvalues lambda = -gamma_k / 2 +- sqrt(gamma_k^2 / 4 - omega_k^2) with
gamma_k = c + tau omega_k^2 (c: ``mass_damping_rate``, tau: ``internal_damping``). One step h of an
integrator maps lambda to an amplification z(h lambda) (the method's stability function); the mode it
really simulates has the eigenvalue s = ln(z) / h. So

* the **numerical damping ratio** of mode k is zeta(s) - zeta(lambda), zeta = -Re / |.|: what the
  integrator adds (implicit Euler: about omega h / 2; BDF2: O((omega h)^3); implicit midpoint: 0);
* **ringing**: a mode the physics kills in a step (|exp(h lambda)| small) that the integrator keeps
  (|z| near 1: implicit midpoint on stiff modes maps z -> -1, a sign-alternating oscillation).

:func:`numerical_damping_check` compares both on the lowest modes (the ones wrist forces see)
with the fitted physical damping ratio and says whether numerical damping stays below
``max_ratio`` times it.
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.stability import stiffness_spectrum

RING_PHYSICAL = 0.1  # a mode is "killed in a step" by the physics when |exp(h lambda)| is below this
RING_NUMERICAL = 0.5  # ... and rings when the integrator keeps |z| above this


def amplification(method: str, hl: complex, h: float = 0.0, omega: float = 0.0, gamma: float = 0.0) -> complex:
    """Principal amplification factor z of one step of ``method`` on the mode eigenvalue h lambda.

    Symplectic Euler is not a one-step map of lambda alone: its 2x2 matrix (omega [rad/s],
    gamma [1/s], step h [s]) is used and its eigenvalue nearest exp(h lambda) returned.
    """
    if method == "implicit_euler":
        return 1.0 / (1.0 - hl)
    if method == "implicit_midpoint":
        return (1.0 + hl / 2.0) / (1.0 - hl / 2.0)
    if method == "explicit_euler":
        return 1.0 + hl
    if method == "rk4":
        return 1.0 + hl + hl**2 / 2.0 + hl**3 / 6.0 + hl**4 / 24.0
    if method == "bdf2":  # (3/2 - h lambda) z^2 - 2 z + 1/2 = 0: the root nearest exp(h lambda)
        roots = np.roots([1.5 - hl, -2.0, 0.5])
    elif method == "symplectic_euler":
        a = np.array([[1.0 - h * h * omega**2, h * (1.0 - h * gamma)], [-h * omega**2, 1.0 - h * gamma]])
        roots = np.linalg.eigvals(a)
    else:
        raise ValueError(f"no stability function for {method!r}")
    target = cmath.exp(hl)
    return complex(roots[int(np.argmin(np.abs(roots - target)))])


def damping_ratio(s: complex) -> float:
    """zeta = -Re(s) / |s| of a continuous eigenvalue s (1 for a real decaying one)."""
    return -s.real / abs(s) if abs(s) > 0 else 0.0


def mode_eigenvalue(omega: float, gamma: float) -> complex:
    """The physical eigenvalue of x'' + gamma x' + omega^2 x = 0 with the larger imaginary part [1/s]."""
    return -gamma / 2.0 + cmath.sqrt(gamma**2 / 4.0 - omega**2)


@dataclass(frozen=True)
class ModeCheck:
    """One mode at one step: omega [rad/s]; physical and numerical-added damping ratios [-];
    amplification per step |z| of the integrator and |exp(h lambda)| of the physics."""

    omega: float
    physical_ratio: float
    numerical_ratio: float
    step_gain: float
    physical_step_gain: float


def mode_check(method: str, h: float, omega: float, gamma: float) -> ModeCheck:
    """Numerical damping of one mode (omega [rad/s], damping rate gamma [1/s]) at step h [s]."""
    lam = mode_eigenvalue(omega, gamma)
    z = amplification(method, h * lam, h, omega, gamma)
    phys = damping_ratio(lam)
    num = damping_ratio(cmath.log(z) / h) - phys if abs(z) > 0 else math.inf
    return ModeCheck(float(omega), float(phys), float(num), float(abs(z)), float(abs(cmath.exp(h * lam))))


@dataclass(frozen=True)
class NumericalDampingCheck:
    """The verdict of :func:`numerical_damping_check`; ``to_dict`` is its JSON form."""

    integrator: str
    dt: float
    n_masses: int
    modes: list[ModeCheck]
    stiffest: ModeCheck
    max_ratio: float
    worst_share: float
    ringing: bool
    ok: bool
    message: str

    def to_dict(self) -> dict:
        """JSON-able summary."""
        mode = lambda m: {"omega_rad_s": m.omega, "frequency_hz": m.omega / (2 * math.pi),
                          "physical_damping_ratio": m.physical_ratio, "numerical_damping_ratio": m.numerical_ratio}
        return {"integrator": self.integrator, "dt_s": self.dt, "n_masses": self.n_masses,
                "lowest_modes": [mode(m) for m in self.modes],
                "stiffest_mode": {**mode(self.stiffest), "step_gain_integrator": self.stiffest.step_gain,
                                  "step_gain_physics": self.stiffest.physical_step_gain},
                "allowed_share": self.max_ratio, "worst_share": self.worst_share if math.isfinite(self.worst_share)
                else None, "ringing": self.ringing, "ok": self.ok, "message": self.message,
                "method": "stability function of the integrator on the linearised modes about the static shape "
                          "(bullet_dlo.core.stability.stiffness_spectrum), numerical damping ratio = "
                          "zeta(ln z / dt) - zeta(lambda)"}


def lowest_modes(model: CableModel, state: CableState, count: int) -> tuple[np.ndarray, float]:
    """Angular frequencies [rad/s] of the ``count`` lowest non-rigid modes about ``state`` and the stiffest one."""
    w2 = stiffness_spectrum(model, state)
    w = np.sqrt(np.clip(w2, 0.0, None))
    w = w[w > 1e-6 * max(float(w.max()), 1e-300)]
    return w[:count], float(w.max()) if len(w) else 0.0


def numerical_damping_check(model: CableModel, state: CableState, integrator: str, dt: float,
                            max_ratio: float = 0.1, modes: int = 3) -> NumericalDampingCheck:
    """Does ``integrator`` at ``dt`` [s] add less damping than ``max_ratio`` x the physical damping ratio
    on the ``modes`` lowest modes of ``model`` about ``state`` (and not ring on its stiffest mode)?"""
    spec = model.spec
    c, tau = spec.mass_damping_rate, spec.internal_damping
    omegas, w_max = lowest_modes(model, state, modes)
    checks = [mode_check(integrator, dt, w, c + tau * w * w) for w in omegas]
    stiff = mode_check(integrator, dt, w_max, c + tau * w_max * w_max)
    shares = [abs(m.numerical_ratio) / m.physical_ratio if m.physical_ratio > 0 else
              (0.0 if abs(m.numerical_ratio) < 1e-9 else math.inf) for m in checks]
    worst = max(shares) if shares else 0.0
    ringing = stiff.physical_step_gain < RING_PHYSICAL and stiff.step_gain > RING_NUMERICAL
    ok = worst <= max_ratio and not ringing
    msgs = []
    if worst > max_ratio and checks:
        k = int(np.argmax(shares))
        msgs.append(f"{integrator} at dt {dt:.3g} s adds a damping ratio {checks[k].numerical_ratio:.3g} to the "
                    f"{checks[k].omega / (2 * math.pi):.3g} Hz mode, {worst:.3g}x its physical {checks[k].physical_ratio:.3g} "
                    f"(allowed {max_ratio:.3g}x): the fitted damping is not the cable's")
    if ringing:
        msgs.append(f"{integrator} at dt {dt:.3g} s keeps the stiffest mode ({stiff.omega / (2 * math.pi):.3g} Hz) "
                    f"at |z| = {stiff.step_gain:.3g} per step where the physics leaves {stiff.physical_step_gain:.3g}: "
                    "it rings; use bdf2 or a smaller dt")
    return NumericalDampingCheck(integrator, float(dt), int(spec.n_masses), checks, stiff, float(max_ratio),
                                 float(worst), bool(ringing), bool(ok), "; ".join(msgs) or "numerical damping "
                                 f"below {max_ratio:.3g}x the physical on the {len(checks)} lowest modes, no ringing")
