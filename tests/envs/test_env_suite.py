"""Every registered ``bullet_dlo/`` environment through the same checks, in the manner of dm_control's
``suite_test.py``: Gymnasium's ``check_env``, seeded determinism, finite observations inside their
spaces, finite rewards, ``render()`` giving an image, ``gymnasium.make_vec`` in both vectorisation
modes and the declared autoreset mode honoured by them.

Bounded for CI (whole file well under a minute on two busy cores): one environment per id, built
once (module fixture) with a short settle time and reused by every check; episodes of a few steps.
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import bullet_dlo  # noqa: F401  (registers the ids)
from bullet_dlo._gym_registration import ENV_IDS

ENV_IDS_REGISTERED = sorted(k for k in gym.registry if k.startswith("bullet_dlo/"))
FAST = {"settle_time": 0.05}  # [s] of settling per reset (0.25 by default): the checks reset often
RENDER_SIZE = (48, 32)
STEPS = 3


def actions(env, n: int = STEPS, seed: int = 0) -> np.ndarray:
    """``n`` seeded actions of the environment's action space."""
    space = env.action_space
    return np.random.default_rng(seed).uniform(space.low, space.high, (n, *space.shape)).astype(space.dtype)


def run(env, seed: int, acts: np.ndarray) -> tuple[list[dict], list[float]]:
    """Observations (reset and after every step) and rewards of ``acts`` after ``reset(seed=seed)``."""
    obs, _ = env.reset(seed=seed)
    out, rewards = [obs], []
    for a in acts:
        obs, reward, term, trunc, _ = env.step(a)
        out.append(obs)
        rewards.append(reward)
        if term or trunc:
            break
    return out, rewards


@pytest.fixture(scope="module", params=ENV_IDS_REGISTERED)
def env(request):
    """One environment per registered id, built once and shared by the checks of this module."""
    e = gym.make(request.param, render_mode="rgb_array", render_size=RENDER_SIZE, **FAST)
    yield e
    e.close()


def test_the_sweep_covers_every_registered_id():
    assert ENV_IDS_REGISTERED == sorted(ENV_IDS)


def test_check_env(env):
    check_env(env.unwrapped, skip_render_check=False)


def test_declares_its_autoreset_mode_and_episode_length(env):
    assert env.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert env.spec.max_episode_steps == ENV_IDS[env.spec.id][1]
    assert "rgb_array" in env.metadata["render_modes"]


def test_same_seed_same_observations_another_seed_others(env):
    acts = actions(env)
    first, rewards_1 = run(env, 7, acts)
    again, rewards_2 = run(env, 7, acts)
    assert len(first) == len(again) == STEPS + 1
    for a, b in zip(first, again):
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"{env.spec.id} obs[{key!r}]")
    assert rewards_1 == rewards_2
    other, _ = run(env, 8, acts[:1])
    assert any(not np.array_equal(first[0][k], other[0][k]) for k in first[0])  # another draw


def test_observations_finite_and_in_their_space_rewards_finite(env):
    obs_list, rewards = run(env, 3, actions(env, seed=1))
    for obs in obs_list:
        assert env.observation_space.contains(obs)
        for key, value in obs.items():
            assert np.all(np.isfinite(value)), f"{env.spec.id} obs[{key!r}]"
    assert all(np.isfinite(r) for r in rewards)


def test_render_gives_an_rgb_image(env):
    env.reset(seed=0)
    frame = env.render()
    width, height = RENDER_SIZE
    assert isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.shape == (height, width, 3)
    assert frame.std() > 0  # a picture, not a blank


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize("env_id", ENV_IDS_REGISTERED)
def test_make_vec_batches_and_autoresets_on_the_next_step(env_id, mode):
    """Episodes of 2 steps: step 2 truncates, step 3 (NEXT_STEP) returns the first observation of a new
    episode (its clock back at the settle time), reward 0 and both flags false; step 4 goes on."""
    vec = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, max_episode_steps=2, **FAST)
    try:
        assert vec.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
        obs, info = vec.reset(seed=[1, 2])
        assert vec.observation_space.contains(obs)
        start = info["time"].copy()
        a = np.random.default_rng(0).uniform(-1, 1, (4, *vec.action_space.shape)).astype(vec.action_space.dtype)
        _, rewards, term, trunc, info = vec.step(a[0])
        assert not (term | trunc).any() and np.isfinite(rewards).all()
        _, rewards, term, trunc, info = vec.step(a[1])
        assert (term | trunc).all()  # the 2-step limit (or the task's own end)
        obs, rewards, term, trunc, info = vec.step(a[2])
        np.testing.assert_array_equal(rewards, 0.0)
        assert not (term | trunc).any()
        np.testing.assert_allclose(info["time"], start)  # a fresh episode's first observation
        assert all(np.all(np.isfinite(v)) for v in obs.values())
        obs, rewards, term, trunc, info = vec.step(a[3])
        assert (info["time"] > start).all()
    finally:
        vec.close()


def test_same_step_mode_gives_the_final_observation():
    """The other modes work too: SAME_STEP resets within the ending step, the ended episode's last
    observation in ``info["final_obs"]``."""
    env_id = ENV_IDS_REGISTERED[0]
    vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", max_episode_steps=1,
                       vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}, **FAST)
    try:
        _, info0 = vec.reset(seed=[1, 2])
        _, _, term, trunc, info = vec.step(np.zeros(vec.action_space.shape, vec.action_space.dtype))
        assert (term | trunc).all() and info["_final_obs"].all()
        np.testing.assert_allclose(info["time"], info0["time"])  # already the next episode
        assert all(np.all(np.isfinite(o["wrench"])) for o in info["final_obs"])
    finally:
        vec.close()
