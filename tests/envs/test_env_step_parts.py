"""The env step's cheaper parts against the direct queries they replace: the observation's grasp frames
and wrenches, the Tension measures computed once per step, and the compiled IK's tracking."""
from __future__ import annotations

import numpy as np
import pybullet as pb

from bullet_dlo.envs.tension import TensionTrackingEnv, axial_tension


def test_observation_and_measures_are_the_direct_queries_bit_for_bit():
    """After each step: gripper_pos/quat are PyBullet's getLinkState of the grasp frame, the wrench the
    sensors' latest world-frame sample (float32, inside the box); the cached tension, sensed tension and
    midpoint error equal fresh computations, also right after a reset (a new world counts steps from 0)."""
    env = TensionTrackingEnv()
    try:
        for seed in (0, 1):
            obs, _ = env.reset(seed=seed)
            rng = np.random.default_rng(seed)
            for k in range(4):
                robots = env.physics.robots
                poses = [pb.getLinkState(r.body, r.grasp_link, computeForwardKinematics=True,
                                         physicsClientId=r.client) for r in robots]
                assert np.array_equal(obs["gripper_pos"], np.array([p[4] for p in poses], np.float32))
                assert np.array_equal(obs["gripper_quat"], np.array([p[5] for p in poses], np.float32))
                assert np.array_equal(obs["wrench"], np.array([s.last.world() for s in env.sensors], np.float32))
                grippers = np.array(env.physics.cable.holder_positions())
                assert env.tension() == axial_tension(env.physics.cable.end_forces(), grippers)
                sensed = axial_tension(np.array([s.last.force_world for s in env.sensors]), grippers)
                assert env.tension_sensed() == sensed
                assert obs["task"][2] == np.float32(sensed)
                assert env._midpoint_error() == float(np.linalg.norm(env.midpoint() - env.target_point))
                obs, *_ = env.step(rng.uniform(-1, 1, 6).astype(np.float32))
    finally:
        env.close()


def test_tracking_puts_the_grippers_on_their_targets():
    """Held still for a few control steps, each gripper settles on its target pose (the IK's joints, the
    arms' position control): within 1 mm of the target (the cable's load on a position-controlled arm)."""
    env = TensionTrackingEnv()
    try:
        env.reset(seed=2)
        for _ in range(3):
            env.step(np.array([0.5, 0, -0.5, -0.5, 0, 0.5], np.float32))
        for _ in range(15):
            env.step(np.zeros(6, np.float32))
        reached = np.array([r.grasp_pose()[0] for r in env.physics.robots])
        assert np.abs(reached - env.target).max() < 1e-3
        assert np.abs(env.target - env.home).max() > 2e-3  # the targets did move
    finally:
        env.close()


def test_action_cleaning_is_nan_to_num_then_clip_bit_for_bit():
    """The env's action cleaning (``DualArmEnv._clean_action``) gives the bits of np.clip(np.nan_to_num(a), -1, 1)
    for NaN, both infinities, -0.0, subnormals, values out of the box, float32 arrays and lists, and returns a
    new array (cleaning never writes into the caller's action)."""
    from bullet_dlo.envs.dual_arm_env import DualArmEnv

    cases = [np.array([np.nan, np.inf, -np.inf, -0.0, 0.3, -7.0]), [1e308, -1e-320, np.nan, 2.0, -2.0, 0.5],
             np.array([0.1, -0.2, np.nan, 3.0, 0.0, -0.0], np.float32), np.random.default_rng(0).normal(0, 2, 6)]
    for a in cases:
        before = np.array(a, dtype=float)
        ref = np.clip(np.nan_to_num(np.asarray(a, dtype=float)), -1.0, 1.0)
        got = DualArmEnv._clean_action(a)
        assert got.dtype == np.float64 and np.array_equal(ref.view(np.int64), got.view(np.int64))
        got[:] = 5.0
        assert np.array_equal(np.array(a, dtype=float), before, equal_nan=True)  # the caller's action untouched


def test_a_step_with_a_bad_action_moves_the_targets_as_the_cleaned_action_does():
    """NaN reads as 0 and infinities as +-1: two envs with the same seed, one given the bad action, one its
    cleaned form, reach the same targets and observations bit for bit."""
    bad = np.array([np.nan, np.inf, -np.inf, 0.5, -2.0, -0.0], np.float32)
    clean = np.array([0.0, 1.0, -1.0, 0.5, -1.0, -0.0], np.float32)
    out = []
    for action in (bad, clean):
        env = TensionTrackingEnv()
        try:
            env.reset(seed=4)
            obs, *_ = env.step(action)
            out.append((env.target.copy(), obs))
        finally:
            env.close()
    (t0, o0), (t1, o1) = out
    assert np.array_equal(t0, t1) and not np.array_equal(t0, env.home)
    assert all(np.array_equal(o0[k], o1[k]) for k in o0)
