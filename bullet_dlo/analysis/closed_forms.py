"""Closed forms the model is checked against, and the reference set-ups that realise them.

Every closed form of the package lives here once (tests, benchmarks and peers import it):

* cantilever under its own weight, small deflection: delta = w L^4 / (8 E I), w = M g / L
* cantilever first bending frequency: f1 = 1.8751^2 / (2 pi) sqrt(E I / (rho A L^4))
* cable hanging from a pinned end: elongation = M g L / (2 E A)
* slack cable between two points at equal height: the catenary (sag and end forces)

The set-ups: the horizontal cantilever (:func:`cantilever_model`), the cantilever released
from a small static deflection (:func:`cantilever_release`), the hanging cable, and the
convergence and frequency checks built on them.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from bullet_dlo.analysis.measures import zero_crossing_frequency
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

GRAVITY = 9.81
"""Standard gravity of every reference set-up [m/s^2]."""

BETA1 = 1.8751040687119611
"""First root of 1 + cos(b) cosh(b) = 0 (clamped-free beam)."""

CLAMP_HEIGHT = 0.5
"""Height of the clamp (and of the straight cable) in the reference set-ups [m]."""


# ----- closed forms ------------------------------------------------------------------------------
def cantilever_deflection(spec: CableSpec, g: float = GRAVITY) -> float:
    """Small-deflection tip deflection w L^4 / (8 E I) [m] of a cantilever under its weight."""
    w = spec.mass * g / spec.length
    return w * spec.length**4 / (8.0 * spec.bending_rigidity)


def cantilever_frequency(spec: CableSpec) -> float:
    """First bending frequency f1 [Hz] of a clamped-free beam."""
    return BETA1**2 / (2.0 * math.pi) * math.sqrt(spec.bending_rigidity / (spec.linear_density * spec.length**4))


def cantilever_angular_frequency(spec: CableSpec) -> float:
    """First bending angular frequency omega1 = 2 pi f1 [rad/s] of a clamped-free beam."""
    return 2.0 * math.pi * cantilever_frequency(spec)


def release_gravity(spec: CableSpec, amplitude_ratio: float) -> float:
    """Gravity [m/s^2] under which the cantilever's tip deflects ``amplitude_ratio`` * L (closed form)."""
    return GRAVITY * amplitude_ratio * spec.length / cantilever_deflection(spec)


def hanging_elongation(spec: CableSpec, g: float = GRAVITY) -> float:
    """Elongation M g L / (2 E A) [m] of a cable hanging from one end."""
    return spec.mass * g * spec.length / (2.0 * spec.axial_rigidity)


def catenary(span: float, length: float, weight_per_length: float) -> tuple[float, float, float]:
    """Catenary through two points ``span`` [m] apart at equal height, cable ``length`` [m],
    weight per length w [N/m]: (sag [m], horizontal force [N], vertical force per end [N])."""
    lo, hi = 1e-6, 1e3  # bisection on the parameter a [m] of L = 2 a sinh(span / 2a)
    for _ in range(200):
        a = math.sqrt(lo * hi)
        if 2 * a * math.sinh(span / (2 * a)) > length:
            lo = a
        else:
            hi = a
    a = math.sqrt(lo * hi)
    return a * (math.cosh(span / (2 * a)) - 1.0), weight_per_length * a, weight_per_length * length / 2


# ----- reference set-ups -------------------------------------------------------------------------
def with_damping_rate(spec: CableSpec, rate: float) -> CableSpec:
    """``spec`` with mass-proportional drag: every mass decays at ``rate`` [1/s] (no k_d)."""
    return spec.with_(damping=0.0, damping_rate=rate)


def small_deflection_spec(n_masses: int, discretisation: str = "default", deflection_ratio: float = 1e-3) -> CableSpec:
    """Lv cable geometry with E chosen so the tip deflects ``deflection_ratio`` * L (linear regime)."""
    base = CableSpec.lv2017(n_masses=n_masses, discretisation=discretisation)
    w = base.mass * GRAVITY / base.length
    e = w * base.length**3 / (8.0 * base.second_moment * deflection_ratio)
    return base.with_(youngs_modulus=e)


def cantilever_model(spec: CableSpec, gravity: float = GRAVITY) -> CableModel:
    """Horizontal cantilever: first end clamped at (0, 0, 0.5) along +x, last end free."""
    return CableModel.straight(spec, (0.0, 0.0, CLAMP_HEIGHT), (1.0, 0.0, 0.0), ("clamped", "free"), (),
                               (0.0, 0.0, -gravity))


def cantilever_release(spec: CableSpec, amplitude_ratio: float = 1e-3) -> tuple[CableModel, CableState]:
    """A cantilever without gravity, at rest in the static shape under :func:`release_gravity`.

    That shape is close to the first mode, and small enough (tip at ``amplitude_ratio`` * L)
    to stay linear: released, the tip oscillates at f1. Returns (model without gravity, start state).
    """
    start = solve_static(cantilever_model(spec, release_gravity(spec, amplitude_ratio))).x
    return cantilever_model(spec, 0.0), CableState(start, np.zeros_like(start))


def hanging_model(spec: CableSpec, top: Sequence[float] = (0.0, 0.0, 1.0)) -> CableModel:
    """Cable pinned at ``top``, laid straight downwards at rest length, free lower end."""
    return CableModel.straight(spec, top, (0.0, 0.0, -1.0), ("pinned", "free"))


# ----- checks of the model against the closed forms ----------------------------------------------
def cantilever_static_error(n_masses: int, discretisation: str = "default") -> float:
    """Signed relative error of the static tip deflection vs beam theory."""
    spec = small_deflection_spec(n_masses, discretisation)
    res = solve_static(cantilever_model(spec))
    return (CLAMP_HEIGHT - res.x[-1, 2]) / cantilever_deflection(spec) - 1.0


def cantilever_convergence(n_masses: Sequence[int] = (5, 10, 20, 40)) -> list[dict]:
    """Rows {n_masses, default, paper} of relative tip-deflection errors."""
    return [{"n_masses": int(n), "default": cantilever_static_error(n, "default"),
             "paper": cantilever_static_error(n, "paper")} for n in n_masses]


def measured_cantilever_frequency(spec: CableSpec, integrator: str, dt: float, periods: float = 4.0,
                                  amplitude_ratio: float = 2e-3) -> float:
    """First bending frequency f1 [Hz] of the simulated cantilever released by :func:`cantilever_release`."""
    model, start = cantilever_release(spec, amplitude_ratio)
    res = simulate(model, integrator, dt, periods / cantilever_frequency(spec), state=start, max_records=20001)
    return zero_crossing_frequency(res.t, res.x[:, -1, 2] - CLAMP_HEIGHT)
