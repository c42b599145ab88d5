"""Shared fixtures, and markers by layer: ``core`` tests (core, analysis, config) need no PyBullet.

``pytest -m core`` runs the numerical core's suite alone; ``tests/test_layers.py`` runs it
once with PyBullet, h5py, matplotlib and PyAV made unimportable to prove it, and a session that
selects that test leaves the core tests to it (they are deselected in the session itself).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

CORE_DIRS = {"core", "analysis", "config"}


CORE_RUNNER = "test_core_suite_passes_without_pybullet_h5py_matplotlib_av_cv2"
"""The test of ``tests/test_layers.py`` that runs the whole core suite in a process without PyBullet."""


def pytest_collection_modifyitems(config, items):
    for item in items:
        parts = Path(str(item.fspath)).parts
        layer = parts[parts.index("tests") + 1] if "tests" in parts else ""
        item.add_marker(pytest.mark.core if layer in CORE_DIRS else pytest.mark.bullet)
    # When the core runner is selected, the core tests run inside it (all of them, without PyBullet,
    # and it fails unless every one passes): running them here as well would cost the suite twice.
    if any(item.name == CORE_RUNNER for item in items):
        inside = [item for item in items if item.get_closest_marker("core")]
        if inside:
            config.hook.pytest_deselected(items=inside)
            items[:] = [item for item in items if not item.get_closest_marker("core")]


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
