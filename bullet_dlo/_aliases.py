"""Old flat module paths (``bullet_dlo.scene``, ``bullet_dlo.dual_arm``, ...) as aliases of their new homes.

Release 0.2 moved the 27 flat modules into layered subpackages. For one release the old
paths still import, with a DeprecationWarning that names the new path and points at the
line that asked for the old one, so scripts written against 0.1 keep working. An alias is
the real module under a second name: ``bullet_dlo.scene is bullet_dlo.config.scene``, and
the real module keeps its own ``__name__`` and ``__spec__``.

Four 0.1 modules became subpackages of the same name (``robots``, ``render``, ``bench``,
``cli``) and need no alias. ``bullet_dlo.simulate`` is not a module: that name is the
function :func:`bullet_dlo.simulate` (as it already was after ``import bullet_dlo`` in 0.1);
the engine module is ``bullet_dlo.core.engine``.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from types import FrameType, ModuleType

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
    "bullet_dlo.bench_cli": "bullet_dlo.cli.bench",
}

SIMULATE_IS_A_FUNCTION = ("bullet_dlo.simulate is the function bullet_dlo.simulate, not a module; "
                          "import it with 'from bullet_dlo import simulate' (the engine module is bullet_dlo.core.engine)")

def _is_machinery(frame: FrameType) -> bool:
    """A frame of the import system or of this package's own lookup (``bullet_dlo.__getattr__``, this module)."""
    name = frame.f_globals.get("__name__", "")
    return name in ("importlib", "bullet_dlo", __name__) or name.startswith("importlib.")


def _requesting_frame() -> FrameType | None:
    """The innermost frame of the code that asked for the old path (None if there is none)."""
    frame = sys._getframe(1)
    while frame is not None and _is_machinery(frame):
        frame = frame.f_back
    return frame


def _warn_moved(old: str, new: str) -> None:
    """DeprecationWarning attributed to the line that imported ``old`` (so the default filters apply to it)."""
    message = f"{old} moved to {new}; the old path goes in the next release"
    frame = _requesting_frame() or sys._getframe(1)
    warnings.warn_explicit(message, DeprecationWarning, filename=frame.f_code.co_filename, lineno=frame.f_lineno,
                           module=frame.f_globals.get("__name__", "__main__"),
                           registry=frame.f_globals.setdefault("__warningregistry__", {}))


class _AliasFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves an old module path to the module at its new path."""

    def find_spec(self, fullname, path, target=None):
        if fullname == "bullet_dlo.simulate":
            raise ModuleNotFoundError(SIMULATE_IS_A_FUNCTION, name=fullname)
        if fullname in OLD_TO_NEW:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        new = OLD_TO_NEW[spec.name]
        _warn_moved(spec.name, new)
        real = importlib.import_module(new)
        spec.loader_state = real.__spec__  # the import system stamps the alias spec on the module next
        return real  # one module object under two names

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = module.__spec__.loader_state  # already executed under its new name: restore its spec


def install() -> None:
    """Register the alias finder once."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
