"""Resolution with contact: a scene's smallest wrapped radius and narrowest passage set a floor on n, and resolve
says so."""
from __future__ import annotations

import math
from dataclasses import replace

import pytest

from bullet_dlo.analysis.resolve import ResolveProblem, contact_floor, passage_masses, resolve_masses
from bullet_dlo.config.scene import BulletOptions, Scene
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.sim import resolve_problem
from test_edge_cylinder import rod_urdf  # (tests/bullet is on sys.path: pytest puts each test file's folder there)


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


def _slot(width: float, yaw: float = 0.0) -> ResolveProblem:
    """Two boxes 0.1 m long, 2 cm wide, 5 cm tall on the ground, ``width`` [m] apart, their slot's axis at ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    quat = [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
    boxes = tuple({"type": "box", "half_extents": [0.05, 0.01, 0.025], "orientation": quat,
                   "position": [0.2 - side * s * (width / 2 + 0.01), side * c * (width / 2 + 0.01), 0.025]}
                  for side in (-1, 1))
    return resolve_problem(Scene(cable=CableSpec.lv2017(n_masses=10, damping=0.05), ends=("pinned", "free"),
                                 direction=(1, 0, 0), dt=1e-3, duration=0.1, bullet=BulletOptions(obstacles=boxes)))


def test_a_slot_between_two_boxes_sets_the_passage_floor():
    """Bullet's narrow phase measures the slot at any orientation; the floor keeps the segments shorter than its free
    width (width - diameter, so none can wedge across it); a slot the cable cannot enter sets none."""
    length, diameter = 0.3, 0.004
    for yaw in (0.0, 0.7):
        problem = _slot(0.02, yaw)
        assert problem.passage_widths[0] == pytest.approx(0.02, abs=1e-9)
        n, why = contact_floor(problem)
        assert n == math.ceil(length / (0.02 - diameter)) + 1 == 20
        assert (n - 1) * (0.02 - diameter) >= length > (n - 2) * (0.02 - diameter)
        assert "passage (20.0 mm)" in why and "16.0 mm" in why
    assert contact_floor(_slot(0.03))[0] == math.ceil(length / 0.026) + 1  # a wider slot: fewer masses
    assert _slot(0.003).passage_widths == () and contact_floor(_slot(0.003)) == (2, "")  # narrower than the cable
    with pytest.raises(ParameterError, match="cannot take a cable"):
        passage_masses(length, diameter, 0.004)


def test_the_binding_floor_is_the_larger_one():
    """A scene with a peg and a slot: the floor is the larger of the two, and its reason names that one."""
    slot, peg = _slot(0.02), _scene(0.008)
    both = replace(slot, cylinder_radii=peg.cylinder_radii)
    assert contact_floor(both) == contact_floor(peg)  # 35 > 20: the peg's sag binds
    assert contact_floor(replace(slot, cylinder_radii=(0.05,)))[0] == contact_floor(slot)[0] == 20


def test_a_urdf_rod_on_a_child_link_sets_the_contact_floor(tmp_path):
    """A cylinder on a URDF's child link binds n as a scene cylinder of the same radius does (before, only the scene's
    own ``cylinder`` obstacles were read: the floor was 2); one out of the cables' contact model sets none."""
    urdf = rod_urdf(tmp_path / "rod.urdf", 0.008, at=(0.0, 0.0, 0.3))

    def problem(contact: bool) -> ResolveProblem:
        obstacles = ({"type": "urdf", "path": urdf, "position": [0, 0, 0], "contact": contact},)
        return resolve_problem(Scene(cable=CableSpec.lv2017(n_masses=10, damping=0.05), ends=("pinned", "free"),
                                     direction=(0, 0, -1), dt=1e-3, duration=0.1,
                                     bullet=BulletOptions(obstacles=obstacles)))
    assert problem(True).cylinder_radii == pytest.approx((0.008,))
    assert contact_floor(problem(True)) == contact_floor(_scene(0.008))
    assert contact_floor(problem(True))[0] == 35
    assert problem(False).cylinder_radii == () and contact_floor(problem(False)) == (2, "")
