"""What happens in a dual-arm episode of the grasp study: grasp, release, and Cartesian gripper moves.

A move translates one grasp frame along a straight line with a minimum-jerk profile (the
orientation is kept). Before every Bullet step during a move, the arm's joint targets are set
by one IK solve (:meth:`~bullet_dlo.robots.arm.Robot.track`) for the frame's target at the
end of that step; the arm's position control follows. Another task (e.g. an environment
whose actions are joint targets) replaces this one and keeps the physics and observation.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from bullet_dlo.core.boundary import min_jerk
from bullet_dlo.core.validate import check_positive, check_vector3
from bullet_dlo.robots.dual_arm.physics import DualArmPhysics, arm_index, arm_indices


@dataclass(frozen=True)
class CartesianMove:
    """A straight-line move of arm ``arm``'s grasp frame (index, 0 left, 1 right) by ``displacement`` [m], shape
    (3,), starting at ``start`` [s] and lasting ``duration`` [s]."""

    arm: int
    displacement: np.ndarray
    start: float
    duration: float

    def fraction(self, t: float) -> float:
        """Fraction of the displacement done at time t [s] (minimum jerk, 0 before, 1 after)."""
        return float(min_jerk((t - self.start) / self.duration)[0])


class DualArmTask:
    """Grasp, release and Cartesian moves of the two grippers, tracked by IK from a ``before_step`` hook."""

    def __init__(self, physics: DualArmPhysics):
        self.physics = physics
        self.moves: list[CartesianMove] = []
        physics.world.before_step.append(self._track)

    def grasp(self, arm: int | str | None = None) -> None:
        """Clamp the cable end(s) to the gripper(s) (both when ``arm`` is None)."""
        for a in arm_indices(arm):
            self.physics.clamp(a)

    def release(self, arm: int | str | None = None) -> None:
        """Open the gripper(s): the cable end falls free."""
        for a in arm_indices(arm):
            self.physics.unclamp(a)

    def move(self, arm: int | str, displacement: Sequence[float], duration: float, start: float | None = None) -> None:
        """Schedule a straight-line gripper move by ``displacement`` [m] over ``duration`` [s] from ``start`` [s]
        (default: now). Moves of one arm add up; the end target is checked for reachability with IK
        now (ParameterError if unreachable)."""
        a = arm_index(arm)
        d = check_vector3("displacement", displacement)
        t0 = self.physics.world.time if start is None else float(start)
        position, quat = self.physics.grasp_poses[a]
        end = position + d + sum((m.displacement for m in self.moves if m.arm == a), np.zeros(3))
        robot = self.physics.robots[a]
        robot.solve_ik(end, quat, seed=robot.joint_positions())
        self.moves.append(CartesianMove(a, d, t0, check_positive("move duration", duration)))

    def target(self, arm: int, t: float) -> np.ndarray:
        """Grasp-frame position [m] of arm ``arm`` scheduled for time ``t`` [s], shape (3,)."""
        pos = self.physics.grasp_poses[arm][0].copy()
        for m in self.moves:
            if m.arm == arm:
                pos += m.displacement * m.fraction(t)
        return pos

    def _track(self) -> None:
        """Before the Bullet step: joint targets for the arms that move during it."""
        world = self.physics.world
        t_next = world.time + world.dt
        for a, robot in enumerate(self.physics.robots):
            if any(m.arm == a and m.start <= t_next <= m.start + m.duration + world.dt for m in self.moves):
                robot.set_targets(robot.track(self.target(a, t_next), self.physics.grasp_poses[a][1]))
