"""A built scene, ready to step and run: one class per engine, one interface.

:func:`bullet_dlo.sim.build` makes them from a :class:`~bullet_dlo.config.scene.Scene`; nothing
else assembles a runtime. All three share ``scene``, ``run(duration)`` (returning a
:class:`~bullet_dlo.core.engine.SimulationResult` for the cable), ``close()`` and the context
manager; the two Bullet ones also ``step(n)`` and take ``after_step`` hooks (recorders, user
extensions). The coupled step itself is written once, in
:meth:`bullet_dlo.bullet.world.BulletWorld.step` (its phases), with the dual-arm grasp's phases in
:mod:`bullet_dlo.robots.dual_arm.physics`.

* :class:`CoreSimulation`: the cable alone in the PyBullet-free core engine (one compiled loop).
* :class:`BulletSimulation`: the cable as Bullet spheres in a world with ground and obstacles.
* :class:`ArmsSimulation`: two arms hold the cable's ends (grasped, following the scene's motion),
  wrist sensors, table and obstacles: :class:`~bullet_dlo.robots.dual_arm.DualArmScene`.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable

import numpy as np

from bullet_dlo.bullet.cable import BulletCable
from bullet_dlo.bullet.world import BulletWorld
from bullet_dlo.config.scene import Scene
from bullet_dlo.core.engine import (
    NEWTON_WARN_SHARE,
    STRAIN_REASON,
    DetectorOptions,
    SimulationResult,
    confirm_strain,
    held_move_warnings,
    simulate,
)
from bullet_dlo.core.model import CableModel
from bullet_dlo.robots.dual_arm import DualArmScene

Hook = Callable[[], None]


def cable_result(cable: BulletCable, dt: float, wall: float, t: np.ndarray, x: np.ndarray, v: np.ndarray,
                 end_forces: np.ndarray, energy: np.ndarray) -> SimulationResult:
    """A Bullet cable's run as a SimulationResult: its status, counters, final state and end moments, with
    the recorded rows given (t [s] (k,), x [m] and v [m/s] (k, n, 3), end_forces [N] (k, 2, 3), energy [J] (k,));
    ``dt`` [s] the Bullet step, ``wall`` [s] the run's wall time."""
    result = SimulationResult(
        integrator=cable.method.name, dt=dt, stable=cable.stable, time_to_instability=cable.time_to_instability,
        reason=cable.reason, steps=cable.steps, wall_time_s=wall, t=t, x=x, v=v, end_forces=end_forces,
        energy=energy, final_state=cable.state(), end_moments=cable.end_moments(),
        newton_failures=cable.newton_failures, newton_iterations=cable.newton_iterations)
    solver = cable.solver  # as the core engine: say when Newton failed in many steps, and why a run stopped
    if solver.stop_report is not None:
        result.warnings.append(solver.stop_report)
    elif solver.newton_failures > NEWTON_WARN_SHARE * max(solver.steps_planned, 1):
        result.warnings.append(solver.failure_message())
    return result


class Simulation:
    """What every built scene offers (see the module doc)."""

    engine = ""

    def __init__(self, scene: Scene):
        self.scene = scene

    def run(self, duration: float | None = None) -> SimulationResult:
        """Run for ``duration`` [s] (default: the scene's); the cable's result."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the engine's resources (a PyBullet client)."""

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class CoreSimulation(Simulation):
    """The cable alone in the core engine: ``model`` (end conditions and motion from the scene)."""

    engine = "core"

    def __init__(self, scene: Scene, model: CableModel):
        super().__init__(scene)
        self.model = model

    def run(self, duration: float | None = None, *, max_records: int = 2001) -> SimulationResult:
        """One compiled run (a run stopped by the default strain bound is re-run without it, see
        :func:`~bullet_dlo.core.engine.simulate`)."""
        scene = self.scene
        return simulate(self.model, scene.integrator, scene.dt, scene.duration if duration is None else duration,
                        state=scene.initial_state(self.model), newton=scene.newton, detector=scene.detector,
                        max_records=max_records)


class BulletSimulation(Simulation):
    """The cable as Bullet spheres in ``world`` (ground, obstacles): ``cable``, built from ``model``.

    ``rebuild(detector)`` makes the same simulation anew with other detector settings: the strain
    re-run of :meth:`run` needs a fresh world.
    """

    engine = "bullet"

    def __init__(self, scene: Scene, model: CableModel, world: BulletWorld, cable: BulletCable,
                 rebuild: Callable[[DetectorOptions], "BulletSimulation"]):
        super().__init__(scene)
        self.model, self.world, self.cable = model, world, cable
        self._rebuild = rebuild

    @property
    def after_step(self) -> list[Hook]:
        """Hooks called at the end of every step (recorders, user extensions)."""
        return self.world.after_step

    def step(self, n: int = 1) -> None:
        """``n`` steps of the world (phases: :meth:`~bullet_dlo.bullet.world.BulletWorld.step`)."""
        self.world.step(n)

    def run(self, duration: float | None = None, progress: Callable[[int], Any] | None = None) -> SimulationResult:
        """Step until ``duration`` [s] or instability (``progress(k)``: told of every hundred or so steps taken). As
        with the core engine, a run stopped by the default strain bound (50 %) is re-run without it in a fresh world:
        if the re-run stays finite with no energy growth it is the result, stable, with a warning that the stretch is
        physical; otherwise the first run stands, its cause confirmed."""
        duration = self.scene.duration if duration is None else duration
        first = self._run_here(duration, progress)
        first.warnings.extend(held_move_warnings(self.model, self.scene.dt, duration))
        if first.reason != STRAIN_REASON or self.scene.detector.max_strain is not None:
            return first

        def rerun(bound: float) -> SimulationResult:
            with self._rebuild(replace(self.scene.detector, max_strain=bound)) as again:
                return again._run_here(duration)

        return confirm_strain(self.model, first, rerun)

    def _run_here(self, duration: float, progress: Callable[[int], Any] | None = None) -> SimulationResult:
        cable = self.cable
        wall = self.world.run_while_stable(self.world.steps_in(duration), cable, progress)
        rec = cable.record.arrays()
        return cable_result(cable, self.scene.dt, wall, rec["t"], rec["x"], rec["v"], rec["end_forces"],
                            rec["energy"])

    def close(self) -> None:
        self.world.close()


class ArmsSimulation(Simulation):
    """Two arms hold the cable: ``arms`` (:class:`~bullet_dlo.robots.dual_arm.DualArmScene`: ``physics``,
    ``task``, ``observation``), built grasped and following the scene's motion."""

    engine = "arms"

    def __init__(self, scene: Scene, arms: DualArmScene):
        super().__init__(scene)
        self.arms = arms

    @property
    def world(self) -> BulletWorld:
        return self.arms.world

    @property
    def cable(self) -> BulletCable:
        return self.arms.cable

    @property
    def physics(self):
        return self.arms.physics

    @property
    def observation(self):
        return self.arms.observation

    @property
    def after_step(self) -> list[Hook]:
        """Hooks called at the end of every step (recorders, user extensions)."""
        return self.world.after_step

    def step(self, n: int = 1) -> None:
        """``n`` coupled steps (phases: :meth:`~bullet_dlo.bullet.world.BulletWorld.step` and
        :mod:`bullet_dlo.robots.dual_arm.physics`)."""
        self.world.step(n)

    def run(self, duration: float | None = None) -> SimulationResult:
        """Step until ``duration`` [s] or instability; the cable's result (its end forces and moments are the
        model's loads on the grippers; the wrist sensors' record is ``observation.record``)."""
        cable = self.cable
        wall = self.arms.run(self.scene.duration if duration is None else duration)
        return cable_result(cable, self.scene.dt, wall, np.array([self.world.time]), cable.x[None].copy(),
                            cable.v[None].copy(), cable.end_forces()[None], np.full(1, np.nan))

    def close(self) -> None:
        self.arms.close()
