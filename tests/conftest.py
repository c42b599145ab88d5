"""Shared fixtures, and markers by layer: ``core`` tests (core, analysis, config) need no PyBullet.

``pytest -m core`` runs the numerical core's suite alone; ``tests/test_layers.py`` runs it
once with PyBullet, h5py, matplotlib and PyAV made unimportable to prove it, and a session that
selects that test leaves the core tests to it (they are deselected in the session itself).
"""
from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

CORE_DIRS = {"core", "analysis", "config"}


CORE_RUNNER = "test_core_suite_passes_without_pybullet_h5py_matplotlib_av_cv2"
"""The test of ``tests/test_layers.py`` that runs the whole core suite in a process without PyBullet."""


def _selects_a_directory(config) -> bool:
    """True when the session runs a test directory (or the default, the whole suite), not named files."""
    args = [a.split("::")[0] for a in config.args] or ["."]
    return any(Path(config.invocation_params.dir, a).is_dir() for a in args)


def pytest_sessionstart(session):
    """With pytest-xdist (``-n N``): compile the shared Numba kernels into the cache before the workers
    start (``tests/warm_kernels.py``, its two parts in parallel). On a cold cache the workers, the core
    runner and the demos' subprocesses otherwise compile the same kernels at the same time, each."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return  # a worker (the controller warmed the cache), or one process (it compiles each kernel once)
    if os.environ.get("NUMBA_DISABLE_JIT", "0") != "0":
        return
    if not _selects_a_directory(config):
        return  # a few files or tests: their own kernels compile faster than the whole warm-up (~3 min)
    script = Path(__file__).with_name("warm_kernels.py")
    parts = [subprocess.Popen([sys.executable, str(script), part], stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for part in ("core", "bullet")]
    for part in parts:
        _, err = part.communicate()
        if part.returncode:  # the tests that use these kernels will fail and say why; warn only
            warnings.warn(f"warming the kernel cache failed ({part.args[-1]}): {err.strip()[-400:]}")


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
        # the runner is the suite's longest test (minutes): first, so that a worker starts it at once and
        # the other tests fill the other worker, instead of it running alone at the end
        items.sort(key=lambda item: item.name != CORE_RUNNER)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
