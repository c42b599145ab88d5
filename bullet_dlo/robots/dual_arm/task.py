"""What happens in a dual-arm episode of the grasp study: grasp, release, and gripper trajectories.

A move translates one grasp frame along a straight line with a minimum-jerk profile (the
orientation is kept). Any core motion item (:class:`~bullet_dlo.core.boundary.Move` with
rotation, :class:`~bullet_dlo.core.boundary.Waypoints`, :class:`~bullet_dlo.core.boundary.Sine`;
end ``first`` = left arm, ``last`` = right arm) moves and turns the grasp frame as the core
moves and turns a held end (:meth:`DualArmTask.follow`): the held tangent turns with the gripper.
Before every Bullet step during a motion, the arm's joint targets are set by one IK solve
(:meth:`~bullet_dlo.robots.arm.Robot.track`) for the frame's target at the end of that step;
the arm's position control follows. Another task (e.g. an environment
whose actions are joint targets) replaces this one and keeps the physics and observation.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from bullet_dlo.core.boundary import Motion, MotionOffset, min_jerk
from bullet_dlo.core.validate import ParameterError, check_positive, check_vector3
from bullet_dlo.robots.dual_arm.physics import ARMS, DualArmPhysics, arm_index, arm_indices
from bullet_dlo.robots.transforms import quat_from_matrix, rotation

END_OF_ARM = ("first", "last")
HORIZON = 2.0
"""How far [s] :meth:`DualArmTask.follow` checks a motion item that runs forever (a sine without a duration)."""
POSE_MISS = 0.02
"""[m] A grasp frame this far from its scheduled target has lost the motion (position control lags a slow roll by
0.1 mm and the fast moves of dataset captures by up to about 5 mm; an arm that loses a roll at a joint limit
drifts on to centimetres)."""
SETTLED_MISS = 0.002
"""[m] A grasp frame this far from its target :data:`SETTLE` s after its arm's last motion item ended has not
reached the final pose: nothing lags once the targets stop moving (a KUKA rolled 120 degrees about the cable came
to rest 11 mm off, its wrist joints near their limits, below :data:`POSE_MISS`)."""
SETTLE = 0.2
"""[s] Time after an arm's last motion item ends at which :data:`SETTLED_MISS` is checked."""


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
    """Grasp, release and Cartesian moves of the two grippers, tracked by IK in the physics' load phase."""

    def __init__(self, physics: DualArmPhysics):
        self.physics = physics
        self.moves: list[CartesianMove] = []
        self.motion: list[Motion] = []  # core motion items (end first = left, last = right), times from t = 0
        self._offsets: list[MotionOffset | None] = [None, None]  # per arm, rebuilt when an item is added
        self.pose_misses: list[tuple[float, int, float]] = []
        """(time [s], arm, distance [m]) where an arm's grasp frame first missed its target (:meth:`_check_pose`)."""
        physics.task = self  # the physics calls drive() every step, after loading the grippers

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

    def follow(self, item: Motion) -> None:
        """Add a core motion item (Move, Waypoints, Sine) to the grasp frame of the arm holding its end
        (first = left, last = right): displacements [m] and rotations [rad] about world axes, relative
        to the grasp pose, times [s] of the world clock. Checks that the arm can follow it: the targets at the
        item's start, end and every 50 ms between (the first :data:`HORIZON` s of an item that runs forever),
        each solved from the joints found for the one before, as the per-step tracking does
        (:meth:`~bullet_dlo.robots.arm.Robot.path_miss`; ParameterError naming the time and the miss: a
        target out of reach, or a joint at its limit on the way, e.g. a large roll)."""
        a = END_OF_ARM.index(item.end)
        before = self._offsets[a]
        self.motion.append(item)
        self._offsets[a] = MotionOffset(self.motion, item.end)
        robot = self.physics.robots[a]
        end = item.start + (item.duration if math.isfinite(item.duration) else HORIZON)
        times = np.unique(np.r_[np.arange(item.start, end, 0.05), end])
        miss = robot.path_miss([self.target_pose(a, float(t)) for t in times])
        if miss is not None:
            self.motion.pop()
            self._offsets[a] = before
            k, err_p, err_r = miss
            raise ParameterError(f"the {ARMS[a]} arm ({robot.spec.name}) cannot follow this motion: at t = "
                                 f"{times[k]:.3f} s its grasp target is missed by {err_p * 1000:.1f} mm / "
                                 f"{math.degrees(err_r):.1f} deg (out of reach, or a joint at its limit on the way)")

    def target(self, arm: int, t: float) -> np.ndarray:
        """Grasp-frame position [m] of arm ``arm`` scheduled for time ``t`` [s], shape (3,)."""
        return self.target_pose(arm, t)[0]

    def target_pose(self, arm: int, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Grasp-frame position [m] (3,) and quaternion (x, y, z, w) (4,) of arm ``arm`` scheduled for ``t`` [s]."""
        pos, quat = self.physics.grasp_poses[arm]
        pos = pos.copy()
        for m in self.moves:
            if m.arm == arm:
                pos += m.displacement * m.fraction(t)
        offset = self._offsets[arm]
        if offset is not None:
            disp, _, _, turn = offset(t)
            pos += disp
            quat = quat_from_matrix(turn @ rotation(quat))
        return pos, quat

    def _moving(self, arm: int, t: float) -> bool:
        """Whether arm ``arm`` has a move or motion item under way at ``t`` [s] (one step of slack)."""
        dt = self.physics.world.dt
        if any(m.arm == arm and m.start <= t <= m.start + m.duration + dt for m in self.moves):
            return True
        return any(m.end == END_OF_ARM[arm] and m.start <= t <= m.start + m.duration + dt for m in self.motion)

    def drive(self) -> None:
        """Before the Bullet step (phase 2 of the dual-arm step): joint targets for the arms that move during it."""
        if not (self.moves or self.motion):  # nothing scheduled (an environment drives the arms itself)
            return
        world = self.physics.world
        t_next = world.time + world.dt
        for a, robot in enumerate(self.physics.robots):
            if self._moving(a, t_next):
                self._check_pose(a, world.time, POSE_MISS)
                robot.set_targets(robot.track(*self.target_pose(a, t_next)))
                continue
            settled = self._settled_at(a)
            if settled is not None and 0.0 <= world.time - settled < world.dt:
                self._check_pose(a, world.time, SETTLED_MISS)

    def _settled_at(self, arm: int) -> float | None:
        """When [s] arm ``arm`` should have reached its final pose: :data:`SETTLE` after its last move or motion item
        ends (None when it has none, or one that runs forever)."""
        ends = [m.start + m.duration for m in self.moves if m.arm == arm]
        ends += [m.start + m.duration for m in self.motion if m.end == END_OF_ARM[arm]]
        return max(ends) + SETTLE if ends and all(math.isfinite(e) for e in ends) else None

    def _check_pose(self, arm: int, t: float, limit: float) -> None:
        """Warn once per arm (and note it in :attr:`pose_misses`) when its grasp frame is ``limit`` [m] or more
        from its target at ``t`` [s] (:data:`POSE_MISS` while it moves, :data:`SETTLED_MISS` once it should have
        come to rest): the arm does not follow the motion (too fast for its joints, a large roll that takes a wrist
        joint to its limit, a gripper driven into the table), and what the wrists read belongs to the pose it
        reached, not the one asked for."""
        if any(m[1] == arm for m in self.pose_misses):
            return
        # the grasp frame as the coupling measured it after the last Bullet step (no query of its own)
        miss = float(np.linalg.norm(self.physics.cable.ext.pos[arm] - self.target_pose(arm, t)[0]))
        if miss >= limit:
            self.pose_misses.append((t, arm, miss))
            warnings.warn(f"the {ARMS[arm]} arm's grasp frame is {miss * 1000:.1f} mm from its target at t = "
                          f"{t:.3f} s: the arm does not follow the motion (too fast for its joints, a joint at its "
                          "limit, or blocked); the wrists read the pose it reached, not the one asked for",
                          stacklevel=2)
