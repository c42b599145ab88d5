"""The environments through LeRobot's ``make_env``: an ``EnvConfig`` and the observations LeRobot reads.

LeRobot (0.4) builds simulated environments from an ``EnvConfig`` subclass registered under a type
name (``lerobot.envs.factory.make_env``: ``gym.make(cfg.gym_id, **cfg.gym_kwargs)`` in a vector
env), and its evaluation loop (``lerobot.envs.utils.preprocess_observation``) reads three
observation keys: ``agent_pos`` -> ``observation.state``, ``environment_state`` ->
``observation.environment_state`` and ``pixels`` -> ``observation.image``. :class:`LeRobotObservation`
maps an environment's observation onto them in the layout of ``bullet-dlo export lerobot``
(:mod:`bullet_dlo.data.lerobot`), so a policy trained on an exported dataset is evaluated on the
environment it came from:

* ``agent_pos`` (2 (j + 7),): per arm (left = the cable's first end) its joint positions [rad],
  grasp position [m] and grasp quaternion (x, y, z, w) — the export's ``observation.state``;
* ``environment_state`` (3 K,): the cable at K points [m] (``privileged=True``, the default here) —
  the export's ``observation.environment_state`` with ``--cable-points K``;
* ``wrench`` (12,): both wrists' wrenches [N, N m], sensor frame, left then right — the export's
  ``observation.wrench.left`` / ``.right``. LeRobot 0.4's ``preprocess_observation`` does not pass
  this key on: a policy that uses the wrenches needs a processor step that does;
* ``pixels`` (H, W, 3) uint8 when ``camera="rgb"``.

:class:`BulletDLOEnv` is defined when ``lerobot`` is importable (it lives in its own venv: lerobot
0.4.4 pins torch < 2.11 and av < 16); :func:`make` is the gym entry point it names
(``bullet_dlo/LeRobot-v0``, ``task`` one of the environment ids without the namespace)::

    from lerobot.envs.factory import make_env
    from bullet_dlo.envs.lerobot_env import BulletDLOEnv

    envs = make_env(BulletDLOEnv(task="TensionTracking-v0"), n_envs=2)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from bullet_dlo._gym_registration import ENV_IDS
from bullet_dlo.core.validate import ParameterError

TASKS = tuple(env_id.split("/", 1)[1] for env_id in ENV_IDS)
"""The environments LeRobot can build: ids without the ``bullet_dlo/`` namespace."""
LEROBOT_ID = "bullet_dlo/LeRobot-v0"


class LeRobotObservation(gym.ObservationWrapper):
    """An environment's dict observation as LeRobot's evaluation loop reads it (see the module doc)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        inner = env.observation_space
        j = inner["joint_q"].shape[1]
        out = {"agent_pos": spaces.Box(-np.inf, np.inf, (2 * (j + 7),), np.float32),
               "wrench": spaces.Box(-np.inf, np.inf, (12,), np.float32)}
        if "cable" in inner.spaces:
            out["environment_state"] = spaces.Box(-np.inf, np.inf, (int(np.prod(inner["cable"].shape)),), np.float32)
        if "rgb" in inner.spaces:
            out["pixels"] = inner["rgb"]
        self.observation_space = spaces.Dict(out)

    def observation(self, obs: dict) -> dict:
        state = np.concatenate([np.concatenate([obs["joint_q"][a], obs["gripper_pos"][a], obs["gripper_quat"][a]])
                                for a in range(2)])
        out = {"agent_pos": state.astype(np.float32), "wrench": np.asarray(obs["wrench"], np.float32).reshape(12)}
        if "environment_state" in self.observation_space.spaces:
            out["environment_state"] = np.asarray(obs["cable"], np.float32).reshape(-1)
        if "pixels" in self.observation_space.spaces:
            out["pixels"] = obs["rgb"]
        return out


def make(task: str = "TensionTracking-v0", privileged: bool = True, **kwargs) -> gym.Env:
    """The environment ``bullet_dlo/<task>`` (its kwargs) with LeRobot's observation keys; ``privileged``
    defaults to True here so that ``environment_state`` (the cable) is there, as in an exported dataset."""
    if task not in TASKS:
        raise ParameterError(f"task must be one of {', '.join(TASKS)}, got {task!r}")
    entry, _ = ENV_IDS[f"bullet_dlo/{task}"]
    module, name = entry.split(":")
    import importlib

    cls = getattr(importlib.import_module(module), name)
    return LeRobotObservation(cls(privileged=privileged, **kwargs))


def register() -> None:
    """Register :data:`LEROBOT_ID` with Gymnasium (done on import of this module)."""
    if LEROBOT_ID not in gym.registry:
        gym.register(id=LEROBOT_ID, entry_point="bullet_dlo.envs.lerobot_env:make")


register()

try:  # the EnvConfig exists only where lerobot is installed
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.envs.configs import EnvConfig
except ImportError:  # pragma: no cover - exercised where lerobot is absent
    EnvConfig = None

if EnvConfig is not None:

    @EnvConfig.register_subclass("bullet_dlo")
    @dataclass
    class BulletDLOEnv(EnvConfig):
        """LeRobot's config of a bullet_dlo environment: ``task`` (a :data:`TASKS` entry), ``fps`` its control
        rate [Hz] (1 / control_dt), ``episode_length`` [control steps], the cable at ``shape_points`` points,
        ``camera`` None or ``"rgb"`` at ``image_size`` (width, height) [px], ``robots`` (None: the environment's
        own draw). ``features`` and ``features_map`` follow the observation layout of the module doc."""

        task: str | None = "TensionTracking-v0"
        fps: int = 20
        episode_length: int = 100
        shape_points: int = 10
        camera: str | None = None
        image_size: tuple[int, int] = (64, 64)
        features: dict = field(default_factory=dict)
        features_map: dict = field(default_factory=dict)

        def __post_init__(self) -> None:
            if self.task not in TASKS:
                raise ParameterError(f"task must be one of {', '.join(TASKS)}, got {self.task!r}")
            probe = make(self.task, **{k: v for k, v in self.gym_kwargs.items() if k not in ("task", "max_episode_steps")})
            spaces_ = probe.observation_space  # the constructor builds the spaces only (no world until reset)
            self.features = {"action": PolicyFeature(type=FeatureType.ACTION, shape=probe.action_space.shape),
                             "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=spaces_["agent_pos"].shape),
                             "environment_state": PolicyFeature(type=FeatureType.ENV,
                                                                shape=spaces_["environment_state"].shape)}
            probe.close()
            self.features_map = {"action": "action", "agent_pos": "observation.state",
                                 "environment_state": "observation.environment_state"}
            if self.camera == "rgb":
                w, h = self.image_size
                self.features["pixels"] = PolicyFeature(type=FeatureType.VISUAL, shape=(h, w, 3))
                self.features_map["pixels"] = "observation.image"

        @property
        def package_name(self) -> str:
            return "bullet_dlo.envs.lerobot_env"  # imported by make_env when the id is not registered yet

        @property
        def gym_id(self) -> str:
            return LEROBOT_ID

        @property
        def gym_kwargs(self) -> dict:
            kw = {"task": self.task, "control_dt": 1.0 / self.fps, "max_episode_steps": self.episode_length,
                  "shape_points": self.shape_points, "camera": self.camera}
            if self.camera is not None:
                kw["image_size"] = tuple(self.image_size)
            return kw
