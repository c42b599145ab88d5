"""The dual-arm scene's cable against the other arm (issue 23 item 5): a Panda holds one end of a cable
(the other end released) and lifts it; the other Panda drives its hand through the hanging cable. The
cable meets that arm's fingers and hand (links 8-10, distal to its wrist sensor joint) and its
panda_link7 (link 6, proximal to it).

Physics checked:
- non-penetration: no node or segment centre of the cable comes inside the arm's collision shapes (Bullet's
  getClosestPoints of a sphere of the cable's radius at each point stays above -(radius + Bullet's 1 mm mesh
  margin)); with the arm excluded from the cable's contacts (``exclude_contact``) the same motion drives the
  centre line deep inside, so the check can fail;
- balance of forces at the wrist: the tool side (hand, fingers) is pushed only by the cable, so the change of
  the wrist reading of the pushing arm (unloaded before: it reads 0) must equal the force the cable's contact
  model reports on the tool links (``contact_forces()``, rows with this body and a tool link), and the contact
  on panda_link7 must not appear at the sensor. Before the fix in ``DualArmObservation.read_sensors`` the
  sensor's Newton-Euler counted the held cable's end load and Bullet's own contacts, but not the reactions the
  cable's contact model applies to the tool links with applyExternalForce: the pushing arm's sensor read
  0.000 N while the model reported up to 2.0 N on its hand.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from probes import deepest

from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmScene

HZ = 240.0
MESH_MARGIN = 1e-3  # [m] Bullet's collision margin of the Panda's convex meshes (docs/concepts/contact.md)


def push_through(exclude: bool = False) -> dict:
    """Left Panda holds the cable's first end and lifts it 15 cm; the right Panda (its end released) moves its
    hand 28 cm towards the left one through the hanging cable. Returns per-check-step records."""
    spec = DualArmSpec(robot="panda", dt=1.0 / HZ, cable=CableSpec.lv2017(n_masses=12, damping=0.02))
    out = {"depth": [], "tool": [], "proximal": [], "sensor": [], "links": set(), "stable": True, "model_loads": []}
    with DualArmScene(spec, record=False) as scene:
        cid, cable = scene.world.client, scene.cable
        right = scene.robots[1].body
        tool = sorted(scene.sensors[1]._tool_links)  # links below the right arm's sensor joint
        if exclude:
            cable.exclude_contact(right)
        scene.grasp()
        scene.release("right")
        scene.move("left", (0.0, 0.0, 0.15), 0.4, start=0.0)
        scene.move("right", (-0.28, 0.0, 0.0), 0.8, start=0.5)
        r = spec.cable.diameter / 2
        probe = pb.createCollisionShape(pb.GEOM_SPHERE, radius=r, physicsClientId=cid)
        for k in range(int(1.4 * HZ)):
            scene.run(1.0 / HZ)
            out["stable"] &= bool(cable.stable)
            out["model_loads"].append((scene.observation._model_tool_loads(), full_tool_loads(scene)))
            if scene.world.time < 0.9:
                continue
            x = cable.x
            out["depth"].append(deepest(cid, right, np.vstack([x, 0.5 * (x[1:] + x[:-1])]), probe))
            pc = cable.contact_forces()
            mine = pc["body"] == right
            on_tool = mine & np.isin(pc["link"], tool)
            out["links"] |= set(pc["link"][mine].tolist())
            out["tool"].append(-pc["force"][on_tool].sum(axis=0))  # the cable's push on the hand and fingers [N]
            out["proximal"].append(-pc["force"][mine & ~on_tool].sum(axis=0))
            out["sensor"].append(scene.sensors[1].last.world()[:3].copy())
        out["check"] = np.array(scene.observation.check.worst)  # (2, 2): worst force/moment mismatch per arm
    for key in ("tool", "proximal", "sensor"):
        out[key] = np.array(out[key])
    out["radius"] = r
    return out


def full_tool_loads(scene) -> np.ndarray | None:
    """The contact model's reactions on each arm's tool links summed over every contact of ``contact_forces()``
    (force [N], moment about the world origin [N m]; None when no contact is on a tool link): the reference for
    ``DualArmObservation._model_tool_loads``, which skips the sum when no contact is on an arm at all."""
    pc = scene.cable.contact_forces()
    out, hit = np.zeros((2, 6)), False
    for arm, s in enumerate(scene.sensors):
        sel = (pc["body"] == s.robot.body) & np.isin(pc["link"], list(s._tool_links))
        if sel.any():
            f = -pc["force"][sel]
            out[arm, :3] = f.sum(axis=0)
            out[arm, 3:] = np.cross(pc["point"][sel], f).sum(axis=0)
            hit = True
    return out if hit else None


@pytest.fixture(scope="module")
def pushed() -> dict:
    return push_through()


def test_the_cable_stays_outside_the_other_arm(pushed):
    """The cable meets the fingers/hand and panda_link7 and its centre line stays outside their shapes."""
    assert pushed["stable"]
    assert {9, 10} & pushed["links"], pushed["links"]  # a finger
    assert 6 in pushed["links"], pushed["links"]  # panda_link7, proximal to the sensor joint
    assert np.abs(pushed["tool"]).max() > 0.1  # a real push [N], not a graze
    assert min(pushed["depth"]) > -(pushed["radius"] + MESH_MARGIN), min(pushed["depth"])


def test_without_the_arm_in_the_contact_model_the_cable_goes_inside():
    """The same motion with the right arm excluded: the hand passes through the cable (centre line inside its
    shapes), so the check above can fail."""
    free = push_through(exclude=True)
    assert not free["links"]
    assert min(free["depth"]) < -(free["radius"] + MESH_MARGIN), min(free["depth"])


def test_the_wrist_sensor_reads_the_push_on_its_hand(pushed):
    """Balance of forces on the tool side (hand, fingers): the right sensor's reading (the load on the tool, world
    frame; released and tared unloaded, so it read 0 before) equals the contact model's force on the tool links
    that Bullet's step applied. ``contact_forces()`` after a step holds the contacts planned for the *next* Bullet
    step, so sensor row k is compared with contact row k - 1. The payload compensation removes the hand's own
    weight and inertia with the URDF's payload exactly, so the rest is the cable's push to rounding: within
    1e-9 N (measured 3e-15 N over 42 steps of contact, up to 0.74 N). Steps where the cable also pushes
    panda_link7 (proximal to the sensor joint; 14 steps, up to 1.1 N) read the tool's push alone: that push goes
    into the arm above the sensor. Before the fix the sensor read 0.000 N throughout (it missed the reactions
    applied with applyExternalForce)."""
    tool, prox, sensor = pushed["tool"][:-1], pushed["proximal"][:-1], pushed["sensor"][1:]
    on_tool = np.linalg.norm(tool, axis=1) > 0.05
    assert on_tool.sum() >= 5
    np.testing.assert_allclose(sensor[on_tool], tool[on_tool], rtol=0, atol=1e-9)
    on_proximal = np.linalg.norm(prox, axis=1) > 0.05
    assert on_proximal.sum() >= 3
    assert np.abs(sensor[on_proximal] - tool[on_proximal]).max() < 1e-9
    # the per-sample sensor check (SensorCheck) expects the model's push too: it does not flag this run
    assert np.abs(pushed["check"]).max() < 1e-9, pushed["check"]


def test_the_tool_loads_skip_only_steps_without_a_contact_on_a_tool(pushed):
    """The sensors' per-step read of the contact model's reactions on the tools (which skips the per-contact sum
    when no contact touches an arm) equals the full sum in every step of the push: None in the steps where the
    cable touches nothing of an arm's tool side, the same bits where it touches the hand."""
    rows = pushed["model_loads"]
    touched = [full is not None for _, full in rows]
    assert sum(touched) >= 5 and not all(touched)
    for fast, full in rows:
        assert (fast is None) == (full is None)
        assert fast is None or np.array_equal(fast, full)
