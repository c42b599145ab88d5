"""Bounding-volume hierarchies over a hull's triangles and edges, so that a node or a segment near a finely faceted
hull tests the few features near it instead of all of them.

A hierarchy is a binary tree of axis-aligned boxes (the union of its items' boxes), built once per hull geometry by
median splits along the longest axis of the items' centres, leaves of at most :data:`LEAF_ITEMS` items, and stored
flat in depth-first order: node k's left child is k + 1, its right child ``right[k]`` (-1: a leaf, whose items are
``item[first[k]:first[k] + count[k]]``). Several trees share one set of arrays (each starts at its root index);
node and item indices are global. The queries here miss nothing: :func:`overlapping` returns every item whose box meets
a query box (with the rest of its leaf, in ascending order, as a loop over all items would meet them), and the triangles' closest-point search
(``contact._closest_triangle``) prunes a subtree only when its box is farther than the best triangle found.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bullet_dlo.core.kernels.jit import njit

LEAF_ITEMS = 4
"""Items per leaf at most (a leaf's items are tested one by one: a few cost less than another level's boxes)."""
STACK = 128
"""Depth of the traversal stack (a tree of a million items is about 40 deep with its siblings pushed)."""


class Tree(NamedTuple):
    """One hierarchy's arrays (nodes N, items I): lo, hi (N, 3) [m] the node boxes; right (N,) int the right child
    (-1: leaf); first, count (N,) int a leaf's items in ``item``; item (I,) int the item indices (local: 0 .. I-1)."""

    lo: np.ndarray
    hi: np.ndarray
    right: np.ndarray
    first: np.ndarray
    count: np.ndarray
    item: np.ndarray


def build(lo: np.ndarray, hi: np.ndarray) -> Tree:
    """The hierarchy of items with boxes lo, hi (I, 3) [m] (I >= 1)."""
    centre = 0.5 * (lo + hi)
    nodes: list[list] = []  # [lo, hi, right, first, count]
    order: list[int] = []

    def node(idx: np.ndarray) -> int:
        k = len(nodes)
        nodes.append([lo[idx].min(axis=0), hi[idx].max(axis=0), -1, 0, 0])
        if len(idx) <= LEAF_ITEMS:
            nodes[k][3], nodes[k][4] = len(order), len(idx)
            order.extend(sorted(int(i) for i in idx))
            return k
        c = centre[idx]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        idx = idx[np.argsort(c[:, axis], kind="stable")]
        half = len(idx) // 2
        node(idx[:half])
        nodes[k][2] = node(idx[half:])
        return k

    node(np.arange(len(lo)))
    return Tree(lo=np.array([a[0] for a in nodes], float).reshape(-1, 3),
                hi=np.array([a[1] for a in nodes], float).reshape(-1, 3),
                right=np.array([a[2] for a in nodes], np.int64), first=np.array([a[3] for a in nodes], np.int64),
                count=np.array([a[4] for a in nodes], np.int64), item=np.array(order, np.int64))


def triangle_boxes(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boxes lo, hi (T, 3) [m] of triangles tri (T, 3, 3)."""
    return tri.min(axis=1), tri.max(axis=1)


def edge_boxes(p: np.ndarray, a: np.ndarray, hl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boxes lo, hi (E, 3) [m] of edges with midpoints p (E, 3), unit directions a (E, 3), half lengths hl (E,)."""
    ext = np.abs(a) * hl[:, None]
    return p - ext, p + ext


@njit(cache=True, error_model="numpy", inline="always")
def box_distance2(lo, hi, q) -> float:
    """Squared distance [m^2] of point q from the box [lo, hi] (0 inside)."""
    d2 = 0.0
    for j in range(3):
        if q[j] < lo[j]:
            d2 += (lo[j] - q[j]) ** 2
        elif q[j] > hi[j]:
            d2 += (q[j] - hi[j]) ** 2
    return d2


@njit(cache=True, error_model="numpy")
def overlapping(lo_t, hi_t, right, first, count, item, root, item0, lo, hi, out, stack) -> int:
    """The items of the leaves of the tree at ``root`` whose boxes meet the box [lo, hi] [m]: every item whose own box
    meets it, and the others of its leaf (the caller tests each item), into ``out`` in ascending order (item indices
    + ``item0``); returns how many. ``stack``: scratch (:data:`STACK`,) int."""
    n_out = 0
    top = 0
    stack[0] = root
    while top >= 0:
        k = stack[top]
        top -= 1
        miss = False
        for j in range(3):
            if lo[j] > hi_t[k, j] or hi[j] < lo_t[k, j]:
                miss = True
        if miss:
            continue
        if right[k] < 0:
            for a in range(first[k], first[k] + count[k]):
                out[n_out] = item[a] + item0
                n_out += 1
        else:
            top += 1
            stack[top] = right[k]
            top += 1
            stack[top] = k + 1
    for a in range(1, n_out):  # insertion sort: a handful of items
        v = out[a]
        b = a - 1
        while b >= 0 and out[b] > v:
            out[b + 1] = out[b]
            b -= 1
        out[b + 1] = v
    return n_out
