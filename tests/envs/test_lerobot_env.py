"""The environments as LeRobot builds them: ``bullet_dlo/LeRobot-v0`` with LeRobot's observation keys here, and
LeRobot's own ``make_env`` / ``preprocess_observation`` on :class:`~bullet_dlo.envs.lerobot_env.BulletDLOEnv`
in a venv with lerobot (``BULLET_DLO_LEROBOT_PYTHON``; lerobot cannot be installed beside this project)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from bullet_dlo.core.validate import ParameterError  # noqa: E402
from bullet_dlo.envs.lerobot_env import LEROBOT_ID, TASKS, make  # noqa: E402

pytestmark = pytest.mark.bullet
ROOT = Path(__file__).resolve().parents[2]
KW = {"settle_time": 0.05}


def test_observation_keys_follow_the_export_layout():
    """agent_pos is per arm [joint_q, gripper_pos, gripper_quat] (the export's observation.state), wrench the two
    wrists' wrenches, environment_state the cable's points; the wrapped and the raw environment step alike."""
    env = gym.make(LEROBOT_ID, task="TensionTracking-v0", max_episode_steps=2, **KW)
    raw = gym.make("bullet_dlo/TensionTracking-v0", privileged=True, **KW)
    try:
        obs, _ = env.reset(seed=5)
        ref, _ = raw.reset(seed=5)
        j = ref["joint_q"].shape[1]
        assert set(obs) == {"agent_pos", "wrench", "environment_state"} and obs["agent_pos"].shape == (2 * (j + 7),)
        for a in range(2):
            part = obs["agent_pos"][a * (j + 7):(a + 1) * (j + 7)]
            np.testing.assert_array_equal(part, np.concatenate([ref["joint_q"][a], ref["gripper_pos"][a],
                                                                ref["gripper_quat"][a]]).astype(np.float32))
        np.testing.assert_array_equal(obs["wrench"], ref["wrench"].reshape(12).astype(np.float32))
        np.testing.assert_array_equal(obs["environment_state"], ref["cable"].reshape(-1).astype(np.float32))
        a = np.array([0.5, 0, 0, -0.5, 0, 0], np.float32)
        obs, r1, *_ = env.step(a)
        ref, r2, *_ = raw.step(a)
        assert r1 == r2 and np.array_equal(obs["wrench"], ref["wrench"].reshape(12).astype(np.float32))
        assert env.observation_space.contains(obs)
        *_, truncated, _ = env.step(a)
        assert truncated  # max_episode_steps reaches the TimeLimit as LeRobot passes it
    finally:
        env.close()
        raw.close()


def test_unknown_task_is_one_line():
    with pytest.raises(ParameterError, match="task must be one of " + ", ".join(TASKS)):
        make("Juggling-v0")


LEROBOT_PYTHON = os.environ.get("BULLET_DLO_LEROBOT_PYTHON")
SCRIPT = """
import json, sys, numpy as np
from lerobot.envs.factory import make_env
from lerobot.envs.utils import env_to_policy_features, preprocess_observation
from bullet_dlo.envs.lerobot_env import BulletDLOEnv
cfg = BulletDLOEnv(task=sys.argv[1], episode_length=3)
features = {k: list(v.shape) for k, v in env_to_policy_features(cfg).items()}
vec = make_env(cfg, n_envs=2)["bullet_dlo"][0]
obs, _ = vec.reset(seed=[1, 2])
truncated = []
for _ in range(3):
    obs, reward, terminated, trunc, _ = vec.step(np.zeros((2, *vec.single_action_space.shape), np.float32))
    truncated.append(trunc.tolist())
policy = preprocess_observation(obs)
print(json.dumps({"features": features, "policy": {k: list(v.shape) for k, v in policy.items()},
                  "state_equal": bool(np.allclose(policy["observation.state"].numpy(), obs["agent_pos"])),
                  "truncated": truncated, "autoreset": str(vec.metadata.get("autoreset_mode"))}))
"""


@pytest.mark.skipif(not LEROBOT_PYTHON, reason="set BULLET_DLO_LEROBOT_PYTHON to a Python with lerobot installed "
                    "(its own venv: lerobot pins torch<2.11 and av<16; docs/guides/environments.md says how)")
@pytest.mark.parametrize("task", ["TensionTracking-v0", "Routing-v0"])
def test_lerobot_make_env_builds_and_steps_the_environment(task, tmp_path):
    """LeRobot's make_env builds a 2-env vector of the task from BulletDLOEnv; its preprocess_observation gives
    exactly the policy features the config declares, observation.state is the env's agent_pos, and the episode
    is truncated at episode_length."""
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    run = subprocess.run([LEROBOT_PYTHON, str(script), task], capture_output=True, text=True, timeout=900, env=env,
                         cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    declared = {k: v for k, v in out["features"].items() if k != "action"}
    assert out["features"]["action"] == list(gym.make(f"bullet_dlo/{task}").action_space.shape)
    assert out["policy"] == {k: [2, *v] for k, v in declared.items()}
    assert out["state_equal"] and out["truncated"][-1] == [True, True] and out["truncated"][0] == [False, False]


def test_gymnasium_checks_and_vectorises_the_lerobot_id():
    """Gymnasium's own checker passes, and make_vec builds it (sync) with the base environment's autoreset mode."""
    from gymnasium.utils.env_checker import check_env

    env = gym.make(LEROBOT_ID, task="TensionTracking-v0", max_episode_steps=3, **KW)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()
    vec = gym.make_vec(LEROBOT_ID, num_envs=2, vectorization_mode="sync",
                       vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.NEXT_STEP},
                       task="TensionTracking-v0", max_episode_steps=3, **KW)
    try:
        obs, _ = vec.reset(seed=[1, 2])
        assert obs["agent_pos"].shape[0] == 2 and np.all(np.isfinite(obs["agent_pos"]))
        obs, reward, terminated, truncated, _ = vec.step(np.zeros((2, 6), np.float32))
        assert reward.shape == (2,) and np.all(np.isfinite(obs["wrench"]))
    finally:
        vec.close()
