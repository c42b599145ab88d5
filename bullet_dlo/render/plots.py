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
