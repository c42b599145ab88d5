"""The coupled step's kernel called on packed arguments (``bullet/solver_call.py``: one StructRef for the ten
objects that are the same every step) sees the live objects, also when the contact set is rebuilt between steps (a
box added under the falling cable: new contact arrays that must be packed anew).

The plain call (``solver.PACK_ARGS = False``) is kept for A/B timing (docs/results/speed.md); comparing the two bit
for bit here compiled the whole coupled step a second time (60 s of CPU in a cold CI run). A pack that kept the old
contact set would leave the added box out of the step: the cable would sink into it, which is what this checks.
"""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

pytestmark = pytest.mark.bullet


def test_the_packed_step_meets_a_box_added_after_the_contact_set_was_packed():
    """A 12-mass cable dropped from 6 cm across a box, a second box (3 cm high, x 0.04-0.10 m) added after 10 steps
    (the contact set is rebuilt): after 0.3 s the kernel's packed contacts are the live set, the cable lies on the
    second box (no node over it deeper than 0.1 radius below its top plus the radius) and that box carries part of
    the cable's weight."""
    spec = CableSpec.lv2017(n_masses=12)
    r = spec.diameter / 2
    with BulletWorld(dt=1.0 / 240.0) as world:
        world.add_box((0.04, 0.1, 0.01), (0.2, 0.0, 0.01))
        cable = world.add_cable(spec, start=(0.0, 0.0, 0.06))
        world.step(10)
        first = cable.contacts
        second = world.add_box((0.03, 0.1, 0.015), (0.07, 0.0, 0.015))
        world.step(62)
        assert cable.contacts is not first  # the set was rebuilt with the new box
        assert cable.solver._packed[7] is cable.contacts  # what the kernel sees is the live set
        assert cable.stable, cable.reason
        over = np.abs(cable.x[:, 0] - 0.07) < 0.03
        assert over.any()
        assert cable.x[over, 2].min() > 0.03 + 0.9 * r
        assert cable.body_forces()[second][2] < -0.05 * spec.mass * 9.81  # the cable pushes it down
