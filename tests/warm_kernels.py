"""Compile the suite's shared Numba kernels into the cache before the test processes start.

On a clean checkout every process that meets a cold kernel compiles it: pytest-xdist's workers, the
core suite's PyBullet-free runner and the demos' subprocesses start together and compiled the same
kernels several times over (minutes each). ``tests/conftest.py`` runs this module once per part,
the parts in parallel, before the workers start; each part is a few short runs that reach the
kernels the suite uses (the runs' results are not checked here: the tests check them).

A kernel two parts reach at once is compiled by one of them while the other waits for it (``bullet_dlo/_numba_cache.py``
locks each kernel's compile between processes), so the parts can share kernels. Three parts: ``core``, ``bullet``
(the dual-arm environment: IK, sensors, hulls, detection) and ``step`` (the coupled Bullet step, about 200 s of CPU
cold, then the twist's and the free bodies' kernels and the plain steps), which starts on the step at once instead of
after the environment's 170 s; the environment then loads it. Cold, beside the core suite's runner (2026-12-07,
2-core AMD EPYC): the environment and the step in one part took 393 s of wall, the critical path of the warm-up.

A kernel called with an argument of another type (a writable array where models pass read-only ones) is
compiled again with everything below it: two core tests that replaced a model array by a writable one compiled
the coupled twist step's Newton matrix and residual anew (44 and 26 s of CPU, 2026-11-29). They pass read-only
arrays now, and the core part of the warm-up no longer runs them: cold, 291 s of CPU for the core part with them
taking 14 s, against 347 s with 81 s before (2026-11-30, ``NUMBA_CACHE_DIR`` empty, ``/usr/bin/time``).

Usage: ``python tests/warm_kernels.py core|bullet|step``.
"""
from __future__ import annotations

import sys


def core() -> None:
    """The core engine's loop with every integrator, with and without a material frame."""
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


def bullet() -> None:
    """A dual-arm environment (arms, grasps, sensors, IK, model contact with the arms' links)."""
    import gymnasium as gym

    import bullet_dlo  # noqa: F401  (registers the environments)

    env = gym.make("bullet_dlo/TensionTracking-v0")
    env.reset(seed=0)
    for _ in range(2):
        env.step(env.action_space.sample())
    env.close()


def step() -> None:
    """The coupled Bullet step (one argument type for every cable) on a cable falling in a world without ground
    (nothing to detect), then a twisting cable under a light box, then a cable's plain steps."""
    from bullet_dlo.bullet.world import BulletWorld
    from bullet_dlo.core.spec import CableSpec

    with BulletWorld(dt=1e-3, ground=False) as world:
        world.add_cable(CableSpec.lv2017(n_masses=6), start=(0.0, 0.0, 1.0))
        world.step(2)
    # a twisting cable lying on the ground of a bare Bullet world with a light box dropped on it: the kernels the
    # environment does not reach (the twist's and the free bodies')
    spec = CableSpec.lv2017(n_masses=6, twist=True)
    with BulletWorld(dt=1e-3) as world:
        world.add_cable(spec, start=(0.0, 0.0, 0.5 * spec.diameter))
        world.add_box((0.01, 0.01, 0.01), (0.05, 0.0, spec.diameter + 0.0102), mass=0.01)
        world.step(5)
    # plain steps (bullet/plain_steps.py: every run of at least PLAIN_FROM steps takes them, so many tests do): a cable
    # falling 1 mm onto the ground, plain from its second step
    from bullet_dlo.bullet import plain_steps

    plain_steps.PLAIN_FROM = 0
    falling = CableSpec.lv2017(n_masses=6)
    with BulletWorld(dt=1e-3) as world:
        world.add_cable(falling, start=(0.0, 0.0, 0.5 * falling.diameter + 1e-3))
        world.step(100)


if __name__ == "__main__":
    {"core": core, "bullet": bullet, "step": step}[sys.argv[1]]()
