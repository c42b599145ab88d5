"""Force plots to read at a glance: both grippers, sensor against model, units and phases marked."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

COMPONENT_COLORS = {"x": "tab:blue", "y": "tab:green", "z": "tab:red"}


@dataclass(frozen=True)
class PlotInfo:
    """A written plot: its file, time range [s] and, per time axis, its pixel box (x0, x1, y0, y1)
    in the image (origin top-left), so a video can draw a time cursor inside each axis."""

    path: Path
    t_range: tuple[float, float]
    axes_px: tuple[tuple[int, int, int, int], ...]


def plot_wrenches(t: np.ndarray, sensor: np.ndarray | None, model: np.ndarray, path: str | Path,
                  title: str = "wrist forces", phases: Sequence[tuple[float, float, str]] = ()) -> PlotInfo:
    """PNG of the forces on both grippers over time.

    t: times [s], (k,); sensor: tared wrist wrenches in the world frame, (k, 2, >=3) [N] (None:
    no sensors); model: the force the cable exerts on each held end, (k, 2, 3) [N]; phases:
    (start [s], end [s], label) spans shaded on both axes. One axis per gripper; x, y, z in
    fixed colours, sensor solid and model dashed; the legend sits above the axes, off the data.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(2, 1, figsize=(7.2, 6.0), dpi=100, sharex=True)
    for a, (ax, name) in enumerate(zip(axes, ("left gripper (first cable end)", "right gripper (last cable end)"))):
        for k, comp in enumerate("xyz"):
            color = COMPONENT_COLORS[comp]
            if sensor is not None:
                ax.plot(t, sensor[:, a, k], color=color, lw=1.6)
            ax.plot(t, model[:, a, k], color=color, lw=1.1, ls="--" if sensor is not None else "-")
        shown = [(s, min(e, t[-1]), label) for s, e, label in phases if s < t[-1]]  # clipped to the plot
        for k, (start, end, label) in enumerate(shown):
            ax.axvspan(start, end, color="0.9" if k % 2 == 0 else "0.95", zorder=0)
            if a == 0:
                ax.text(0.5 * (start + end), 1.01, label, transform=ax.get_xaxis_transform(), ha="center",
                        va="bottom", fontsize=8, color="0.3", in_layout=False)
        ax.axhline(0.0, color="0.6", lw=0.6, zorder=1)
        ax.set_ylabel("force [N]")
        ax.set_title(name, fontsize=10, loc="left", pad=14 if phases and a == 0 else 4)
        ax.grid(alpha=0.3)
        ax.set_xlim(float(t[0]), float(t[-1]))
    axes[-1].set_xlabel("time [s]")
    components = [Line2D([], [], color=c, lw=2, label=f"F{comp}") for comp, c in COMPONENT_COLORS.items()]
    fig.suptitle(title, fontsize=12)
    fig.legend(handles=components, loc="upper center", bbox_to_anchor=(0.5, 0.95), ncol=3, fontsize=9,
               frameon=False)
    if sensor is not None:
        sources = [Line2D([], [], color="0.3", lw=1.6, label="wrist sensor (tared, world frame)"),
                   Line2D([], [], color="0.3", lw=1.1, ls="--", label="model: force of the cable on its end")]
        fig.legend(handles=sources, loc="upper center", bbox_to_anchor=(0.5, 0.91), ncol=2, fontsize=9,
                   frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.9 if sensor is not None else 0.94))
    path = Path(path)
    fig.savefig(path, dpi=100)
    fig.canvas.draw()
    height = fig.canvas.get_width_height()[1]
    boxes = tuple((int(b.x0), int(b.x1), int(height - b.y1), int(height - b.y0))
                  for b in (ax.get_window_extent() for ax in axes))
    plt.close(fig)
    return PlotInfo(path, (float(t[0]), float(t[-1])), boxes)


def _pyplot():
    """matplotlib's pyplot on the file backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | Path) -> Path:
    """Lay out, write ``fig`` as a PNG at ``path`` (its folder made), close it; returns the path."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_run(t: np.ndarray, x: np.ndarray, end_forces: np.ndarray, energy: np.ndarray, path: str | Path,
             title: str = "run", held: Sequence[bool] = (True, True)) -> Path:
    """PNG of a cable run: the force of the cable on each held end [N] and its mechanical energy [J] over time
    [s], and its shape seen from the side (x-z) and from above (x-y) [m] at the first and the last recorded
    row. t (k,), x (k, n, 3), end_forces (k, 2, 3), energy (k,); ``held``: which ends' forces to draw."""
    plt = _pyplot()

    fig, axes = plt.subplots(2, 2, figsize=(10.0, 6.4), dpi=100)
    (f_ax, e_ax), (side, top) = axes
    for end, (name, style) in enumerate((("first end", "-"), ("last end", "--"))):
        if not held[end]:
            continue
        for k, comp in enumerate("xyz"):
            f_ax.plot(t, end_forces[:, end, k], color=COMPONENT_COLORS[comp], ls=style, lw=1.3,
                      label=f"F{comp}, {name}")
    f_ax.set_xlabel("time [s]")
    f_ax.set_ylabel("force of the cable on the end [N]")
    f_ax.set_title("end forces", fontsize=10, loc="left")
    if any(held):
        f_ax.legend(fontsize=7, ncol=2)
    f_ax.grid(alpha=0.3)
    e_ax.plot(t, energy, color="0.2", lw=1.3)
    e_ax.set_xlabel("time [s]")
    e_ax.set_ylabel("mechanical energy [J]")
    e_ax.set_title("energy (kinetic + elastic + gravity)", fontsize=10, loc="left")
    e_ax.grid(alpha=0.3)
    for ax, (i, j), label in ((side, (0, 2), ("x [m]", "z [m]")), (top, (0, 1), ("x [m]", "y [m]"))):
        ax.plot(x[0, :, i], x[0, :, j], "o-", color="0.65", ms=3, lw=1.2, label=f"t = {t[0]:.3g} s")
        ax.plot(x[-1, :, i], x[-1, :, j], "o-", color="tab:red", ms=3, lw=1.5, label=f"t = {t[-1]:.3g} s")
        ax.set_xlabel(label[0])
        ax.set_ylabel(label[1])
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    side.set_title("shape, side view", fontsize=10, loc="left")
    top.set_title("shape, from above", fontsize=10, loc="left")
    fig.suptitle(title, fontsize=12)
    return _save(fig, path)


def plot_critical_dt(critical: dict[str, float | None], dt: float, path: str | Path, title: str = "stability") -> Path:
    """PNG of each integrator's critical time step [s] (log scale) against the scene's step ``dt`` [s]: bars
    below the line are unstable at ``dt``; ``None`` (unconditionally stable, linear analysis) drawn as an
    arrow above the axis."""
    plt = _pyplot()

    names = list(critical)
    finite = [v for v in critical.values() if v is not None and v > 0.0]
    top = 10 * max(finite + [dt])
    fig, ax = plt.subplots(figsize=(7.2, 4.0), dpi=100)
    for k, name in enumerate(names):
        crit = critical[name]
        if crit is not None and crit <= 0.0:  # unstable at any step (e.g. explicit Euler without damping)
            ax.text(k, 0.0, "unstable\nat any dt", ha="center", va="bottom", fontsize=8, color="tab:red",
                    transform=ax.get_xaxis_transform())
            continue
        value = top if crit is None else crit
        stable = crit is None or dt <= crit
        ax.bar(k, value, color="tab:green" if stable else "tab:red", alpha=0.8)
        ax.text(k, value, "no limit" if crit is None else f"{crit:.3g} s", ha="center", va="bottom", fontsize=8)
    ax.axhline(dt, color="0.2", ls="--", lw=1.2, label=f"scene dt = {dt:.3g} s")
    ax.set_yscale("log")
    ax.set_xticks(range(len(names)), names, rotation=20, fontsize=8)
    ax.set_ylabel("critical time step [s]")
    ax.set_title(f"{title}: green stable at dt, red unstable (linear analysis)", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3, axis="y")
    return _save(fig, path)


def plot_convergence(rows: Sequence[dict], path: str | Path, title: str = "cantilever convergence") -> Path:
    """PNG of the relative error of each discretisation against n (log-log) with a second-order slope.
    rows: dicts with ``n_masses`` and one relative error [-] per discretisation (other keys)."""
    plt = _pyplot()

    n = np.array([r["n_masses"] for r in rows], dtype=float)
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=100)
    for key in [k for k in rows[0] if k != "n_masses"]:
        err = np.abs([r[key] for r in rows])
        ax.loglog(n, err, "o-", label=f"{key} discretisation")
    if len(n) > 1:
        ref = np.abs(rows[0][[k for k in rows[0] if k != "n_masses"][0]]) * (n[0] / n) ** 2
        ax.loglog(n, ref, ":", color="0.5", label="second order (n^-2)")
    ax.set_xlabel("masses n [-]")
    ax.set_ylabel("relative error of the tip deflection [-]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_resolve(trials: Sequence[dict], tolerance: float, path: str | Path, title: str = "resolve") -> Path:
    """PNG of ``resolve``'s trials: the spatial error against n, and the temporal error against dt per
    integrator (log-log), with the tolerance [-]; unstable trials are marked on the axis."""
    plt = _pyplot()

    fig, (sp, tm) = plt.subplots(1, 2, figsize=(10.0, 4.2), dpi=100)
    spatial = [t for t in trials if "spatial" in t]
    ok = [t for t in spatial if t["spatial"] is not None]
    if ok:
        sp.loglog([t["n"] for t in ok], [max(t["spatial"], 1e-16) for t in ok], "o-", color="tab:blue")
    for t in spatial:
        if t["spatial"] is None:
            sp.axvline(t["n"], color="tab:red", ls=":", lw=1)
    sp.axhline(tolerance, color="0.3", ls="--", lw=1, label=f"tolerance {tolerance:g}")
    sp.set_xlabel("masses n [-]")
    sp.set_ylabel("spatial error [-]")
    sp.set_title("spatial (n) trials; red: unstable", fontsize=10, loc="left")
    temporal = [t for t in trials if "temporal" in t]
    for name in dict.fromkeys(t["integrator"] for t in temporal):
        pts = sorted((t["dt"], t["temporal"]) for t in temporal if t["integrator"] == name and t["temporal"] is not None)
        if pts:
            tm.loglog(*zip(*[(d, max(e, 1e-16)) for d, e in pts]), "o-", label=name)
        for t in temporal:
            if t["integrator"] == name and t["temporal"] is None:
                tm.axvline(t["dt"], color="tab:red", ls=":", lw=1)
    tm.axhline(tolerance, color="0.3", ls="--", lw=1)
    tm.set_xlabel("time step dt [s]")
    tm.set_ylabel("temporal error [-]")
    tm.set_title("temporal (dt) trials per integrator", fontsize=10, loc="left")
    for ax in (sp, tm):
        ax.grid(alpha=0.3, which="both")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=12)
    return _save(fig, path)


def plot_paper_table(runs: Sequence, path: str | Path, title: str = "the study's stability table") -> Path:
    """PNG of ``paper-table``: one panel per Young's modulus, integrators (rows) against (n, dt) (columns),
    green stable, red unstable (with the time it went unstable [s])."""
    from matplotlib.colors import ListedColormap

    plt = _pyplot()

    moduli = sorted({r.youngs_modulus for r in runs})
    fig, axes = plt.subplots(len(moduli), 1, figsize=(10.0, 1.2 + 2.2 * len(moduli)), dpi=100, squeeze=False)
    for ax, e in zip(axes[:, 0], moduli):
        cells = [r for r in runs if r.youngs_modulus == e]
        integrators = list(dict.fromkeys(r.integrator for r in cells))
        cols = sorted({(r.n_masses, r.dt) for r in cells})
        grid = np.full((len(integrators), len(cols)), np.nan)
        for r in cells:
            i, j = integrators.index(r.integrator), cols.index((r.n_masses, r.dt))
            grid[i, j] = 1.0 if r.stable else 0.0
            if not r.stable and r.time_to_instability is not None:
                ax.text(j, i, f"{r.time_to_instability:.2g} s", ha="center", va="center", fontsize=6, color="white")
        ax.imshow(grid, cmap=ListedColormap(["tab:red", "tab:green"]), vmin=0, vmax=1,
                  aspect="auto")
        ax.set_yticks(range(len(integrators)), integrators, fontsize=8)
        ax.set_xticks(range(len(cols)), [f"n={n}\ndt={dt:.2g} s" for n, dt in cols], fontsize=6)
        ax.set_title(f"E = {e / 1e6:g} MPa: green stable, red unstable (time it went unstable)", fontsize=9,
                     loc="left")
    fig.suptitle(title, fontsize=11)
    return _save(fig, path)
