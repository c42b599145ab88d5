"""Benchmark scenarios with known answers: S1-S4 and their references.

Each scenario runner returns a :class:`BenchPoint`: the error against the scenario's known
answer and the wall time per simulated second of the run that produced it.

* S1: clamped cantilever under its own weight, small deflection: tip deflection vs
  delta = w L^4 / (8 E I) (settled with damping from the straight start).
* S2: the same cantilever released from a small deflection, undamped: first frequency vs
  f1 = 1.8751^2/(2 pi) sqrt(E I / (rho A L^4)), and the amplitude kept over the last full period of 1 s.
* S3: the study's scenario (Lv cable clamped at both ends, one end lifted 5 mm): end forces
  against a converged reference run (n = 41, BDF2 at 0.1 ms), as 0.2 s means
  (:func:`bullet_dlo.analysis.measures.force_error`).
* S4: a slack, thin cable hanging between two pinned ends 0.25 m apart: sag and end forces
  against the catenary.
* T1 (twist, issue 22): pure torsion: the Lv cable with a material frame, clamped at both ends, no
  gravity, the last clamp rolled by pi/2 about the cable axis; the moments about the axis at both
  ends vs G J (pi/2) / L.
* T2 (twist): a steel strip cantilever (10 mm x 1 mm) under gravity whose clamp rolls it edge-on
  (90 degrees about the axis) in a run: the tip sag vs w L^4 / (8 E I_strong).

The twisting scenarios run the implicit methods only (:data:`TWIST_SCENARIOS`): the twist is an
implicit sub-step in every method, and the steel strip's explicit limit is a few microseconds.

Every run goes through :func:`run_model`, with the core engine or coupled to Bullet.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from bullet_dlo.analysis.closed_forms import (
    CLAMP_HEIGHT,
    GRAVITY,
    cantilever_angular_frequency,
    cantilever_deflection,
    cantilever_frequency,
    cantilever_model,
    cantilever_release,
    catenary,
    small_deflection_spec,
    with_damping_rate,
)
from bullet_dlo.analysis.measures import (amplitude_kept, force_error, relative_error, wrench_error,
                                         zero_crossing_frequency)
from bullet_dlo.analysis.study import study_model
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.enums import Engine
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

SCENARIOS = ("S1", "S2", "S3", "S4", "T1", "T2")
TWIST_SCENARIOS = ("T1", "T2")
"""Scenarios whose cable has a material frame (run with the implicit methods only)."""
ENGINES = (Engine.CORE.value, Engine.BULLET.value)  # the engines a scenario runs on (of bullet_dlo.core.enums.Engine)


@dataclass
class BenchPoint:
    """One run: scenario, engine, integrator, n (number of masses), dt [s]; error (relative, NaN
    if unstable); wall time per simulated second [s]; extra: amplitude kept (S2) or None."""

    scenario: str
    engine: str
    integrator: str
    n: int
    dt: float
    stable: bool
    error: float
    wall_per_sim_s: float
    extra: float | None = None


class Run(NamedTuple):
    """A recorded run: stable, t (k,) [s], x (k, n, 3) [m], end forces (k, 2, 3) [N], wall per sim s [s]."""

    stable: bool
    t: np.ndarray
    x: np.ndarray
    end_forces: np.ndarray
    wall_per_sim_s: float


def run_model(model: CableModel, integrator: str, dt: float, duration: float, engine: str = "core",
              state: CableState | None = None, records: int = 400) -> Run:
    """Run ``model`` for ``duration`` [s] with the core engine or coupled to Bullet (no ground),
    keeping about ``records`` samples."""
    if engine == "core":
        res = simulate(model, integrator, dt, duration, state=state, max_records=records + 1)
        return Run(res.stable, res.t, res.x, res.end_forces, res.wall_time_s / max(res.steps * dt, 1e-12))
    from bullet_dlo.bullet.world import BulletWorld

    n_steps = max(1, int(round(duration / dt)))
    with BulletWorld(dt=dt, gravity=model.gravity, ground=False) as world:
        cable = world.add_cable(model, integrator=integrator, state=state, record_every=max(1, n_steps // records))
        wall = world.run_while_stable(n_steps, cable)
        rec = cable.record.arrays()
        return Run(cable.stable, rec["t"], rec["x"], rec["end_forces"], wall / max(cable.steps * dt, 1e-12))


def _unstable(scenario: str, engine: str, integrator: str, n: int, dt: float, run: Run) -> BenchPoint:
    return BenchPoint(scenario, engine, integrator, n, dt, False, float("nan"), run.wall_per_sim_s)


# ----- S1, S2: the cantilever --------------------------------------------------------------------
def s1_spec(n: int) -> CableSpec:
    """Stiff Lv-geometry cantilever: tip deflects 1e-3 L; damping critical for the first mode (rate 2 omega1)."""
    spec = small_deflection_spec(n)
    return with_damping_rate(spec, 2.0 * cantilever_angular_frequency(spec))


def s1(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 1.0) -> BenchPoint:
    """S1: static tip deflection after ``duration`` [s] of damped settling, vs w L^4 / (8 E I)."""
    spec = s1_spec(n)
    run = run_model(cantilever_model(spec), integrator, dt, duration, engine)
    if not run.stable:
        return _unstable("S1", engine, integrator, n, dt, run)
    err = relative_error(CLAMP_HEIGHT - run.x[-1, -1, 2], cantilever_deflection(spec))
    return BenchPoint("S1", engine, integrator, n, dt, True, err, run.wall_per_sim_s)


def s2(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 1.0) -> BenchPoint:
    """S2: first frequency of the undamped cantilever released from a 1e-3 L tip deflection, vs f1;
    ``extra`` is the amplitude kept over the last period."""
    spec = s1_spec(n).with_(damping=0.0, damping_rate=0.0)
    model, start = cantilever_release(spec, 1e-3)
    run = run_model(model, integrator, dt, duration, engine, start, records=4000)
    if not run.stable:
        return _unstable("S2", engine, integrator, n, dt, run)
    y = run.x[:, -1, 2] - CLAMP_HEIGHT
    err = relative_error(zero_crossing_frequency(run.t, y), cantilever_frequency(spec))
    return BenchPoint("S2", engine, integrator, n, dt, True, err, run.wall_per_sim_s, amplitude_kept(run.t, y))


# ----- S3: the study's scenario ------------------------------------------------------------------
def s3_model(n: int) -> CableModel:
    """The study's scenario, the 5 mm lift from 0.1 s to 0.2 s, with the damping rate of
    k_d = 0.01 N s/m at n = 10 (gamma = 3.3 1/s) for every n."""
    return study_model(CableSpec.lv2017().youngs_modulus, n, 0.01 * 10 / n, move_start=0.1, move_duration=0.1)


@lru_cache(maxsize=2)
def s3_reference(duration: float = 0.6) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Converged end loads of the study's scenario: t (k,) [s], forces (k, 2, 3) [N], clamp moments (k, 2, 3)
    [N m]; n = 41, BDF2 at 0.1 ms, from the settled state."""
    model = s3_model(41)
    res = simulate(model, "bdf2", 1e-4, duration, state=solve_static(model).state(), max_records=601)
    return res.t, res.end_forces, res.end_moment_history


def s3(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 0.6) -> BenchPoint:
    """S3: end forces in 0.2 s means against :func:`s3_reference`."""
    model = s3_model(n)
    run = run_model(model, integrator, dt, duration, engine, solve_static(model).state())
    if not run.stable:
        return _unstable("S3", engine, integrator, n, dt, run)
    t, forces, _ = s3_reference(duration)
    err = force_error(run.t, run.end_forces, t, forces)
    return BenchPoint("S3", engine, integrator, n, dt, True, err, run.wall_per_sim_s)


def s3_wrench_error(n: int, integrator: str, dt: float, duration: float = 0.6) -> float:
    """S3's end forces and clamp moments against :func:`s3_reference` (:func:`~bullet_dlo.analysis.measures.
    wrench_error`, what ``resolve``'s target ``forces`` converges) [-]; NaN when the run is unstable (core engine)."""
    model = s3_model(n)
    res = simulate(model, integrator, dt, duration, state=solve_static(model).state(), max_records=401)
    if not res.stable:
        return float("nan")
    t, forces, moments = s3_reference(duration)
    return wrench_error(res.t, res.end_forces, res.end_moment_history, t, forces, moments, model.spec.length)


# ----- S4: the catenary --------------------------------------------------------------------------
S4_SPAN = 0.25
"""Distance between the pinned ends of S4 after the move [m]."""


def s4_model(n: int) -> CableModel:
    """A thin (0.3 mm: bending carries < 0.3 % of the load), flexible cable pinned at both ends;
    the last end moves in to a 0.25 m span; damping rate 40 1/s settles it in about a second."""
    spec = CableSpec(length=0.3, diameter=0.0003, mass=0.01, youngs_modulus=2e9, n_masses=n, damping=0.0)
    return CableModel.straight(with_damping_rate(spec, 40.0), (0, 0, CLAMP_HEIGHT), (1, 0, 0), ("pinned", "pinned"),
                               [Move("last", (S4_SPAN - spec.length, 0.0, 0.0), 0.0, 0.3)])


def s4(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 2.0) -> BenchPoint:
    """S4: sag, horizontal and vertical end force (largest relative error of the three) vs the catenary."""
    model = s4_model(n)
    run = run_model(model, integrator, dt, duration, engine)
    if not run.stable:
        return _unstable("S4", engine, integrator, n, dt, run)
    spec = model.spec
    sag_ref, h_ref, v_ref = catenary(S4_SPAN, spec.length, spec.mass * GRAVITY / spec.length)
    sag = CLAMP_HEIGHT - float(np.min(run.x[-1, :, 2]))
    f_end = run.end_forces[-1, 0]
    err = max(relative_error(sag, sag_ref), relative_error(abs(f_end[0]), h_ref), relative_error(abs(f_end[2]), v_ref))
    return BenchPoint("S4", engine, integrator, n, dt, True, err, run.wall_per_sim_s)


# ----- T1, T2: twist (issue 22) ------------------------------------------------------------------
T1_ROLL = 0.5 * np.pi
"""Roll of the last clamp of T1 about the cable axis [rad]."""


def t1_model(n: int, twist: bool = True) -> CableModel:
    """T1: the Lv cable (with a material frame unless ``twist`` is False: the same cable's model of before)
    clamped at both ends without gravity; the last clamp rolls by pi/2 about the axis from 0.05 s over
    0.3 s; twist damping rate 5 1/s and internal damping 1 ms settle it."""
    spec = CableSpec.lv2017(n_masses=n, twist=twist, damping_rate=5.0, internal_damping=1e-3)
    return CableModel.straight(spec, (0, 0, CLAMP_HEIGHT), (1, 0, 0), ("clamped", "clamped"),
                               [Move("last", rotation=(T1_ROLL, 0.0, 0.0), start=0.05, duration=0.3)], (0, 0, 0))


def t1(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 1.0) -> BenchPoint:
    """T1: the end moments about the axis after ``duration`` [s] vs G J (pi/2) / L (the larger error of
    the two ends). Core engine only (the clamp moments are the core's ``end_moments``)."""
    if engine != "core":
        raise ValueError("T1 runs on the core engine only")
    model = t1_model(n)
    res = simulate(model, integrator, dt, duration, max_records=401)
    if not res.stable:
        return BenchPoint("T1", engine, integrator, n, dt, False, float("nan"), res.wall_time_s / max(res.steps * dt, 1e-12))
    spec = model.spec
    expected = spec.torsional_rigidity * T1_ROLL / spec.length
    err = max(relative_error(res.end_moments[0, 0], expected), relative_error(-res.end_moments[1, 0], expected))
    return BenchPoint("T1", engine, integrator, n, dt, True, err, res.wall_time_s / max(res.steps * dt, 1e-12))


def t2_model(n: int) -> CableModel:
    """T2: a steel strip 0.3 m x 10 mm x 1 mm clamped flat (thickness vertical) at one end, free at the
    other, under gravity; the clamp rolls it 90 degrees about the axis from 0.05 s over 0.3 s (edge-on);
    damping rate 20 1/s and internal damping 0.1 ms settle it."""
    spec = CableSpec(length=0.3, diameter=0.001, mass=0.024, youngs_modulus=2e11, section="rectangle", width=0.01,
                     thickness=0.001, n_masses=n, damping_rate=20.0, internal_damping=1e-4)
    return CableModel.straight(spec, (0, 0, CLAMP_HEIGHT), (1, 0, 0), ("clamped", "free"),
                               [Move("first", rotation=(0.5 * np.pi, 0.0, 0.0), start=0.05, duration=0.3)])


def t2(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 0.8) -> BenchPoint:
    """T2: the tip sag after ``duration`` [s] vs w L^4 / (8 E I_strong) (the strip edge-on)."""
    model = t2_model(n)
    run = run_model(model, integrator, dt, duration, engine)
    if not run.stable:
        return _unstable("T2", engine, integrator, n, dt, run)
    spec = model.spec
    w = spec.mass * GRAVITY / spec.length
    sag = w * spec.length**4 / (8 * max(spec.bending_rigidities))
    err = relative_error(CLAMP_HEIGHT - run.x[-1, -1, 2], sag)
    return BenchPoint("T2", engine, integrator, n, dt, True, err, run.wall_per_sim_s)


RUNNERS = {"S1": s1, "S2": s2, "S3": s3, "S4": s4, "T1": t1, "T2": t2}


def scenario_model(scenario: str, n: int) -> CableModel:
    """The model a scenario runs (for its stability limits)."""
    if scenario == "S1":
        return cantilever_model(s1_spec(n))
    if scenario == "S2":
        return cantilever_release(s1_spec(n).with_(damping=0.0, damping_rate=0.0))[0]
    if scenario == "T1":
        return t1_model(n)
    if scenario == "T2":
        return t2_model(n)
    return s3_model(n) if scenario == "S3" else s4_model(n)
