"""The coupled step's kernel called on packed arguments (``bullet/solver_call.py``: one StructRef for the ten
objects that are the same every step) takes the same steps, bit for bit, as the plain call, also when the contact
set is rebuilt between steps (a box added under the falling cable: new contact arrays that must be packed anew)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.bullet import solver
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.spec import CableSpec

pytestmark = pytest.mark.bullet


def drop(packed: bool) -> tuple[np.ndarray, np.ndarray]:
    """The state after 0.3 s of a 12-mass cable dropped from 6 cm across a box, a second box added after 10 steps."""
    solver.PACK_ARGS = packed
    try:
        with BulletWorld(dt=1.0 / 240.0) as world:
            world.add_box((0.04, 0.1, 0.01), (0.2, 0.0, 0.01))
            cable = world.add_cable(CableSpec.lv2017(n_masses=12), start=(0.0, 0.0, 0.06))
            world.step(10)
            first = cable.contacts
            world.add_box((0.03, 0.1, 0.015), (0.35, 0.0, 0.015))
            world.step(62)
            assert cable.contacts is not first  # the set was rebuilt with the new box
            assert cable.stable, cable.reason
            assert cable.contacts_last_step > 0
            if packed:
                assert cable.solver._packed[7] is cable.contacts  # what the kernel sees is the live set
            return cable.x.copy(), cable.v.copy()
    finally:
        solver.PACK_ARGS = True


def test_the_packed_call_takes_the_plain_calls_steps():
    x_packed, v_packed = drop(True)
    x_plain, v_plain = drop(False)
    assert np.array_equal(x_packed, x_plain) and np.array_equal(v_packed, v_plain)
