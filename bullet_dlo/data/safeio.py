"""File access of a capture directory that never goes through a link and never blocks.

Writing: every file is created exclusively (``O_CREAT | O_EXCL``, which refuses an existing
name, a symbolic link among them) under a temporary name and renamed over its final name
(:func:`atomic_write`): a link the user left at the final name is replaced, its target never
touched. Reading: :func:`read_regular` opens with ``O_NOFOLLOW | O_NONBLOCK`` and refuses
anything but a regular file (a link, a directory, a FIFO, a device), so a damaged or planted
entry is reported instead of followed or waited on. Write failures (a full disk, a read-only
folder, a name too long) raise :class:`StorageError`, one line naming the file.
"""
from __future__ import annotations

import errno
import hashlib
import os
import stat
from pathlib import Path
from typing import Callable, IO

from bullet_dlo.core.validate import ParameterError

CHUNK = 1 << 20  # [B] read size while hashing


class StorageError(OSError):
    """A file of the capture directory could not be written (disk full, read-only, name too long);
    ``str()`` is one line naming the file and the cause."""

    def __init__(self, path: str | Path, err: BaseException | str, note: str = ""):
        if isinstance(err, str):
            cause = err
        else:
            cause = err.strerror if isinstance(err, OSError) and err.strerror else str(err) or type(err).__name__
        super().__init__(getattr(err, "errno", None) or errno.EIO,
                         f"cannot write {path}: {cause}" + (f" ({note})" if note else ""))
        self.path = Path(path)
        self.cause = cause
        self.note = note

    def __reduce__(self):  # crosses process boundaries whole (OSError's own pickling loses path and cause)
        return type(self), (str(self.path), self.cause, self.note)

    def __str__(self) -> str:
        return self.strerror


class NotARegularFile(ParameterError):
    """An entry that should be a regular file is a link, a directory, a FIFO, a device or missing;
    ``kind`` says which ("missing", "symbolic link", "directory", "FIFO", "special file")."""

    def __init__(self, path: Path, kind: str):
        super().__init__(f"{path} is {'missing' if kind == 'missing' else 'a ' + kind}, not a regular file")
        self.path = path
        self.kind = kind


def entry_kind(path: Path) -> str:
    """What is at ``path`` without following a link: file, missing, symbolic link, directory, FIFO, special file."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return "missing"
    except OSError:
        return "special file"
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISLNK(mode):
        return "symbolic link"
    if stat.S_ISDIR(mode):
        return "directory"
    if stat.S_ISFIFO(mode):
        return "FIFO"
    return "special file"


def open_regular(path: Path) -> int:
    """A read-only descriptor of the regular file ``path`` (a link, FIFO, directory or device raises
    :class:`NotARegularFile`; nothing blocks)."""
    flags = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise NotARegularFile(path, "missing") from None
    except OSError as err:
        if err.errno in (errno.ELOOP, errno.EMLINK):
            raise NotARegularFile(path, "symbolic link") from None
        kind = entry_kind(path)
        if kind != "file":
            raise NotARegularFile(path, kind) from None
        raise ParameterError(f"{path} cannot be read: {err.strerror}") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise NotARegularFile(path, entry_kind(path))
    return fd


def read_regular(path: Path) -> bytes:
    """All bytes of the regular file ``path`` (see :func:`open_regular`)."""
    fd = open_regular(path)
    with os.fdopen(fd, "rb") as fh:
        return fh.read()


def file_facts(path: Path) -> dict[str, int | str]:
    """``{"size": bytes, "sha256": hex}`` of the regular file ``path`` (see :func:`open_regular`)."""
    fd = open_regular(path)
    digest = hashlib.sha256()
    size = 0
    with os.fdopen(fd, "rb") as fh:
        while chunk := fh.read(CHUNK):
            digest.update(chunk)
            size += len(chunk)
    return {"size": size, "sha256": digest.hexdigest()}


def sha256(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def temporary_name(path: Path) -> Path:
    """The temporary name ``path`` is written under (``<name>.tmp-<pid>``; a capture's start removes them)."""
    return path.with_name(f"{path.name}.tmp-{os.getpid()}")


def create_new(path: Path) -> int:
    """A write-only descriptor of a new file ``path`` (refuses an existing name or a link)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)
    return os.open(path, flags, 0o644)


def atomic_write(path: Path, write: Callable[[IO[bytes]], None]) -> None:
    """Create ``path`` atomically: ``write(fh)`` fills a new temporary file (exclusive creation), which
    is flushed to disk and renamed over ``path`` (a link at ``path`` is replaced, not followed).
    A failure removes the temporary file, leaves ``path`` as it was and raises :class:`StorageError`."""
    path = Path(path)
    tmp = temporary_name(path)
    try:
        _remove_stale(tmp)
        with os.fdopen(create_new(tmp), "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as err:
        _remove_stale(tmp, quiet=True)
        raise StorageError(path, err) from None


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """:func:`atomic_write` of ``data``."""
    atomic_write(path, lambda fh: fh.write(data))


def _remove_stale(tmp: Path, quiet: bool = False) -> None:
    """Remove a leftover temporary name (a file or a link, never what a link points to)."""
    try:
        if entry_kind(tmp) in ("file", "symbolic link", "FIFO"):
            os.unlink(tmp)
    except OSError:
        if not quiet:
            raise
