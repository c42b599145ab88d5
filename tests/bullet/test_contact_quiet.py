"""Skipping the contact detection when it provably finds nothing (``ContactSet.update``, ``contact.quiet``) changes
no bit: a cable falling through the air onto a box and the ground (the detection skipped while it falls, run while
it lands and lies) ends in the same state, bit for bit, with the skip on and off."""
from __future__ import annotations

import numpy as np

from bullet_dlo.bullet import contact
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec


def drop(skip: bool) -> tuple[np.ndarray, np.ndarray, bool]:
    """The state after 0.3 s of a 12-mass cable dropped from 6 cm across a box, and whether the detection was
    skipped through the first 10 steps of the fall."""
    contact.SKIP_QUIET = skip
    try:
        with BulletWorld(dt=1.0 / 240.0) as world:
            world.add_box((0.04, 0.1, 0.01), (0.2, 0.0, 0.01))
            cable = world.add_cable(CableSpec.lv2017(n_masses=12), start=(0.0, 0.0, 0.06))
            world.step(10)
            skipped = cable.contact.set._detect is None  # (bound on its first call)
            world.step(62)
            assert cable.stable, cable.reason
            assert cable.contacts_last_step > 0  # it lies on the box and the ground
            return cable.x.copy(), cable.v.copy(), skipped
    finally:
        contact.SKIP_QUIET = True


def test_skipping_a_quiet_detection_changes_no_bit():
    x_on, v_on, skipped = drop(True)
    x_off, v_off, detected = drop(False)
    assert skipped and not detected
    assert np.array_equal(x_on, x_off) and np.array_equal(v_on, v_off)
