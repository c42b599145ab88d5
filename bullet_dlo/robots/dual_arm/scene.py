"""The dual-arm scene as one object: physics, the grasp-study task and the observation, composed.

:class:`DualArmScene` is what scripts, the CLI, rendering and the README use; it holds no
logic of its own. Code that needs a different episode (an environment, a dataset capture)
composes :class:`~.physics.DualArmPhysics` and :class:`~.observation.DualArmObservation`
with a task of its own instead (see :mod:`bullet_dlo.robots.dual_arm`).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.robots.dual_arm.observation import DualArmObservation
from bullet_dlo.robots.dual_arm.physics import DualArmPhysics
from bullet_dlo.robots.dual_arm.task import DualArmTask


class DualArmScene:
    """Two arms holding a cable across a table, built from ``spec``; use as a context manager.
    ``record``: keep the observation's per-step record (sensors beside the model).

    Parts: ``physics`` (world, arms, cable, grasp coupling), ``task`` (grasp, release, moves),
    ``observation`` (wrist sensors, per-step record). Shortcuts: ``world``, ``robots``,
    ``cable``, ``sensors``, ``record``.
    """

    def __init__(self, spec: DualArmSpec = DualArmSpec(), record: bool = True):
        self.physics = DualArmPhysics(spec)
        try:
            self.observation = DualArmObservation(self.physics, record=record)
            self.task = DualArmTask(self.physics)
        except Exception:
            self.physics.close()
            raise

    # ----- the parts' objects, by their usual names -------------------------------------------------
    @property
    def spec(self) -> DualArmSpec:
        return self.physics.spec

    config = spec  # the name before DualArmConfig became DualArmSpec

    @property
    def world(self):
        return self.physics.world

    @property
    def robots(self):
        return self.physics.robots

    @property
    def cable(self):
        return self.physics.cable

    @property
    def sensors(self):
        return self.observation.sensors

    @property
    def record(self):
        return self.observation.record

    # ----- the episode ------------------------------------------------------------------------------
    def grasp(self, arm: int | str | None = None) -> None:
        """Clamp the cable end(s) to the gripper(s) (both when ``arm`` is None); see :meth:`DualArmTask.grasp`."""
        self.task.grasp(arm)

    def release(self, arm: int | str | None = None) -> None:
        """Open the gripper(s): the cable end falls free."""
        self.task.release(arm)

    def move(self, arm: int | str, displacement: Sequence[float], duration: float, start: float | None = None) -> None:
        """Schedule a straight-line gripper move [m] over ``duration`` [s]; see :meth:`DualArmTask.move`."""
        self.task.move(arm, displacement, duration, start)

    def follow_motion(self, items: Sequence) -> None:
        """Schedule a scene's motion items for the grippers (the first cable end is the left gripper's):
        a plain straight-line Move as a gripper move (:meth:`move`), anything with rotations,
        waypoints or sines as a pose the gripper follows (:meth:`DualArmTask.follow`)."""
        for m in items:
            if type(m).__name__ == "Move" and not any(m.rotation):
                self.move("left" if m.end == "first" else "right", m.displacement, m.duration, start=m.start)
            else:
                self.task.follow(m)

    def run(self, duration: float) -> float:
        """Step for ``duration`` [s] (stopping early if the cable goes unstable); returns the wall time [s]."""
        return self.physics.run(duration)

    def run_timed(self, duration: float) -> tuple[float, float]:
        """:meth:`run` with the first step (kernel loading or compiling) timed apart: (first step, rest) [s]."""
        return self.physics.run_timed(duration)

    def window_mean(self, seconds: float = 0.5) -> dict[str, np.ndarray]:
        """Averages over the last ``seconds`` [s]: sensor wrench in world (2, 6), model end forces (2, 3)."""
        return self.observation.window_mean(seconds)

    def close(self) -> None:
        self.physics.close()

    def __enter__(self) -> "DualArmScene":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
