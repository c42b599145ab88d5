"""Charts a reader takes in at a glance: legends off the data, tick labels apart, units in labels."""
from __future__ import annotations

import math

import matplotlib.pyplot as plt

from bullet_dlo.bench.plots import pareto, stability_figure, work_precision_figure
from bullet_dlo.bench.scenarios import BenchPoint


def _rows() -> list[BenchPoint]:
    rows = []
    for sc, spread in (("S1", 1.0), ("S2", 3.0), ("S3", 0.3), ("S4", 0.05)):  # S4: costs within a fraction of a decade
        for k, name in enumerate(("implicit_euler", "bdf2", "rk4")):
            for j in range(4):
                cost = 1e-3 * 10 ** (spread * j / 3) * (1 + k)
                rows.append(BenchPoint(sc, "core", name, 10, 1e-3, True, 0.05 / (1 + j) / (1 + k), cost))
        rows.append(BenchPoint(sc, "core", "rk4", 10, 1e-2, False, math.nan, 2e-3))
    return rows


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def _check_readable(fig) -> None:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert fig.legends and not any(ax.get_legend() for ax in axes)  # one legend, for the whole figure
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        assert not any(_overlap(box, ax.get_window_extent(renderer)) for ax in axes)
    for ax in axes:
        assert "[" in ax.get_xlabel() and "[" in ax.get_ylabel()  # units
        assert ax.get_title()
        for axis in (ax.xaxis, ax.yaxis):
            boxes = [t.get_window_extent(renderer) for t in axis.get_ticklabels(which="both")
                     if t.get_visible() and t.get_text()]
            assert len(boxes) >= 2  # at least a decade labelled
            assert not any(_overlap(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_work_precision_figure_is_readable():
    peers = [dict(scenario="S1", peer="mujoco", stable=True, error=0.2, wall_per_sim_s=0.17)]
    fig = work_precision_figure(_rows(), peers)
    _check_readable(fig)
    assert len([ax for ax in fig.axes if ax.get_visible()]) == 4
    plt.close(fig)


def test_stability_figure_is_readable():
    rows = []
    for e in (1e6, 1e8, 1e10):
        for name, c in (("symplectic_euler", 2.0), ("rk4", 2.83)):
            rows.append(dict(youngs_modulus=e, n_masses=10, integrator=name, predicted=c * 1e-1 / math.sqrt(e),
                             measured=c * 1e-1 / math.sqrt(e) * 1.01))
        rows.append(dict(youngs_modulus=e, n_masses=10, integrator="bdf2", predicted=None, measured=1 / 60))
    fig = stability_figure(rows)
    _check_readable(fig)
    plt.close(fig)


def test_pareto_keeps_the_cheapest_run_per_accuracy():
    assert pareto([(1.0, 0.1), (2.0, 0.2), (3.0, 0.01), (0.5, 0.5)]) == [(0.5, 0.5), (1.0, 0.1), (3.0, 0.01)]
