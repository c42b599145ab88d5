"""``bullet_dlo/TensionTracking-v0``: follow a tension profile with a held cable while carrying its midpoint.

Both grippers hold the cable. The episode asks for an axial tension T*(t) [N] that varies in time,
T*(t) = mean + amplitude sin(2 pi t / period + phase) (drawn at reset: mean in ``tension_range``,
amplitude up to ``max_amplitude`` x mean, period in [2, 6] s), and a target point p* [m] for the
cable's midpoint (the reset midpoint moved by up to ``target_offset`` per axis).

**Axial tension** T at the wrists: the mean over both arms of the pull along the gripper-to-gripper
axis u (from this gripper to the other), f_left . u + f_right . (-u) over 2, with f the force on the
tool. The observation's ``task`` holds what the wrist sensors give (noise, bias, rate included); the
reward uses the cable model's own end forces (the truth the sensors measure):

``task`` = [T*(t), T*(t + 0.5 s) - T*(t), T sensed, p* - gripper midpoint (3)]  (6,), [N, N, N, m]

**Reward** in [0, 1]: 0.5 exp(-|T - T*| / 1 N) + 0.5 exp(-|m - p*| / 3 cm), m the cable's midpoint.
**Termination**: the cable goes unstable (reward 0, ``info["unstable"]``) or overloaded: true
tension above ``overload`` [N] (``info["overload"]``: a real cell would stop). ``info`` also has
``tension``, ``tension_sensed``, ``tension_target``, ``midpoint_error`` [m].
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from bullet_dlo.envs import params
from bullet_dlo.envs.dual_arm_env import DualArmEnv
from bullet_dlo.robots.transforms import norm

PREVIEW = 0.5  # [s] how far ahead the observation shows the profile
TENSION_SCALE = 1.0  # [N] reward scale of the tension error
POSITION_SCALE = 0.03  # [m] reward scale of the midpoint error


def axial_tension(forces: np.ndarray, grippers: np.ndarray) -> float:
    """Mean pull [N] along the gripper-to-gripper axis of the forces on the tools, forces (2, 3) [N], grippers (2, 3) [m]."""
    u = grippers[1] - grippers[0]
    u = u / max(norm(u), 1e-9)
    return 0.5 * float(forces[0] @ u - forces[1] @ u)


class TensionTrackingEnv(DualArmEnv):
    """Tension tracking and midpoint carrying (see the module doc); arguments of :class:`DualArmEnv` plus:

    tension_range: (low, high) [N] of the profile's mean, each in [0, 100] with low <= high;
    max_amplitude: largest amplitude as a fraction of the mean, in [0, 1]; target_offset: largest
    midpoint target offset per axis [m], in [0, 0.5]; overload [N]: axial tension that ends the episode,
    in (0, 1000]. All checked at construction, before the base's (:mod:`~.params`: ParameterError).
    """

    task_dim = 6
    default_randomisation = {
        "sample": {
            "robot": {"dist": "fixed", "value": "panda"},
            "youngs_modulus": {"dist": "log_uniform", "low": 1.0e7, "high": 5.0e7},
            "mass": {"dist": "uniform", "low": 0.02, "high": 0.04},
            "damping": {"dist": "uniform", "low": 0.01, "high": 0.03},
            "noise_std": {"dist": "uniform", "low": 0.0, "high": 0.05},
        }
    }

    def __init__(self, *args, tension_range: tuple[float, float] = (1.0, 4.0), max_amplitude: float = 0.5,
                 target_offset: float = 0.04, overload: float = 30.0, **kwargs):
        self.tension_range = params.number_pair("tension_range", tension_range)
        self.max_amplitude = params.number("max_amplitude", max_amplitude)
        self.target_offset = params.number("target_offset", target_offset)
        self.overload = params.number("overload", overload)
        super().__init__(*args, **kwargs)

    # ----- targets --------------------------------------------------------------------------------
    def _task_reset(self, rng: np.random.Generator) -> None:
        self._cache = None  # a new world: its step count starts again
        mean = rng.uniform(*self.tension_range)
        self.profile = (mean, rng.uniform(0.0, self.max_amplitude) * mean, rng.uniform(2.0, 6.0),
                        rng.uniform(0.0, 2 * math.pi))
        self.t0 = self.physics.world.time
        self.target_point = self.midpoint() + rng.uniform(-self.target_offset, self.target_offset, 3)

    def tension_target(self, t: float | None = None) -> float:
        """T*(t) [N] at episode time t [s] (default: now)."""
        t = self.physics.world.time - self.t0 if t is None else t
        mean, amplitude, period, phase = self.profile
        return mean + amplitude * math.sin(2 * math.pi * t / period + phase)

    # ----- measures -------------------------------------------------------------------------------
    def midpoint(self) -> np.ndarray:
        """The cable's midpoint [m] (3,) (interpolated between the two middle nodes for an even count)."""
        x = self.physics.cable.x
        return 0.5 * (x[(len(x) - 1) // 2] + x[len(x) // 2])

    def grippers(self) -> np.ndarray:
        """The grasp frames' positions [m] (2, 3) as the cable's held ends last took them (a copy)."""
        return self.physics.cable.holder_positions()

    def tension(self) -> float:
        """True axial tension [N] from the cable model's end forces."""
        return self._measure("tension", lambda: axial_tension(self.physics.cable.end_forces(), self.grippers()))

    def tension_sensed(self) -> float:
        """Axial tension [N] from the wrist sensors' readings."""
        return self._measure("tension_sensed", lambda: axial_tension(
            np.array([s.values[6:9] for s in self.sensors]), self.grippers()))

    def _measure(self, name: str, compute) -> float:
        """``compute()``, once per physics state: an env step asks for the tension three times (observation,
        reward, info); the cache is keyed on the world's step count and emptied at every reset."""
        key = self.physics.world.steps
        cache = getattr(self, "_cache", None)
        if cache is None or cache[0] != key:
            cache = self._cache = (key, {})
        if name not in cache[1]:
            cache[1][name] = compute()
        return cache[1][name]

    def _midpoint_error(self) -> float:
        """Distance [m] of the cable's midpoint from its target now."""
        return self._measure("midpoint_error", lambda: norm(self.midpoint() - self.target_point))

    def _task_observation(self) -> np.ndarray:
        t = self.physics.world.time - self.t0
        now = self.tension_target(t)
        grippers = self.grippers()
        mean = (grippers[0] + grippers[1]) / 2  # grippers.mean(axis=0): its sum and division, without its wrapper
        out = np.empty(6)
        out[0], out[1], out[2] = now, self.tension_target(t + PREVIEW) - now, self.tension_sensed()
        np.subtract(self.target_point, mean, out=out[3:])
        return out

    def _task_reward(self) -> tuple[float, bool]:
        err_t = abs(self.tension() - self.tension_target())
        err_p = self._midpoint_error()
        reward = 0.5 * math.exp(-err_t / TENSION_SCALE) + 0.5 * math.exp(-err_p / POSITION_SCALE)
        return reward, self.tension() > self.overload

    def scripted_policy(self):
        """The proportional controller :func:`scripted_action` (observation only)."""
        return scripted_action

    def _task_info(self) -> dict[str, Any]:
        tension = self.tension()
        return {"tension": tension, "tension_sensed": self.tension_sensed(), "tension_target": self.tension_target(),
                "midpoint_error": self._midpoint_error(),
                "overload": bool(tension > self.overload)}


def scripted_action(obs: dict[str, np.ndarray], gain_tension: float = 0.5, gain_position: float = 20.0) -> np.ndarray:
    """A proportional controller from the observation only: pull apart along x by the sensed tension error
    (``gain_tension`` action per N), move both grippers toward the midpoint target (``gain_position`` per m)."""
    target, _, sensed, *offset = obs["task"]
    pull = np.clip(gain_tension * (target - sensed), -1.0, 1.0)
    carry = np.clip(gain_position * np.asarray(offset), -1.0, 1.0)
    action = np.concatenate([carry + [-pull, 0.0, 0.0], carry + [pull, 0.0, 0.0]])
    return np.clip(action, -1.0, 1.0).astype(np.float32)
