"""The dual-arm scene as one object: physics, the grasp-study task and the observation, composed.

:class:`DualArmScene` is what scripts, the CLI, rendering and the README use; it holds no
logic of its own. Code that needs a different episode (an environment, a dataset capture)
composes :class:`~.physics.DualArmPhysics` and :class:`~.observation.DualArmObservation`
with a task of its own instead (see :mod:`bullet_dlo.robots.dual_arm`).
"""
from __future__ import annotations

import math
import warnings
from typing import Sequence

import numpy as np

from bullet_dlo.analysis.resolve import ROLL_TOL, end_roll
from bullet_dlo.config.robot import DualArmSpec
from bullet_dlo.core.boundary import EndHolder
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
        waypoints or sines as a pose the gripper follows (:meth:`DualArmTask.follow`).

        A motion that rolls a gripper about the cable's axis while the cable has no material frame warns
        (:func:`roll_warning`): the wrists would read no torsion. Scene files and :func:`bullet_dlo.sim.build`
        switch the frame on by need instead; this object's cable is built already."""
        why = roll_warning(self.cable.model.spec.twist_enabled, self.cable.x, items)
        if why:
            warnings.warn(why, UserWarning, stacklevel=2)
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


def roll_warning(twisting: bool, x: np.ndarray, items: Sequence, samples: int = 401) -> str:
    """Why a gripper motion needs a material frame the cable lacks, or "": the largest roll [rad] of each end's
    motion ``items`` about the cable's axis (its end-to-end direction of the node positions ``x`` [m], (n, 3))
    until the last item ends (an item that runs forever: 2 s after its start)
    (:func:`~bullet_dlo.analysis.resolve.end_roll`) beyond :data:`~bullet_dlo.analysis.resolve.ROLL_TOL`,
    when ``twisting`` is False."""
    if twisting or not items:
        return ""
    axis = x[-1] - x[0]
    axis = axis / np.linalg.norm(axis)
    def end_of(m) -> float:
        duration = getattr(m, "duration", None)
        duration = 2.0 if duration is None or not math.isfinite(duration) else float(duration)
        return float(getattr(m, "start", 0.0) or 0.0) + duration

    horizon = max(end_of(m) for m in items)
    times = np.linspace(0.0, horizon, samples)
    rolls = []
    for end, arm, node in (("first", "left", 0), ("last", "right", -1)):
        moves = tuple(m for m in items if m.end == end)
        if not moves:
            continue
        roll = float(np.abs(np.unwrap(end_roll(EndHolder("clamped", x[node], axis, moves), times))).max())
        if roll > ROLL_TOL:
            rolls.append(f"the {arm} gripper {np.degrees(roll):.3g} deg")
    if not rolls:
        return ""
    return ("the motion rolls " + " and ".join(rolls) + " about the cable axis, but the cable has no material frame: "
            "the wrists read no torsion; give the cable twist=True (scene files and bullet_dlo.sim.build do so by need)")
