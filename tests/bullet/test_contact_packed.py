"""The contact set's kernels on packed arrays (``bullet/contact_call.py``: ``quiet_with``, ``detect_with``,
``probe_broad_with``) give the bits of the plain calls: a cable dropped across a box onto the ground (the detection
skipped while it falls, run while it lands and lies) with ``contact.PACK_ARGS`` on and off, and the probe of the
arms' links (the broad phase) packed and plain on the same contact set."""
from __future__ import annotations

import numpy as np
import pytest
from probes import lines_through_links

from bullet_dlo.bullet import contact
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmPhysics, DualArmSpec


def with_packing(packed: bool, run):
    contact.PACK_ARGS = packed
    try:
        return run()
    finally:
        contact.PACK_ARGS = True


def drop() -> tuple:
    """0.3 s of a 12-mass cable dropped from 6 cm across a box: final state, contact count, whether it was packed."""
    with BulletWorld(dt=1.0 / 240.0) as world:
        world.add_box((0.04, 0.1, 0.01), (0.2, 0.0, 0.01))
        cable = world.add_cable(CableSpec.lv2017(n_masses=12), start=(0.0, 0.0, 0.06))
        world.step(72)
        assert cable.stable, cable.reason
        cs = cable.contact.set
        return cable.x.copy(), cable.v.copy(), cable.contacts_last_step, cs._set_args is not None


def probe_answers(cs, x: np.ndarray, dt: float, packed: bool) -> list[np.ndarray]:
    """``cs._probe`` of positions x with the broad phase packed or plain: the probes it found."""
    contact.PACK_ARGS = packed
    saved, cs._broad = cs._broad, None  # bound anew to the packed or the plain kernel
    try:
        cs._probe(x, np.zeros_like(x), dt, dt)
    finally:
        contact.PACK_ARGS = True
        cs._broad = saved
    pr, k = cs.probes, int(cs.probes.count[0])
    return [pr.shape[:k].copy(), pr.node[:k].copy(), pr.weight[:k].copy(), pr.point[:k].copy(), pr.normal[:k].copy(),
            pr.key[:k].copy(), cs.hulls.near.copy()]


def test_the_packed_broad_phase_finds_what_the_plain_one_finds():
    """A short cable laid through each of the arms' probed links' boxes in turn (a random line through a random
    point of it): the same probes, bit for bit."""
    physics = DualArmPhysics(DualArmSpec(robot="panda", cable=CableSpec.lv2017(n_masses=8, damping=0.02)))
    try:
        physics.world.step(3)
        cs, cid, dt = physics.cable.contact.set, physics.world.client, physics.world.dt
        if cs._broad_args is None:
            pytest.skip("native reads off here: no compiled broad phase to pack")
        found = 0
        for _, x in lines_through_links(cid, cs.rows, sorted(cs._probe_rows.values()), physics.cable.model.n, 1):
            packed, plain = probe_answers(cs, x, dt, True), probe_answers(cs, x, dt, False)
            for a, b in zip(packed, plain):
                np.testing.assert_array_equal(a, b)
            found += len(packed[0]) + int(packed[6].sum())  # probe answers, hulls near
        assert found > 5 and cs._broad_pack is not None  # the links answered, through the packed kernel
    finally:
        physics.close()


def test_packed_detection_changes_no_bit():
    x_on, v_on, k_on, packed = with_packing(True, drop)
    x_off, v_off, k_off, plain_packed = with_packing(False, drop)
    assert packed and not plain_packed
    assert k_on == k_off and k_on > 0  # the packed kernels ran where contacts (or probed links) were found
    assert np.array_equal(x_on, x_off) and np.array_equal(v_on, v_off)
