"""Native Bullet calls (bullet.native): the same physics as PyBullet's Python API, without its per-call Python.

The speed itself is measured by ``python demos/env_speed.py`` (ratios, not timed tests); here: the
native path is taken, it changes no result, it makes the per-step PyBullet Python calls go away,
and it steps aside cleanly when it cannot be trusted.
"""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest
from probes import lines_through_links

from bullet_dlo.bullet import native
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmObservation, DualArmPhysics, DualArmSpec

needs_compiler = pytest.mark.skipif(native.plugin_library() is None,
                                    reason="no C compiler: the handle plugin cannot be built here")


def scene(robot: str = "panda", n: int = 8) -> tuple[DualArmPhysics, DualArmObservation]:
    physics = DualArmPhysics(DualArmSpec(robot=robot, cable=CableSpec.lv2017(n_masses=n, damping=0.02)))
    obs = DualArmObservation(physics)
    physics.clamp(0)
    physics.clamp(1)
    return physics, obs


def drive(physics: DualArmPhysics, steps: int) -> None:
    """Step while the right arm's joint targets swing (arms, grasp and sensors all move)."""
    right = physics.robots[1]
    q0 = right.joint_positions()
    for k in range(steps):
        q = q0.copy()
        q[0] += 0.15 * np.sin(2 * np.pi * 2.0 * k * physics.world.dt)
        right.set_targets(q)
        physics.world.step()


def run(monkeypatch, enabled: bool, steps: int = 120) -> dict[str, np.ndarray]:
    monkeypatch.setenv("BULLET_DLO_NATIVE", "1" if enabled else "0")
    physics, obs = scene()
    try:
        assert bool(physics.world.native_handle()) == enabled
        drive(physics, steps)
        rec = obs.record.arrays()
        return {"x": physics.cable.x.copy(), "wrench": rec["wrench_world"], "end": rec["end_forces"],
                "grasp": rec["grasp_pos"]}
    finally:
        physics.close()


@needs_compiler
def test_native_and_python_paths_give_identical_dual_arm_runs(monkeypatch):
    """Forces applied and states read natively are bit for bit what PyBullet's Python API gives."""
    a, b = run(monkeypatch, True), run(monkeypatch, False)
    assert np.abs(a["wrench"]).max() > 0.05  # the sensors carry the cable's moving load
    assert np.ptp(a["grasp"][:, 1, 0]) > 1e-3  # the right gripper moved
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@needs_compiler
def test_a_dual_arm_step_makes_no_per_step_pybullet_calls_but_the_step(monkeypatch):
    """Before: 26 PyBullet Python calls per step at n = 10 (n force calls, two wrenches, three reads per
    arm, two obstacle poses, ...); now the Bullet step and the contact query: the arms, the cable's
    forces, the contact model's obstacle poses and its broad phase against the arms' links (one overlap query
    and the boxes of the links it names, before: one ``getOverlappingObjects`` and up to 8 ``getAABB`` a step) go
    through compiled calls."""
    physics, _ = scene(n=10)
    try:
        drive(physics, 5)  # everything compiled and bound
        counts: dict[str, int] = {}
        for name in dir(pb):
            fn = getattr(pb, name)
            if callable(fn) and not name[0].isupper() and not name.startswith("_"):
                def counted(*a, _fn=fn, _name=name, **k):
                    counts[_name] = counts.get(_name, 0) + 1
                    return _fn(*a, **k)
                monkeypatch.setattr(pb, name, counted)
        physics.world.step(10)
        per_step = {k: v / 10 for k, v in counts.items()}
        # the cable's contact model meets the arms (issue 23): its broad phase (the grippers round the held ends,
        # whose end nodes are excluded: no closest-point query follows) is compiled; the body count stays
        assert per_step == {"stepSimulation": 1.0, "getContactPoints": 1.0, "getNumBodies": 1.0}, per_step
    finally:
        physics.close()


@needs_compiler
def test_reader_matches_pybullet_while_the_arm_moves():
    physics, _ = scene()
    try:
        drive(physics, 30)
        reader = physics.reader
        assert reader.handle
        reader.read()
        for b, body in enumerate(reader.bodies.tolist()):
            ref = pb.getLinkStates(body, reader.links[b].tolist(), computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=physics.world.client)
            flat = np.array([[v for part in st for v in part] for st in ref])
            np.testing.assert_array_equal(reader.link_rows[b, :, :native.LINK_STATE_FIELDS], flat)
            js = pb.getJointState(body, int(reader.joints[b]), physicsClientId=physics.world.client)
            np.testing.assert_array_equal(reader.joint_rows[b, 2:8], js[2])
        assert np.abs(reader.link_rows[:, :, 21:27]).max() > 1e-3  # velocities, not a resting arm
    finally:
        physics.close()


@needs_compiler
def test_a_reader_that_disagrees_with_pybullet_falls_back_with_a_warning(monkeypatch):
    """A PyBullet whose structs differ from the layout assumed here is detected, not trusted."""
    physics, _ = scene()
    try:
        def wrong_layout(handle, bodies, links, joints, link_out, joint_out):
            link_out[...] = 1.0
            return 0
        monkeypatch.setattr(native, "read_states", wrong_layout)
        with pytest.warns(RuntimeWarning, match="native Bullet calls disabled"):
            reader = native.StateReader(physics.world.client, physics.world.native_handle(),
                                        physics.reader.bodies, physics.reader.links, physics.reader.joints)
        assert reader.handle == 0
        reader.read()  # through PyBullet's Python API now
        monkeypatch.undo()
        physics.reader.read()
        np.testing.assert_array_equal(reader.link_rows[..., :native.LINK_STATE_FIELDS],
                                      physics.reader.link_rows[..., :native.LINK_STATE_FIELDS])
    finally:
        physics.close()


def test_switched_off_or_closed_worlds_have_no_handle(monkeypatch):
    monkeypatch.setenv("BULLET_DLO_NATIVE", "0")
    assert native.connect(0) == 0
    monkeypatch.setenv("BULLET_DLO_NATIVE", "1")
    physics, _ = scene()
    world = physics.world
    physics.close()
    assert world.native_handle() == 0  # never a dangling handle after close


def drop_on_box(monkeypatch, enabled: bool) -> dict[str, np.ndarray]:
    """A cable falls across a light dynamic box on the ground (its pose and velocity read every step)."""
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.model import CableModel

    monkeypatch.setenv("BULLET_DLO_NATIVE", "1" if enabled else "0")
    world = BulletWorld(dt=1 / 240)
    try:
        box = world.add_box([0.05, 0.05, 0.02], [0.0, 0.0, 0.02], mass=0.2)
        spec = CableSpec.lv2017(n_masses=12)
        model = CableModel.straight(spec, ends=("free", "free"), start=(-0.25, 0.01, 0.08), direction=(1, 0, 0))
        cable = world.add_cable(model, integrator="implicit_euler")
        assert bool(world.native_handle()) == enabled
        assert (cable._contact_set._read_bases is not None) == enabled
        world.step(150)
        assert cable.contacts_last_step > 0  # it lies on the box
        box_pos, box_orn = pb.getBasePositionAndOrientation(box, physicsClientId=world.client)
        return {"x": cable.x.copy(), "box": np.array([*box_pos, *box_orn])}
    finally:
        world.close()


@needs_compiler
def test_native_obstacle_reads_give_identical_contact_runs(monkeypatch):
    """The contact model's obstacle poses and velocities read natively are PyBullet's, bit for bit."""
    a, b = drop_on_box(monkeypatch, True), drop_on_box(monkeypatch, False)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


@needs_compiler
def test_the_native_broad_phase_finds_what_pybullets_finds():
    """The contact model's probe of the arms' links (``ContactSet._probe``) with the compiled broad phase and with
    PyBullet's (``getOverlappingObjects``, ``getAABB``) gives the same answers bit for bit: a short cable laid
    through each probed link's box in turn (a random line through a random point of it)."""
    physics, _ = scene(n=8)
    try:
        drive(physics, 3)
        cs, cid = physics.cable._contact_set, physics.world.client
        assert cs._broad_args is not None
        found = 0
        for _, x in lines_through_links(cid, cs.rows, sorted(cs._probe_rows.values()), physics.cable.model.n, 0):
            answers = []
            for broad in (cs._broad_args, None):
                saved, cs._broad_args = cs._broad_args, broad
                cs._probe(x, np.zeros_like(x), physics.world.dt, physics.world.dt)
                cs._broad_args = saved
                pr, k = cs.probes, int(cs.probes.count[0])
                answers.append([pr.shape[:k].copy(), pr.node[:k].copy(), pr.weight[:k].copy(), pr.point[:k].copy(),
                                pr.normal[:k].copy(), pr.key[:k].copy(), cs.hulls.near.copy()])
            for a, b in zip(*answers):
                np.testing.assert_array_equal(a, b)
            found += len(answers[0][0]) + int(answers[0][6].sum())  # probe answers, hulls near
        assert found > 5  # the links answered
    finally:
        physics.close()
