"""A gripper target stays where its arm can follow: beyond the arm's reach (the IK misses it) or with the gripper
blocked, an action leaves the target where it was, so that the arm does not chase an unreachable target into
another configuration and reversing the action acts at once (no wind-up hidden from the observation)."""
from __future__ import annotations

import numpy as np
import pytest

from bullet_dlo.envs.tension import TensionTrackingEnv

UP = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
INWARD = np.array([1.0, 0.0, 0.0, -1.0, 0.0, 0.0])


@pytest.mark.parametrize("solver", ["compiled", "bullet"])
def test_grippers_driven_beyond_reach_stop_there_and_come_back_at_once(solver):
    """Both grippers driven up at 0.5 m/s for 1.5 s, far beyond the arms' reach (workspace 2 m): they stop at the
    edge of reach on their targets (within 1 mm, the reach check's tolerance), the cable between them stays
    stable, and the first two steps back down move them down by more than one step's travel. Before, the
    targets ran on, the IK swung an arm into another configuration and the cable tore ("segment strain beyond
    bound") within 1 s."""
    env = TensionTrackingEnv(max_speed=0.5, workspace=2.0)
    try:
        env.reset(seed=0)
        for robot in env.physics.robots:
            robot.ik_solver = solver
        lags = []
        for _ in range(30):
            obs, _, _, _, info = env.step(UP)
            assert not info["unstable"], info["reason"]
            lags.append(info["gripper_lag"])
        assert np.max(lags[-10:]) < 1e-3
        top = obs["gripper_pos"][:, 2].copy()
        assert np.all(top - env.home[:, 2] > 0.2)  # they did climb before stopping
        for _ in range(2):
            obs, _, _, _, info = env.step(-UP)
        assert not info["unstable"]
        assert np.all(top - obs["gripper_pos"][:, 2] > 0.5 * env.max_speed * env.control_dt)
    finally:
        env.close()


def test_blocked_grippers_do_not_wind_their_targets_up():
    """The two grippers driven into each other (0.1 m/s for 2.25 s): once blocked, their targets stop within
    :meth:`lag_limit` (plus the push the grippers take after that) of the grasp frames, and driven apart they
    separate within five steps. Before, the targets ran 12 cm past the blocked grippers, which then sat still
    until the targets came back."""
    env = TensionTrackingEnv(max_speed=0.1, workspace=0.5)
    try:
        env.reset(seed=0)
        for _ in range(45):
            obs, _, _, _, info = env.step(INWARD)
        assert np.all(info["gripper_lag"] < env.lag_limit() + 0.01)
        x = obs["gripper_pos"][:, 0].copy()
        for _ in range(5):
            obs, _, _, _, info = env.step(-INWARD)
        apart = (x - obs["gripper_pos"][:, 0]) * np.array([1.0, -1.0])  # left moves -x, right +x
        assert np.all(apart > 0.005)
    finally:
        env.close()
