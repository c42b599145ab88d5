"""An upright cylinder standing on a cable (issue 23: any collision shape, bodies resting on the cable).

A segment passing under a cylinder's flat end is pressed by that end, not by the mantle. Before, every segment
point inside a cylinder got the mantle's row: the segment under the flat end of a standing cylinder was pushed
sideways by up to the cylinder's radius. A 3 kg cylinder (r 15 mm) dropped on a thin cable at 60 Hz was shoved 9 mm
and tipped with the cable reported 15 mm inside it; a 10 kg one stopped the run as energy growth; a puck (r 12 mm)
between two nodes of a coarse cable was pushed through it to the ground, or below it.
Closed forms: at rest the cable's centre line is outside the body (by at least its radius less twice the load depth,
:data:`bullet_dlo.bullet.contact.LOAD_DEPTH`), the body has not been pushed along the ground, and the ground carries
the cable's and the body's weight. A level segment under a level flat end rests on the two points where its chord
meets the rim (as a box's edges take it), a tilted end digs in at one.
"""
from __future__ import annotations

import warnings

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

G = 9.81


def _inside(cable, body: int, radius: float, half_height: float, cid: int) -> float:
    """How far [m] the cable's centre line reaches inside the upright cylinder ``body`` at its deepest (< 0:
    outside)."""
    pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
    rot = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)
    s = np.linspace(0.0, 1.0, 33)
    x = cable.x
    points = (x[:-1, None] * (1.0 - s)[None, :, None] + x[1:, None] * s[None, :, None]).reshape(-1, 3)
    local = (points - np.asarray(pos)) @ rot
    q = np.stack([np.hypot(local[:, 0], local[:, 1]) - radius, np.abs(local[:, 2]) - half_height], axis=1)
    signed = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    return float(-signed.min())


def _drop(spec: CableSpec, hz: float, m_body: float, radius: float, height: float, seconds: float = 2.0,
          x0: float = 0.0):
    """A cylinder dropped 1 cm, upright, on the cable lying on the ground, x0 [m] from its middle. Returns (deepest
    [m] the centre line reached inside it, at the end [m], its sideways move [m], its final speed [m/s], the cable's
    status, the ground's load / both weights at the end, the inside warnings)."""
    r = spec.diameter / 2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with BulletWorld(dt=1.0 / hz) as world:
            cid = world.client
            cable = world.add_cable(spec, start=(-spec.length / 2, 0.0, r + 2e-4), direction=(1, 0, 0))
            world.run(0.2)
            top = float(cable.x[:, 2].max()) + r
            body = world.add_cylinder(radius, height, (x0, 0.0, top + height / 2 + 0.01), mass=m_body, friction=0.5)
            deepest = -np.inf
            for _ in range(world.steps_in(seconds)):
                world.step()
                deepest = max(deepest, _inside(cable, body, radius, height / 2, cid))
                if not cable.stable:
                    break
            pos = pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0]
            speed = float(np.linalg.norm(pb.getBaseVelocity(body, physicsClientId=cid)[0]))
            pc = cable.contact_forces()
            ground = float(pc["force"][pc["body"] == world.ground_id][:, 2].sum())  # on the cable, and on the body:
            ground += sum(cp[9] for cp in pb.getContactPoints(body, world.ground_id, physicsClientId=cid))
            balance = ground / ((spec.mass + m_body) * G)
            end = _inside(cable, body, radius, height / 2, cid)
            status = "stable" if cable.stable else cable.reason
    inside = [str(w.message) for w in caught if "inside it" in str(w.message)]
    return deepest, end, float(np.hypot(pos[0] - x0, pos[1])), speed, status, balance, inside


THIN = CableSpec(length=0.25, diameter=0.0025, mass=0.008, youngs_modulus=2e9, n_masses=20, damping=0.02)


@pytest.mark.parametrize("m_body, hz, landing", [(0.3, 60.0, 0.0), (3.0, 60.0, 0.0), (10.0, 60.0, 1.0),
                                                  (3.0, 240.0, 0.0), (10.0, 240.0, 0.0)])
def test_a_heavy_cylinder_standing_on_a_thin_cable_presses_it_with_its_flat_end(m_body, hz, landing):
    """r 15 mm, 20 mm tall, on the thin light cable (2.5 mm, 8 g, 2 GPa, n 20): two nodes under its flat end, the
    segments beside them on its rim. It rests on the cable pressing it at most the load depth, not pushed aside;
    ``landing``: how far [cable radii] the centre line may enter it for a step of the landing (10 kg at 60 Hz meets
    rows not yet stiffened to its load, and is reported: contact docs, "Bodies resting on the cable")."""
    r = THIN.diameter / 2
    deepest, end, moved, speed, status, balance, inside = _drop(THIN, hz, m_body, 0.015, 0.02)
    assert status == "stable", status
    assert landing > 0.0 or not inside, inside
    assert end < -(1.0 - 0.1) * r, f"centre line {end / r:+.2f} r inside at the end"
    assert deepest < landing * r, f"centre line {deepest / r:+.2f} r inside in the landing"
    assert moved < 2e-3, f"pushed {1e3 * moved:.1f} mm sideways"
    assert speed < 1e-4 and balance == pytest.approx(1.0, abs=0.01), (speed, balance)


@pytest.mark.parametrize("m_body, hz", [(0.003, 60.0), (0.03, 60.0), (0.3, 240.0), (0.03, 1000.0)])
def test_a_puck_between_two_nodes_of_a_coarse_cable_rests_on_the_segment(m_body, hz):
    """A puck (r 12 mm, 6 mm thick) on the Lv cable at n 7 (segments 5 cm), its centre between two nodes: no node
    under its flat end, the segment's chord carries it; it tips onto the ground and rests leaning on the cable,
    the cable's centre line outside it (before: pushed through the cable to the ground, or below it)."""
    spec = CableSpec.lv2017(n_masses=7)
    r = spec.diameter / 2
    deepest, end, moved, speed, status, balance, inside = _drop(spec, hz, m_body, 0.012, 0.006, x0=0.025, seconds=3.0)
    assert status == "stable", status
    assert not inside, inside
    assert end < 0.1 * r, f"centre line {end / r:+.2f} r inside it at the end"
    assert deepest < 0.5 * r, f"centre line {deepest / r:+.2f} r inside it in the landing"
    assert moved < 0.03, f"thrown {1e3 * moved:.0f} mm"
    assert speed < 1e-4 and balance == pytest.approx(1.0, abs=0.01), (speed, balance)
