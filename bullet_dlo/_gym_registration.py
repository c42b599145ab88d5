"""Registering the environments of :mod:`bullet_dlo.envs` with Gymnasium, without importing Gymnasium or them.

A root module rather than part of ``bullet_dlo.envs``: the package's ``__init__`` imports it,
and every layer imports the package, so it must name the environments without importing them.

``import bullet_dlo`` calls :func:`register_when_gymnasium_loads`: if Gymnasium is already
imported, the environments are registered now; otherwise a one-shot import hook registers
them right after Gymnasium's own first import. Entry points are strings, so nothing of the
environments (PyBullet, the arms) loads until ``gymnasium.make``. A program that never
imports Gymnasium pays nothing (``import bullet_dlo.core`` stays as light as before).
"""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys

ENV_IDS = {
    "bullet_dlo/TensionTracking-v0": ("bullet_dlo.envs.tension:TensionTrackingEnv", 100),
    "bullet_dlo/Shaping-v0": ("bullet_dlo.envs.shaping:ShapingEnv", 100),
    "bullet_dlo/Routing-v0": ("bullet_dlo.envs.routing:RoutingEnv", 250),
}
"""Environment id -> (entry point, episode length in control steps: the TimeLimit's ``max_episode_steps``)."""


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` with Gymnasium (ids already registered are left alone)."""
    import gymnasium

    for env_id, (entry_point, max_steps) in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, max_episode_steps=max_steps)


class _RegisterAfterImport(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds ``gymnasium`` once, lets its own loader run, then calls :func:`register_envs`."""

    def __init__(self) -> None:
        self._inner: importlib.abc.Loader | None = None

    def find_spec(self, fullname, path, target=None):
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)  # one shot; the real finders locate the package
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        self._inner, spec.loader = spec.loader, self
        return spec

    def create_module(self, spec):
        return self._inner.create_module(spec)

    def exec_module(self, module) -> None:
        module.__spec__.loader = module.__loader__ = self._inner  # as if loaded without us
        self._inner.exec_module(module)
        register_envs()


def register_when_gymnasium_loads() -> None:
    """Register now if Gymnasium is imported, else as soon as it is (nothing if it is not installed)."""
    if "gymnasium" in sys.modules:
        register_envs()
    elif importlib.util.find_spec("gymnasium") is not None:
        if not any(isinstance(f, _RegisterAfterImport) for f in sys.meta_path):
            sys.meta_path.insert(0, _RegisterAfterImport())
