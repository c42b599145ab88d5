"""The image renderer of a PyBullet client: TinyRenderer or the EGL plugin.

The EGL plugin only draws bodies created after it was loaded, so it belongs to the world's
set-up (:class:`bullet_dlo.bullet.world.BulletWorld` takes ``renderer=``); cameras, frames
and video live in :mod:`bullet_dlo.render`.
"""
from __future__ import annotations

import pkgutil

import numpy as np
import pybullet as pb

from bullet_dlo.core.enums import Renderer as RendererName, name_of


RENDERERS = RendererName.names()


class RenderError(RuntimeError):
    """The renderer produced no usable image."""


class Renderer:
    """The image renderer of one PyBullet client.

    Attributes: name (``tiny`` or ``egl``), note (why this renderer was chosen), flag (the
    ``renderer=`` value for ``getCameraImage``).
    """

    def __init__(self, client: int, renderer: str = "auto"):
        renderer = name_of("renderer", renderer, RendererName)
        self.client = client
        self.plugin = -1
        self.name = "tiny"
        self.note = "TinyRenderer requested"
        if renderer in ("auto", "egl"):
            error = self._load_egl()
            if error is None:
                self.name, self.note = "egl", "EGL plugin loaded"
            elif renderer == "egl":
                raise RenderError(f"renderer='egl' is not available on this machine: {error}; use renderer='tiny'")
            else:
                self.note = f"EGL unavailable ({error}); using TinyRenderer"
        self.flag = pb.ER_BULLET_HARDWARE_OPENGL if self.name == "egl" else pb.ER_TINY_RENDERER

    def _load_egl(self) -> str | None:
        """Try the EGL plugin; return None on success or the reason it failed."""
        loader = pkgutil.get_loader("eglRenderer")
        if loader is None:
            return "the eglRenderer module is not installed with pybullet"
        path = egl_plugin_path(loader)
        try:
            self.plugin = pb.loadPlugin(path, "_eglRendererPlugin", physicsClientId=self.client)
        except pb.error as err:  # pragma: no cover - depends on the machine
            return f"loadPlugin failed: {err}"
        if self.plugin < 0:
            return "the EGL plugin did not load (no EGL/GL libraries or device)"
        return None

    def check(self, rgb: np.ndarray) -> None:
        """Raise RenderError for a blank frame (no variation at all)."""
        if float(np.std(rgb)) < 1.0:
            raise RenderError(f"the {self.name} renderer returned a blank frame (was the EGL plugin unloaded, or is "
                              "the camera looking at nothing?)")


def egl_plugin_path(loader) -> str:
    """File of the EGL plugin (a function so tests can simulate a machine without it)."""
    return loader.get_filename()
