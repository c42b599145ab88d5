"""Policy rollouts recorded in the dataset's episode format.

:func:`record_rollouts` runs a policy in one of the environments and writes every episode as
a dataset capture writes its episodes (:mod:`bullet_dlo.data.episode`: the same HDF5 columns
at ``record_rate``, the same manifest, status and quality flags, the same ``--resume``), so
:class:`bullet_dlo.data.reader.Dataset`, ``bullet-dlo dataset-summary`` and
``bullet-dlo fit`` read rollouts as they read captures. Each episode file adds the control
steps (m of them, a action dimensions):

============ =========================================================== ===========
column       meaning                                                     shape
============ =========================================================== ===========
control_t    time of each control step's end [s]                         (m,)
action       the action the policy gave (before the environment clips)   (m, a)
reward       the reward of that step                                     (m,)
obs_<key>    every observation entry, at reset and after each step       (m + 1, ...)
============ =========================================================== ===========

and attributes ``env_id``, ``policy``, ``return`` (sum of rewards), ``terminated``,
``truncated`` and ``final_info`` (the last step's info as JSON text). Episode i is reset with
seed ``seed + i``, so a rollout directory reproduces with the same policy. The directory's
``capture.json`` holds the :class:`RolloutSpec` (environment, its arguments and randomisation,
policy, seed, rate): a directory never mixes rollouts of two specs.

Policies: a callable ``policy(obs) -> action`` (with a ``reset(obs)`` method, it is called at
every episode's first observation), or by name: ``random`` (the action space, seeded per episode), ``scripted``
(the environment's :meth:`~bullet_dlo.envs.dual_arm_env.DualArmEnv.scripted_policy`),
``zero`` (no motion) or ``package.module:function``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

import numpy as np

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.enums import RolloutPolicy
from bullet_dlo.core.model import STANDARD_GRAVITY
from bullet_dlo.core.validate import ParameterError, check_int, check_in_range
from bullet_dlo.data.capture import CaptureResult
from bullet_dlo.data.episode import COLUMNS_NOTE, EpisodeRecorder
from bullet_dlo.data.quality import quality_issues, quality_metrics, sensor_metrics
from bullet_dlo.data.storage import (
    append_manifest,
    episode_result,
    failed_record,
    locked,
    prepare,
    read_manifest,
    version,
    write_episode,
)

Policy = Callable[[Any], np.ndarray]
POLICY_NAMES = RolloutPolicy.names()  # the built-in policies (bullet_dlo.core.enums.RolloutPolicy)


@dataclasses.dataclass(frozen=True)
class RolloutSpec:
    """What a rollout directory holds.

    env_id: the Gymnasium id; env_kwargs: its keyword arguments; randomisation: a capture spec's dict
    form; policy: the policy's name; seed: the first reset seed; record_rate: the rate the physics
    columns are recorded at [Hz].
    """

    env_id: str
    env_kwargs: dict
    randomisation: dict
    policy: str
    seed: int
    record_rate: float

    def to_dict(self) -> dict:
        return {"rollout": {"env_id": self.env_id, "env_kwargs": self.env_kwargs, "policy": self.policy,
                            "seed": self.seed, "record_rate": self.record_rate},
                "randomisation": self.randomisation}

    def digest(self) -> str:
        """Hash of the spec (a directory holds rollouts of one spec only)."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True, default=str).encode()).hexdigest()[:16]


def resolve_policy(policy: str | Policy, env) -> tuple[Policy, str]:
    """The policy as a callable and its name (see the module doc); ParameterError for an unknown name."""
    if callable(policy):
        return policy, getattr(policy, "__qualname__", type(policy).__name__)
    name = str(policy)
    if name == "random":
        return (lambda obs: env.action_space.sample()), name
    if name == "zero":
        return (lambda obs: np.zeros(env.action_space.shape, env.action_space.dtype)), name
    if name == "scripted":
        try:
            return env.unwrapped.scripted_policy(), name
        except NotImplementedError:
            raise ParameterError(f"--policy scripted: {type(env.unwrapped).__name__} has no scripted policy; "
                                 f"use one of random, zero or package.module:function") from None
    if ":" in name:
        mod, _, attr = name.partition(":")
        try:
            fn = getattr(importlib.import_module(mod), attr)
        except (ImportError, AttributeError) as err:
            raise ParameterError(f"--policy {name}: cannot load it ({err})") from None
        if not callable(fn):
            raise ParameterError(f"--policy {name} is not callable")
        return fn, name
    raise ParameterError(f"--policy must be one of {', '.join(POLICY_NAMES)} or package.module:function, got {name!r}")


def record_rollouts(env_id: str, policy: str | Policy, out: str | Path, episodes: int, *, seed: int = 0,
                    record_rate: float = 120.0, env_kwargs: dict | None = None, resume: bool = False,
                    progress: bool = True) -> CaptureResult:
    """Run ``policy`` for ``episodes`` episodes of ``env_id`` (resets with seeds seed, seed + 1, ...) and
    write them into the capture directory ``out`` (see the module doc). With ``resume``, episodes
    already finished there are kept. Returns the counts as :func:`bullet_dlo.data.capture.capture` does."""
    import time

    import gymnasium as gym
    from tqdm import tqdm

    import bullet_dlo  # noqa: F401  (registers the environments)

    episodes = check_int("--episodes", episodes, 1, 100_000)
    seed = check_int("--seed", seed, 0, 2**31 - 1)
    record_rate = check_in_range("--record-rate [Hz]", record_rate, 0.01, 1e5)
    env_kwargs = dict(env_kwargs or {})
    if env_id not in gym.registry or not env_id.startswith("bullet_dlo/"):  # others lack the cable and sensors
        known = ", ".join(k for k in gym.registry if k.startswith("bullet_dlo/"))
        what = "not one of bullet_dlo's environments" if env_id in gym.registry else "unknown environment"
        raise ParameterError(f"{what} {env_id!r}: rollouts record the cable and the wrist sensors; known: {known}")
    env = gym.make(env_id, **env_kwargs)
    try:
        fn, name = resolve_policy(policy, env)
        spec = RolloutSpec(env_id, env_kwargs, env.unwrapped.randomisation.spec.to_dict(), name, seed, record_rate)
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        tic = time.perf_counter()
        with locked(out):
            records = prepare(spec, out, resume, episodes=episodes)
            todo = [i for i in range(episodes) if records.get(i, {}).get("status") not in ("ok", "flagged")]
            for index in tqdm(todo, desc="rollouts", unit="ep", disable=not progress):
                append_manifest(out, _run_safely(env, fn, spec, index, out))
        final = read_manifest(out)
    finally:
        env.close()
    statuses = [final[i]["status"] for i in range(episodes) if i in final]
    failed = tuple(i for i in range(episodes) if final.get(i, {}).get("status") == "failed")
    missing = tuple(i for i in range(episodes) if i not in final)
    return CaptureResult(out, len(statuses), len(todo), len(failed), statuses.count("flagged"),
                         time.perf_counter() - tic, failed, missing)


def _run_safely(env, policy: Policy, spec: RolloutSpec, index: int, out: Path) -> dict:
    """:func:`run_rollout` with an exception turned into a failed record (the next episode still runs)."""
    try:
        return run_rollout(env, policy, spec, index, out)
    except ParameterError:
        raise
    except Exception as err:  # noqa: BLE001 - recorded in the manifest, not swallowed
        return failed_record(index, f"{type(err).__name__}: {err}")


def run_rollout(env, policy: Policy, spec: RolloutSpec, index: int, out: Path) -> dict:
    """One episode of ``policy`` in ``env`` (reset seed ``spec.seed + index``), written to ``out``;
    returns its manifest record."""
    obs, _ = env.reset(seed=spec.seed + index)
    env.action_space.seed(spec.seed + index)  # the random policy's draws repeat with the episode
    if hasattr(policy, "reset"):  # a stateful policy plans from the episode's first observation
        policy.reset(obs)
    inner = env.unwrapped
    physics = inner.physics
    every = max(1, int(round(1.0 / (spec.record_rate * physics.world.dt))))
    view = SimpleNamespace(world=physics.world, cable=physics.cable, sensors=inner.sensors, robots=physics.robots)
    recorder = EpisodeRecorder(view, every, CaptureSpec())  # CaptureSpec(): no camera frames
    recorder.record_row()  # the state at reset: the settled, loaded grasp
    physics.world.after_step.append(recorder)
    observations = {k: [v] for k, v in obs.items()}
    control_t, actions, rewards = [], [], []
    info: dict = {}
    done = terminated = truncated = False
    while not done:
        action = np.asarray(policy(obs))
        obs, reward, terminated, truncated, info = env.step(action)
        control_t.append(physics.world.time)
        actions.append(action.astype(float).reshape(-1))
        rewards.append(float(reward))
        for k, v in obs.items():
            observations[k].append(v)
        done = terminated or truncated
    data = recorder.arrays()
    data.update(control_t=np.asarray(control_t), action=np.asarray(actions), reward=np.asarray(rewards))
    data.update({f"obs_{k}": np.asarray(v) for k, v in observations.items()})
    cable = physics.cable
    stable = cable.stable and not info.get("unstable", False)
    t_bad = cable.time_to_instability
    check = inner.observation.check
    metrics = quality_metrics(data["t"], data["wrench_world"][:, :, :3], data["end_forces"]) | sensor_metrics(check)
    randomisation = CaptureSpec.from_dict(spec.randomisation)
    weight = float(np.sum(cable.arrays.mass)) * float(np.linalg.norm(STANDARD_GRAVITY))
    issues = quality_issues(metrics, weight, randomisation.max_sensor_model_rms,
                            randomisation.max_hf_energy) + check.failures() if stable else []
    params, decision = dict(inner.draw.params), dict(inner.draw.decision)
    attrs = {"params": params, "decision": decision, "metrics": metrics, "seed": spec.seed + index, "episode": index,
             "version": version(), "sensor_compensation": inner.sensors[0].compensation,
             "sensor_transmitted": inner.sensors[0].TRANSMITTED,
             "spec_digest": spec.digest(), "stable": bool(stable),
             "time_to_instability": -1.0 if t_bad is None else float(t_bad), "columns": COLUMNS_NOTE,
             "env_id": spec.env_id, "policy": spec.policy, "return": float(np.sum(rewards)),
             "terminated": bool(terminated), "truncated": bool(truncated),
             "final_info": json.dumps(_jsonable(info), sort_keys=True),
             "obstacles": json.dumps(_jsonable(inner.obstacles()) if hasattr(inner, "obstacles") else [])}
    name = write_episode(out, index, data, attrs)
    reason = info.get("reason") if not stable else None
    return episode_result(index, name, stable, t_bad, reason, params, decision, metrics, issues)


def _jsonable(value: Any) -> Any:
    """``value`` with numpy scalars and arrays made plain (non-finite numbers become None)."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, (np.integer, np.bool_)):
        return value.item()
    return value
