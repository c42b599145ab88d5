"""The grid search of self-contact candidates finds exactly the pairs of the O(n^2) search, in its order.

:func:`bullet_dlo.bullet.contact._grid_pairs` (a uniform grid, O(n log n)) and ``_self_pairs`` (the grid
above 64 nodes, every pair below) against
:func:`~bullet_dlo.bullet.contact._self_pairs_brute` (every pair tried, the search it replaced) on random
cable configurations: random walks (3-D, flat on a table, straight along an axis), tight coils, nodes on top
of each other, a stretched cable and non-finite positions; and the candidates cover every pair of segments
that is actually close (so the reach leaves nothing out), with neighbouring segments excluded.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet.contact import _grid_pairs, _segments_closest, _self_pairs, _self_pairs_brute


def random_walk(rng, n: int, step: float, flat: bool = False, persistence: float = 0.8) -> np.ndarray:
    """Nodes n x 3 [m] a fixed ``step`` apart, each direction a blend of the last one and a random one."""
    x = np.zeros((n, 3))
    d = np.array([1.0, 0.0, 0.0])
    for i in range(1, n):
        r = rng.normal(size=3)
        if flat:
            r[2] = 0.0
        d = persistence * d + (1.0 - persistence) * r / np.linalg.norm(r)
        d /= np.linalg.norm(d)
        x[i] = x[i - 1] + step * d
    return x


def coil(n: int, step: float, radius: float, pitch: float) -> np.ndarray:
    th = 2.0 * np.arcsin(step / (2.0 * radius)) * np.arange(n)
    return np.stack([radius * np.cos(th), radius * np.sin(th), pitch * th / (2 * np.pi)], axis=1)


def configurations():
    rng = np.random.default_rng(24)
    for n in (2, 3, 5, 17, 60, 200):
        yield f"walk{n}", random_walk(rng, n, 0.3 / max(n - 1, 1), persistence=0.5)
        yield f"flat{n}", random_walk(rng, n, 0.3 / max(n - 1, 1), flat=True, persistence=0.3)
    for n in (40, 150, 400):
        yield f"coil{n}", coil(n, 0.3 / (n - 1), 0.01, 0.0045)
        yield f"line_y{n}", np.stack([np.zeros(n), np.linspace(0, 0.3, n), np.zeros(n)], axis=1)
    heap = rng.uniform(-0.01, 0.01, size=(120, 3))  # a crumpled heap: everything near everything
    yield "heap", heap
    stacked = np.repeat(rng.uniform(size=(10, 3)) * 0.02, 5, axis=0)  # five nodes on each of ten points
    yield "coincident", stacked
    stretched = random_walk(rng, 80, 0.004)
    stretched[40:] += 5.0  # one segment 8.7 m long: a stretched (failing) cable
    yield "stretched", stretched


@pytest.mark.parametrize("skip", [2, 4, 9])
@pytest.mark.parametrize("reach_factor", [1.0, 3.0])
def test_grid_pairs_equal_the_brute_force_pairs(skip, reach_factor):
    for name, x in configurations():
        reach = reach_factor * (2.5 * np.linalg.norm(x[1] - x[0]) + 0.004 + 0.003)
        grid, brute = _grid_pairs(x, skip, reach), _self_pairs_brute(x, skip, reach)
        assert np.array_equal(grid, brute), name  # same pairs, same order (so the same contact rows)
        assert np.array_equal(_self_pairs(x, skip, reach), brute), name
        n = len(x)
        i, j = grid // n, grid % n
        assert np.all(j > i + skip) and np.all(j <= n - 2), name  # neighbours along the cable left out


def test_non_finite_positions_fall_back_to_the_brute_force_search():
    x = random_walk(np.random.default_rng(1), 30, 0.01)
    x[7, 1] = np.nan
    assert np.array_equal(_grid_pairs(x, 2, 0.05), _self_pairs_brute(x, 2, 0.05))


def test_candidates_cover_every_close_pair_of_segments():
    """Independent of both searches: a pair of distant segments closer than 2 r + margin (closest points of
    the two segments) is a candidate for the reach the contact detection uses."""
    radius, margin = 0.002, 0.003
    for name, x in configurations():
        n = len(x)
        if n < 3 or not np.all(np.isfinite(x)):
            continue
        l0 = float(np.linalg.norm(x[1] - x[0]))
        skip = 1 + int(np.ceil(max(np.pi * radius, 2 * radius + margin) / max(l0, 1e-12)))
        reach = 2.5 * l0 + 2.0 * radius + margin
        found = set(_grid_pairs(x, skip, reach).tolist())
        lengths = np.linalg.norm(np.diff(x, axis=0), axis=1)
        for i in range(n - 1):
            for j in range(i + 1 + skip, n - 1):
                if max(lengths[i], lengths[j]) > 1.25 * l0:
                    continue  # the reach assumes segments near the first one's length
                s, t = _segments_closest(x[i], x[i + 1], x[j], x[j + 1])
                d = np.linalg.norm(x[i] + s * (x[i + 1] - x[i]) - x[j] - t * (x[j + 1] - x[j]))
                if d - 2 * radius < margin:
                    assert i * n + j in found, (name, i, j)
