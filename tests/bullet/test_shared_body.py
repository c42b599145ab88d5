"""A body resting on two or more cables (issue 23 item 2): each cable's step moves it with its whole mass and the
other cables' reactions, and their reactions are combined before Bullet's step (bullet_dlo/bullet/held_bodies.py,
"Bodies on several cables"; docs/concepts/contact.md, "A body on two cables").

The scene of demos/box_on_two_cables.py: parallel Lv cables lying on a table, a 40 x 40 x 20 mm box dropped 5 mm
across them. Resting, its bottom lies one cable diameter above the table (z_on for its centre), the cables carry its
weight by the lever rule where two do (three alike cables under a level box: a third each), and the table all the
weights.

Fails before (08ac6ba): a body two cables share kept the condensed contact, which sinks about g h^2 (the box rested
0.5 mm into the cables at 240 Hz and 0.03 mm at 1 kHz, after dipping 1.7 / 0.4 mm). The cases at 60 and 120 Hz fail
on 286b99f (each cable's step with its share of the mass, ``held_bodies.COUPLE_SHARED = False``): every box went
through both cables to the table at 60 Hz, off-centre ones at 120 Hz too.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet import held_bodies

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "demos"))
from box_on_two_cables import drop  # noqa: E402  (the demo's scene)
from leaning_on_two_cables import build, lean  # noqa: E402  (the demo's scene)

pytestmark = pytest.mark.bullet


@pytest.mark.parametrize("mass", [0.001, 0.03, 3.0])
def test_a_box_dropped_across_two_cables_rests_on_both_at_1_khz(mass):
    """1 g to 3 kg, centred, 1 kHz: within 2 s at rest on the cables (0.01 mm into them; never 0.1 mm), each cable
    carrying half the box's weight within 1 %, the table all the weight within 1 %. Condensed, every one dipped 0.4
    mm into the cables."""
    out = drop(1000.0, mass)
    assert not out["stopped"], out
    assert abs(out["z"]) < 1e-5 and out["lowest"] > -1e-4 and out["speed"] < 1e-4, out
    assert out["carried"] == pytest.approx([0.5, 0.5], abs=0.01), out
    assert out["table"] == pytest.approx(1.0, abs=0.01), out


@pytest.mark.parametrize("mass", [0.001, 0.03, 3.0])
def test_a_box_dropped_across_two_cables_stays_on_them_at_240_hz(mass):
    """1 g to 3 kg, centred, 240 Hz: on the cables after 2 s within 0.1 mm (condensed: 0.5 mm into them), never more
    than 0.2 mm into them (condensed: 1.7 mm), each cable carrying half the weight and the table all of it within 1 %;
    3 kg at rest. (1 g and 30 g still sway across the cables at up to 1e-4 and 8e-4 m/s after 2 s, decaying: the
    turn each share makes under its own cable's support, docs/concepts/contact.md, "A body on two cables".)"""
    out = drop(240.0, mass)
    assert not out["stopped"], out
    assert abs(out["z"]) < 1e-4 and out["lowest"] > -2e-4, out
    assert out["carried"] == pytest.approx([0.5, 0.5], abs=0.01), out
    assert out["table"] == pytest.approx(1.0, abs=0.01), out
    if mass >= 1.0:
        assert out["speed"] < 1e-4, out


def test_an_off_centre_box_on_two_cables_comes_to_rest_on_them():
    """300 g, 8 mm off the middle towards one cable, 240 Hz: at rest on the cables within 0.2 mm, the cables
    carrying all its weight, the nearer one more."""
    out = drop(240.0, 0.3, offset=0.008)
    assert not out["stopped"], out
    assert abs(out["z"]) < 2e-4 and out["speed"] < 1e-4, out
    assert sum(out["carried"]) == pytest.approx(1.0, abs=0.01) and out["carried"][1] > out["carried"][0], out


def _lever(out: dict) -> list[float]:
    """The two cables' shares of the box's weight by the lever rule at the box's final position across them."""
    ys = out["ys"]
    far = (out["y"] - ys[0]) / (ys[1] - ys[0])
    return [1.0 - far, far]


@pytest.mark.parametrize("hz", [60.0, 120.0])
@pytest.mark.parametrize("mass, offset", [(0.001, 0.008), (0.03, 0.0), (0.3, 0.008), (3.0, 0.0), (3.0, 0.008)])
def test_a_box_dropped_across_two_cables_rests_on_both_at_60_and_120_hz(hz, mass, offset):
    """1 g to 3 kg, centred or 8 mm towards one cable, at 60 and 120 Hz: within 2 s at rest on the cables (within 0.3
    mm, never 0.5 mm into them; measured: 3 kg at 60 Hz 0.31 mm at the landing and 0.21 mm at rest, 8 mm off, with 90 %
    of its weight on one cable, the penalty's compression there), level, the cables carrying the box's weight by the
    lever rule at where it lies within 1 %, the table all the weights."""
    out = drop(hz, mass, offset)
    assert not out["stopped"], out
    assert out["speed"] < 1e-4 and abs(out["z"]) < 3e-4 and out["lowest"] > -5e-4, out
    assert out["tilt"] < 0.02, out
    assert out["carried"] == pytest.approx(_lever(out), abs=0.01), out
    assert out["table"] == pytest.approx(1.0, abs=0.01), out


@pytest.mark.parametrize("n", [20, 30, 40])
def test_a_10_kg_box_across_two_cables_near_its_edges_comes_to_rest_at_60_hz(n):
    """10 kg, centred on two cables 30 mm apart (each 5 mm inside the box's side faces) at 60 Hz, n 20-40: at rest
    within 2 s (below 1e-4 m/s), level, each cable carrying half the weight and the table all the weights within 1 %.
    Fails on 0ec665f: the box kept rocking about the cables' direction at 0.6 / 0.8 / 1.5 mm/s, period three steps
    (with the table's friction 0.1 or 0.3, or the cables 20 mm apart, it rested). Each segment crossing a bottom edge
    had, beside that edge's row, a row of the bottom face found from the vertical edge at the corner nearby, and
    segments along the cable one found from the bottom edge parallel to them (its closest point anywhere along
    it); both were admitted within a margin that grows with the box's speed, so they came and went with the rocking
    (36, 40, 38 rows, period three), and with them the face's stiffness at the crossing."""
    out = drop(60.0, 10.0, n=n, sep=0.03)
    assert not out["stopped"], out
    assert out["speed"] < 1e-4 and out["tilt"] < 1e-3, out
    assert out["carried"] == pytest.approx([0.5, 0.5], abs=0.01), out
    assert out["table"] == pytest.approx(1.0, abs=0.01), out


def test_a_segment_meets_a_box_face_once_where_it_crosses_its_edge():
    """The 10 kg box resting across the two cables of the test above (each 5 mm inside the box's side faces): each
    step, no two of the box's rows on one segment lie within the cable radius of each other along it, and the rows
    are the same in every step of the last half second. Fails on 0ec665f: where a segment crossed a bottom edge the
    edge's row and a row of the bottom face found from the corner's vertical edge lay 0.03 mm apart, and rows found
    from the bottom edge along the cable came and went."""
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec

    spec = CableSpec.lv2017(n_masses=30, damping=0.02)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / 60.0, ground=False) as world:
        world.add_box((0.3, 0.2, 0.05), (0.0, 0.0, -0.05), friction=0.5, name="table")
        cables = [world.add_cable(spec, start=(-0.15, y, r), direction=(1, 0, 0), name=f"c{k}")
                  for k, y in enumerate((-0.015, 0.015))]
        world.run(0.2)
        box = world.add_box((0.02, 0.02, 0.01), (0.0, 0.0, 2 * r + 0.01 + 0.002), mass=10.0, friction=0.5)
        world.run(1.5)
        seen = None
        for _ in range(30):
            world.step()
            rows = []
            for c in cables:
                cf = c.contact_forces()
                on = cf["body"] == box
                for (a, b), w in zip(cf["node"][on], cf["weight"][on]):
                    if a != b:
                        rows.append((c.name, int(a), round(float(w[1]), 2)))
                        length = float(np.linalg.norm(c.x[b] - c.x[a]))
                        same = [(int(a2), float(w2[1])) for (a2, b2), w2 in zip(cf["node"][on], cf["weight"][on])
                                if a2 == a and b2 == b]
                        close = [t for t in same if abs(t[1] - w[1]) * length < r]
                        assert len(close) == 1, (c.name, a, same)
            assert seen is None or sorted(rows) == seen, (sorted(rows), seen)
            seen = sorted(rows)
        assert seen, "no segment row on the box"


@pytest.mark.parametrize("mass", [0.001, 3.0])
def test_a_box_across_three_cables_rests_with_a_third_on_each(mass):
    """1 g and 3 kg across three alike cables 15 mm apart at 60 Hz: at rest on them within 0.2 mm, a third of the
    weight on each within 1 % (a level box presses alike cables alike); 10 mm off the middle, with the far cable
    outside the box, on the other two by the lever rule."""
    out = drop(60.0, mass, count=3, sep=0.015)
    assert not out["stopped"], out
    assert out["speed"] < 1e-4 and abs(out["z"]) < 2e-4 and out["lowest"] > -5e-4, out
    assert out["carried"] == pytest.approx([1 / 3] * 3, abs=0.01), out
    off = drop(60.0, mass, offset=0.01, count=3, sep=0.015)
    assert not off["stopped"] and off["speed"] < 1e-4 and abs(off["z"]) < 2e-4, off
    far = off["y"] / 0.015
    assert off["carried"] == pytest.approx([0.0, 1.0 - far, far], abs=0.01), off


def test_a_shared_body_that_gains_energy_from_the_cables_stops_the_run(monkeypatch):
    """The energy check books a body several cables move, in one of them, with the work of all their reactions: the
    reactions handed twice over (as a broken coupling would hand them) stop the run as the body's energy growth, where
    the same drop without that rests (the tests above). Fails before 2026-12-05 afternoon: a body two cables share was
    booked by neither, and the box was thrown off the cables with both reporting "stable"."""
    real = held_bodies.settle

    def doubled(shares, step, targets):
        out = real(shares, step, targets)
        for body in targets:
            for p in shares[body].values():
                if p.step == step:
                    p.cs.bodies.impulse[p.slot] *= 50.0
        return out

    monkeypatch.setattr(held_bodies, "settle", doubled)
    out = drop(240.0, 0.03)
    assert any("a body gained energy from contact" in s for s in out["stopped"]), out


def _tipped_across(hz: float, mass: float, scene: str) -> dict:
    """A 40 x 40 x 20 mm box that two cables lying on the table share while the table holds it too: ``crossing``,
    dropped 4 mm onto two cables crossing at right angles (the second over the first), 10 mm off the crossing along
    both, so that it tips an edge onto the table; ``lean``, dropped 4 mm onto two parallel cables 5 and 15 mm off its
    middle, so that it leans on the table and the inner cable. After 2 s: its lowest gap to a cable over the run
    (negative: into it), centre height z, speed, and the cables' and the table's support over its weight."""
    from bullet_dlo.bullet.world import BulletWorld

    with BulletWorld(dt=1.0 / hz, ground=False) as world:
        cid = world.client
        table, cables, box = build(world, mass, 0.5, scene)
        lowest = 0.0
        for _ in range(round(2.0 * hz)):
            world.step()
            for c in cables:
                cf = c.contact_forces()
                on = cf["body"] == box
                if on.any():
                    lowest = min(lowest, float(cf["gap"][on].min()))
        weight = mass * 9.81
        return {"lowest": lowest, "z": pb.getBasePositionAndOrientation(box, physicsClientId=cid)[0][2],
                "speed": float(np.linalg.norm(pb.getBaseVelocity(box, physicsClientId=cid)[0])),
                "cables": [float(c.body_forces().get(box, np.zeros(3))[2]) / weight for c in cables],
                "table": sum(cp[9] for cp in pb.getContactPoints(box, table, physicsClientId=cid)) / weight,
                "stopped": [c.reason for c in cables if not c.stable]}


@pytest.mark.parametrize("scene, mass", [("crossing", 0.3), ("crossing", 3.0), ("lean", 0.003), ("lean", 3.0)])
def test_a_box_two_cables_and_the_table_share_comes_to_rest_on_them_at_60_hz(scene, mass):
    """A box that two cables share while the table holds it too (in the landing, or at rest: the 3 kg box across the
    crossing), at 60 Hz: never through a cable (less than 3 of its 4 mm into it; measured 2.2 mm for the 3 kg box
    across the crossing as it tips onto the table, 0.35 mm at most for the others), at rest within 2 s (below 2e-4
    m/s: a box leaning on a cable and the table creeps at about 1e-4 m/s), tilted on its supports (its centre above
    lying flat on the table, 10 mm), which carry its weight within 1 %. Three of the four fail on a916460, where such a
    body kept the condensed contact: they went through the cables to the table (9-13 mm into them); the 300 g box
    across the crossing, which ends on the cables alone, passes there too."""
    out = _tipped_across(60.0, mass, scene)
    assert not out["stopped"], out
    assert out["lowest"] > -3e-3 and out["z"] > 0.012 and out["speed"] < 2e-4, out
    assert sum(out["cables"]) + out["table"] == pytest.approx(1.0, abs=0.01), out
    assert min(out["cables"]) > -0.01 and max(out["cables"]) > 0.1, out


def test_a_cable_whose_rows_carry_nothing_does_not_move_the_body_another_cable_plans():
    """Two cables' plans of one body, one of them with no reaction and no load mass (its rows within reach, carrying
    nothing): the other plan stands as made, its velocity the body's, and nobody is planned again. (On ac3ebf8 the
    two were combined by a body equation without the table's hold points: 0.047 rad/s off the plan, handed to Bullet
    through the planning cable's load mass.)"""
    rng = np.random.default_rng(1)
    e = rng.normal(size=(6, 6))
    planned = held_bodies.Share(None, 0, rng.normal(size=6), e @ e.T, rng.normal(size=6), np.zeros(6), 7, False)
    idle = held_bodies.Share(None, 0, np.zeros(6), np.zeros((6, 6)), rng.normal(size=6), np.zeros(6), 7, True)
    again, targets = held_bodies.unsettled({5: {"c0": planned, "c1": idle}}, 7, 1.0 / 60.0)
    assert again == set()
    assert np.array_equal(targets[5], planned.vel)


@pytest.mark.parametrize("hz, mass, friction", [(240.0, 0.03, 2.0), (240.0, 0.003, 0.5), (120.0, 0.3, 2.0)])
def test_a_cable_within_reach_that_carries_nothing_changes_nothing(hz, mass, friction):
    """A box leaning on the table and on one of two cables, the other under its raised side within the contact's
    reach but carrying nothing (demos/leaning_on_two_cables.py, 2 s): the box moves to the bit as with the second
    cable out of reach, and rests with its weight carried. On ac3ebf8 the idle cable's zero share made the body's
    velocity one combined without the table's hold points, and the box's speed differed by 0.011-0.039 m/s from
    the run without it (3 g at 60 Hz, friction 2: kicked from rest to 0.058 m/s at 3.7 s)."""
    idle, alone = lean(hz, mass, friction, 0.015, 2.0), lean(hz, mass, friction, 0.06, 2.0)
    assert not idle["stopped"], idle["stopped"]
    assert np.array_equal(idle["speeds"], alone["speeds"])
    assert idle["speeds"][-int(hz) // 4:].max() < 1e-4
    assert idle["support"] == pytest.approx(1.0, abs=0.01)


def test_the_cables_together_move_a_held_body_by_the_equation_of_their_plans(monkeypatch):
    """Where a cable's plan alone loads a body that the table also holds (the leaning box beside an idle cable,
    demos/leaning_on_two_cables.py, 60 Hz, 30 g, friction 2), the cables' combined velocity (``_together``) solved from
    the shares is that plan's own velocity: the same body equation with the apparent mass and the table's hold points
    (median difference below 1e-9 m/s and rad/s over the steps; on ac3ebf8 its equation left both out: 0.9 mm/s
    and 0.14 rad/s in the median)."""
    differences = []
    unsettled = held_bodies.unsettled

    def watched(shares, step, dt):
        for parts in shares.values():
            now = [p for p in parts.values() if p.step == step]
            loaded = [p for p in now if p.impulse.any() or p.load_mass.any()]
            if len(loaded) == 1 and not loaded[0].coupled and loaded[0].slot in loaded[0].cs._measured:
                d = held_bodies._together(now, dt) - loaded[0].vel
                differences.append((np.linalg.norm(d[:3]), np.linalg.norm(d[3:])))
        return unsettled(shares, step, dt)

    monkeypatch.setattr(held_bodies, "unsettled", watched)
    lean(60.0, 0.03, 2.0, 0.015, 1.5)
    assert len(differences) > 30
    assert np.median(np.array(differences), axis=0).max() < 1e-9, np.median(np.array(differences), axis=0)
