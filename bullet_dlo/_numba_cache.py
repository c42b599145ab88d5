"""Keep Numba's on-disk cache consistent with the package sources.

Numba invalidates a cached function only when *its own* file changes, not when a kernel it
inlines from another module does; after editing e.g. ``forces.py`` the cached time loop in
``simulate.py`` would silently keep the old physics. At import we hash every module of the
package (all subpackages) that defines kernels (and ``model.py``, whose types they take) and, if the hash differs from the one stored beside the cache, delete the cache.
"""
from __future__ import annotations

import hashlib
from pathlib import Path


def ensure_fresh_cache() -> None:
    """Delete stale ``*.nbi``/``*.nbc`` files of this package if any source changed."""
    pkg = Path(__file__).resolve().parent
    cache = pkg / "__pycache__"
    digest = hashlib.sha1()
    for src in sorted(pkg.rglob("*.py")):
        text = src.read_bytes()
        if b"@njit" in text or src.name == "model.py":  # kernels, and the types they take
            digest.update(str(src.relative_to(pkg)).encode())
            digest.update(text)
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
