"""Policy rollouts recorded in the dataset's episode format (bullet_dlo.envs.rollouts)."""
from __future__ import annotations

import json
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import bullet_dlo  # noqa: F401  (registers the environments)
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data import Dataset
from bullet_dlo.envs.rollouts import record_rollouts
from bullet_dlo.envs.tension import scripted_action

pytestmark = pytest.mark.bullet

ENV = "bullet_dlo/TensionTracking-v0"
STEPS = 6  # control steps per episode (0.3 s)


@pytest.fixture(scope="module")
def rollouts(tmp_path_factory):
    out = tmp_path_factory.mktemp("rollouts")
    res = record_rollouts(ENV, "scripted", out, 2, seed=5, record_rate=240.0,
                          env_kwargs={"max_episode_steps": STEPS}, progress=False)
    return out, res


def test_rollouts_are_a_dataset_with_the_capture_columns_and_the_control_steps(rollouts):
    out, res = rollouts
    assert res.complete and res.done == 2 and res.ran == 2
    ds = Dataset(out)
    assert [r["status"] for r in ds.records] == ["ok", "ok"]
    ep = ds.load(ds.records[1])
    assert ep["env_id"] == ENV and ep["policy"] == "scripted" and int(ep["seed"]) == 6
    assert ep["action"].shape == (STEPS, 6) and ep["reward"].shape == (STEPS,)
    assert ep["obs_wrench"].shape == (STEPS + 1, 2, 6) and ep["obs_task"].shape == (STEPS + 1, 6)
    assert bool(ep["truncated"]) and not bool(ep["terminated"])
    assert ep["return"] == pytest.approx(float(np.sum(ep["reward"])))
    # physics rows every step at 240 Hz: the reset row plus 12 per control step of 0.05 s
    assert ep["t"].shape == (1 + 12 * STEPS,) and np.allclose(np.diff(ep["t"]), 1 / 240)
    for key in ("cable_x", "wrench_world", "end_forces", "joint_q", "ee_pos"):
        assert key in ep and len(ep[key]) == len(ep["t"])
    # the settled grasp at reset: the two ends carry the cable's weight (static balance)
    weight = float(ep["params"]["mass"]) * 9.80665
    assert ep["end_forces"][0, :, 2].sum() == pytest.approx(-weight, rel=0.01)


def test_the_recorded_rows_are_the_environment_s_own_readings(rollouts):
    """The wrench observed after control step k is the sensor reading recorded at that step's end time."""
    out, _ = rollouts
    ds = Dataset(out)
    ep = ds.load(ds.records[0])
    for k, t in enumerate(ep["control_t"]):
        row = int(np.argmin(np.abs(ep["t"] - t)))
        assert abs(ep["t"][row] - t) < 1e-9
        assert np.allclose(ep["obs_wrench"][k + 1], ep["wrench_world"][row], atol=1e-5)  # float32 observation


def test_a_rollout_reproduces_from_its_seed(rollouts):
    """Replaying episode 1's seed with the same policy in a fresh environment gives the stored rewards."""
    out, _ = rollouts
    ep = Dataset(out).load(Dataset(out).records[1])
    env = gym.make(ENV, max_episode_steps=STEPS)
    obs, _ = env.reset(seed=int(ep["seed"]))
    rewards = []
    for _ in range(STEPS):
        obs, r, *_ = env.step(scripted_action(obs))
        rewards.append(r)
    env.close()
    assert np.array_equal(np.asarray(rewards), ep["reward"])


def test_resume_adds_episodes_and_another_policy_is_refused(rollouts, tmp_path):
    out, _ = rollouts
    before = (out / "episode_000000.h5").stat().st_mtime_ns
    with pytest.raises(ParameterError, match="--resume"):
        record_rollouts(ENV, "scripted", out, 3, seed=5, record_rate=240.0,
                        env_kwargs={"max_episode_steps": STEPS}, progress=False)
    res = record_rollouts(ENV, "scripted", out, 3, seed=5, record_rate=240.0,
                          env_kwargs={"max_episode_steps": STEPS}, resume=True, progress=False)
    assert res.ran == 1 and res.done == 3
    assert (out / "episode_000000.h5").stat().st_mtime_ns == before  # finished episodes untouched
    with pytest.raises(ParameterError, match="different spec"):
        record_rollouts(ENV, "zero", out, 3, seed=5, record_rate=240.0,
                        env_kwargs={"max_episode_steps": STEPS}, resume=True, progress=False)


@pytest.mark.parametrize("args, key", [
    (["--policy", "nonsense"], "--policy"),
    (["--policy", "os:nothing_here"], "--policy"),
    (["--episodes", "0"], "--episodes"),
    (["--record-rate", "-1"], "--record-rate"),
])
def test_bad_rollout_arguments_give_one_line_and_exit_code_2(tmp_path, args, key):
    cmd = [sys.executable, "-m", "bullet_dlo.cli", "rollouts", ENV, "--out", str(tmp_path / "r"), "--episodes", "1",
           "--max-steps", "2", *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip() and "pybullet build time" not in ln]
    assert len(lines) == 1 and key in lines[0], proc.stderr


def test_final_info_is_json(rollouts):
    out, _ = rollouts
    ep = Dataset(out).load(Dataset(out).records[0])
    info = json.loads(ep["final_info"])
    assert set(info) >= {"unstable", "tension", "tension_target"}


@pytest.mark.parametrize("env_id", ["bullet_dlo/Shaping-v0", "bullet_dlo/Routing-v0"])
def test_every_environment_records_its_scripted_and_a_seeded_random_policy(env_id, tmp_path):
    """Each environment names its scripted baseline (stateful ones are reset per episode); random rollouts
    repeat with the seed."""
    kwargs = {"max_episode_steps": 3}
    returns = []
    for run in ("a", "b"):
        res = record_rollouts(env_id, "random", tmp_path / run, 1, seed=3, env_kwargs=kwargs, progress=False)
        assert res.complete
        returns.append(Dataset(tmp_path / run).load(Dataset(tmp_path / run).records[0])["action"])
    assert np.array_equal(returns[0], returns[1])
    res = record_rollouts(env_id, "scripted", tmp_path / "s", 1, seed=3, env_kwargs=kwargs, progress=False)
    ep = Dataset(tmp_path / "s").load(Dataset(tmp_path / "s").records[0])
    assert res.complete and ep["policy"] == "scripted" and np.abs(ep["action"]).max() > 0.0
