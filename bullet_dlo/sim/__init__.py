"""One typed scene, one builder, one step: the runtime every entry point uses.

A :class:`~bullet_dlo.config.scene.Scene` (a YAML scene file, or built in Python) becomes a
:class:`Simulation` through :func:`build`, for any engine: the cable alone in the core engine,
the cable in a Bullet world, or two arms holding it. ``simulate``, ``grasp``, ``render``,
dataset captures and the Gymnasium environments all build their runtime here, so one scene
file means the same physics through every door; a key an engine cannot honour is refused by
name. The coupled step's phases are written once, in
:meth:`bullet_dlo.bullet.world.BulletWorld.step`::

    from bullet_dlo.sim import Scene, build

    scene = Scene.from_yaml("demos/scenes/lv_study.yaml")
    with build(scene, "core") as sim:
        result = sim.run()
    print(result.end_forces[-1])   # force of the cable on each held end [N], (2, 3)
"""
from bullet_dlo.config.scene import Scene
from bullet_dlo.sim.builder import ENGINES, build, build_arms, engine_for, resolve_problem, resolved
from bullet_dlo.sim.simulation import ArmsSimulation, BulletSimulation, CoreSimulation, Simulation

__all__ = ["ENGINES", "ArmsSimulation", "BulletSimulation", "CoreSimulation", "Scene", "Simulation", "build",
           "build_arms", "engine_for", "resolve_problem", "resolved"]
