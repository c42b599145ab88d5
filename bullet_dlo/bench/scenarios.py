"""Speed against accuracy: benchmark scenarios with known answers, work-precision data,
stability maps and the cost of the implicit solve.

Scenarios (each returns an error against its known answer and the wall time per simulated
second of the run that produced it):

* S1: clamped cantilever under its own weight, small deflection: tip deflection vs
  delta = w L^4 / (8 E I) (settled with damping from the straight start).
* S2: the same cantilever released from a small deflection, undamped: first frequency vs
  f1 = 1.8751^2/(2 pi) sqrt(E I / (rho A L^4)), and the amplitude kept after 1 s.
* S3: the study's scenario (Lv cable clamped at both ends, one end lifted 5 mm): end forces
  against a converged reference run (n = 41, BDF2 at 0.1 ms), as 0.2 s means (see
  :func:`force_error`).
* S4: a slack, thin cable hanging between two pinned ends 0.25 m apart: sag and end forces
  against the catenary.
"""
from __future__ import annotations

import csv
import math
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from bullet_dlo.analysis.closed_forms import (
    cantilever_deflection,
    cantilever_frequency,
    cantilever_model,
    small_deflection_spec,
    zero_crossing_frequency,
)
from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import DetectorOptions, simulate
from bullet_dlo.core.integrators import INTEGRATORS
from bullet_dlo.core.model import CableModel, CableState
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.statics import solve_static

SCENARIOS = ("S1", "S2", "S3", "S4")


@dataclass
class BenchPoint:
    """One run: scenario, engine, integrator, n, dt [s]; error (relative, NaN if unstable);
    wall time per simulated second [s]; extra: amplitude kept (S2) or None."""

    scenario: str
    engine: str
    integrator: str
    n: int
    dt: float
    stable: bool
    error: float
    wall_per_sim_s: float
    extra: float | None = None


# ----- scenario definitions ------------------------------------------------------------------------
def s1_spec(n: int) -> CableSpec:
    """Stiff Lv-geometry cantilever: tip deflects 1e-3 L; damping critical for the first mode."""
    spec = small_deflection_spec(n)
    omega1 = 2 * math.pi * cantilever_frequency(spec)
    return spec.with_(damping=2.0 * omega1 * spec.mass / n)


def _run(model, integrator, dt, duration, engine, state=None, record=400):
    """Run with the core or the Bullet engine; returns (stable, t, x, end_forces, wall per sim second)."""
    if engine == "core":
        res = simulate(model, integrator, dt, duration, state=state, max_records=record + 1)
        sim = res.steps * dt
        return res.stable, res.t, res.x, res.end_forces, res.wall_time_s / max(sim, 1e-12)
    from bullet_dlo.bullet.world import BulletWorld

    steps = max(1, int(round(duration / dt)))
    every = max(1, steps // record)
    with BulletWorld(dt=dt, gravity=model.gravity, ground=False) as world:
        cable = world.add_cable(model, integrator=integrator, state=state, record_every=every)
        wall = world.run_while_stable(steps, cable)
        rec = cable.record.arrays()
        return cable.stable, rec["t"], rec["x"], rec["end_forces"], wall / max(cable.steps * dt, 1e-12)


def s1(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 1.0) -> BenchPoint:
    spec = s1_spec(n)
    ok, t, x, f, cost = _run(cantilever_model(spec), integrator, dt, duration, engine)
    err = abs((0.5 - x[-1, -1, 2]) / cantilever_deflection(spec) - 1.0) if ok else float("nan")
    return BenchPoint("S1", engine, integrator, n, dt, ok, err, cost)


def s2(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 1.0) -> BenchPoint:
    spec = s1_spec(n).with_(damping=0.0)
    g_small = 9.81 * 1e-3 * spec.length / cantilever_deflection(spec)  # tip deflects 1e-3 L
    start = solve_static(cantilever_model(spec, g_small)).x
    model = cantilever_model(spec, 0.0)
    ok, t, x, f, cost = _run(model, integrator, dt, duration, engine, CableState(start, np.zeros_like(start)),
                             record=4000)
    if not ok:
        return BenchPoint("S2", engine, integrator, n, dt, False, float("nan"), cost)
    y = x[:, -1, 2] - 0.5
    freq = zero_crossing_frequency(t, y)
    a0 = abs(y[0])
    period = 1.0 / cantilever_frequency(spec)
    kept = float(np.max(np.abs(y[t >= t[-1] - period])) / a0)
    return BenchPoint("S2", engine, integrator, n, dt, True, abs(freq / cantilever_frequency(spec) - 1.0), cost, kept)


def s3_model(n: int) -> CableModel:
    """The study's scenario with the damping rate of k_d = 0.01 N s/m at n = 10 (gamma = 3.3 1/s) for every n."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.01 * 10 / n)
    return CableModel.straight(spec, (0, 0, 0.5), (1, 0, 0), ("clamped", "clamped"),
                               [Move("last", (0.0, 0.0, 0.005), 0.1, 0.1)])


@lru_cache(maxsize=2)
def s3_reference(duration: float = 0.6) -> tuple[np.ndarray, np.ndarray]:
    """Converged end forces of the study's scenario: n = 41, BDF2 at 0.1 ms, from the settled state."""
    model = s3_model(41)
    res = simulate(model, "bdf2", 1e-4, duration, state=solve_static(model).state(), max_records=601)
    return res.t, res.end_forces


def s3(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 0.6) -> BenchPoint:
    model = s3_model(n)
    ok, t, x, f, cost = _run(model, integrator, dt, duration, engine, solve_static(model).state())
    if not ok:
        return BenchPoint("S3", engine, integrator, n, dt, False, float("nan"), cost)
    tr, fr = s3_reference(duration)
    err = force_error(t, f, tr, fr)
    return BenchPoint("S3", engine, integrator, n, dt, True, err, cost)


def force_error(t: np.ndarray, f: np.ndarray, t_ref: np.ndarray, f_ref: np.ndarray, block: float = 0.2) -> float:
    """RMS difference of end forces (k, 2, 3) [N] in ``block``-second means (what a 5 Hz force
    sensor sees), relative to the reference's peak force.

    Pointwise histories are not a fair target: with absolute (air-like) damping only, the
    stiff axial and clamp modes that a move excites ring on, and refining n adds new ones.
    """
    edges = np.arange(t_ref[0], t_ref[-1] + 1e-12, block)
    rows_a, rows_b = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        rows_a.append(f[(t >= lo) & (t < hi)].mean(axis=0))
        rows_b.append(f_ref[(t_ref >= lo) & (t_ref < hi)].mean(axis=0))
    a, b = np.array(rows_a), np.array(rows_b)
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))) / np.max(np.abs(f_ref)))


def catenary(span: float, length: float, weight_per_length: float) -> tuple[float, float, float]:
    """Catenary through two points at equal height: (sag [m], horizontal force [N], vertical force per end [N])."""
    lo, hi = 1e-6, 1e3  # parameter a [m]: L = 2 a sinh(s / 2a)
    for _ in range(200):
        a = math.sqrt(lo * hi)
        if 2 * a * math.sinh(span / (2 * a)) > length:
            lo = a
        else:
            hi = a
    a = math.sqrt(lo * hi)
    return a * (math.cosh(span / (2 * a)) - 1.0), weight_per_length * a, weight_per_length * length / 2


def s4_model(n: int) -> CableModel:
    """A thin (0.3 mm: bending carries < 0.3 % of the load), flexible cable pinned at both ends;
    the last end moves in to a 0.25 m span."""
    spec = CableSpec(length=0.3, diameter=0.0003, mass=0.01, youngs_modulus=2e9, n_masses=n, damping=0.0)
    spec = spec.with_(damping=40.0 * spec.mass / n)  # settles in about a second
    return CableModel.straight(spec, (0, 0, 0.5), (1, 0, 0), ("pinned", "pinned"),
                               [Move("last", (-0.05, 0.0, 0.0), 0.0, 0.3)])


def s4(n: int, integrator: str, dt: float, engine: str = "core", duration: float = 2.0) -> BenchPoint:
    model = s4_model(n)
    ok, t, x, f, cost = _run(model, integrator, dt, duration, engine)
    if not ok:
        return BenchPoint("S4", engine, integrator, n, dt, False, float("nan"), cost)
    spec = model.spec
    sag_ref, h_ref, v_ref = catenary(0.25, spec.length, spec.mass * 9.81 / spec.length)
    sag = 0.5 - float(np.min(x[-1, :, 2]))
    fh = abs(f[-1, 0, 0])
    fv = abs(f[-1, 0, 2])
    err = max(abs(sag / sag_ref - 1), abs(fh / h_ref - 1), abs(fv / v_ref - 1))
    return BenchPoint("S4", engine, integrator, n, dt, True, err, cost)


RUNNERS = {"S1": s1, "S2": s2, "S3": s3, "S4": s4}


def scenario_model(scenario: str, n: int) -> CableModel:
    """The model a scenario runs (for its stability limits)."""
    if scenario == "S1":
        return cantilever_model(s1_spec(n))
    if scenario == "S2":
        return cantilever_model(s1_spec(n).with_(damping=0.0), 0.0)
    return s3_model(n) if scenario == "S3" else s4_model(n)


# ----- work-precision ----------------------------------------------------------------------------
def default_steps(integrator: str, quick: bool, critical: float | None = None) -> list[float]:
    """Steps to sweep: robot rates and below for implicit methods; fractions of the predicted
    limit for explicit ones (and one step beyond it, to show the failure)."""
    if INTEGRATORS[integrator].explicit:
        fractions = (1.2, 0.9, 0.3) if quick else (1.2, 0.9, 0.5, 0.2)
        return [f * critical for f in fractions] if critical else []
    return [1e-3, 1 / 240] if quick else [1 / 60, 1 / 240, 1e-3, 5e-4, 2e-4]


def work_precision(scenarios: Sequence[str] = SCENARIOS, integrators: Iterable[str] | None = None,
                   masses: Sequence[int] = (10, 20, 40), engines: Sequence[str] = ("core",), quick: bool = False,
                   progress=None) -> list[BenchPoint]:
    """Every scenario x engine x integrator x n x dt (explicit Euler is left out: it needs
    heavy damping to be stable at all, which would change the scenarios)."""
    from bullet_dlo.core.stability import critical_dt

    names = list(integrators or [i for i in INTEGRATORS if i != "explicit_euler"])
    rows = []
    for sc in scenarios:
        for engine in engines:
            for name in names:
                for n in masses:
                    crit = critical_dt(scenario_model(sc, n), name)
                    for dt in default_steps(name, quick, crit):
                        point = RUNNERS[sc](n, name, dt, engine)
                        rows.append(point)
                        if progress:
                            progress(point)
    return rows


def write_csv(rows: Sequence[BenchPoint], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        w.writeheader()
        for r in rows:
            w.writerow(asdict(r))
    return path


COLORS = {"symplectic_euler": "tab:red", "rk4": "tab:brown", "implicit_euler": "tab:blue", "bdf2": "tab:orange",
          "implicit_midpoint": "tab:purple", "explicit_euler": "tab:gray"}
PEER_STYLE = {"pyelastica": ("*", "tab:green"), "mujoco": ("P", "tab:cyan")}


def pareto(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """Lower-left envelope of (cost, error) points: the cheapest run for each accuracy."""
    front, best = [], math.inf
    for cost, err in sorted(points):
        if err < best:
            front.append((cost, err))
            best = err
    return front


def plot_work_precision(rows: Sequence[BenchPoint], path: str | Path, peers: Sequence = ()) -> Path:
    """Log-log error vs wall time per simulated second, one panel per scenario: every run as a
    dot (hollow: Bullet engine), the cheapest-for-its-accuracy front of each method as a line,
    unstable runs as x along the top, peers as stars/crosses."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scen = sorted({r.scenario for r in rows})
    fig, axes = plt.subplots(1, len(scen), figsize=(4.3 * len(scen), 4.0), squeeze=False)
    for ax, sc in zip(axes[0], scen):
        sel = [r for r in rows if r.scenario == sc]
        top = max([r.error for r in sel if r.stable and r.error > 0] or [1.0]) * 3
        for name in [m for m in COLORS if any(r.integrator == m for r in sel)]:
            color = COLORS[name]
            for engine, face in (("core", color), ("bullet", "none")):
                pts = [(r.wall_per_sim_s, r.error) for r in sel
                       if r.integrator == name and r.engine == engine and r.stable and r.error > 0]
                if not pts:
                    continue
                ax.loglog(*zip(*pts), "o", ms=3.5, mfc=face, mec=color, alpha=0.6)
                front = pareto(pts)
                ax.loglog(*zip(*front), color=color, lw=1.5 if engine == "core" else 0.8,
                          ls="-" if engine == "core" else "--",
                          label=name + ("" if engine == "core" else " (Bullet)"))
            bad = [r.wall_per_sim_s for r in sel if r.integrator == name and not r.stable]
            if bad:
                ax.loglog(bad, [top] * len(bad), "x", color=color)
        for peer, (marker, color) in PEER_STYLE.items():
            pts = [(p["wall_per_sim_s"], p["error"]) for p in peers
                   if p.get("scenario") == sc and p.get("peer") == peer and p.get("stable") and p.get("error")]
            if pts:
                ax.loglog(*zip(*pts), marker, ms=9, color=color, label=peer)
        ax.axhline(0.01, color="grey", lw=0.8, ls=":")
        ax.set_title(f"{sc}  (x: unstable run)")
        ax.set_xlabel("wall time per simulated second [s]")
        ax.set_ylabel("relative error")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=6, loc="lower left")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ----- stability map -----------------------------------------------------------------------------
def stability_map(moduli: Sequence[float] = (1e6, 1e7, 1e8, 1e9, 1e10), masses: Sequence[int] = (10, 40),
                  integrators: Sequence[str] = ("symplectic_euler", "rk4"), duration: float = 0.2,
                  implicit_steps: Sequence[float] = (1e-3, 1 / 60)) -> list[dict]:
    """Largest stable dt (bisection) and the predicted one, per E, n and explicit method (study's
    scenario, k_d = 0.01); implicit methods are checked at ``implicit_steps`` instead."""
    from bullet_dlo.analysis.study import study_model
    from bullet_dlo.core.stability import critical_dt, measured_critical_dt

    rows = []
    for e in moduli:
        for n in masses:
            model = study_model(e, n, 0.01)
            start = solve_static(model).state()
            for name in integrators:
                pred = critical_dt(model, name)
                meas = measured_critical_dt(model, name, duration, state=start, rel_tol=0.02)
                rows.append(dict(youngs_modulus=e, n_masses=n, integrator=name, predicted=pred, measured=meas))
            for name in ("implicit_euler", "bdf2"):
                ok = all(simulate(model, name, dt, 1.0, state=start, max_records=3).stable for dt in implicit_steps)
                rows.append(dict(youngs_modulus=e, n_masses=n, integrator=name, predicted=None,
                                 measured=max(implicit_steps) if ok else None))
    return rows


def plot_stability_map(rows: Sequence[dict], path: str | Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for (name, n) in sorted({(r["integrator"], r["n_masses"]) for r in rows if r["predicted"]}):
        sel = sorted([r for r in rows if r["integrator"] == name and r["n_masses"] == n],
                     key=lambda r: r["youngs_modulus"])
        e = [r["youngs_modulus"] for r in sel]
        line, = ax.loglog(e, [r["measured"] for r in sel], "o", label=f"{name} n={n} measured")
        ax.loglog(e, [r["predicted"] for r in sel], "-", color=line.get_color(), lw=1, label=f"{name} n={n} predicted")
    ax.axhline(1e-3, color="grey", ls="--", lw=1)
    ax.axhline(1 / 60, color="grey", ls=":", lw=1)
    ax.text(1.1e6, 1.15e-3, "1 kHz (Gazebo)", fontsize=7)
    ax.text(1.1e6, 1.15 / 60, "60 Hz (Isaac Sim): implicit_euler, bdf2 stable", fontsize=7)
    ax.set_xlabel("Young's modulus E [Pa]")
    ax.set_ylabel("largest stable time step [s]")
    ax.set_title("Stability limits, study's scenario (k_d = 0.01)")
    ax.legend(fontsize=6)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# ----- cost of the implicit solve ----------------------------------------------------------------
def implicit_scaling(masses: Sequence[int] = (50, 100, 200, 500, 1000), steps: int = 200) -> tuple[list[dict], float]:
    """Wall time per implicit-Euler step vs n, and the fitted exponent of cost ~ n^p."""
    rows = []
    for n in masses:
        spec = CableSpec.lv2017(n_masses=n, damping=0.01)
        model = CableModel.straight(spec, ends=("clamped", "clamped"))
        simulate(model, "implicit_euler", 1e-3, 5e-3, max_records=3)
        res = simulate(model, "implicit_euler", 1e-3, steps * 1e-3, max_records=3,
                       detector=DetectorOptions(energy_every=10**6))
        rows.append({"n_masses": n, "seconds_per_step": res.wall_time_s / res.steps})
    x = np.log([r["n_masses"] for r in rows])
    y = np.log([r["seconds_per_step"] for r in rows])
    return rows, float(np.polyfit(x, y, 1)[0])
