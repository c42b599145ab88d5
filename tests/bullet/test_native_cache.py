"""The native-call kernels (bullet.native, the contact model's broad phase) load from Numba's cache in a new
process: they call Bullet's C API through addresses passed in (``native.kernel_api``), not through ctypes
objects whose addresses Numba would compile in. Before, every process compiled the six again (about 2.4 s
of CPU each: every demo, CLI run and capture worker paid it)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bullet_dlo.bullet import native

SCRIPT = r"""
import json
import numpy as np
from bullet_dlo.bullet import contact, native
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.spec import CableSpec
from bullet_dlo.robots.dual_arm import DualArmPhysics, DualArmSpec

physics = DualArmPhysics(DualArmSpec(robot="panda", cable=CableSpec.lv2017(n_masses=8, damping=0.02)))
physics.clamp(0)
physics.clamp(1)
physics.world.step(5)  # arms' links probed (overlapping, _probe_broad), wrist reads and wrenches
physics.close()
world = BulletWorld(dt=1 / 240)
world.add_box([0.05, 0.05, 0.02], [0.0, 0.0, 0.02], mass=0.2)  # a dynamic body: its base state read natively
model = CableModel.straight(CableSpec.lv2017(n_masses=8), ends=("free", "free"), start=(-0.2, 0.01, 0.08),
                            direction=(1, 0, 0))
world.add_cable(model, integrator="implicit_euler", bullet_spheres="live")  # forces applied natively
world.step(5)
world.close()
kernels = {f.__name__: f for f in (native.apply_forces, native.apply_wrenches, native.read_states,
                                   native.read_base_states, contact._probe_broad)}  # (overlapping: in _probe_broad)
print(json.dumps({name: [len(f.signatures), sum(f.stats.cache_misses.values()), sum(f.stats.cache_hits.values())]
                  for name, f in kernels.items()}))
"""


@pytest.mark.skipif(native.plugin_library() is None, reason="no C compiler: the handle plugin cannot be built here")
@pytest.mark.skipif(not native.enabled(), reason="native calls off (BULLET_DLO_NATIVE=0 or NUMBA_DISABLE_JIT=1)")
def test_native_kernels_load_from_the_cache_in_a_new_process():
    runs = []
    for _ in range(2):  # the first may compile (a cold cache); the second must load every kernel
        out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    for name, (signatures, misses, hits) in runs[1].items():
        assert signatures == 1, (name, runs)  # used, with one argument type
        assert misses == 0 and hits == 1, (name, runs)  # loaded, not compiled
