"""Charts of the benchmarks: work-precision (error vs cost) and the stability map.

Every chart: a title, axis labels with units, one legend outside the data, and log axes that
span at least a decade so that only whole powers of ten are labelled.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

from bullet_dlo.bench.scenarios import BenchPoint

COLORS = {"symplectic_euler": "tab:red", "rk4": "tab:olive", "implicit_euler": "tab:blue", "bdf2": "tab:orange",
          "implicit_midpoint": "tab:purple", "gauss_legendre": "tab:brown", "explicit_euler": "tab:gray"}
PEER_STYLE = {"pyelastica": ("*", "tab:green"), "mujoco": ("P", "tab:cyan"), "newton": ("X", "tab:olive")}
SCENARIO_TITLES = {"S1": "S1: cantilever, static tip deflection", "S2": "S2: cantilever, first frequency",
                   "S3": "S3: study's lift, end forces (0.2 s means)", "S4": "S4: catenary, sag and end forces",
                   "T1": "T1: pure torsion, end moments G J theta / L", "T2": "T2: strip rolled edge-on, tip sag"}
TARGET_ERROR = 0.01


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def pareto(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """Lower-left envelope of (cost, error) points: the cheapest run for each accuracy."""
    front, best = [], math.inf
    for cost, err in sorted(points):
        if err < best:
            front.append((cost, err))
            best = err
    return front


def _log_limits(values: Sequence[float]) -> tuple[float, float]:
    """Axis limits around positive ``values``: the whole decades that hold them (so at least two
    powers of ten are labelled), with a margin of 1.5 x where a value sits near a decade."""
    lo = 10.0 ** math.floor(math.log10(min(values) / 1.5))
    hi = 10.0 ** math.ceil(math.log10(max(values) * 1.5))
    return lo, hi


def _decade_ticks(ax) -> None:
    """Label whole powers of ten only (minor ticks stay, unlabelled)."""
    from matplotlib.ticker import LogLocator, NullFormatter

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(LogLocator(base=10.0, numticks=8))
        axis.set_minor_formatter(NullFormatter())


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def plot_work_precision(rows: Sequence[BenchPoint], path: str | Path, peers: Sequence[dict] = ()) -> Path:
    """:func:`work_precision_figure` saved as a PNG at ``path``."""
    return _save(work_precision_figure(rows, peers), path)


def work_precision_figure(rows: Sequence[BenchPoint], peers: Sequence[dict] = ()):
    """Log-log error vs wall time per simulated second, one panel per scenario: every run as a dot
    (hollow: Bullet engine), each method's cheapest-for-its-accuracy front as a line, unstable runs
    as x in a grey band above the data, peers (dicts with scenario, peer, stable, error, wall_per_sim_s)
    as stars and crosses; one legend for all panels, below them."""
    plt = _pyplot()
    from matplotlib.lines import Line2D

    scen = sorted({r.scenario for r in rows})
    ncols = min(2, len(scen))
    nrows = math.ceil(len(scen) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.6 * ncols, 4.2 * nrows + 1.2), squeeze=False,
                             layout="constrained")
    handles: dict[str, Line2D] = {}
    for ax, sc in zip(axes.flat, scen):
        sel = [r for r in rows if r.scenario == sc]
        ok = [r for r in sel if r.stable and r.error > 0]
        peer_pts = [p for p in peers if p.get("scenario") == sc and p.get("stable") and p.get("error")]
        errors = [r.error for r in ok] + [p["error"] for p in peer_pts] + [TARGET_ERROR]
        costs = [r.wall_per_sim_s for r in sel if r.wall_per_sim_s > 0] + [p["wall_per_sim_s"] for p in peer_pts]
        y_lo, y_hi = _log_limits(errors)
        ax.axhspan(y_hi, 4 * y_hi, color="grey", alpha=0.12, lw=0)  # a band above the data for unstable runs
        for name in [m for m in COLORS if any(r.integrator == m for r in sel)]:
            color = COLORS[name]
            for engine, face, style in (("core", color, "-"), ("bullet", "none", "--")):
                pts = [(r.wall_per_sim_s, r.error) for r in ok if r.integrator == name and r.engine == engine]
                if not pts:
                    continue
                ax.loglog(*zip(*pts), "o", ms=4, mfc=face, mec=color, alpha=0.7)
                label = name + ("" if engine == "core" else " in Bullet")
                handles[label], = ax.loglog(*zip(*pareto(pts)), color=color, ls=style,
                                            lw=1.6 if engine == "core" else 1.0, label=label)
            bad = [r.wall_per_sim_s for r in sel if r.integrator == name and not r.stable]
            if bad:
                ax.loglog(bad, [2 * y_hi] * len(bad), "x", color=color, ms=7)
        for peer, (marker, color) in PEER_STYLE.items():
            pts = [(p["wall_per_sim_s"], p["error"]) for p in peer_pts if p.get("peer") == peer]
            if pts:
                handles[peer], = ax.loglog(*zip(*pts), marker, ms=9, color=color, ls="none", label=peer)
        ax.axhline(TARGET_ERROR, color="grey", lw=0.8, ls=":")
        ax.set_xlim(*_log_limits(costs))
        ax.set_ylim(y_lo, 4 * y_hi)
        _decade_ticks(ax)
        ax.set_title(SCENARIO_TITLES.get(sc, sc), fontsize=10)
        ax.set_xlabel("wall time per simulated second [s/s]")
        ax.set_ylabel("relative error [-]")
        ax.grid(True, which="major", alpha=0.3)
    for ax in axes.flat[len(scen):]:
        ax.set_visible(False)
    handles["unstable run"] = Line2D([], [], marker="x", color="k", ls="none", label="unstable run (grey band)")
    handles["target"] = Line2D([], [], color="grey", lw=0.8, ls=":", label="1 % error")
    handles["dots"] = Line2D([], [], marker="o", color="k", mfc="none", ls="none",
                             label="dot: one run (hollow: in Bullet)")
    fig.legend(handles=list(handles.values()), loc="outside lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle("Work-precision: error against cost, lines join each method's cheapest runs (lower left is better)",
                 fontsize=11)
    return fig


def plot_stability_map(rows: Sequence[dict], path: str | Path) -> Path:
    """:func:`stability_figure` saved as a PNG at ``path``."""
    return _save(stability_figure(rows), path)


def stability_figure(rows: Sequence[dict]):
    """Largest stable time step vs Young's modulus per explicit method and n: measured (dots) and
    predicted (lines), with the robot simulators' steps as horizontal lines; legend right of the axes."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.6), layout="constrained")
    explicit = sorted({(r["integrator"], r["n_masses"]) for r in rows if r["predicted"]})
    moduli = sorted({r["youngs_modulus"] for r in rows})
    styles = dict(zip(sorted({n for _, n in explicit}), (("-", "o"), ("--", "s"), (":", "^"))))
    for name, n in explicit:
        sel = sorted([r for r in rows if r["integrator"] == name and r["n_masses"] == n],
                     key=lambda r: r["youngs_modulus"])
        e = [r["youngs_modulus"] for r in sel]
        line_style, marker = styles[n]
        color = COLORS.get(name)
        ax.loglog(e, [r["predicted"] for r in sel], line_style, color=color, lw=1.2, label=f"{name}, n = {n}: predicted")
        ax.loglog(e, [r["measured"] for r in sel], marker, color=color, ls="none", label=f"{name}, n = {n}: measured")
    implicit_ok = all(r["measured"] is not None for r in rows if r["predicted"] is None)
    for dt, text in ((1e-3, "1 kHz (Gazebo)"), (1 / 60, "60 Hz (Isaac Sim)")):
        ax.axhline(dt, color="grey", ls="--", lw=0.8)
        ax.annotate(text, (moduli[-1], dt), xytext=(-4, 3), textcoords="offset points", ha="right", fontsize=8,
                    color="dimgrey")
    steps = [r["predicted"] for r in rows if r["predicted"]] + [r["measured"] for r in rows if r["measured"]]
    ax.set_ylim(*_log_limits(steps + [1 / 60]))
    _decade_ticks(ax)
    ax.set_xlabel("Young's modulus E [Pa]")
    ax.set_ylabel("largest stable time step [s]")
    note = "implicit_euler, bdf2: stable at both rates" if implicit_ok else "implicit_euler, bdf2: NOT stable at both"
    ax.set_title(f"Stability limits, study's scenario (k_d = 0.01 N s/m)\n{note}", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    fig.legend(handles=ax.get_legend_handles_labels()[0], loc="outside right upper", fontsize=8, frameon=False)
    return fig


def plot_scaling(core_rows: Sequence[dict], core_exponent: float, coupled_rows: Sequence[dict],
                 coupled_exponents: dict, path: str | Path) -> Path:
    """:func:`scaling_figure` saved as a PNG at ``path``."""
    return _save(scaling_figure(core_rows, core_exponent, coupled_rows, coupled_exponents), path)


def scaling_figure(core_rows: Sequence[dict], core_exponent: float, coupled_rows: Sequence[dict],
                   coupled_exponents: dict):
    """CPU time per simulated second vs n: the cable on a table in Bullet with contact on (total, with its
    range over the repeats, Bullet's step and the cable's side) and the core's implicit solve at 1 kHz."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 4.6), layout="constrained")
    n = [r["n_masses"] for r in coupled_rows]
    cost = [r["cost"] for r in coupled_rows]
    err = [[c - r["cost_min"] for c, r in zip(cost, coupled_rows)], [r["cost_max"] - c for c, r in zip(cost, coupled_rows)]]
    ax.errorbar(n, cost, yerr=err, fmt="o-", color="tab:blue", capsize=3,
                label=f"in Bullet, on a table (contact on): ~ n^{coupled_exponents['cost']:.2f}")
    ax.loglog(n, [r["bullet"] for r in coupled_rows], "s--", color="tab:red",
              label=f"  of which Bullet's stepSimulation: ~ n^{coupled_exponents['bullet']:.2f}")
    ax.loglog(n, [r["model"] for r in coupled_rows], "^--", color="tab:green",
              label=f"  of which the cable's side: ~ n^{coupled_exponents['model']:.2f}")
    if core_rows:
        ax.loglog([r["n_masses"] for r in core_rows], [1e3 * r["seconds_per_step"] for r in core_rows], "d:",
                  color="tab:gray", label=f"core engine, implicit Euler at 1 kHz: ~ n^{core_exponent:.2f}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("number of masses n")
    ax.set_ylabel("CPU time per simulated second [s]")
    ax.set_title("Cost vs n: a cable lying on a table, 240 Hz\n(thread CPU time, medians and ranges of interleaved "
                 "repeats)", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda k: not labels[k].startswith("in Bullet"))  # the total first
    fig.legend([handles[k] for k in order], [labels[k] for k in order], loc="outside right upper", fontsize=8,
               frameon=False)
    return fig
