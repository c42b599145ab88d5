"""Skipping the contact detection when it provably finds nothing (``ContactSet.update``, ``contact.quiet``) changes
no bit: a cable falling through the air onto a box and the ground (the detection skipped while it falls, run while
it lands and lies) ends in the same state, bit for bit, with the skip on and off; also with dynamic boxes in the
world, one far from the cable and one it lands on (the detection skipped while neither can be in reach)."""
from __future__ import annotations

import numpy as np
import pybullet as pb
import pytest

from bullet_dlo.bullet import contact
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec


def drop(skip: bool, dynamic: bool = False) -> tuple[np.ndarray, bool]:
    """The state (positions and velocities, flat) after 0.3 s of a 12-mass cable dropped from 6 cm across a box, and whether the detection was
    skipped through the first 5 steps of the fall; ``dynamic``: with a 30 g box lying on the ground 30 cm from the
    cable and a 2 x 2 x 1 cm box of 5 g under it (the poses of both are returned with the cable's state)."""
    contact.SKIP_QUIET = skip
    try:
        with BulletWorld(dt=1.0 / 240.0) as world:
            world.add_box((0.04, 0.1, 0.01), (0.2, 0.0, 0.01))
            boxes = ([world.add_box((0.02, 0.02, 0.01), (0.1, 0.3, 0.01), mass=0.03),
                      world.add_box((0.01, 0.01, 0.005), (0.05, 0.0, 0.005), mass=0.005)] if dynamic else [])
            cable = world.add_cable(CableSpec.lv2017(n_masses=12), start=(0.0, 0.0, 0.06))
            world.step(5)
            skipped = cable.contact.set._detect is None  # (bound on its first call)
            world.step(67)
            assert cable.stable, cable.reason
            assert cable.contacts_last_step > 0  # it lies on the box and the ground
            if dynamic:
                assert boxes[1] in cable.body_forces()  # and on the small box
            poses = [np.concatenate(pb.getBasePositionAndOrientation(b, physicsClientId=world.client))
                     for b in boxes]
            return np.concatenate([cable.x.ravel(), cable.v.ravel(), *poses]), skipped
    finally:
        contact.SKIP_QUIET = True


@pytest.mark.parametrize("dynamic", [False, True], ids=["static", "dynamic-boxes"])
def test_skipping_a_quiet_detection_changes_no_bit(dynamic):
    """The detection is skipped while the cable falls, and the end state is the same to the bit (with dynamic boxes
    this fails on 98d892c, which never skipped it while the world held a dynamic body)."""
    on, skipped = drop(True, dynamic)
    off, detected = drop(False, dynamic)
    assert skipped and not detected
    assert np.array_equal(on, off)
