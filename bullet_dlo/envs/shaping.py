"""``bullet_dlo/Shaping-v0``: bring the held cable to a target shape.

The target is a shape the arms can make: at reset, random gripper displacements are drawn (left
end inward by up to ``inward`` along x, right end likewise, both by up to ``lateral`` in y and
``vertical`` in z, orientations kept), checked reachable by each arm's IK, and run in the cable
model itself (:func:`bullet_dlo.core.simulate`, both ends clamped and moved over 1 s, then
settling): its final node positions, resampled to ``shape_points`` points, are the target.

``task`` = target points minus the current ones (shape_points * 3,) [m], flattened (the
current shape is the privileged ``cable`` key, on by default here: ``privileged=True``).

**Reward** in [0, 1]: exp(-e / 1 cm), e the mean distance [m] between the cable's points and the
target's. ``info["is_success"]``: e below ``success_error`` (5 mm); the episode goes on (as in
dm_control), ending at the time limit or on instability.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from bullet_dlo.core.boundary import Move
from bullet_dlo.core.engine import simulate
from bullet_dlo.core.model import CableModel
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.envs import params
from bullet_dlo.envs.dual_arm_env import DualArmEnv

SHAPE_SCALE = 0.01  # [m] reward scale of the mean shape error
MOVE_TIME, SETTLE_TIME = 1.0, 3.0  # [s] of the model run that makes the target
MAX_DRAWS = 10


class ShapingEnv(DualArmEnv):
    """Shape matching (see the module doc); arguments of :class:`DualArmEnv` (``privileged`` on by default) plus
    inward, lateral, vertical: the largest gripper displacements [m] of a target, each in [0, 0.5];
    success_error [m]: mean shape error of a success, in (0, 0.5]. All checked at construction, before
    the base's (:mod:`~.params`: ParameterError)."""

    default_randomisation = {
        "sample": {
            "robot": {"dist": "fixed", "value": "panda"},
            "youngs_modulus": {"dist": "log_uniform", "low": 1.0e7, "high": 5.0e7},
            "mass": {"dist": "uniform", "low": 0.02, "high": 0.04},
            "damping": {"dist": "uniform", "low": 0.01, "high": 0.03},
        }
    }

    def __init__(self, *args, privileged: bool = True, inward: float = 0.06, lateral: float = 0.05,
                 vertical: float = 0.04, success_error: float = 0.005, **kwargs):
        self.inward, self.lateral, self.vertical = (params.number(k, v) for k, v in
                                                    (("inward", inward), ("lateral", lateral), ("vertical", vertical)))
        self.success_error = params.number("success_error", success_error)
        self.task_dim = 3 * params.shape_points(kwargs.get("shape_points", 10))
        super().__init__(*args, privileged=privileged, **kwargs)

    # ----- the target -----------------------------------------------------------------------------
    def _task_reset(self, rng: np.random.Generator) -> None:
        self.displacements = self._reachable_displacements(rng)
        self.target_shape = self.cable_points(self._model_shape(self.displacements))

    def _reachable_displacements(self, rng: np.random.Generator) -> np.ndarray:
        """Gripper displacements [m] (2, 3) whose end poses both arms reach (IK), within the workspace."""
        box = min(self.workspace, 1.0)
        for _ in range(MAX_DRAWS):
            d = np.array([[rng.uniform(0.0, self.inward), rng.uniform(-self.lateral, self.lateral),
                           rng.uniform(-0.5 * self.vertical, self.vertical)] for _ in range(2)])
            d[1, 0] = -d[1, 0]  # the right end moves inward along -x
            d = np.clip(d, -box, box)
            try:
                for arm, robot in enumerate(self.physics.robots):
                    robot.solve_ik(self.home[arm] + d[arm], self._quat[arm], seed=robot.joint_positions())
            except ParameterError:
                continue
            return d
        raise ParameterError(f"no reachable shaping target in {MAX_DRAWS} draws: lower inward/lateral/vertical")

    def _model_shape(self, displacements: np.ndarray) -> np.ndarray:
        """Node positions [m] (n, 3) of the cable model at rest after both clamped ends moved by ``displacements``."""
        cable = self.physics.cable
        start = cable.x[0]
        model = CableModel.straight(cable.model.spec, start, cable.x[-1] - start, ("clamped", "clamped"),
                                    (Move("first", tuple(displacements[0]), 0.0, MOVE_TIME),
                                     Move("last", tuple(displacements[1]), 0.0, MOVE_TIME)),
                                    self.physics.world.gravity)
        result = simulate(model, "implicit_euler", dt=1e-3, duration=MOVE_TIME + SETTLE_TIME, record_every=10**9)
        return result.final_state.x

    # ----- measures -------------------------------------------------------------------------------
    def shape_error(self) -> float:
        """Mean distance [m] between the cable's points and the target's."""
        return float(np.linalg.norm(self.cable_points() - self.target_shape, axis=1).mean())

    def _task_observation(self) -> np.ndarray:
        return (self.target_shape - self.cable_points()).reshape(-1)

    def _task_reward(self) -> tuple[float, bool]:
        return math.exp(-self.shape_error() / SHAPE_SCALE), False

    def scripted_policy(self):
        """The privileged expert :func:`scripted_action` on this environment (it reads the target's moves)."""
        return lambda obs: scripted_action(self)

    def _task_info(self) -> dict[str, Any]:
        error = self.shape_error()
        return {"shape_error": error, "is_success": bool(error < self.success_error)}


def scripted_action(env: ShapingEnv, gain: float = 20.0) -> np.ndarray:
    """The privileged expert: move each gripper toward the pose the target was made with (``gain`` action per m)."""
    error = env.home + env.displacements - np.array([r.grasp_pose()[0] for r in env.physics.robots])
    return np.clip(gain * error.reshape(-1), -1.0, 1.0).astype(np.float32)
