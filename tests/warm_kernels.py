"""Compile the suite's shared Numba kernels into the cache before the test processes start.

On a clean checkout every process that meets a cold kernel compiles it: pytest-xdist's workers, the
core suite's PyBullet-free runner and the demos' subprocesses start together and compiled the same
kernels several times over (minutes each). ``tests/conftest.py`` runs this module once per part,
the parts in parallel, before the workers start; each part is a few short runs that reach the
kernels the suite uses (the runs' results are not checked here: the tests check them).

Numba has no lock between processes: a kernel both parts reach before either has cached it is compiled
twice. The coupled Bullet step (``sync_and_advance`` and the chain below it, one argument type for every
cable, about 150 s of CPU cold) is therefore reached in the Bullet part only; the core part instead compiles
what the PyBullet-free core runner would otherwise compile alone during the tests (measured with a
``numba:compile`` listener per test on a cold run: about 100 s, 70 of them in two tests). Measured cold,
CPU per part (2026-11-29, compile listener): before, core 250 s and Bullet 253 s with 103 s compiled in both;
with four such tests here, core 286 s and Bullet 271 s with 22 s in both; the two largest are kept, so that
the core part does not outlast the Bullet part, and the core runner compiles about 70 s less.

Usage: ``python tests/warm_kernels.py core|bullet``.
"""
from __future__ import annotations

import sys
from pathlib import Path

# core tests whose kernels take argument types of their own (test file::test name, under tests/core): the two
# largest cold compiles of the core runner (44 and 26 s of CPU, 2026-11-29); the next ones (test_damping's, 23 s)
# would make this part longer than the Bullet part
DIRECT_KERNEL_TESTS = (
    "test_twist_exact_jacobian.py::test_newton_matrix_is_the_residuals_jacobian",
    "test_rest_shape.py::test_forces_are_minus_the_energy_gradient_and_jacobian_their_derivative",
)


def core() -> None:
    """The core engine's loop with every integrator, with and without a material frame, then the core tests that
    call kernels directly (``DIRECT_KERNEL_TESTS``)."""
    from bullet_dlo.core.boundary import Move
    from bullet_dlo.core.engine import simulate
    from bullet_dlo.core.model import CableModel
    from bullet_dlo.core.spec import CableSpec

    moves = [Move("last", (0.0, 0.0, 0.005), 0.0, 0.01)]
    for twist in (False, True):
        model = CableModel.straight(CableSpec.lv2017(n_masses=6, twist=twist), ends=("clamped", "clamped"),
                                    motion=moves)
        for integrator in ("explicit_euler", "symplectic_euler", "rk4", "implicit_euler", "bdf2",
                           "implicit_midpoint", "gauss_legendre"):
            simulate(model, integrator, 1e-4, 2e-3, max_records=3)
    # core tests that call kernels from Python with argument types of their own: run here, the PyBullet-free core
    # runner (tests/test_layers.py) then finds them cached
    import pytest

    here = Path(__file__).parent / "core"
    pytest.main([str(here / test) for test in DIRECT_KERNEL_TESTS] + ["-q", "-p", "no:cacheprovider"])


def bullet() -> None:
    """A dual-arm environment (arms, grasps, sensors, IK, model contact with the arms' links), then a twisting
    cable under a light box."""
    import gymnasium as gym

    import bullet_dlo  # noqa: F401  (registers the environments)

    env = gym.make("bullet_dlo/TensionTracking-v0")
    env.reset(seed=0)
    for _ in range(2):
        env.step(env.action_space.sample())
    env.close()
    # a twisting cable lying on the ground of a bare Bullet world with a light box dropped on it: the kernels the
    # environment does not reach (the twist's and the free bodies'); the coupled step itself has one argument type
    # for every cable, compiled above in this process (the core part would compile it a second time, in parallel)
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec

    spec = CableSpec.lv2017(n_masses=6, twist=True)
    with BulletWorld(dt=1e-3) as world:
        world.add_cable(spec, start=(0.0, 0.0, 0.5 * spec.diameter))
        world.add_box((0.01, 0.01, 0.01), (0.05, 0.0, spec.diameter + 0.0102), mass=0.01)
        world.step(5)


if __name__ == "__main__":
    {"core": core, "bullet": bullet}[sys.argv[1]]()
