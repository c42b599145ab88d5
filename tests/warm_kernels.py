"""Compile the suite's shared Numba kernels into the cache before the test processes start.

On a clean checkout every process that meets a cold kernel compiles it: pytest-xdist's workers, the
core suite's PyBullet-free runner and the demos' subprocesses start together and compiled the same
kernels several times over (minutes each). ``tests/conftest.py`` runs this module once per part,
the parts in parallel, before the workers start; each part is a few short runs that reach the
kernels the suite uses (the runs' results are not checked here: the tests check them).

Usage: ``python tests/warm_kernels.py core|bullet``.
"""
from __future__ import annotations

import sys


def core() -> None:
    """The core engine's loop with every integrator, with and without a material frame, then a twisting cable
    lying on the ground of a bare Bullet world under a box."""
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
    # a twisting cable lying on the ground of a bare Bullet world with a light box dropped on it: the kernels the
    # dual-arm environment of the other part does not reach (the twist's and the free bodies'); the coupled step
    # itself (one argument type for every cable) the other part has mostly compiled by the time this part gets here
    from bullet_dlo.bullet.world import BulletWorld

    world = BulletWorld(dt=1e-3)
    spec = CableSpec.lv2017(n_masses=6, twist=True)
    world.add_cable(spec, start=(0.0, 0.0, 0.5 * spec.diameter))
    world.add_box((0.01, 0.01, 0.01), (0.05, 0.0, spec.diameter + 0.0102), mass=0.01)
    world.step(5)


def bullet() -> None:
    """A dual-arm environment (arms, grasps, sensors, IK, model contact with the arms' links)."""
    import gymnasium as gym

    import bullet_dlo  # noqa: F401  (registers the environments)

    env = gym.make("bullet_dlo/TensionTracking-v0")
    env.reset(seed=0)
    for _ in range(2):
        env.step(env.action_space.sample())
    env.close()


if __name__ == "__main__":
    {"core": core, "bullet": bullet}[sys.argv[1]]()
