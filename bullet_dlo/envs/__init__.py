"""Gymnasium environments for two-arm cable manipulation with force feedback.

Registered under the ``bullet_dlo/`` namespace as soon as both ``bullet_dlo`` and ``gymnasium``
are imported (in either order; :mod:`bullet_dlo._gym_registration`), so::

    import gymnasium as gym
    import bullet_dlo  # noqa: F401  (registers the environments)
    env = gym.make("bullet_dlo/TensionTracking-v0")

* ``bullet_dlo/TensionTracking-v0`` (:class:`~.tension.TensionTrackingEnv`): both grippers hold
  the cable; follow a target axial tension profile while carrying the cable's midpoint to a point.
* ``bullet_dlo/Shaping-v0`` (:class:`~.shaping.ShapingEnv`): bring the held cable to a target shape.
* ``bullet_dlo/Routing-v0`` (:class:`~.routing.RoutingEnv`): the left end held fixed, the right
  gripper routes the cable around 1-2 pegs on their required sides and into a clip's slot (the
  cable's own contact model against the pegs and clip boxes).

**Vector environments** (Gymnasium 1.x): every id works with ``gymnasium.make_vec``::

    envs = gym.make_vec("bullet_dlo/TensionTracking-v0", num_envs=4, vectorization_mode="async")

``"sync"`` (the default: every sub-environment in this process, one after another) or ``"async"``
(one worker process each). Each sub-environment is its own PyBullet world; a step's time is
PyBullet's stepping and IK (C calls, one world at a time) and the cable kernels, so there is no
native batched vector env: in one process it could only run the worlds one after another, as
``"sync"`` does. ``"sync"`` is the choice on a busy machine and to debug: on 2 cores under a load
of about 4, TensionTracking-v0 ran 206 env-steps/s with ``"sync"`` against 144 with ``"async"``
(2 sub-environments; 198 against 156 with 4). ``"async"`` can only pay off with idle cores, one
per sub-environment: measure on yours before choosing it. Both use ``AutoresetMode.NEXT_STEP``, the mode every environment declares in
``metadata["autoreset_mode"]``; ``vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}`` also works.

The common machinery (arms, actions, observations, randomisation, rendering) is
:class:`~.dual_arm_env.DualArmEnv`. Importing this package does not import Gymnasium or PyBullet:
the classes load on first use.
"""
from __future__ import annotations

import importlib

from bullet_dlo._gym_registration import ENV_IDS, register_envs

_LAZY = {
    "DualArmEnv": "bullet_dlo.envs.dual_arm_env",
    "TensionTrackingEnv": "bullet_dlo.envs.tension",
    "ShapingEnv": "bullet_dlo.envs.shaping",
    "RoutingEnv": "bullet_dlo.envs.routing",
    "EnvRandomisation": "bullet_dlo.envs.randomisation",
}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ENV_IDS", "register_envs", *_LAZY]
