"""The kernels' on-disk cache follows the sources: one folder per hash of the kernel modules.

A process that imported the sources before they changed compiles the old code; with a single cache it wrote that
code where later processes loaded it as current (2026-11-30: a Bullet step ran an edited module's previous
twisting step). Each hash now has its own folder."""
from __future__ import annotations

from pathlib import Path

from numba.core import caching

import bullet_dlo
from bullet_dlo import _numba_cache
from bullet_dlo._numba_cache import CACHE_ROOT, PACKAGE, cache_folder, sources_digest


def test_the_package_kernels_cache_in_the_folder_of_their_sources_hash():
    from bullet_dlo.core.kernels.loop import run_loop

    locator = caching.CacheImpl._locator_classes[0]
    assert locator.__name__ == "DigestLocator"
    py_file = run_loop.py_func.__code__.co_filename
    found = locator.from_function(run_loop.py_func, py_file)
    assert Path(found.get_cache_path()) == cache_folder() / "core" / "kernels"
    assert cache_folder().name == f"numba-{sources_digest()}"
    assert Path(run_loop._cache._cache_path) == cache_folder() / "core" / "kernels"


def test_functions_outside_the_package_keep_numbas_own_cache(tmp_path):
    outside = tmp_path / "user_module.py"
    outside.write_text("def f(a):\n    return a\n")
    namespace: dict = {}
    exec(compile(outside.read_text(), str(outside), "exec"), namespace)
    assert caching.CacheImpl._locator_classes[0].from_function(namespace["f"], str(outside)) is None


def test_a_change_of_the_sources_means_another_folder_and_the_old_one_goes(tmp_path, monkeypatch):
    pkg = tmp_path / "pkg"
    (pkg / "core").mkdir(parents=True)
    src = pkg / "core" / "k.py"
    src.write_text("@njit\ndef f(): return 1\n")
    before = cache_folder(pkg)
    src.write_text("@njit\ndef f(): return 2\n")
    assert cache_folder(pkg) != before and cache_folder(pkg).parent == before.parent
    (pkg / "core" / "plain.py").write_text("x = 1\n")  # no kernel: not hashed
    after = cache_folder(pkg)
    assert cache_folder(pkg) == after
    # ensure_fresh_cache keeps only the present folder
    stale = CACHE_ROOT / "numba-0000000000000000"
    stale.mkdir(parents=True, exist_ok=True)
    (stale / "x.nbi").write_bytes(b"")
    _numba_cache.ensure_fresh_cache()
    assert not stale.exists() and cache_folder().is_dir()
    assert Path(bullet_dlo.__file__).resolve().parent == PACKAGE


def test_a_process_waits_for_another_one_compiling_the_same_kernel():
    """Two processes meeting one cold kernel compile it once: the second waits on the kernel's lock file and then
    loads the first one's build from the cache (``_numba_cache._compile_locked``). Here this process holds the
    lock of ``band_solve`` for its argument types: a fresh process calling it does not return until it lets go."""
    import fcntl
    import os
    import subprocess
    import sys
    import time

    import numpy as np
    from numba import typeof

    from bullet_dlo.core.kernels.banded import band_solve

    band, rhs = np.zeros((6, 17)), np.ones(6)  # (a diagonal 2 in the band's layout, half-width 8)
    band[:, 8] = 2.0
    band_solve(band.copy(), rhs.copy())  # (in the cache: the other process then loads it in milliseconds)
    path = _numba_cache.lock_file(cache_folder() / "locks", band_solve.py_func, (typeof(band), typeof(rhs)))
    script = ("import numpy as np\nfrom bullet_dlo.core.kernels.banded import band_solve\n"
              "band, rhs = np.zeros((6, 17)), np.ones(6)\nband[:, 8] = 2.0\nprint('ready', flush=True)\n"
              "band_solve(band, rhs)\nprint('done', rhs[0], flush=True)\n")
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(2.0)
        assert proc.poll() is None  # waiting for this process's lock (unlocked, a cached kernel loads at once)
    finally:
        os.close(fd)
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0 and out.split() == ["done", "0.5"]
