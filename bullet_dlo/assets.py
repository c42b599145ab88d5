"""Where the project's data files are: ``robots/`` (robot descriptions) and ``urdf/`` (URDF models).

In the source tree they sit beside the package; a built wheel ships them inside it as
``bullet_dlo/_assets/robots`` and ``bullet_dlo/_assets/urdf`` (``pyproject.toml`` maps the
top-level folders there), so robots load from any install, editable or not.
"""
from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent


def asset_dir(name: str) -> Path:
    """The folder of asset kind ``name`` (``"robots"`` or ``"urdf"``), installed or in the source tree."""
    for candidate in (_PKG / "_assets" / name, _PKG.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"bullet_dlo asset folder {name!r} not found beside or inside the package ({_PKG})")


ROBOTS_DIR = asset_dir("robots")
URDF_DIR = asset_dir("urdf")
