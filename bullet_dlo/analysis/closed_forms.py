"""Closed forms the model is checked against, and the reference set-ups that realise them.

Every closed form of the package lives here once (tests, benchmarks and peers import it):

* cantilever under its own weight, small deflection: delta = w L^4 / (8 E I), w = M g / L
* cantilever first bending frequency: f1 = 1.8751^2 / (2 pi) sqrt(E I / (rho A L^4))
* cable hanging from a pinned end: elongation = M g L / (2 E A)
* slack cable between two points at equal height: the catenary (sag and end forces)
* capstan: tension ratio at the onset of slip over a fixed cylinder, exp(mu theta) for a string, with the
  wrapped part's weight and with bending stiffness (lift-off of an elastica)

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


def capstan_lift_off(bending_rigidity: float, tension: float, radius: float) -> float:
    """Angle [rad] through which a rod of bending rigidity B [N m^2] under tension T [N] turns between a cylinder of
    (centre-line) radius rho [m] that it wraps and its straight far part: sin(Delta / 2) = sqrt(B / T) / (2 rho).

    The free part is an elastica under the constant force T along its far direction, straight at infinity: B kappa^2
    / 2 = T (1 - cos psi), psi the angle between the tangent and that force; it leaves the cylinder with the curvature
    1 / rho (its moment B kappa is continuous: the cylinder applies no couple). Raises ValueError where the bend length
    sqrt(B / T) reaches the diameter 2 rho: the rod cannot bend to the cylinder and touches it at points only."""
    bend_length = math.sqrt(bending_rigidity / tension)
    if bend_length >= 2.0 * radius:
        raise ValueError(f"bend length sqrt(B/T) = {bend_length:.4g} m reaches the wrap diameter 2 rho = "
                         f"{2 * radius:.4g} m: the rod does not wrap the cylinder")
    return 2.0 * math.asin(bend_length / (2.0 * radius))


def capstan_ratio(theta: float, mu: float, radius: float, slack_tension: float, bending_rigidity: float = 0.0,
                  weight_per_length: float = 0.0) -> float:
    """Tension ratio T_tight / T_slack [-] at the onset of slip of a rod over a fixed cylinder with friction mu.

    ``theta`` [rad] is the wrap of the string (the angle between the two far directions), ``radius`` rho [m] the
    radius of the rod's centre line on the cylinder (cylinder radius plus the rod's), ``slack_tension`` [N] the far
    tension on the side that holds. A string: exp(mu theta). With weight w [N/m] (the cylinder's axis horizontal, the
    slack side hanging straight down, the wrap over the top from there), dT/dalpha + mu T = w rho (cos alpha - mu sin
    alpha) along the arc (alpha the position angle from the horizontal, pi on the slack side, decreasing towards the
    tight side): T = C exp(-mu alpha) + w rho ((1 - mu^2) sin alpha + 2 mu cos alpha) / (1 + mu^2), which for theta = pi
    gives T_slack exp(mu pi) + w rho (2 mu / (1 + mu^2)) (1 + exp(mu pi)).

    With bending rigidity B [N m^2] the rod leaves the cylinder Delta_s and Delta_t short of the string's tangent
    points (:func:`capstan_lift_off`, at each side's far tension), so the arc in contact spans theta - Delta_s -
    Delta_t. Inside it the curvature is 1 / rho, the moment constant, the shear zero: the string's law holds there.
    At each lift-off point the free part's force, T along its far direction, meets the arc's tangent at Delta: the
    cylinder takes a point load P = T sin Delta, whose friction mu P the slip engages too, so the arc's end tensions
    are T_slack (cos Delta_s + mu sin Delta_s) and T_tight (cos Delta_t - mu sin Delta_t). To first order in Delta
    the two ends cancel; to second, the ratio falls by about (1 + mu^2) (Delta_s^2 - Delta_t^2) / 2 of exp(mu theta)
    (the slack side, at the lower tension, bends further). Frictionless, the ratio is 1 at any B (T cos Delta grows with
    T). The free parts' weight is left out (the bend length is short against the hanging parts). Raises ValueError
    where the rod does not wrap (bend length at least 2 rho) or no arc is left in contact."""
    if not (theta > 0 and mu >= 0 and radius > 0 and slack_tension > 0 and bending_rigidity >= 0
            and weight_per_length >= 0):
        raise ValueError("capstan_ratio needs theta > 0, mu >= 0, radius > 0, slack_tension > 0, "
                         "bending_rigidity >= 0, weight_per_length >= 0")
    w, rho = weight_per_length, radius

    def particular(alpha: float) -> float:  # a particular solution of the arc's tension equation [N]
        return w * rho * ((1.0 - mu * mu) * math.sin(alpha) + 2.0 * mu * math.cos(alpha)) / (1.0 + mu * mu)

    def lift_off(tension: float) -> float:
        return capstan_lift_off(bending_rigidity, tension, rho) if bending_rigidity > 0 else 0.0

    d_s = lift_off(slack_tension)
    if d_s >= theta:
        raise ValueError(f"no arc in contact: the slack side's lift-off {d_s:.4g} rad takes the whole wrap "
                         f"{theta:.4g} rad")
    a0 = math.pi - d_s  # where the arc in contact starts, from the slack side
    t0 = slack_tension * (math.cos(d_s) + mu * math.sin(d_s))

    def excess(ratio: float) -> float:  # the ratio the arc carries at the tight side's lift-off for this ratio, less it
        d_t = lift_off(ratio * slack_tension)
        a1 = math.pi - theta + d_t
        hold = math.cos(d_t) - mu * math.sin(d_t)
        if hold <= 0.0:  # the tight lift-off's friction alone holds any pull
            return math.inf
        t1 = (t0 - particular(a0)) * math.exp(mu * (a0 - a1)) + particular(a1)
        return t1 / hold / slack_tension - ratio

    # the tight side's lift-off shrinks as its tension grows, so the excess falls with the ratio: one root, bisected
    # (a fixed-point iteration on it oscillates and barely contracts for stiff rods). Below lo the tight side's lift-off
    # would leave no arc (or the rod would not wrap at all).
    lo = 0.0
    if bending_rigidity > 0:
        half = min(theta - d_s, math.pi) / 2.0
        lo = bending_rigidity / (slack_tension * (2.0 * rho * math.sin(half)) ** 2) * (1.0 + 1e-12)
    hi = max(2.0 * lo, math.exp(mu * theta), 1.0)
    while excess(hi) > 0.0:
        hi *= 2.0
    if lo > 0.0 and not excess(lo) > 0.0:
        raise ValueError("no arc in contact: the rod is too stiff to wrap theta at these tensions")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if excess(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


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
