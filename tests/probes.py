"""Measuring probes shared by tests in several folders (imported as ``from probes import ...``: pytest puts
``tests/`` on ``sys.path`` for its conftest). Independent of the contact model: Bullet's own queries."""
from __future__ import annotations

import numpy as np
import pybullet as pb


def deepest(cid: int, body: int, points: np.ndarray, probe: int, search: float = 0.02) -> float:
    """Smallest signed distance [m] between a collision shape ``probe`` (e.g. a sphere of the cable's radius)
    placed at each point (k, 3) and any link of ``body`` in client ``cid``; inf when no link is within
    ``search`` [m] of any point."""
    worst = np.inf
    for link in range(-1, pb.getNumJoints(body, physicsClientId=cid)):
        for p in np.asarray(points, dtype=float).tolist():
            for hit in pb.getClosestPoints(-1, body, search, -1, link, probe, -1, p, physicsClientId=cid):
                worst = min(worst, hit[8])
    return worst


def lines_through_links(cid: int, rows: list, links: list[int], n: int, seed: int, half_length: float = 0.06):
    """For each row s of ``links`` (rows[s] = (body, link, ...)): (s, positions (n, 3) [m] of a straight line of
    length 2 ``half_length`` through a random point of the link's broad-phase box, in a random direction)."""
    rng = np.random.default_rng(seed)
    for s in links:
        lo, hi = np.array(pb.getAABB(rows[s][0], rows[s][1], physicsClientId=cid))
        d = rng.normal(size=3)
        yield s, rng.uniform(lo, hi) + np.outer(np.linspace(-half_length, half_length, n), d / np.linalg.norm(d))
