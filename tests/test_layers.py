"""The layer contract, proven rather than claimed.

* import-linter's contracts (``[tool.importlinter]`` in pyproject.toml) are kept, and every
  subpackage of ``bullet_dlo`` sits in a layer, so none escapes the import direction;
* importing ``bullet_dlo``, ``bullet_dlo.core`` or ``bullet_dlo.analysis`` in a fresh
  interpreter loads none of the modules the core must not import;
* the core suite (``pytest -m core`` on tests/core, tests/analysis, tests/config) passes in
  an interpreter where PyBullet, h5py, matplotlib, PyAV, OpenCV and yourdfpy cannot be
  imported at all. YAML stays importable there: the config layer's tests read scene files.
  The whole core suite runs (about 20 s with a warm Numba cache).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

import core_runner  # tests/core_runner.py

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
IMPORTLINTER = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
LAYERS = next(c for c in IMPORTLINTER["contracts"] if c["type"] == "layers")
CORE_FORBIDDEN = next(c for c in IMPORTLINTER["contracts"] if c["type"] == "forbidden")
CORE_SUITE_DIRS = core_runner.CORE_SUITE_DIRS
BLOCKER = core_runner.BLOCKER


def run(args: list[str], timeout: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run(args, cwd=ROOT, capture_output=True, text=True, timeout=timeout)


def test_import_linter_contracts_are_kept():
    proc = run([sys.executable, "-c",
                "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports(no_cache=True))"])
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for contract in IMPORTLINTER["contracts"]:
        assert f"{contract['name']} KEPT" in proc.stdout, proc.stdout
    assert f"Contracts: {len(IMPORTLINTER['contracts'])} kept, 0 broken." in proc.stdout


def test_every_subpackage_sits_in_a_layer():
    layered = {name.strip() for layer in LAYERS["layers"] for name in layer.split("|")}
    subpackages = {f"bullet_dlo.{p.parent.name}" for p in (ROOT / "bullet_dlo").glob("*/*.py")
                   if not p.parent.name.startswith((".", "_"))}
    assert subpackages - layered == set(), "add these to the layers contract in pyproject.toml"
    assert layered - subpackages == set(), "the layers contract names packages that do not exist"


@pytest.mark.parametrize("module", ["bullet_dlo", "bullet_dlo.core", "bullet_dlo.analysis"])
def test_importing_the_core_loads_no_forbidden_module(module):
    """Numba itself imports yaml (for its optional config file): what numpy, scipy and numba load is the baseline."""
    forbidden = CORE_FORBIDDEN["forbidden_modules"]
    probe = f"""
import json, sys
import numba, numpy, scipy

def loaded():
    return {{m for m in sys.modules if m.partition('.')[0] in {forbidden!r}}}

baseline = loaded()
import {module}
print(json.dumps({{"baseline": sorted(baseline), "added": sorted(loaded() - baseline)}}))
"""
    proc = run([sys.executable, "-c", probe], timeout=120)
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout.splitlines()[-1])
    assert report["added"] == []
    assert {m.partition(".")[0] for m in report["baseline"]} <= {"yaml"}
    assert {"pybullet", "h5py", "matplotlib", "av", "cv2", "yaml"} <= set(forbidden)


@pytest.mark.parametrize("module", ["bullet_dlo", "bullet_dlo.core", "bullet_dlo.analysis"])
def test_core_imports_with_every_forbidden_module_unimportable(module):
    proc = run([sys.executable, "-c", BLOCKER + f"import {module}\nprint({module}.__name__)",
                ",".join(CORE_FORBIDDEN["forbidden_modules"])], timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == module


def test_core_suite_passes_without_pybullet_h5py_matplotlib_av_cv2(tmp_path):
    assert {"pybullet", "pybullet_data", "h5py", "matplotlib", "av", "cv2"} <= set(core_runner.blocked_modules())
    collected = run([sys.executable, "-m", "pytest", "--collect-only", *core_runner.selection()])
    n_core = int(re.search(r"(\d+)(?:/\d+)? tests? collected", collected.stdout).group(1))
    started = os.environ.get(core_runner.ENV)  # the session started the run at its beginning (tests/conftest.py)
    out = Path(started) if started else tmp_path
    if not started:
        core_runner.write_result(out)
    deadline = time.monotonic() + core_runner.TIMEOUT + 60.0
    while not (out / "returncode").is_file():
        assert time.monotonic() < deadline, f"the core suite started by the session wrote no result in {out}"
        time.sleep(0.5)
    code = int((out / "returncode").read_text())
    stdout, stderr = (out / "stdout").read_text(), (out / "stderr").read_text()
    assert code == 0, stdout[-4000:] + stderr[-4000:]
    summary = stdout.strip().splitlines()[-1]
    counts = dict((kind, int(n)) for n, kind in
                  re.findall(r"(\d+) (passed|failed|errors?|skipped|xfailed|xpassed|deselected)", summary))
    assert counts == {"passed": n_core}, summary  # every core test ran and passed: none skipped or deselected
