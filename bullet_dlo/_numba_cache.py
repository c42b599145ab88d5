"""Keep Numba's on-disk cache consistent with the package sources.

Numba invalidates a cached function only when *its own* file changes, not when a kernel it
inlines from another module does; after editing e.g. ``core/kernels/forces.py`` the cached time
loop in ``core/kernels/loop.py`` would silently keep the old physics. At import we hash every
module of the package (all subpackages) that defines kernels (``@njit``) or the NamedTuples
they take (``ModelArrays``, ``HolderPlan``, ``Workspace``, ...), and the package's kernels are
cached in a folder named after that hash, ``__pycache__/numba-<hash>/`` beside the package
(:class:`DigestLocator`); folders of other hashes are deleted.

A folder per hash, rather than one cache emptied when the hash changes: a process that imported the
sources before they changed keeps compiling the old code and writing it to the cache. With one
cache, whatever it wrote after a newer process had emptied the cache was then loaded as current by
every later process (seen on 2026-11-30: a Bullet step ran the twisting step of an edited module's
previous version, with nothing to say so). Now it writes to its own hash's folder, which no process
with the new sources reads. Where the package folder is not writable, Numba's own locations are
used (cached per function file, as before).
"""
from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
CACHE_ROOT = PACKAGE / "__pycache__"
"""Where the kernels' cache folders (``numba-<hash>``) live."""
JIT = Path("core", "kernels", "jit.py")
"""The compiler every kernel is built with (its passes change the compiled code: hashed with the kernels)."""


def kernel_sources(pkg: Path = PACKAGE) -> list[Path]:
    """Modules of ``pkg`` (all subpackages) that define kernels or the NamedTuples they take, and the compiler."""
    sources = []
    for src in sorted(pkg.rglob("*.py")):
        text = src.read_bytes()
        if b"@njit" in text or b"(NamedTuple)" in text or src == pkg / JIT:
            sources.append(src)
    return sources


def sources_digest(pkg: Path = PACKAGE) -> str:
    """Hash (hex, 16 digits) of the kernel sources of ``pkg``: their paths and contents."""
    digest = hashlib.sha1()
    for src in kernel_sources(pkg):
        digest.update(str(src.relative_to(pkg)).encode())
        digest.update(src.read_bytes())
    return digest.hexdigest()[:16]


def cache_folder(pkg: Path = PACKAGE) -> Path:
    """The cache folder of the present sources of ``pkg``."""
    return pkg / "__pycache__" / f"numba-{sources_digest(pkg)}"


def kernels_cold(pkg: Path = PACKAGE) -> bool:
    """Whether the core time loop has no cached build (a fresh install, an upgrade or an edited kernel
    starts a new cache folder): the first run then compiles for minutes (``bullet-dlo warmup`` compiles every family
    in about 14 minutes of CPU). A cache filled by other commands may still lack some kernels; those compile on their
    first call."""
    return not any(cache_folder(pkg).glob("core/kernels/loop.run_loop-*.nbi"))


def _locator_class(folder: Path):
    """A Numba cache locator that keeps the package's kernels in ``folder`` (mirroring the package's layout)."""
    from numba.core.caching import InTreeCacheLocator

    class DigestLocator(InTreeCacheLocator):
        """Caches a function of this package in the folder of its sources' hash; other functions: not here."""

        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            self._cache_path = str(folder / Path(py_file).resolve().parent.relative_to(PACKAGE))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not Path(py_file).resolve().is_relative_to(PACKAGE):
                return None
            return super().from_function(py_func, py_file)

    return DigestLocator


def ensure_fresh_cache() -> None:
    """Cache the package's kernels in the folder of the present sources' hash and delete the folders of other
    hashes (and caches left beside the sources by earlier versions)."""
    from numba.core import caching

    folder = cache_folder()
    locators = getattr(getattr(caching, "CacheImpl", None), "_locator_classes", None)
    if not isinstance(locators, list):  # a Numba without this hook: its own per-file caches
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # read-only install: Numba then uses its own cache location
        return
    locators[:] = [c for c in locators if getattr(c, "__name__", "") != "DigestLocator"]
    locators.insert(0, _locator_class(folder))
    for old in CACHE_ROOT.glob("numba-*"):
        if old != folder:
            shutil.rmtree(old, ignore_errors=True)
    legacy = CACHE_ROOT / "numba_sources.sha1"
    if legacy.is_file():  # the single cache of earlier versions (they wrote this stamp): deleted once
        for old in list(PACKAGE.rglob("__pycache__/*.nbi")) + list(PACKAGE.rglob("__pycache__/*.nbc")):
            if folder not in old.parents:
                old.unlink(missing_ok=True)
        legacy.unlink(missing_ok=True)
