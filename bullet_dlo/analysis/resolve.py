"""Automatic resolution: model no more than a scene needs.

``resolve(problem, tol)`` picks the fewest masses, then the cheapest integrator and the largest
step that meet a tolerance on what the scene needs (end forces, shape, or both), by
convergence tests on a short rollout of the scene itself (never by a lookup table). The scene
comes as a :class:`ResolveProblem`: its cable, duration, curved obstacles and a function that runs
it (:func:`bullet_dlo.sim.resolve_problem` makes one from a scene), so this layer knows no scene type.


Forces are compared as a 5 Hz force-torque sensor would see them (0.2 s block means, RMS over the
rollout, relative to the peak force; the end moments alike, relative to their peak:
:func:`~bullet_dlo.analysis.measures.wrench_error`); shape as the largest distance between the final
shapes, relative to the largest displacement of the cable during the rollout.

1. spatial: for n = 5, 7, 10, 14, 20, 28, 40, 56, 80, compare a run with n masses against one
   with 2n - 1 masses (both BDF2 at a small step); the first n whose difference is within half
   the tolerance is kept (the difference times 4/3 estimates the error of n: twice the
   segments of a second-order discretisation leave a quarter of it);
2. temporal: with that n, try the steps from 1/60 s down and the integrators from the
   cheapest; the first whose difference from the small-step run is within the other half wins.

Contact sets a floor on n before the convergence test (the rollouts have no obstacles, so they
cannot see it): a cable wrapping a cylinder or sphere of radius R follows it with a polygon,
whose segments cut into the arc by l^2 / (8 (R + r)); keeping that sag within half the cable
radius r needs l <= 2 sqrt((R + r) r), i.e. n >= L / l + 1 for the smallest curved obstacle of
the scene (:attr:`ResolveProblem.cylinder_radii`: its obstacles' cylinders and capsules, a URDF's links too). A passage
of width w between two bodies (a clip's slot, :attr:`ResolveProblem.passage_widths`) leaves the
segment capsules' centre line a free width w - 2 r; a straight segment longer than that, turned
across the passage, spans it wall to wall and wedges like a stick in a channel (a real cable bends
out of it; the chain of rigid segments cannot, and its contact forces then grow with the
penetration until the solve stalls), so l <= w - 2 r, i.e. n >= L / (w - 2 r) + 1. Edges set no
floor: segments collide as capsules, so an edge is caught at any n. :attr:`Resolution.why` says
which bound chose n.

The predicted error is the sum of both differences. When it changes n, resolve keeps the
damping rate gamma = k_d n / M fixed (k_d is the paper's per-mass coefficient), so that all
trials describe the same cable; the chosen n comes with the k_d that keeps gamma.
``damping_rate`` and ``internal_damping`` need no rescaling: they mean the same at any n.

Twist by need (issue 22): before any trial, :func:`twist_need` reads the scene's held ends
(:attr:`ResolveProblem.holders`). A clamp whose motion rolls it about the cable's axis (the roll of
its orientation about the tangent, relative to the minimal rotation that carries the start tangent
to the current one, non-zero at some time of the run) or a non-round section needs the material
frame: every trial then runs with ``twist`` on, and :attr:`Resolution.twist` / :attr:`Resolution.why`
say so and why. A round cable whose ends never roll keeps the model (and cost) without a frame.
A pinned end does not hold the roll, so its rotations never ask for the frame.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Callable

import numpy as np

from bullet_dlo.analysis.measures import force_error, shape_error, wrench_error
from bullet_dlo.core.boundary import ROLL_SAMPLES, ROLL_TOL, EndHolder, end_roll  # (ROLL_TOL, end_roll: re-exported)
from bullet_dlo.core.engine import SimulationResult
from bullet_dlo.core.enums import EndMode, ToleranceTarget, name_of
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError, check_positive

TARGETS = ToleranceTarget.names()
N_MASSES = (5, 7, 10, 14, 20, 28, 40, 56, 80)
"""Numbers of masses tried, fewest first."""
DTS = (1 / 60, 1 / 120, 1 / 240, 1 / 500, 1e-3, 5e-4, 2.5e-4)
"""Time steps tried [s], largest first."""
INTEGRATORS = ("implicit_euler", "bdf2")
"""Integrators tried, cheapest first."""


@dataclass(frozen=True)
class ResolveProblem:
    """What :func:`resolve` needs of a scene (SI units).

    cable: the scene's cable (its n_masses is a start; its k_d is rescaled with n); duration: the
    scene's run [s]; run(cable, integrator, dt, duration): one run of the scene with that cable,
    integrator, step [s] and duration [s], its core-engine result (about 200 records are enough);
    cylinder_radii: radii [m] of the cylinders and capsules among the scene's obstacles' collision shapes (the contact
    floor on n; :meth:`bullet_dlo.bullet.world.BulletWorld.round_radii`);
    passage_widths: widths [m] of the gaps between the scene's bodies wider than the cable (the passage floor on
    n; :meth:`bullet_dlo.bullet.world.BulletWorld.passages`);
    holders: the scene's two held ends (first, last) with their motion, for :func:`twist_need`
    (empty: the scene is taken not to roll its ends).
    """

    cable: CableSpec
    duration: float
    run: Callable[[CableSpec, str, float, float], SimulationResult]
    cylinder_radii: tuple[float, ...] = ()
    passage_widths: tuple[float, ...] = ()
    holders: tuple[EndHolder, ...] = ()


@dataclass
class Resolution:
    """What :func:`resolve` chose and why (SI units)."""

    n_masses: int
    dt: float
    integrator: str
    damping: float
    predicted_error: float
    spatial_error: float
    temporal_error: float
    wall_time_per_sim_s: float
    target: str
    tolerance: float
    rollout_s: float
    trials: list = field(default_factory=list)
    why: str = ""
    twist: bool = False
    """Whether the chosen model has the material frame (see :func:`twist_need`)."""

    def to_dict(self) -> dict:
        return asdict(self)


def twist_need(problem: ResolveProblem) -> str:
    """Why the scene needs the material frame (issue 22), or "" when a round cable's ends never roll.

    A non-round section always has it; otherwise the largest roll about the cable axis of a clamped or fork
    end over the scene's duration (:func:`end_roll` at :data:`ROLL_SAMPLES` instants) must exceed
    :data:`ROLL_TOL`. A pinned end does not hold the roll.
    """
    c = problem.cable
    if c.section != "round":
        if c.section == "rectangle":
            return "material frame on: the rectangle section bends unequally about its two axes and twists"
        return f"material frame on: a {c.section} section always carries it (its torsion G J)"
    if c.twist:
        return "material frame on: the cable asks for it (twist: true)"
    times = np.linspace(0.0, problem.duration, ROLL_SAMPLES)
    rolls = []
    for name, holder in zip(("first", "last"), problem.holders):
        if not EndMode(holder.mode).holds_roll or not holder.moves:
            continue
        roll = float(np.max(np.abs(np.unwrap(end_roll(holder, times)))))  # (a roll past half a turn: unwrapped)
        if roll > ROLL_TOL:
            held_by = EndMode(holder.mode).holder
            rolls.append(f"the {name} {held_by} rolls {np.degrees(roll):.3g} deg about the cable axis")
    if rolls:
        return "material frame on: " + " and ".join(rolls) + " (a clamp or a fork holds the twist)"
    return ""


def with_twist(problem: ResolveProblem) -> tuple[ResolveProblem, str]:
    """``problem`` with the material frame switched on when :func:`twist_need` says so: (problem, why)."""
    why = twist_need(problem)
    if why and not problem.cable.twist_enabled:
        problem = replace(problem, cable=problem.cable.with_(twist=True))
    return problem, why


def _cable(problem: ResolveProblem, n: int) -> CableSpec:
    """The scene's cable with n masses, k_d rescaled to keep its rate k_d n / M (k_d is per mass;
    ``damping_rate`` and ``internal_damping`` mean the same at any n)."""
    c = problem.cable
    return c.with_(n_masses=n, damping=c.damping * c.n_masses / n)


def contact_floor(problem: ResolveProblem) -> tuple[int, str]:
    """The fewest masses the scene's curved obstacles and passages need (see module doc): (n, why); (2, "") if
    none. The larger of the two floors binds; ``why`` names it."""
    c = problem.cable
    r = c.diameter / 2
    floors = [(2, "")]
    if problem.cylinder_radii:
        radius = min(problem.cylinder_radii)
        seg = cylinder_segment(radius, c.diameter)
        floors.append((cylinder_masses(c.length, c.diameter, radius),
                       f"the smallest cylinder (radius {radius * 1e3:.1f} mm) is wrapped by segments of at most "
                       f"{seg * 1e3:.1f} mm (chord sag within half the cable radius)"))
    widths = [w for w in problem.passage_widths if w > c.diameter]
    if widths:
        width = min(widths)
        seg = passage_segment(width, c.diameter)
        floors.append((passage_masses(c.length, c.diameter, width),
                       f"the narrowest passage ({width * 1e3:.1f} mm) is threaded by segments of at most "
                       f"{seg * 1e3:.1f} mm (shorter than its free width: none can wedge across it)"))
    n, why = max(floors)
    return n, (f"contact floor n >= {n}: {why}" if why else "")


def cylinder_segment(radius: float, diameter: float) -> float:
    """The longest segment [m] of a cable ``diameter`` [m] thick that follows a cylinder of ``radius`` [m]: its chord
    round the cylinder sags into the rounding radius + r by at most half the cable radius r, 2 sqrt((radius + r) r)."""
    r = diameter / 2
    return 2.0 * float(np.sqrt((radius + r) * r))


def cylinder_masses(length: float, diameter: float, radius: float) -> int:
    """The fewest masses of a cable ``length`` [m] long and ``diameter`` [m] thick whose segments follow a cylinder of
    ``radius`` [m] (:func:`cylinder_segment`)."""
    return int(np.ceil(length / cylinder_segment(radius, diameter))) + 1


def passage_segment(width: float, diameter: float) -> float:
    """The longest segment [m] that cannot wedge across a passage ``width`` [m] wide: its free width for the
    centre line of a cable ``diameter`` [m] thick, width - diameter."""
    return width - diameter


def passage_masses(length: float, diameter: float, width: float) -> int:
    """The fewest masses of a cable ``length`` [m] long and ``diameter`` [m] thick whose segments cannot wedge across
    a passage ``width`` [m] wide (:func:`passage_segment`); ParameterError if the cable cannot enter it."""
    if width <= diameter:
        raise ParameterError(f"a passage {width} m wide cannot take a cable {diameter} m thick")
    return int(np.ceil(length / passage_segment(width, diameter))) + 1


def _rollout(problem: ResolveProblem, n: int, integrator: str, dt: float,
             rollout: float) -> tuple[SimulationResult, float]:
    """A ``rollout``-second run of the scene with n masses: (result, wall time per simulated second [s])."""
    res = problem.run(_cable(problem, n), integrator, dt, rollout)
    return res, res.wall_time_s / max(res.steps * dt, 1e-12)


def _difference(a: SimulationResult, b: SimulationResult, target: str, length: float) -> float:
    """Relative difference of run ``a`` from run ``b`` in what the scene needs.

    forces: end forces and moments as a 5 Hz force-torque sensor sees them (0.2 s means; pointwise force
    histories of lightly damped cables carry stiff modes that refining n only adds to; the moments where both runs
    recorded them: a clamp rolled about the cable loads it with moments alone); shape: the final shapes, relative
    to how far the cable moved from its start (1e-3 L at least).
    """
    errs = []
    if target in ("forces", "both"):
        if a.end_moment_history is not None and b.end_moment_history is not None:
            errs.append(wrench_error(a.t, a.end_forces, a.end_moment_history, b.t, b.end_forces,
                                     b.end_moment_history, length))
        else:
            errs.append(force_error(a.t, a.end_forces, b.t, b.end_forces))
    if target in ("shape", "both"):
        moved = float(np.max(np.linalg.norm(b.x[-1] - b.x[0], axis=1)))
        errs.append(shape_error(a.final_state.x, b.final_state.x, max(moved, 1e-3 * length)))
    return max(errs)


def _resolve_masses(problem: ResolveProblem, tol, target, rollout, n_masses, fine_dt, trials):
    """Spatial part: the fewest masses whose estimated error is within half of ``tol``.

    Returns (n, estimated spatial error, the n-mass run at the fine step).
    """
    length = problem.cable.length
    for n in n_masses:
        a, _ = _rollout(problem, n, "bdf2", fine_dt, rollout)
        b, _ = _rollout(problem, 2 * n - 1, "bdf2", fine_dt, rollout)
        if not (a.stable and b.stable):
            trials.append({"n": n, "spatial": None, "note": "unstable"})
            continue
        # twice the segments of a second-order discretisation: error(n) ~ 4/3 of the difference
        err = 4.0 / 3.0 * _difference(a, b, target, length)
        trials.append({"n": n, "spatial": err})
        if err <= 0.5 * tol:
            return n, err, a
    raise ParameterError(f"no n up to {max(n_masses)} meets tol = {tol} on {target}; loosen the tolerance")


def resolve_masses(problem: ResolveProblem, tol: float = 0.02, target: str = "forces",
                   rollout: float | None = None) -> tuple[int, float]:
    """Only the number of masses (the step and integrator stay the scene's): (n, k_d [N s/m] for that n).

    k_d keeps the scene's damping rate gamma = k_d n / M (see module doc).
    """
    rollout = min(problem.duration, 2.0) if rollout is None else rollout
    problem, _ = with_twist(problem)  # the trials run the model the scene needs (twist_need)
    floor, _ = contact_floor(problem)
    candidates = tuple(n for n in N_MASSES if n >= floor) or (floor,)
    n, _, _ = _resolve_masses(problem, check_positive("tol", tol), target, rollout, candidates, 1e-3, [])
    return n, _cable(problem, n).damping


def resolve(problem: ResolveProblem, tol: float = 0.01, target: str = "both", rollout: float | None = None,
            n_masses=N_MASSES, dts=DTS, integrators=INTEGRATORS) -> Resolution:
    """Fewest masses, cheapest integrator and largest step meeting ``tol`` on ``target``.

    problem: the scene (:func:`bullet_dlo.sim.resolve_problem`; its n_masses, dt and integrator are chosen);
    rollout: seconds simulated per trial (default: the scene's duration, at most 2 s);
    n_masses, dts [s], integrators: the candidates, tried fewest, largest and cheapest first.
    """
    tol = check_positive("tol", tol)
    target = name_of("target", target, ToleranceTarget)
    if not isinstance(problem, ResolveProblem):
        raise TypeError(f"resolve takes a ResolveProblem (bullet_dlo.sim.resolve_problem(scene)), "
                        f"got {type(problem).__name__}")
    rollout = min(problem.duration, 2.0) if rollout is None else check_positive("rollout", rollout)
    problem, why_twist = with_twist(problem)
    fine_dt = min(min(dts) / 2, 1e-3)
    trials: list = []
    floor, why_floor = contact_floor(problem)
    candidates = tuple(n for n in n_masses if n >= floor) or (floor,)
    chosen_n, spatial, reference = _resolve_masses(problem, tol, target, rollout, candidates, fine_dt, trials)
    why = f"n = {chosen_n}: the fewest masses whose estimated {target} error ({spatial:.2g}) is within tol/2"
    if floor > 2:
        why += f"; {why_floor}" + (" (the binding bound)" if chosen_n == candidates[0] else "")
    why += f"; {why_twist}" if why_twist else "; no material frame: a round cable whose clamps never roll"
    for dt in sorted(dts, reverse=True):
        for integ in integrators:
            res, cost = _rollout(problem, chosen_n, integ, dt, rollout)
            if not res.stable:
                trials.append({"n": chosen_n, "dt": dt, "integrator": integ, "temporal": None})
                continue
            err = _difference(res, reference, target, problem.cable.length)
            trials.append({"n": chosen_n, "dt": dt, "integrator": integ, "temporal": err})
            if err <= 0.5 * tol:
                res, cost = _rollout(problem, chosen_n, integ, dt, rollout)  # again, compiled: a fair cost
                return Resolution(chosen_n, dt, integ, _cable(problem, chosen_n).damping, spatial + err, spatial, err,
                                  cost, target, tol, rollout, trials, why, problem.cable.twist_enabled)
    raise ParameterError(f"n = {chosen_n} meets the spatial part, but no step down to {min(dts)} s meets "
                         f"the temporal part of tol = {tol}")
