"""Resolution with contact: a scene's smallest wrapped radius sets a floor on n, and resolve says so."""
from __future__ import annotations

import math

from bullet_dlo.analysis.resolve import ResolveProblem, contact_floor, resolve_masses
from bullet_dlo.config.scene import BulletOptions, Scene
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.sim import resolve_problem


def _scene(radius: float | None) -> ResolveProblem:
    obstacles = () if radius is None else ({"type": "cylinder", "radius": radius, "height": 0.2,
                                            "position": [0, 0, 0.3]},
                                           {"type": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0, 0, 0.1]})
    return resolve_problem(Scene(cable=CableSpec.lv2017(n_masses=10, damping=0.05), ends=("pinned", "free"),
                                 direction=(0, 0, -1), dt=1e-3, duration=0.1, bullet=BulletOptions(obstacles=obstacles)))


def test_contact_floor_follows_the_chord_sag_bound():
    n, why = contact_floor(_scene(0.008))
    r, radius, length = 0.002, 0.008, 0.3
    seg = 2 * math.sqrt((radius + r) * r)  # sag l^2 / (8 (R + r)) = r / 2
    assert n == math.ceil(length / seg) + 1 == 35
    assert "8.0 mm" in why
    assert contact_floor(_scene(0.05))[0] < n  # a larger peg needs fewer masses
    assert contact_floor(_scene(None)) == (2, "")  # boxes and the ground set no floor (capsules)


def test_resolve_masses_respects_the_floor():
    n, _ = resolve_masses(_scene(0.008), tol=0.5, rollout=0.05)
    assert n >= 35  # without the peg the same loose tolerance is met by the fewest masses tried
    assert resolve_masses(_scene(None), tol=0.5, rollout=0.05)[0] == 5
