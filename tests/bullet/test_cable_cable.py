"""Contact between two cables through the model (issue 23 item 4).

Before, cable-cable contact was Bullet's sphere contact: a cable dropped 3 cm across one lying on the
ground fell through it at n = 10, 20, 40 and 60/240/1000 Hz (the segments pass between the spheres,
and Bullet's impulses were not in the cables' implicit steps). Now each cable's step holds the other
cable's segment capsules as contact shapes (``demos/cable_cable.py`` prints the full table).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

_spec = importlib.util.spec_from_file_location("cable_cable_demo",
                                               Path(__file__).resolve().parents[2] / "demos" / "cable_cable.py")
_demo = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_demo)
crossing, segment_distance = _demo.crossing, _demo.segment_distance

G = 9.81


def crossing_at_rest(n: int, rate: float, duration: float = 0.4):
    """A cable on the ground along x and one along y laid across it 0.1 mm above contact."""
    spec = CableSpec.lv2017(n_masses=n, damping=0.02)
    r, L = spec.diameter / 2, spec.length
    world = BulletWorld(dt=1 / rate)
    low = world.add_cable(spec, start=(-L / 2, 0, r), direction=(1, 0, 0), name="low")
    up = world.add_cable(spec, start=(0, -L / 2, 3 * r + 1e-4), direction=(0, 1, 0), name="up")
    world.run(duration)
    return world, low, up, spec


@pytest.mark.parametrize("rate,n", [(60, 10), (60, 40), (240, 20), (240, 40), (1000, 10), (1000, 40)])
def test_crossing_at_rest(rate, n):
    world, low, up, spec = crossing_at_rest(n, rate)
    try:
        assert low.stable and up.stable, (low.reason, up.reason)
        r1_r2 = spec.diameter
        clearance = segment_distance(low.x, up.x)
        assert abs(clearance - r1_r2) <= 0.05 * r1_r2, clearance
        support = sum(float(c.contact_forces()["force"][c.contact_forces()["body"] == world.ground_id, 2].sum())
                      for c in (low, up))
        assert support == pytest.approx(2 * spec.mass * G, rel=0.01)
        # the model's cable-cable forces: present on both cables, Bullet's sphere contacts between them off
        assert (up.contact_forces()["body"] == -2).any() and (low.contact_forces()["body"] == -2).any()
        owners = world._owners
        pairs = [cp for cp in world.contacts() if cp[1] in owners and cp[2] in owners]
        assert not pairs
    finally:
        world.close()


def lying_along(n_low: int, n_up: int, rate: float, d_low: float = 0.004, d_up: float = 0.004, shift: float = 0.0,
                duration: float = 1.0):
    """A cable on the ground along x and one laid along it on top, 0.1 mm above contact, its start ``shift``
    [m] further along x."""
    low_spec = CableSpec.lv2017(n_masses=n_low, damping=0.02, diameter=d_low)
    up_spec = CableSpec.lv2017(n_masses=n_up, damping=0.02, diameter=d_up)
    L = low_spec.length
    world = BulletWorld(dt=1 / rate)
    low = world.add_cable(low_spec, start=(-L / 2, 0, d_low / 2), direction=(1, 0, 0), name="low")
    up = world.add_cable(up_spec, start=(-L / 2 + shift, 0, d_low + d_up / 2 + 1e-4), direction=(1, 0, 0), name="up")
    world.run(duration)
    return world, low, up


@pytest.mark.parametrize("rate,n_low,n_up,d_up,shift", [
    (60, 10, 10, 0.004, 0.0), (240, 10, 10, 0.004, 0.0), (240, 40, 40, 0.004, 0.0), (1000, 20, 20, 0.004, 0.0),
    (240, 10, 40, 0.004, 0.0), (60, 40, 10, 0.006, 0.01), (240, 20, 20, 0.003, 0.0083)])
def test_cable_lying_along_another_rests_on_it(rate, n_low, n_up, d_up, shift):
    """Two cables lying along each other, the upper one on the lower: the ground carries both weights, the lower
    cable carries the upper one's, and each cable's model holds the same force of the other (equal and opposite),
    the centre lines r1 + r2 apart. Before, two parallel segments were taken at one closest point pair: the last
    node of the upper cable had no row and sank into the lower one, and rounding at the shared nodes doubled some
    rows, so the two cables' steps held different forces (the lower cable pushed down by 8 times the upper one's
    weight at n 40 and 240 Hz, the ground's load cycling between 2 and 19 times both weights; stopped as energy
    growth at n 10)."""
    world, low, up = lying_along(n_low, n_up, rate, d_up=d_up, shift=shift)
    try:
        assert low.stable and up.stable, (low.reason, up.reason)
        w_low, w_up = low.model.spec.mass * G, up.model.spec.mass * G
        ground = sum(float(c.contact_forces()["force"][c.contact_forces()["body"] == world.ground_id, 2].sum())
                     for c in (low, up))
        assert ground == pytest.approx(w_low + w_up, rel=0.01)
        on_up = float(up.contact_forces()["force"][up.contact_forces()["body"] == -2, 2].sum())
        on_low = float(low.contact_forces()["force"][low.contact_forces()["body"] == -2, 2].sum())
        assert on_up == pytest.approx(w_up, rel=0.01)
        assert on_low == pytest.approx(-w_up, rel=0.01)
        gap = up.x[:, 2].min() - low.x[:, 2].max()
        assert gap == pytest.approx((0.004 + d_up) / 2, rel=0.05)
        assert max(abs(low.v).max(), abs(up.v).max()) < 1e-4  # at rest
    finally:
        world.close()


@pytest.mark.parametrize("rate,n,shift", [(60, 10, 0.5), (60, 40, 0.0), (240, 10, 0.0), (240, 40, 0.0), (1000, 20, 0.5), (1000, 40, 0.0)])
def test_dropped_cable_does_not_pass_through(rate, n, shift):
    out = crossing(n, 1 / rate, drop=0.03, duration=0.4, shift=shift)
    assert not out["unstable"], out["unstable"]
    assert out["closest_mm"] > 0.95 * 4.0  # never closer than r1 + r2 - 5 % during the fall and after
    assert out["clearance_mm"] == pytest.approx(4.0, rel=0.05)
    assert out["up_mid_z_mm"] == pytest.approx(6.0, rel=0.05)  # resting on top of the lower cable


def test_single_cable_world_has_no_cable_rows():
    spec = CableSpec.lv2017(n_masses=10)
    with BulletWorld(dt=1 / 240) as world:
        c = world.add_cable(spec, start=(-0.15, 0, 0.002))
        assert c._contact_set.others.x.shape == (0, 3)
        world.run(0.05)
        assert not (c.contact_forces()["body"] == -2).any()
