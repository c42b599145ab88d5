"""A finely faceted hull's trees (bullet_dlo.bullet.bvh) answer what testing every face and edge answers."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet import bvh
from bullet_dlo.bullet import contact as C
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

from test_fine_hull import add_mesh, lay_across


def ellipsoid_hull(points: int = 700, seed: int = 3, nodes: int = 0) -> C.Hulls:
    """A convex hull of points on an ellipsoid (about 2 points' worth of triangles each), margin 1 mm; hints for
    ``nodes`` nodes."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(points, 3))
    verts = u / np.linalg.norm(u, axis=1, keepdims=True) * np.array([0.05, 0.03, 0.04])
    geo = C._hull_geometry(verts)
    return C._pack_hulls([(*geo, 1e-3)], [0], 1, nodes)


def without_trees(hu: C.Hulls) -> C.Hulls:
    return hu._replace(tri_root=np.full_like(hu.tri_root, -1), edge_root=np.full_like(hu.edge_root, -1))


def test_a_fine_hull_has_trees_and_a_coarse_one_none():
    fine = ellipsoid_hull()
    assert len(fine.tri) >= C.TREE_MIN_TRIANGLES and fine.tri_root[0] >= 0 and fine.edge_root[0] >= 0
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * 0.05
    coarse = C._pack_hulls([(*C._hull_geometry(box), 1e-3)], [0], 1)
    assert coarse.tri_root[0] == -1 and coarse.edge_root[0] == -1


def test_the_triangle_tree_gives_the_distance_of_every_face():
    """Points inside, on and around the hull (up to 3 cm off): distance, closest point and normal as without the
    tree (ties between triangles that share the closest point may round differently: 1e-12 m)."""
    hu = ellipsoid_hull()
    flat = without_trees(hu)
    rng = np.random.default_rng(0)
    lo, hi = hu.lo[0] - 0.03, hu.hi[0] + 0.03
    points = list(rng.uniform(lo, hi, size=(400, 3)))
    for t in rng.integers(0, len(hu.tri), 100):  # on and just off the surface, at vertices, edges and faces
        w = rng.dirichlet([1, 1, 1]) if t % 3 else np.eye(3)[t % 2]
        p = w @ hu.tri[t]
        points += [p, p * (1 + 1e-9), p * (1 - 1e-6), p * 1.01]
    inside = outside = 0
    for q in points:
        c1, n1, c2, n2 = np.empty(4), np.empty(3), np.empty(4), np.empty(3)
        d1 = C.hull_distance(hu, 0, q, c1, n1)
        d2 = C.hull_distance(flat, 0, q, c2, n2)
        if np.isnan(c2).any():  # a point on a face itself: no normal either way
            assert np.isnan(c1).any()
            continue
        assert d1 == pytest.approx(d2, abs=1e-12)
        assert np.abs(c1[:3] - c2[:3]).max() < 1e-12
        if abs(d2 + 1e-3) > 1e-7:  # (the normal of a point within round-off of the surface is round-off)
            assert np.abs(n1 - n2).max() < 1e-6
        inside += d2 < -1e-3
        outside += d2 > -1e-3
    assert inside > 20 and outside > 300


def test_a_node_beyond_the_cutoff_gets_the_cutoff_as_a_lower_bound():
    """The node loop's shortcut: farther than the cutoff and outside the hull's box or in a cube of its grid that is
    wholly outside the hull, the cutoff; otherwise the distance itself."""
    hu = ellipsoid_hull()
    rng = np.random.default_rng(2)
    p0, p1, t0, t1 = hu.plane_first[0], hu.plane_first[1], hu.tri_first[0], hu.tri_first[1]
    args = (hu.plane[p0:p1], hu.tri[t0:t1], hu.tri_plane[t0:t1], p0)
    pd, stack = np.empty(p1 - p0), np.empty(bvh.STACK, np.int64)
    cutoff, bounded, in_box = 0.006, 0, 0
    for q in rng.uniform(hu.lo[0] - 0.03, hu.hi[0] + 0.03, size=(800, 3)):
        c, n = np.empty(4), np.empty(3)
        exact = C._hull_distance(*args, q, pd, c, n)
        d = C._hull_distance_at(hu, 0, *args, q, pd, c, n, stack, cutoff)
        if d == cutoff:
            bounded += 1
            in_box += bool(((q >= hu.lo[0]) & (q <= hu.hi[0])).all())
            assert exact > cutoff
        else:
            assert d == pytest.approx(exact, abs=1e-12)
    assert bounded > 200 and in_box > 10


def test_the_grid_marks_only_cubes_wholly_outside_the_hull():
    """Every corner and the centre of a cube marked outside lies outside the polytope; most cubes a surface does not
    cross and that lie outside are marked."""
    hu = ellipsoid_hull()
    cell, dims, first = hu.grid_cell[0], hu.grid_dims[0], hu.grid_first[0]
    flags = hu.grid_out[first:first + dims.prod()].reshape(dims[2], dims[1], dims[0])
    p0, p1 = hu.plane_first[0], hu.plane_first[1]
    planes = hu.plane[p0:p1]
    marked = free = 0
    for iz, iy, ix in np.ndindex(*flags.shape):
        lo = hu.lo[0] + cell * np.array([ix, iy, iz])
        pts = lo + cell * np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)] + [[0.5] * 3])
        outside = ((pts @ planes[:, :3].T - planes[:, 3]).max(axis=1) > 0.0)
        if flags[iz, iy, ix]:
            marked += 1
            assert outside.all()
        free += bool(outside.all())
    assert marked > 0.5 * free


def test_the_edge_tree_finds_the_edges_every_box_test_finds():
    hu = ellipsoid_hull()
    rng = np.random.default_rng(1)
    e0, e1 = hu.edge_first[0], hu.edge_first[1]
    ext = np.abs(hu.edge_a) * hu.edge_hl[:, None]
    out = np.empty(e1 - e0, np.int64)
    stack = np.empty(bvh.STACK, np.int64)
    counts = []
    for _ in range(300):
        a = rng.uniform(hu.lo[0] - 0.02, hu.hi[0] + 0.02)
        b = a + rng.normal(scale=0.01, size=3)
        lo, hi = np.minimum(a, b) - 0.003, np.maximum(a, b) + 0.003
        want = np.flatnonzero(np.all((lo <= hu.edge_p + ext) & (hi >= hu.edge_p - ext), axis=1)) + e0
        k = bvh.overlapping(hu.tree_lo, hu.tree_hi, hu.tree_right, hu.tree_first, hu.tree_count, hu.tree_item,
                            hu.edge_root[0], e0, lo, hi, out, stack)
        got = out[:k]
        assert set(want) <= set(got) and list(got) == sorted(set(got))  # (with the rest of their leaves)
        assert k <= 4 * max(len(want), 1) + 8
        counts.append(len(want))
    assert max(counts) > 5 and min(counts) == 0


def test_a_cable_on_the_duck_steps_as_without_the_trees(monkeypatch):
    """Lying across pybullet_data's duck (1070 triangles) for 0.25 s at 240 Hz: the same rows and states as when
    every face and edge is tested (to round-off)."""
    states = []
    for trees in (True, False):
        monkeypatch.setattr(C, "TREE_MIN_TRIANGLES", 64 if trees else 10 ** 9)
        C._HULL_TREES.clear()
        with BulletWorld(dt=1 / 240) as world:
            cable = lay_across(world, add_mesh(world, "duck.obj", 0.08, False), CableSpec.lv2017(n_masses=20,
                                                                                               damping=0.02))
            assert (cable._contact_set.hulls.tri_root >= 0).any() == trees
            world.step(60)
            states.append((cable.x.copy(), cable.contact_forces()["force"].sum(axis=0)))
    assert np.abs(states[0][0] - states[1][0]).max() < 1e-9
    assert np.abs(states[0][1] - states[1][1]).max() < 1e-6


def test_a_nodes_last_triangle_tried_first_gives_the_distance_the_tree_gives():
    """Nodes walking slowly over, off and into the hull (steps of 0.2 mm, as a resting or sliding cable's): through
    each node's hint (its nearest triangle when last measured) the distance, closest point and normal are the tree's
    to the bit, at a cutoff and without, except that a point at least the cutoff in front of its hint's plane gets
    the cutoff (a lower bound: its distance is beyond); the hint is the nearest triangle when the tree was asked, and
    most points are answered from it (the hint is then left as it was)."""
    hu = ellipsoid_hull(nodes=8)
    assert hu.hint.shape == (1, 32) and (hu.hint == -1).all()
    plain = hu._replace(hint=np.zeros((1, 0), np.int64))
    rng = np.random.default_rng(5)
    p0, p1, t0, t1 = hu.plane_first[0], hu.plane_first[1], hu.tri_first[0], hu.tri_first[1]
    args = (hu.plane[p0:p1], hu.tri[t0:t1], hu.tri_plane[t0:t1], p0)
    pd, stack = np.empty(p1 - p0), np.empty(bvh.STACK, np.int64)
    # start each node 1 mm off the surface beside a random triangle, then walk it
    starts = [(w @ hu.tri[t]) * 1.02 for t, w in zip(rng.integers(0, len(hu.tri), 8), rng.dirichlet([1, 1, 1], 8))]
    q = np.array(starts)
    kept = asked = 0
    for step in range(300):
        q += rng.normal(scale=2e-4, size=q.shape) - (2e-5 if step > 150 else 0.0) * q / np.linalg.norm(q, axis=1)[:, None]
        for i in range(len(q)):
            for cutoff in (1e300, 0.004):
                before = hu.hint[0, i]
                c1, n1, c2, n2 = np.full(4, 7.0), np.full(3, 7.0), np.full(4, 7.0), np.full(3, 7.0)
                d1 = C._hull_distance_at(hu, 0, *args, q[i], pd, c1, n1, stack, cutoff, i)
                d2 = C._hull_distance_at(plain, 0, *args, q[i], pd, c2, n2, stack, cutoff, i)
                if d1 == cutoff:  # a lower bound (the point and normal are not written): the distance is beyond
                    assert d2 >= cutoff and C._hull_distance(*args, q[i], pd, c2, n2) >= cutoff, (step, i, d2)
                    continue
                assert d1 == d2 and (c1[:3] == c2[:3]).all() and (n1 == n2).all(), (step, i, d1, d2, c1, c2)
                if hu.hint[0, i] == before:
                    kept += 1
                else:
                    asked += 1
                    cl = np.empty(3)
                    t, _ = C._closest_triangle(hu, 0, q[i], np.empty(4), cl, stack)
                    assert hu.hint[0, i] == t
    assert kept > 4 * asked > 0, (kept, asked)
    inside = [C._hull_distance_at(hu, 0, *args, 0.5 * p, pd, np.empty(4), np.empty(3), stack, 1e300, 0) < 0
              for p in starts]
    assert all(inside)  # deep inside: the full scan, whatever the hint


def _segment_distances(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Exact distances [m] between segment ab and each segment c[k] d[k] ((K, 3) arrays; closest points by clamping,
    as in Ericson's Real-Time Collision Detection, 5.1.9), all edges at once."""
    d1, d2, r = b - a, d - c, a - c
    p, q, f = d1 @ d1, np.einsum("kj,kj->k", d2, d2), np.einsum("kj,kj->k", d2, r)
    cc, bb = r @ d1, d2 @ d1
    den = p * q - bb * bb
    s = np.where(den > 1e-30, np.clip((bb * f - cc * q) / np.where(den > 1e-30, den, 1.0), 0.0, 1.0), 0.0)
    t = (bb * s + f) / q
    low, high = t < 0.0, t > 1.0
    s = np.where(low, np.clip(-cc / p, 0.0, 1.0), np.where(high, np.clip((bb - cc) / p, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(a + s[:, None] * d1 - (c + t[:, None] * d2), axis=1)


def test_a_segment_ahead_of_a_face_is_out_of_every_edges_reach():
    """The hull contacts skip a segment's edge search where both its nodes lie more than the reach in front of one
    node's hint plane (``_ahead_of_a_face``). Segments between points 0-6 mm off the surface (hints set by each
    node's distance query, as in a step): wherever it skips, the exact distance from the segment to every edge of the
    hull exceeds the reach (a wrong sign or plane would skip segments that touch an edge); it skips most segments
    that are out of reach, and none within it."""
    hu = ellipsoid_hull(nodes=8)
    rng = np.random.default_rng(11)
    p0, p1, t0, t1 = hu.plane_first[0], hu.plane_first[1], hu.tri_first[0], hu.tri_first[1]
    args = (hu.plane[p0:p1], hu.tri[t0:t1], hu.tri_plane[t0:t1], p0)
    pd, stack = np.empty(p1 - p0), np.empty(bvh.STACK, np.int64)
    e0, e1 = hu.edge_first[0], hu.edge_first[1]
    starts = hu.edge_p[e0:e1] - hu.edge_hl[e0:e1, None] * hu.edge_a[e0:e1]
    ends = hu.edge_p[e0:e1] + hu.edge_hl[e0:e1, None] * hu.edge_a[e0:e1]
    reach = 0.0025  # [m] radius + margin + the hull's margin
    skipped = out_of_reach = within = 0
    for _ in range(300):
        t = rng.integers(0, len(hu.tri))
        centre = rng.dirichlet([1, 1, 1]) @ hu.tri[t]
        out = centre / np.linalg.norm(centre)
        q = [centre + out * rng.uniform(0.0, 0.006) + rng.normal(scale=0.004, size=3) for _ in range(2)]
        for node in (0, 1):
            C._hull_distance_at(hu, 0, *args, q[node], pd, np.empty(4), np.empty(3), stack, 1e300, node)
        ahead = C._ahead_of_a_face(hu, 0, q[0], q[1], 0, reach)
        nearest = _segment_distances(q[0], q[1], starts, ends).min()
        if ahead:
            assert nearest > reach, (q, nearest)
            skipped += 1
        if nearest > reach:
            out_of_reach += 1
        else:
            within += 1
    assert within > 20 and skipped > 0.5 * out_of_reach > 20, (within, skipped, out_of_reach)


def test_the_edges_columns_give_segment_axis_to_the_bit():
    """A segment's edge search runs :func:`_segment_axis` over the edges as columns (``_edge_rows``, then
    ``_segment_edges`` without branches, several edges at a time): for segments near, across, along and inside the
    hull (and one of zero length), every edge kept is one whose box meets the segment's (every edge for a wrapped
    segment) in the same order, and each gives ``_segment_axis``'s interior parameter and distance to the bit (-1
    where it has none)."""
    hu = ellipsoid_hull()
    rng = np.random.default_rng(5)
    e0, e1 = hu.edge_first[0], hu.edge_first[1]
    every = np.arange(e0, e1)
    rows, kept = np.empty((9, e1 - e0)), np.empty(e1 - e0, np.int64)
    cl, nl = np.empty(4), np.empty(3)
    reach = 0.004
    interior = 0
    for k in range(200):
        t = rng.integers(0, len(hu.tri))
        a = rng.dirichlet([1, 1, 1]) @ hu.tri[t] * rng.uniform(0.8, 1.1)
        b = a + rng.normal(scale=[0.02, 0.005, 0.0][k % 3], size=3)  # (every third: zero length)
        for wrapped in (False, True):
            count = C._edge_rows(hu, every, len(every), e0, e1, wrapped, a, b, reach, rows, kept)
            lo, hi = np.minimum(a, b), np.maximum(a, b)
            ext = np.abs(hu.edge_a[every]) * hu.edge_hl[every, None] + reach
            meets = ~((lo > hu.edge_p[every] + ext) | (hi < hu.edge_p[every] - ext)).any(axis=1)
            assert list(kept[:count]) == (list(every) if wrapped else list(every[meets]))
            C._segment_edges(a, b, rows, count)
            for j, e in enumerate(kept[:count]):
                s = C._segment_axis(a, b, hu.edge_p[e], hu.edge_a[e], hu.edge_hl[e], 1e-3, cl, nl)
                assert rows[7, j] == (s if s > 0.0 else -1.0), (k, e)
                if s > 0.0:
                    assert np.sqrt(rows[8, j]) - 1e-3 == cl[3], (k, e)
                    interior += 1
    assert interior > 1000


def test_hull_distances_in_one_call_give_each_call_to_the_bit():
    """The hull check (``ContactSet._checked_hull``) takes its distances at ~200 points a link in one compiled call
    (:func:`hull_distances`) instead of one call each (30 of a Routing-v0 reset's 278 ms): the same values to the
    bit, inside, on and outside the hull, with the margin."""
    hu = ellipsoid_hull()
    rng = np.random.default_rng(3)
    points = rng.normal(scale=0.03, size=(300, 3))
    points[:50] = hu.tri[rng.integers(0, len(hu.tri), 50), 0]  # on its vertices
    one = C.hull_distances(hu, 0, points)
    cl, nl = np.zeros(3), np.zeros(3)
    each = np.array([C.hull_distance(hu, 0, p, cl, nl) for p in points])
    assert (one < 0).any() and (one > 0).any()
    assert np.array_equal(one, each)
