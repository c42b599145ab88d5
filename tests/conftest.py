"""Shared fixtures, and markers by layer: ``core`` tests (core, analysis, config) need no PyBullet.

``pytest -m core`` runs the numerical core's suite alone; ``tests/test_layers.py`` runs it
once with PyBullet, h5py, matplotlib and PyAV made unimportable to prove it, and a session that
selects that test leaves the core tests to it (they are deselected in the session itself).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import core_runner  # tests/core_runner.py

CORE_DIRS = {"core", "analysis", "config"}


_STARTED: list[subprocess.Popen] = []  # the core suite's run started by this session (pytest_sessionstart)

CORE_RUNNER = "test_core_suite_passes_without_pybullet_h5py_matplotlib_av_cv2"
"""The test of ``tests/test_layers.py`` that runs the whole core suite in a process without PyBullet."""


def _selects_a_directory(config) -> bool:
    """True when the session runs a test directory (or the default, the whole suite), not named files."""
    args = [a.split("::")[0] for a in config.args] or ["."]
    return any(Path(config.invocation_params.dir, a).is_dir() for a in args)


def pytest_sessionstart(session):
    """With pytest-xdist (``-n N``): compile the shared Numba kernels into the cache before the workers
    start (``tests/warm_kernels.py``, its parts in parallel). On a cold cache the workers, the core
    runner and the demos' subprocesses otherwise meet the same cold kernels at once: each is compiled once (the
    kernels are locked between processes, ``bullet_dlo/_numba_cache.py``) while the others wait for it."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return  # a worker (the controller warmed the cache), or one process (it compiles each kernel once)
    if os.environ.get("NUMBA_DISABLE_JIT", "0") != "0":
        return
    if not _selects_a_directory(config):
        return  # a few files or tests: their own kernels compile faster than the whole warm-up (~3 min)
    warm = ["core", "bullet", "step"]
    if _selects_the_core_runner(config):
        # the core suite starts now, beside the Bullet parts, and compiles the core's kernels itself
        # (tests/core_runner.py); the core part would compile them first, before the suite could start
        out = tempfile.mkdtemp(prefix="bullet_dlo_core_suite_")
        os.environ[core_runner.ENV] = out  # set before pytest-xdist starts the workers: the runner test reads it
        _STARTED.append(subprocess.Popen([sys.executable, core_runner.__file__, out], stdout=subprocess.DEVNULL,
                                         stderr=subprocess.DEVNULL))
        warm.remove("core")
    script = Path(__file__).with_name("warm_kernels.py")
    start = time.monotonic()
    logs = [tempfile.TemporaryFile(mode="w+") for _ in warm]
    parts = [subprocess.Popen([sys.executable, str(script), part], stdout=subprocess.DEVNULL, stderr=log, text=True)
             for part, log in zip(warm, logs)]
    ended = _wait_timed(parts, start)
    report = session.config.pluginmanager.get_plugin("terminalreporter")
    if report is not None:  # (where CI's time goes: the workers start when the last part ends)
        report.write_line("kernel warm-up: " + ", ".join(f"{name} part ended at {t:.0f} s ({cpu:.0f} s of CPU)"
                                                        for name, (t, cpu) in zip(warm, ended))
                          + (", the core suite runs beside them" if _STARTED else ""))
    for part, log in zip(parts, logs):
        if part.returncode:  # the tests that use these kernels will fail and say why; warn only
            log.seek(0)
            warnings.warn(f"warming the kernel cache failed ({part.args[-1]}): {log.read().strip()[-400:]}")
        log.close()


def _wait_timed(procs: list[subprocess.Popen], start: float) -> list[tuple[float, float]]:
    """Wait for ``procs`` (only these: the core suite's run is left running); for each, when it ended [s after
    ``start``, monotonic] and its CPU time (user + system) [s]."""
    ended: dict[int, tuple[float, float]] = {}
    while len(ended) < len(procs):
        for proc in procs:
            if proc.pid in ended:
                continue
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                proc.returncode = os.waitstatus_to_exitcode(status)
                ended[pid] = (time.monotonic() - start, usage.ru_utime + usage.ru_stime)
        if len(ended) < len(procs):
            time.sleep(0.2)
    return [ended[proc.pid] for proc in procs]


def _selects_the_core_runner(config) -> bool:
    """Whether the session will run tests/test_layers.py's core runner: a directory holding it is selected and
    no -k or -m expression could deselect it."""
    if getattr(config.option, "keyword", "") or getattr(config.option, "markexpr", ""):
        return False
    layers = Path(__file__).with_name("test_layers.py").resolve()
    args = [Path(config.invocation_params.dir, a.split("::")[0]).resolve() for a in config.args] or [layers.parent]
    return any(a.is_dir() and a in layers.parents for a in args)


def pytest_unconfigure(config):
    """Stop a core suite the session started if the session ends first (an interrupt, ``-x``), and remove its
    output folder."""
    for proc in _STARTED:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if _STARTED:
        shutil.rmtree(os.environ.pop(core_runner.ENV, ""), ignore_errors=True)
    _STARTED.clear()


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
