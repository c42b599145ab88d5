"""Every cable's coupled step has one Numba argument type, so its kernel chain compiles once.

:func:`~bullet_dlo.bullet.kernels.sync_and_advance` and the kernels it calls are compiled per argument type,
about 150 s of CPU on a cold cache (2026-11-29, cold warm-up profile). Before, a twisting cable (the stall
guard held only its non-empty twist arrays: a longer tuple) and a coupling whose gravity came in read-only
each made a new type: three compiles of that chain in the test suite, and a user's first twisting scene paid
another 2-3 minutes.
"""
from __future__ import annotations

import os

import numba
import numpy as np
import pytest

from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.kernels import steppers
from bullet_dlo.core.spec import CableSpec

pytestmark = pytest.mark.bullet


def step_type(cable) -> numba.types.Type:
    """The Numba type of the coupled step's arguments as the cable passes them."""
    inp = cable._step_input(True, False, cable._no_index, cable._no_rows, cable._no_rows)
    return numba.typeof(cable._kernel_args(inp))


def world_cable(gravity=(0.0, 0.0, -9.81), box: bool = False, **spec):
    world = BulletWorld(dt=1.0 / 240.0, gravity=gravity)
    s = CableSpec.lv2017(n_masses=6, **spec)
    cable = world.add_cable(s, start=(0.0, 0.0, 0.5 * s.diameter))
    if box:
        world.add_box((0.01, 0.01, 0.01), (0.05, 0.0, s.diameter + 0.0102), mass=0.01)
    world.step(2)
    return world, cable


def test_every_cable_passes_the_coupled_step_one_argument_type():
    frozen = np.array([0.0, 0.0, -9.81])
    frozen.flags.writeable = False  # as a model's gravity (bench scenarios pass that to the world)
    world, cable = world_cable()
    base = step_type(cable)
    world.close()
    for kind, kw in [("twisting", {"twist": True}), ("free box on it", {"box": True}),
                     ("read-only gravity", {"gravity": frozen})]:
        world, cable = world_cable(**kw)
        try:
            assert step_type(cable) == base, kind
        finally:
            world.close()


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT", "0") != "0", reason="NUMBA_DISABLE_JIT: nothing is compiled")
def test_the_contact_solve_compiles_once():
    """Newton's contact solve (Newton and the friction caps' fixed point, about 11 s of CPU cold each time) is
    compiled once: a count of free bodies started as a literal 0 and the solve's ``bounded`` flag passed as a
    literal False in one call and True in the other compiled it four times (2026-12-07, a ``numba:compile``
    listener on the Bullet part of tests/warm_kernels.py). Numba's cache index holds every signature compiled for
    the present sources, by any process."""
    world, _ = world_cable(box=True)  # lying on the ground with a free box on it: the solve with contacts and bodies
    world.close()
    signatures = [key[0] for key in steppers._contact_solve._cache._cache_file._load_index()]
    assert len(signatures) == 1, f"_contact_solve compiled {len(signatures)} times"
