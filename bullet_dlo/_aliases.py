"""Old flat module paths (``bullet_dlo.scene``, ``bullet_dlo.dual_arm``, ...) as aliases of their new homes.

Release 0.2 moved the 27 flat modules into layered subpackages. For one release the old
paths still import (with a DeprecationWarning naming the new path), so scripts written
against 0.1 keep working. ``bullet_dlo.simulate`` is not aliased: that name is the
function :func:`bullet_dlo.simulate`; the engine module is ``bullet_dlo.core.engine``.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

OLD_TO_NEW = {
    "bullet_dlo.params": "bullet_dlo.core.spec",
    "bullet_dlo.forces": "bullet_dlo.core.kernels.forces",
    "bullet_dlo.linalg": "bullet_dlo.core.kernels.banded",
    "bullet_dlo.model": "bullet_dlo.core.model",
    "bullet_dlo.boundary": "bullet_dlo.core.boundary",
    "bullet_dlo.integrators": "bullet_dlo.core.integrators",
    "bullet_dlo.stability": "bullet_dlo.core.stability",
    "bullet_dlo.statics": "bullet_dlo.core.statics",
    "bullet_dlo.validation": "bullet_dlo.analysis.closed_forms",
    "bullet_dlo.paper": "bullet_dlo.analysis.study",
    "bullet_dlo.resolve": "bullet_dlo.analysis.resolve",
    "bullet_dlo.scene": "bullet_dlo.config.scene",
    "bullet_dlo.randomization": "bullet_dlo.config.capture",
    "bullet_dlo.bullet_scene": "bullet_dlo.bullet.world",
    "bullet_dlo.bullet_cable": "bullet_dlo.bullet.cable",
    "bullet_dlo.sensors": "bullet_dlo.robots.sensors",
    "bullet_dlo.dual_arm": "bullet_dlo.robots.dual_arm",
    "bullet_dlo.video": "bullet_dlo.render.video",
    "bullet_dlo.recording": "bullet_dlo.render.pipeline",
    "bullet_dlo.dataset": "bullet_dlo.data",
    "bullet_dlo.peers": "bullet_dlo.bench.peers",
}


class _AliasFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves an old module path to the module at its new path."""

    def find_spec(self, fullname, path, target=None):
        if fullname in OLD_TO_NEW:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        new = OLD_TO_NEW[spec.name]
        warnings.warn(f"{spec.name} moved to {new}; the old path goes in the next release",
                      DeprecationWarning, stacklevel=3)
        return importlib.import_module(new)  # the real module: one object under two names

    def exec_module(self, module) -> None:  # already executed under its new name
        return None


def install() -> None:
    """Register the alias finder once."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
