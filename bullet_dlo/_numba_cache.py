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

Numba has no lock between processes: two processes that meet the same cold kernel at once both compile it (test
workers, capture workers, the suite's warm-up processes: run side by side as the suite runs them, cold, the core
suite's runner and the Bullet part of the warm-up both compiled 24 kernels, about 30 s of CPU each; of the Bullet
part's 457 compiles 187 are the core runner's too, 200 s of CPU, measured 2026-12-07).
:func:`ensure_fresh_cache` therefore wraps ``Dispatcher.compile`` for the package's cached kernels in a file lock
per kernel and signature (:func:`_compile_locked`): the second process waits and then loads the first one's build
from the cache. Call graphs are acyclic, so two processes never wait for each other.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

from bullet_dlo import _numba_link

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
    _lock_compiles(folder / "locks")
    _numba_link.install()
    for old in CACHE_ROOT.glob("numba-*"):
        if old != folder:
            shutil.rmtree(old, ignore_errors=True)
    legacy = CACHE_ROOT / "numba_sources.sha1"
    if legacy.is_file():  # the single cache of earlier versions (they wrote this stamp): deleted once
        for old in list(PACKAGE.rglob("__pycache__/*.nbi")) + list(PACKAGE.rglob("__pycache__/*.nbc")):
            if folder not in old.parents:
                old.unlink(missing_ok=True)
        legacy.unlink(missing_ok=True)


LOCK_WAIT = 3600.0
"""[s] the longest a process waits for another one's compile of a kernel before compiling it itself (a cold
coupled step takes minutes; a process that dies releases its locks at once)."""


_HELD: set[str] = set()  # the lock keys this process holds


def _lock_compiles(locks: Path) -> None:
    """Make ``Dispatcher.compile`` of the package's cached kernels wait for another process compiling the same
    kernel and signature (module doc); once per process."""
    try:
        import fcntl  # noqa: F401  (POSIX; elsewhere each process compiles on its own, as Numba does)

        from numba.core.dispatcher import Dispatcher
    except ImportError:
        return
    if getattr(Dispatcher.compile, "locked_by_bullet_dlo", False):
        return
    try:
        locks.mkdir(exist_ok=True)
    except OSError:
        return
    compile_unlocked = Dispatcher.compile

    def compile(self, sig):
        return _compile_locked(self, sig, compile_unlocked, locks)

    compile.locked_by_bullet_dlo = True
    compile.__doc__ = compile_unlocked.__doc__
    Dispatcher.compile = compile


def _compile_locked(dispatcher, sig, compile_unlocked, locks: Path):
    """``compile_unlocked(dispatcher, sig)`` holding the file lock of the kernel and signature when the kernel is
    one of the package's cached ones and not yet built in this process (it then loads from the cache what another
    process compiled while this one waited)."""
    from numba.core import sigutils
    from numba.core.compiler_lock import global_compiler_lock

    args, _ = sigutils.normalize_signature(sig)
    args = tuple(args)
    impl = getattr(getattr(dispatcher, "_cache", None), "_impl", None)
    if getattr(type(getattr(impl, "_locator", None)), "__name__", "") != "DigestLocator":
        # a user's cached kernel may call the package's kernels by symbol: it too is built again when they were
        return _numba_link.compile_linked(dispatcher, sig, args, compile_unlocked, mark_build=False)
    if args in dispatcher.overloads:
        return compile_unlocked(dispatcher, sig)
    func = dispatcher.py_func
    path = lock_file(locks, func, args)
    key = path.name
    # the file lock is taken inside Numba's compiler lock (it is re-entrant): a thread of this process never holds
    # a kernel's file lock while waiting for a compiler lock another thread holds waiting for that file lock
    with global_compiler_lock:
        if key in _HELD:  # this process is compiling it already (a recursive kernel): no second lock on it
            return _numba_link.compile_linked(dispatcher, sig, args, compile_unlocked)
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:
            return _numba_link.compile_linked(dispatcher, sig, args, compile_unlocked)
        _HELD.add(key)
        try:
            _acquire(fd)
            return _numba_link.compile_linked(dispatcher, sig, args, compile_unlocked)
        finally:
            _HELD.discard(key)
            os.close(fd)  # (releases the lock)


def lock_file(locks: Path, py_func, arg_types: tuple) -> Path:
    """The lock file in the folder ``locks`` of the kernel with Python function ``py_func`` for the Numba argument
    types ``arg_types``."""
    key = hashlib.sha1(f"{py_func.__module__}.{py_func.__qualname__}{arg_types}".encode()).hexdigest()[:20]
    return locks / f"{py_func.__name__}-{key}.lock"


def _acquire(fd: int) -> None:
    """Take the exclusive lock of ``fd``, polling (a blocking wait could not give up after :data:`LOCK_WAIT`)."""
    import fcntl

    deadline = time.monotonic() + LOCK_WAIT
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() > deadline:
                return
            time.sleep(0.05)
        except OSError:  # a file system without locks: compile unlocked
            return
