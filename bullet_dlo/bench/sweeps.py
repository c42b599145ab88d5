"""Sweeps over the scenarios: work-precision, stability map, cost of the implicit solve, cost vs n
of a cable in Bullet with contact on.

Each sweep first lists its cases, then runs them through ``progress`` (any wrapper of a
sequence that yields its items, e.g. ``tqdm``), so that a caller can show progress and ETA.
"""
from __future__ import annotations

import csv
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Iterable, Sequence, TypeVar

import numpy as np

from bullet_dlo.analysis.study import study_model
from bullet_dlo.bench.scenarios import RUNNERS, SCENARIOS, TWIST_SCENARIOS, BenchPoint, scenario_model, t1_model
from bullet_dlo.core.engine import DetectorOptions, simulate
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.stability import critical_dt, measured_critical_dt
from bullet_dlo.core.statics import solve_static

T = TypeVar("T")
Progress = Callable[[Sequence[T]], Iterable[T]]
ROBOT_DTS = (1e-3, 1 / 60)
"""Time steps of the robot simulators [s]: Gazebo at 1 kHz, Isaac Sim at 60 Hz."""


def _no_progress(items: Sequence[T]) -> Iterable[T]:
    return items


# ----- work-precision ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    """One work-precision run: scenario, engine, integrator, number of masses n, time step dt [s]."""

    scenario: str
    engine: str
    integrator: str
    n: int
    dt: float

    def run(self) -> BenchPoint:
        return RUNNERS[self.scenario](self.n, self.integrator, self.dt, self.engine)


def default_dts(integrator: str, quick: bool, critical: float | None = None) -> list[float]:
    """Time steps [s] to sweep: robot rates and below for implicit methods; fractions of the
    predicted limit ``critical`` [s] for explicit ones (and one step beyond it, to show the failure)."""
    if INTEGRATORS[integrator].explicit:
        fractions = (1.2, 0.9) if quick else (1.2, 0.9, 0.5, 0.2)  # quick: the failure and one stable point
        return [f * critical for f in fractions] if critical else []
    if INTEGRATORS[integrator].order >= 4:  # gauss_legendre: its 4th-order phase keeps S2 within 1 % at ~6 ms
        return [5e-3, 1e-3] if quick else [1 / 60, 1 / 120, 1 / 160, 5e-3, 1 / 240, 2e-3, 1e-3]
    return [1e-3, 1 / 240] if quick else [1 / 60, 1 / 240, 1e-3, 5e-4, 2e-4]


def work_precision_cases(scenarios: Sequence[str] = SCENARIOS, integrators: Iterable[str] | None = None,
                         n_masses: Sequence[int] = (10, 20, 40), engines: Sequence[str] = ("core",),
                         quick: bool = False) -> list[Case]:
    """Every scenario x engine x integrator x n x dt (explicit Euler is left out: it needs heavy
    damping to be stable at all, which would change the scenarios). The twisting scenarios
    (:data:`~bullet_dlo.bench.scenarios.TWIST_SCENARIOS`) run the implicit methods on the core engine.
    ``quick`` runs the explicit methods at the smallest n only: their stable step falls as 1/n^2, so on the
    stiff cantilevers (S1, S2) one explicit run at n = 20 costs as much as the whole implicit sweep."""
    names = list(integrators or [i for i in INTEGRATORS if i != "explicit_euler"])
    cases = []
    for sc in scenarios:
        twisting = sc in TWIST_SCENARIOS
        for name in names:
            if twisting and INTEGRATORS[name].explicit:
                continue
            for n in (n_masses[:1] if quick and INTEGRATORS[name].explicit else n_masses):
                dts = default_dts(name, quick, critical_dt(scenario_model(sc, n), name))
                cases += [Case(sc, engine, name, n, dt) for engine in engines for dt in dts
                          if not (twisting and engine != "core")]
    return cases


def work_precision(cases: Sequence[Case], progress: Progress = _no_progress) -> list[BenchPoint]:
    """Run ``cases`` (from :func:`work_precision_cases`)."""
    return [case.run() for case in progress(cases)]


def cheapest(rows: Sequence[BenchPoint], scenario: str, tol: float) -> dict[tuple[str, str], BenchPoint]:
    """Cheapest stable run per (integrator, engine) of ``scenario`` with error <= ``tol``."""
    out: dict[tuple[str, str], BenchPoint] = {}
    for r in rows:
        if r.scenario == scenario and r.stable and r.error <= tol:
            key = (r.integrator, r.engine)
            if key not in out or r.wall_per_sim_s < out[key].wall_per_sim_s:
                out[key] = r
    return out


def fastest(rows: Sequence[BenchPoint], scenario: str, tol: float) -> BenchPoint | None:
    """The cheapest stable run of ``scenario`` with error <= ``tol`` over every method, or None."""
    return min(cheapest(rows, scenario, tol).values(), key=lambda r: r.wall_per_sim_s, default=None)


def write_csv(rows: Sequence[BenchPoint], path: str | Path) -> Path:
    """One CSV row per :class:`BenchPoint`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        writer.writeheader()
        writer.writerows(asdict(r) for r in rows)
    return path


# ----- stability map -----------------------------------------------------------------------------
def stability_map(moduli: Sequence[float] = (1e6, 1e7, 1e8, 1e9, 1e10), n_masses: Sequence[int] = (10, 40),
                  integrators: Sequence[str] = ("symplectic_euler", "rk4"), duration: float = 0.2,
                  implicit_dts: Sequence[float] = ROBOT_DTS, progress: Progress = _no_progress) -> list[dict]:
    """Largest stable dt [s] (bisection on ``duration``-second runs) and the predicted one, per E [Pa],
    n and explicit method (study's scenario, k_d = 0.01 N s/m); implicit Euler and BDF2 are
    checked at ``implicit_dts`` instead (measured: the largest of them if stable at all, else None)."""
    rows = []
    for e, n in progress([(e, n) for e in moduli for n in n_masses]):
        model = study_model(e, n, 0.01)
        start = solve_static(model).state()
        for name in integrators:
            rows.append(dict(youngs_modulus=e, n_masses=n, integrator=name, predicted=critical_dt(model, name),
                             measured=measured_critical_dt(model, name, duration, state=start, rel_tol=0.02)))
        for name in ("implicit_euler", "bdf2"):
            ok = all(simulate(model, name, dt, 1.0, state=start, max_records=3).stable for dt in implicit_dts)
            rows.append(dict(youngs_modulus=e, n_masses=n, integrator=name, predicted=None,
                             measured=max(implicit_dts) if ok else None))
    return rows


# ----- cost of the implicit solve ----------------------------------------------------------------
def implicit_scaling(n_masses: Sequence[int] = (50, 100, 200, 500, 1000), n_steps: int = 200,
                     progress: Progress = _no_progress) -> tuple[list[dict], float]:
    """Wall time per implicit-Euler step [s] vs n (``n_steps`` steps of 1 ms each), and the fitted
    exponent p of cost ~ n^p."""
    rows = []
    for n in progress(list(n_masses)):
        model = CableModel.straight(CableSpec.lv2017(n_masses=n, damping=0.01), ends=("clamped", "clamped"))
        simulate(model, "implicit_euler", 1e-3, 5e-3, max_records=3)  # warm the caches
        res = simulate(model, "implicit_euler", 1e-3, n_steps * 1e-3, max_records=3,
                       detector=DetectorOptions(energy_every=10**6))
        rows.append({"n_masses": n, "seconds_per_step": res.wall_time_s / res.steps})
    exponent = np.polyfit(np.log([r["n_masses"] for r in rows]), np.log([r["seconds_per_step"] for r in rows]), 1)[0]
    return rows, float(exponent)


# ----- cost of a coupled cable with contact on ---------------------------------------------------
COUPLED_PHASES = ("bullet", "model")


def _cable_on_table(n: int, dt: float):
    """A Lv cable of n masses lying straight on the ground at one radius, model contact, implicit Euler."""
    from bullet_dlo.bullet.world import BulletWorld

    spec = CableSpec.lv2017(n_masses=n, damping=0.01)
    world = BulletWorld(dt=dt)
    cable = world.add_cable(spec, start=(0.0, 0.0, 0.5 * spec.diameter), record_every=10**9)
    return world, cable


def _timed_steps(world, steps: int) -> tuple[float, float]:
    """Thread CPU time [s] of ``steps`` coupled steps (the phases of BulletWorld.step; nothing is hooked on
    these worlds): Bullet's own step and everything else (the cable's side: contacts, model step, I/O)."""
    import time

    bullet = total = 0.0
    for _ in range(steps):
        t0 = time.thread_time()
        world.push_cables()
        t1 = time.thread_time()
        world.step_physics()
        t2 = time.thread_time()
        world.take_cable_steps()
        t3 = time.thread_time()
        bullet += t2 - t1
        total += t3 - t0
    return total, bullet


def coupled_scaling(n_masses: Sequence[int] = (100, 200, 500, 1000), dt: float = 1.0 / 240.0, sim_time: float = 0.1,
                    repeats: int = 5, progress: Progress = _no_progress) -> tuple[list[dict], dict]:
    """CPU time per simulated second [s] of a cable lying on the ground (contact on: the model's) vs n.

    One world per n, warmed up (kernels, contacts settled) first; then ``repeats`` rounds, each timing
    ``sim_time`` [s] of steps of every n in turn (interleaved: load changes hit every n alike), with
    ``time.thread_time``. Rows: n_masses, cost (median), cost_min, cost_max, bullet (median CPU s per
    simulated second of Bullet's stepSimulation alone), model (the rest), all [s per s]. Also returns the
    fitted exponents p of cost ~ n^p over the whole range (total, bullet, model)."""
    worlds = {}
    for n in progress(list(n_masses)):
        world, cable = _cable_on_table(n, dt)
        world.step(max(5, int(round(0.05 / dt))))
        worlds[n] = (world, cable)
    steps = max(1, int(round(sim_time / dt)))
    sim = steps * dt
    times = {n: [] for n in n_masses}
    for _ in range(repeats):
        for n in n_masses:
            times[n].append(_timed_steps(worlds[n][0], steps))
    rows = []
    for n in n_masses:
        world, cable = worlds[n]
        total = np.array([t for t, _ in times[n]]) / sim
        bullet = np.array([b for _, b in times[n]]) / sim
        rows.append({"n_masses": n, "cost": float(np.median(total)), "cost_min": float(total.min()),
                     "cost_max": float(total.max()), "bullet": float(np.median(bullet)),
                     "model": float(np.median(total - bullet)), "stable": cable.stable,
                     "lowest_node_over_radius": float(cable.x[:, 2].min() / cable.radius)})
        world.close()
    logn = np.log([r["n_masses"] for r in rows])
    exponents = {key: float(np.polyfit(logn, np.log([r[key] for r in rows]), 1)[0]) for key in ("cost", "bullet", "model")}
    return rows, exponents


# ----- cost of the material frame (issue 22) -----------------------------------------------------
def twist_cost_model(n: int, twist: bool) -> CableModel:
    """The cost benchmark's scene: the Lv cable clamped at both ends under gravity, the last clamp lifted
    5 mm and rolled by pi/2 about the cable axis from 0.05 s over 0.3 s; with the material frame
    (``twist``) or the same round cable's model of before (the roll then does nothing)."""
    from bullet_dlo.core.boundary import Move

    spec = CableSpec.lv2017(n_masses=n, twist=twist, damping_rate=5.0, internal_damping=1e-3)
    return CableModel.straight(spec, (0, 0, 0.5), (1, 0, 0), ("clamped", "clamped"),
                               [Move("last", (0.0, 0.0, 0.005), 0.05, 0.3, (0.5 * np.pi, 0.0, 0.0))])


def twist_cost(n_masses: Sequence[int] = (10, 20, 40), integrators: Sequence[str] = ("implicit_euler", "bdf2"),
               dt: float = 1e-3, sim_time: float = 0.4, repeats: int = 7,
               progress: Progress = _no_progress) -> list[dict]:
    """Thread CPU time per step [s] of the twist-enabled step against today's round step at the same n.

    For each n and integrator, the same scene (:func:`twist_cost_model`) with and without the material
    frame, from the same settled start, ``sim_time`` [s] at ``dt`` [s], timed with ``time.thread_time``
    ``repeats`` times, the two interleaved (load changes hit both alike), after a warm-up run of each.
    Rows: n_masses, integrator, round and twist (median CPU s per step), their min and max, ratio (of the
    medians), ratio_min and ratio_max (over the interleaved pairs), newton_round and newton_twist (Newton
    iterations per step of the last run), load (the 1-minute load average at the end)."""
    import os
    import time

    rows = []
    steps = max(1, int(round(sim_time / dt)))
    for n, name in progress([(n, name) for n in n_masses for name in integrators]):
        models = {key: twist_cost_model(n, key == "twist") for key in ("round", "twist")}
        starts = {key: solve_static(m).state() for key, m in models.items()}
        det = DetectorOptions(energy_every=10**6)
        times: dict[str, list[float]] = {"round": [], "twist": []}
        iters = {}
        for rep in range(repeats + 1):
            for key in ("round", "twist") if rep % 2 == 0 else ("twist", "round"):
                model = twist_cost_model(n, key == "twist")  # fresh twist state: every run starts alike
                t0 = time.thread_time()
                res = simulate(model, name, dt, steps * dt, state=starts[key], max_records=3, detector=det)
                cpu = time.thread_time() - t0
                if rep > 0:  # the first round warms the caches
                    times[key].append(cpu / res.steps)
                iters[key] = res.newton_iterations / max(res.steps, 1)
                assert res.stable, f"twist cost run unstable (n = {n}, {name}, {key})"
        a, b = np.array(times["round"]), np.array(times["twist"])
        pair = b / a
        rows.append({"n_masses": n, "integrator": name, "round": float(np.median(a)), "round_min": float(a.min()),
                     "round_max": float(a.max()), "twist": float(np.median(b)), "twist_min": float(b.min()),
                     "twist_max": float(b.max()), "ratio": float(np.median(b) / np.median(a)),
                     "ratio_min": float(pair.min()), "ratio_max": float(pair.max()),
                     "newton_round": iters["round"], "newton_twist": iters["twist"],
                     "load": float(os.getloadavg()[0])})
    return rows
