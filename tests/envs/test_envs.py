"""The Gymnasium environments: conventions (check_env, seeding, vector envs, rendering), physics of the
observations (wrist tension against the cable model), the control-rate rule, instability handling."""
from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pybullet as pb
import pytest
from gymnasium.utils.env_checker import check_env

import bullet_dlo  # noqa: F401  (registers the ids)
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.envs import shaping, tension
from bullet_dlo.envs.shaping import ShapingEnv
from bullet_dlo.envs.tension import TensionTrackingEnv
from bullet_dlo.render.video import VideoWriter, probe_video

pytestmark = pytest.mark.bullet

NOISY = {"seed": 0, "sample": {"robot": "panda", "noise_std": {"dist": "uniform", "low": 0.05, "high": 0.2},
                               "youngs_modulus": {"dist": "log_uniform", "low": 1.0e7, "high": 5.0e7}}}


def rollout(env, seed: int, steps: int, action_seed: int = 0):
    """Observations, rewards and infos of ``steps`` seeded random actions after ``reset(seed)``."""
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed)
    out = [obs]
    rewards, infos = [], [info]
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 6).astype(np.float32))
        out.append(obs)
        rewards.append(r)
        infos.append(info)
        if term:
            break
    return out, rewards, infos


def test_importing_the_package_registers_the_ids_without_importing_gymnasium():
    program = ("import sys, bullet_dlo; assert 'gymnasium' not in sys.modules and 'pybullet' not in sys.modules; "
               "import gymnasium; ids = sorted(k for k in gymnasium.registry if k.startswith('bullet_dlo/')); "
               "assert 'pybullet' not in sys.modules; print(ids)")
    proc = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "['bullet_dlo/Routing-v0', 'bullet_dlo/Shaping-v0', 'bullet_dlo/TensionTracking-v0']" in proc.stdout


@pytest.mark.parametrize("env_id", ["bullet_dlo/TensionTracking-v0", "bullet_dlo/Shaping-v0"])
def test_make_gives_the_documented_spaces(env_id):
    env = gym.make(env_id)
    try:
        assert env.spec.max_episode_steps == 100
        assert env.action_space.shape == (6,) and env.action_space.low.min() == -1.0
        obs, _ = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        assert obs["wrench"].shape == (2, 6) and obs["joint_q"].shape == (2, 7)
        assert ("cable" in obs) == (env_id == "bullet_dlo/Shaping-v0")  # privileged shape on by default there
    finally:
        env.close()


def test_check_env_passes_with_randomised_noisy_episodes():
    """check_env on a sampled configuration (noise and stiffness drawn per episode): reset(seed) must still be
    deterministic. The registered ids with their defaults go through check_env in test_env_suite.py."""
    env = TensionTrackingEnv(NOISY, render_mode="rgb_array", render_size=(64, 48), settle_time=0.05)
    try:
        check_env(env, skip_render_check=False)
    finally:
        env.close()


def test_same_seed_and_actions_give_identical_observations_and_another_seed_does_not():
    env_a, env_b = TensionTrackingEnv(NOISY), TensionTrackingEnv(NOISY)
    try:
        obs_a, _, info_a = rollout(env_a, seed=11, steps=8)
        obs_b, _, info_b = rollout(env_b, seed=11, steps=8)
        for oa, ob in zip(obs_a, obs_b):
            for key in oa:
                np.testing.assert_array_equal(oa[key], ob[key])
        obs_c, _, info_c = rollout(env_b, seed=12, steps=1)
        assert info_c[0]["params"]["youngs_modulus"] != info_a[0]["params"]["youngs_modulus"]  # re-drawn at reset
        assert info_a[0]["params"] == info_b[0]["params"]
    finally:
        env_a.close()
        env_b.close()


def test_control_period_must_be_a_whole_multiple_of_the_physics_step():
    with pytest.raises(ParameterError, match=r"control_dt = 0.051 s must be a whole multiple"):
        TensionTrackingEnv(control_dt=0.051)
    two_rates = {"sample": {"robot": "panda", "dt": {"dist": "choice", "values": [1 / 240, 0.001]}}}
    TensionTrackingEnv(two_rates, control_dt=0.05)  # 12 and 50 steps
    with pytest.raises(ParameterError, match="dt = 0.001 s"):
        TensionTrackingEnv(two_rates, control_dt=1 / 120)  # 2 steps at 240 Hz, 8.33 at 1 kHz


def test_sensed_tension_matches_the_cable_model_and_pulling_apart_raises_it():
    """The wrist sensors (noise off) measure the axial tension the cable model exerts, within 3 %, at rest
    and after the grippers pulled apart; pulling raises it (a cable is stiff in tension)."""
    env = TensionTrackingEnv({"sample": {"robot": "panda", "youngs_modulus": 2.0e7}})
    try:
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.zeros(6, np.float32))
        slack = info["tension"]
        assert info["tension_sensed"] == pytest.approx(slack, rel=0.03, abs=0.02)
        for _ in range(3):  # 3 x 2.5 mm apart, then hold
            env.step(np.array([-1, 0, 0, 1, 0, 0], np.float32))
        for _ in range(10):
            _, _, _, _, info = env.step(np.zeros(6, np.float32))
        assert info["tension"] > slack + 1.0
        assert info["tension_sensed"] == pytest.approx(info["tension"], rel=0.03)
    finally:
        env.close()


def test_scripted_tension_controller_earns_more_than_holding_still():
    env = TensionTrackingEnv()
    try:
        returns = {}
        for name in ("hold", "scripted"):
            obs, _ = env.reset(seed=3)
            total = 0.0
            for _ in range(30):
                action = np.zeros(6, np.float32) if name == "hold" else tension.scripted_action(obs)
                obs, r, term, _, info = env.step(action)
                total += r
                assert not term
            returns[name] = total
        assert returns["scripted"] > returns["hold"] + 5.0
        assert abs(info["tension"] - info["tension_target"]) < 0.5  # the scripted controller tracks
    finally:
        env.close()


def test_shaping_target_is_reachable_by_moving_the_grippers_where_it_was_made():
    """The target comes from the cable model with the drawn gripper moves: the Bullet-coupled cable,
    moved there by the arms, matches it to within 5 mm on average."""
    env = ShapingEnv()
    try:
        env.reset(seed=4)
        start_error = env.shape_error()
        for _ in range(50):
            _, _, _, _, info = env.step(shaping.scripted_action(env))
        assert info["shape_error"] < 0.005 < start_error
        assert info["is_success"]
    finally:
        env.close()


def test_an_unstable_step_terminates_and_no_observation_holds_nan():
    """A gripper yanked 30 cm away in one step (its arm's base teleported) tears the cable model:
    the step stops at once, the episode terminates with the reason, the observation stays finite."""
    env = TensionTrackingEnv()
    try:
        env.reset(seed=0)
        t0, robot = env.physics.world.time, env.physics.robots[1]
        p, q = pb.getBasePositionAndOrientation(robot.body, physicsClientId=robot.client)
        pb.resetBasePositionAndOrientation(robot.body, [p[0] + 0.3, p[1], p[2]], q, physicsClientId=robot.client)
        obs, reward, terminated, truncated, info = env.step(np.zeros(6, np.float32))
        assert terminated and info["unstable"] and info["reason"] == "segment strain beyond bound"
        # stopped within two physics steps (the holder moves after Bullet's step, the cable sees it in the next)
        assert info["time"] <= t0 + 2.5 * env.physics.world.dt < t0 + env.control_dt
        assert reward == 0.0
        assert all(np.all(np.isfinite(v)) for v in obs.values())
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_camera_observations_and_a_recorded_video(tmp_path):
    env = TensionTrackingEnv(camera="rgbd", image_size=(32, 24), render_mode="rgb_array", render_size=(96, 64))
    try:
        obs, _ = env.reset(seed=0)
        assert obs["rgb"].shape == (24, 32, 3) and obs["rgb"].dtype == np.uint8
        assert obs["rgb"].std() > 5  # a picture, not a blank
        assert obs["depth"].shape == (24, 32, 1) and 0.1 < obs["depth"].min() < obs["depth"].max() <= 10.0
        writer = VideoWriter(tmp_path / "episode", fps=env.metadata["render_fps"])
        for _ in range(4):
            env.step(env.action_space.sample())
            frame = env.render()
            assert frame.shape == (64, 96, 3)
            writer.write(frame)
        writer.close()
        assert writer.frames == 4 and writer.path.exists()
        if writer.format != "png":
            assert probe_video(writer.path)["frames"] == 4
    finally:
        env.close()


def test_sync_and_async_vector_envs_agree():
    """Two seeded sub-environments stepped with the same actions give the same observations in one
    process (SyncVectorEnv) and in two worker processes (AsyncVectorEnv)."""
    def make():
        return TensionTrackingEnv(NOISY)

    actions = np.random.default_rng(0).uniform(-1, 1, (3, 2, 6)).astype(np.float32)
    results = []
    for vector in (gym.vector.SyncVectorEnv, gym.vector.AsyncVectorEnv):
        envs = vector([make, make])
        try:
            obs, _ = envs.reset(seed=[5, 6])
            for a in actions:
                obs, rewards, term, trunc, infos = envs.step(a)
            assert obs["wrench"].shape == (2, 2, 6) and rewards.shape == (2,)
            results.append(obs)
        finally:
            envs.close()
    for key in results[0]:
        np.testing.assert_array_equal(results[0][key], results[1][key])
    assert not np.array_equal(results[0]["task"][0], results[0]["task"][1])  # two seeds, two episodes


def test_speed_benchmark_steps_the_same_world_in_both_arms_of_the_comparison():
    """demos/env_speed.py: bare blocks are undone (saved and restored Bullet state), so the dual-arm
    scene runs on undisturbed (stable, its clock counting only its own steps) and both times are real."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "demos" / "env_speed.py"
    spec = importlib.util.spec_from_file_location("env_speed", path)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    physics = demo.build("panda", 10)
    try:
        steps0 = physics.world.steps
        full, bare = demo.step_vs_bare(physics, blocks=3)
        assert physics.world.steps == steps0 + 3 * demo.BLOCK and physics.cable.stable
        assert full > 0 and bare > 0
        z_mid = physics.cable.x[5, 2]
        assert abs(z_mid - physics.spec.hold_height) < 0.02  # the cable still hangs between the grippers
        parts = demo.breakdown(physics, 24)
        assert parts["Bullet stepSimulation"] > 0 and parts["wrist sensors (robots/sensors.py)"] > 0
    finally:
        physics.close()



def test_training_demo_feeds_forces_of_order_one_and_its_scripted_baseline_beats_random():
    """demos/train_tension.py without stable-baselines3 (an optional extra): the policy's flat force-feedback
    observation, and the evaluation that the learning curve is compared on."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "demos" / "train_tension.py"
    spec = importlib.util.spec_from_file_location("train_tension", path)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    env = demo.make_env(episode_steps=20)
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (25,) and obs.dtype == np.float32 and np.abs(obs).max() < 10.0
        base = demo.baselines(env, seeds=(1000,))
        assert base["scripted"] > base["random"] + 2.0 and base["scripted"] <= 20.0
    finally:
        env.close()


def test_randomisation_takes_a_capture_spec_file_or_dict_and_names_bad_keys(tmp_path):
    import yaml

    from bullet_dlo.envs.randomisation import EnvRandomisation

    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(NOISY))
    from_file, from_dict = EnvRandomisation(path), EnvRandomisation(NOISY)
    a = from_file.draw(np.random.default_rng(3), None)
    b = from_dict.draw(np.random.default_rng(3), None)
    assert a.params == b.params and a.setup == b.setup
    assert 0.05 <= a.setup.noise_std[0] <= 0.2 and a.setup.robot == "panda"
    with pytest.raises(ParameterError, match=r"sample.youngs_modulus: low \(2.0\) > high \(1.0\)"):
        TensionTrackingEnv({"sample": {"youngs_modulus": {"dist": "uniform", "low": 2.0, "high": 1.0}}})
