"""What the command line prints: ``--quiet`` output and progress bars.

PyBullet's C code writes to the process's file descriptors 1 and 2 (the "pybullet build
time" banner on import, a dozen EGL lines when the renderer plugin loads), out of reach of
Python's ``sys.stdout``. :func:`quiet_output` points both descriptors at /dev/null for the
duration of a command and gives Python's own streams duplicates of the original ones, so
results and errors still print while the C libraries' chatter does not.
"""
from __future__ import annotations

import contextlib
import ctypes
import io
import os
import sys
import threading
import time
import warnings
from typing import Iterator

from tqdm import tqdm


def flush_c_streams() -> None:
    """Flush C stdio buffers (a pipe's are written only at exit otherwise, after fd 1 is restored)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # pragma: no cover - not a POSIX libc
        pass


@contextlib.contextmanager
def _python_stream_on(name: str, fd: int) -> Iterator[None]:
    """Point ``sys.<name>`` at a duplicate of its descriptor, if it writes to one (pytest's capture does not)."""
    stream = getattr(sys, name)
    try:
        uses_fd = stream.fileno() in (1, 2)
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        uses_fd = False
    if not uses_fd:
        yield
        return
    duplicate = open(fd, "w", buffering=1, encoding=stream.encoding, errors="backslashreplace", closefd=False)
    setattr(sys, name, duplicate)
    try:
        yield
    finally:
        try:
            duplicate.flush()
        except BrokenPipeError:  # the reader left (`| head`): what is left to say goes nowhere
            pass
        setattr(sys, name, stream)


@contextlib.contextmanager
def quiet_output(enabled: bool = True) -> Iterator[None]:
    """Silence everything written to file descriptors 1 and 2 except through Python's streams; also
    Python warnings. A no-op when not ``enabled``."""
    if not enabled:
        yield
        return
    sys.stdout.flush()
    sys.stderr.flush()
    flush_c_streams()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in (1, 2):
            os.dup2(devnull, fd)
        with _python_stream_on("stdout", saved[1]), _python_stream_on("stderr", saved[2]), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        flush_c_streams()  # what the C libraries buffered goes to /dev/null too
        for fd in (1, 2):
            os.dup2(saved[fd], fd)
            os.close(saved[fd])
        os.close(devnull)


def bar(total: int | None, desc: str, quiet: bool, unit: str = "run") -> tqdm:
    """A progress bar with ETA on stderr (none with ``--quiet``)."""
    return tqdm(total=total, desc=desc, unit=unit, disable=quiet, file=sys.stderr, dynamic_ncols=True, leave=False)


@contextlib.contextmanager
def elapsed(desc: str, quiet: bool) -> Iterator[None]:
    """An elapsed-time counter on stderr for work that cannot report its own progress."""
    counter = bar(None, desc, quiet, unit="s")
    done = threading.Event()

    def tick() -> None:
        start = time.perf_counter()
        while not done.wait(0.5):
            counter.n = int(time.perf_counter() - start)
            counter.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()
        counter.close()


@contextlib.contextmanager
def native_output() -> Iterator[list[str]]:
    """Collect what C code writes to file descriptors 1 and 2 (e.g. the EGL plugin naming its GL
    renderer); the text is in the yielded list when the block ends."""
    import tempfile

    sys.stdout.flush()
    sys.stderr.flush()
    flush_c_streams()
    text: list[str] = []
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    with tempfile.TemporaryFile() as sink:
        try:
            for fd in (1, 2):
                os.dup2(sink.fileno(), fd)
            with _python_stream_on("stdout", saved[1]), _python_stream_on("stderr", saved[2]):
                yield text
        finally:
            flush_c_streams()
            for fd in (1, 2):
                os.dup2(saved[fd], fd)
                os.close(saved[fd])
            sink.seek(0)
            text.append(sink.read().decode(errors="replace"))
