"""The demos are scripts, not a package: ``load("edge_slide")`` imports ``demos/edge_slide.py`` as a module so that a
test can call its functions."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

DEMOS = Path(__file__).resolve().parents[2] / "demos"


def load(name: str) -> ModuleType:
    """The module of ``demos/<name>.py`` (executed once per call; its ``main`` does not run)."""
    spec = importlib.util.spec_from_file_location(name, DEMOS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
