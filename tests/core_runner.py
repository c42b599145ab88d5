"""The core suite in an interpreter where PyBullet, h5py, matplotlib, PyAV, OpenCV and yourdfpy cannot be imported.

``tests/test_layers.py`` holds the test (every core test runs and passes there). In a parallel session
(``pytest -n N`` on the whole suite) ``tests/conftest.py`` starts this run at once, beside the Bullet part of
the kernel warm-up (``tests/warm_kernels.py``), instead of warming the core's kernels first and running the
suite afterwards: the run compiles what it needs once, in one process, while the Bullet part compiles the coupled
step, and the test then reads its result. Usage: ``python tests/core_runner.py OUT_DIR`` writes ``stdout``,
``stderr`` and, last, ``returncode`` in OUT_DIR.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
CORE_SUITE_DIRS = ("tests/core", "tests/analysis", "tests/config")
ENV = "BULLET_DLO_CORE_RUNNER"
"""Environment variable naming the OUT_DIR of a run started by the session (the test waits for its result)."""
TIMEOUT = 2400.0  # [s] the run's longest wait: about 2-5 min cold on two busy cores of the earlier machines, 18 min on
# this one (2026-12-01, AMD EPYC 2.4 GHz: the core loop's cold compile alone took 753 s beside another process)

# Prefix of a ``python -c`` program: makes the comma-separated names in argv[1] unimportable
# (a meta-path finder in front of every other), checks that it worked, and drops argv[1].
BLOCKER = """
import importlib.abc, sys

blocked = set(sys.argv.pop(1).split(","))


class Unimportable(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path, target=None):
        if fullname.partition(".")[0] in blocked:
            raise ModuleNotFoundError(f"No module named {fullname!r} (blocked by tests/test_layers.py)", name=fullname)
        return None


sys.meta_path.insert(0, Unimportable())
for name in sorted(blocked):
    try:
        __import__(name)
    except ModuleNotFoundError:
        continue
    sys.exit(f"{name} is still importable: the blocker does not work")
"""


def forbidden_modules() -> list[str]:
    """The modules the core must not import (import-linter's forbidden contract in pyproject.toml)."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    return next(c for c in contracts if c["type"] == "forbidden")["forbidden_modules"]


def blocked_modules() -> list[str]:
    """What the run makes unimportable: the forbidden modules but YAML (the config tests read scene files)."""
    return sorted(set(forbidden_modules()) - {"yaml"})


def selection() -> list[str]:
    """pytest's arguments for the core suite: the ``core`` marker on its directories."""
    return ["-m", "core", "-q", "-p", "no:cacheprovider", *(d for d in CORE_SUITE_DIRS if (ROOT / d).is_dir())]


def command() -> list[str]:
    """The run: ``pytest.main(selection())`` behind the blocker."""
    program = BLOCKER + "import pytest\nsys.exit(pytest.main(sys.argv[1:]))"
    return [sys.executable, "-c", program, ",".join(blocked_modules()), *selection()]


def write_result(out: Path) -> None:
    """Run :func:`command` and write its stdout, stderr and return code into ``out`` (the code last: its file marks
    the run as finished)."""
    out.mkdir(parents=True, exist_ok=True)
    try:
        proc = subprocess.run(command(), cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT)
        stdout, stderr, code = proc.stdout, proc.stderr, proc.returncode
    except subprocess.TimeoutExpired as e:
        stdout, stderr, code = str(e.stdout or ""), f"the core suite did not finish in {TIMEOUT:.0f} s", 124
    (out / "stdout").write_text(stdout)
    (out / "stderr").write_text(stderr)
    (out / "returncode.part").write_text(str(code))
    (out / "returncode.part").replace(out / "returncode")


if __name__ == "__main__":
    write_result(Path(sys.argv[1]))
