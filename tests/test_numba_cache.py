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
