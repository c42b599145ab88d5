"""Keep Numba's on-disk cache consistent with the package sources.

Numba invalidates a cached function only when *its own* file changes, not when a kernel it
inlines from another module does; after editing e.g. ``core/kernels/forces.py`` the cached time
loop in ``core/kernels/loop.py`` would silently keep the old physics. At import we hash every
module of the package (all subpackages) that defines kernels (``@njit``) or the NamedTuples
they take (``ModelArrays``, ``HolderPlan``, ``Workspace``, ...) and, if the hash differs from
the one stored beside the cache, delete every cached kernel of the package.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


def kernel_sources(pkg: Path = PACKAGE) -> list[Path]:
    """Modules of ``pkg`` (all subpackages) that define kernels or the NamedTuples they take."""
    sources = []
    for src in sorted(pkg.rglob("*.py")):
        text = src.read_bytes()
        if b"@njit" in text or b"(NamedTuple)" in text:
            sources.append(src)
    return sources


def kernels_cold(pkg: Path = PACKAGE) -> bool:
    """Whether the core time loop has no cached build (a fresh install, an upgrade or an edited kernel
    emptied the cache): the first run then compiles for about a minute. A cache filled by other commands
    may still lack some kernels; those compile on their first call."""
    return not any(pkg.glob("core/kernels/__pycache__/loop.run_loop-*.nbi"))


def ensure_fresh_cache() -> None:
    """Delete stale ``*.nbi``/``*.nbc`` files of this package if any source changed."""
    pkg = PACKAGE
    cache = pkg / "__pycache__"
    digest = hashlib.sha1()
    for src in kernel_sources(pkg):
        digest.update(str(src.relative_to(pkg)).encode())
        digest.update(src.read_bytes())
    stamp = cache / "numba_sources.sha1"
    try:
        if stamp.is_file() and stamp.read_text() == digest.hexdigest():
            return
        for old in list(pkg.rglob("__pycache__/*.nbi")) + list(pkg.rglob("__pycache__/*.nbc")):
            old.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:  # read-only install: Numba then uses its own cache location
        pass
