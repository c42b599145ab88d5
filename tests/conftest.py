"""Shared fixtures, and markers by layer: ``core`` tests (core, analysis, config) need no PyBullet.

``pytest -m core`` runs the numerical core's suite alone; ``tests/test_layers.py`` runs it
once with PyBullet, h5py, matplotlib and PyAV made unimportable to prove it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

CORE_DIRS = {"core", "analysis", "config"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        parts = Path(str(item.fspath)).parts
        layer = parts[parts.index("tests") + 1] if "tests" in parts else ""
        item.add_marker(pytest.mark.core if layer in CORE_DIRS else pytest.mark.bullet)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
