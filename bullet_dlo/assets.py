"""Where the project's data files are: ``robots/`` (robot descriptions), ``urdf/`` (URDF models) and the
example scene files and capture specs (``demos/scenes``, ``demos/specs``).

In the source tree they sit beside the package; a built wheel ships them inside it as
``bullet_dlo/_assets/<kind>`` (``pyproject.toml`` maps the folders there), so robots load and the
examples copy (``bullet-dlo examples DIR``) from any install, editable or not.
"""
from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent


SOURCE = {"robots": "robots", "urdf": "urdf", "scenes": "demos/scenes", "specs": "demos/specs"}
"""Where each asset kind sits in the source tree, relative to the repository root."""


def asset_dir(name: str) -> Path:
    """The folder of asset kind ``name`` (a key of :data:`SOURCE`), installed or in the source tree."""
    for candidate in (_PKG / "_assets" / name, _PKG.parent / SOURCE[name]):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"bullet_dlo asset folder {name!r} not found beside or inside the package ({_PKG})")


ROBOTS_DIR = asset_dir("robots")
URDF_DIR = asset_dir("urdf")
