"""Closed-form checks of the model: the physics the tests and benchmarks compare against.

* cantilever under its own weight, small deflection: delta = w L^4 / (8 E I)
* cable hanging from a pinned end: elongation = rho g L^2 / (2 E) = M g L / (2 E A)
* cantilever first bending frequency: f1 = 1.8751^2 / (2 pi) sqrt(E I / (rho A L^4))
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

BETA1 = 1.8751040687119611  # first root of 1 + cos(b) cosh(b) = 0


def cantilever_deflection(spec: CableSpec, g: float = 9.81) -> float:
    """Small-deflection tip deflection w L^4 / (8 E I) [m] of a cantilever under its weight."""
    w = spec.mass * g / spec.length
    return w * spec.length**4 / (8.0 * spec.bending_rigidity)


def small_deflection_spec(n_masses: int, discretisation: str = "default", deflection_ratio: float = 1e-3) -> CableSpec:
    """Lv cable geometry with E chosen so the tip deflects ``deflection_ratio`` * L (linear regime)."""
    base = CableSpec.lv2017(n_masses=n_masses, discretisation=discretisation)
    w = base.mass * 9.81 / base.length
    e = w * base.length**3 / (8.0 * base.second_moment * deflection_ratio)
    return base.with_(youngs_modulus=e)


def cantilever_model(spec: CableSpec, gravity: float = 9.81) -> CableModel:
    """Horizontal cantilever: first end clamped at (0, 0, 0.5) along +x, last end free."""
    return CableModel.straight(spec, (0.0, 0.0, 0.5), (1.0, 0.0, 0.0), ("clamped", "free"), (), (0.0, 0.0, -gravity))


def cantilever_static_error(n_masses: int, discretisation: str = "default") -> float:
    """Relative error of the static tip deflection vs beam theory (signed)."""
    spec = small_deflection_spec(n_masses, discretisation)
    model = cantilever_model(spec)
    res = solve_static(model)
    delta = 0.5 - res.x[-1, 2]
    return delta / cantilever_deflection(spec) - 1.0


def cantilever_convergence(masses: Sequence[int] = (5, 10, 20, 40)) -> list[dict]:
    """Rows {n_masses, default, paper} of relative tip-deflection errors."""
    return [{"n_masses": int(n), "default": cantilever_static_error(n, "default"),
             "paper": cantilever_static_error(n, "paper")} for n in masses]


def hanging_elongation(spec: CableSpec, g: float = 9.81) -> float:
    """Closed-form elongation M g L / (2 E A) [m] of a cable hanging from one end."""
    return spec.mass * g * spec.length / (2.0 * spec.axial_rigidity)


def hanging_model(spec: CableSpec, top: Sequence[float] = (0.0, 0.0, 1.0)) -> CableModel:
    """Cable pinned at ``top``, laid straight downwards at rest length, free lower end."""
    return CableModel.straight(spec, top, (0.0, 0.0, -1.0), ("pinned", "free"))


def cantilever_frequency(spec: CableSpec) -> float:
    """Closed-form first bending frequency f1 [Hz] of a clamped-free beam."""
    return BETA1**2 / (2.0 * math.pi) * math.sqrt(spec.bending_rigidity / (spec.linear_density * spec.length**4))


def zero_crossing_frequency(t: np.ndarray, y: np.ndarray) -> float:
    """Frequency [Hz] from upward zero crossings of y(t) (linear interpolation between samples)."""
    idx = np.flatnonzero((y[:-1] < 0.0) & (y[1:] >= 0.0))
    if idx.size < 2:
        return float("nan")
    tc = t[idx] - y[idx] * (t[idx + 1] - t[idx]) / (y[idx + 1] - y[idx])
    return (idx.size - 1) / (tc[-1] - tc[0])


def measured_cantilever_frequency(spec: CableSpec, integrator: str, dt: float, periods: float = 4.0,
                                  amplitude_ratio: float = 2e-3) -> float:
    """Release a cantilever from a small static deflection with gravity off; measure f1 [Hz].

    The start shape is the equilibrium under a reduced gravity chosen so the tip deflects
    ``amplitude_ratio`` * L (close to the first mode shape, small enough to stay linear).
    """
    g_small = 9.81 * amplitude_ratio * spec.length / cantilever_deflection(spec)
    start = solve_static(cantilever_model(spec, g_small)).x
    free_model = cantilever_model(spec, 0.0)
    duration = periods / cantilever_frequency(spec)
    res = simulate(free_model, integrator, dt, duration, state=CableState(start, np.zeros_like(start)),
                   max_records=20001)
    return zero_crossing_frequency(res.t, res.x[:, -1, 2] - 0.5)
