"""A capture directory on disk: atomic HDF5 episode files, the manifest, the spec it belongs to.

Layout of a capture directory::

    capture.json            the spec, its digest (recomputed on every read: an edited spec is refused) and
                            the number of episodes planned (``episodes``: the largest N a capture asked for)
    .lock                   held (flock) by the capture writing into the directory
    manifest.jsonl          one JSON record per finished episode (written by the coordinator only)
    episode_000012.h5       one file per episode, written as ``*.h5.tmp-<pid>`` and renamed when complete

A manifest record holds ``episode``, ``file``, ``status`` (ok | flagged | failed), ``error``,
``time_to_instability``, ``reason``, ``params``, ``decision`` and ``metrics``; the line of a
finished episode also holds its file's ``size`` [B] and ``sha256``, the library ``version`` and
the ``spec_digest`` (checked by :mod:`bullet_dlo.data.integrity`). A finished episode file carries
everything needed to rebuild its record, its status, reason and quality flags included (stored
as attributes; recomputed from its metrics and the spec's limits for files written before), so
a manifest line lost to a kill is recovered from the file, flags and all.

Nothing is written through a link: files are created exclusively under a temporary name and
renamed (:mod:`bullet_dlo.data.safeio`), the lock is opened with ``O_NOFOLLOW``. A write that
fails (full disk, read-only folder) raises :class:`~bullet_dlo.data.safeio.StorageError`, one
line; what was written before stays as it was.
"""
from __future__ import annotations

import errno
import hashlib
import io
import json
import os
import stat
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from bullet_dlo.config.capture import RENAMED, CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.safeio import (
    NotARegularFile,
    StorageError,
    atomic_write_bytes,
    entry_kind,
    file_facts,
    read_regular,
    temporary_name,
)

MANIFEST = "manifest.jsonl"
SPEC_FILE = "capture.json"
LOCK_FILE = ".lock"
STATUSES = ("ok", "flagged", "failed")
JSON_ATTRS = ("params", "decision", "metrics", "quality_issues")  # episode attributes stored as JSON text
FILE_FACTS = ("size", "sha256", "version", "spec_digest")  # what a manifest line says of its episode file
GRAVITY = 9.80665  # [m/s^2] standard gravity (a cable's weight, when its quality flags are recomputed)


def version() -> str:
    """The package version stored with every episode."""
    from bullet_dlo import __version__

    return __version__


def episode_name(index: int) -> str:
    """File name of episode ``index``."""
    return f"episode_{index:06d}.h5"


# ----- records ---------------------------------------------------------------------------------
def episode_result(index: int, file: str, stable: bool, time_to_instability: float | None, reason: str | None,
                   params: dict, decision: dict, metrics: dict, quality: list[str] = ()) -> dict[str, Any]:
    """The manifest record of a finished episode: ``flagged`` when it went unstable (``reason``: why) or
    when its forces failed a quality limit (``quality``: the reasons, from
    :func:`~bullet_dlo.data.quality.quality_issues`)."""
    flagged = not stable or bool(quality)
    if stable and quality:
        reason = "quality: " + "; ".join(quality)
    return {"episode": index, "file": file, "status": "flagged" if flagged else "ok", "error": None,
            "time_to_instability": time_to_instability, "reason": reason, "params": params, "decision": decision,
            "metrics": metrics}


def status_attrs(record: dict[str, Any]) -> dict[str, Any]:
    """The attributes an episode file stores so that its record is rebuilt with the same ``status``,
    ``reason`` and ``quality_issues`` (the quality reasons, a list) after a lost manifest line."""
    reason = record.get("reason")
    issues = reason[len("quality: "):].split("; ") if record["status"] == "flagged" and str(reason).startswith(
        "quality: ") else []
    return {"status": record["status"], "reason": "" if reason is None else str(reason), "quality_issues": issues}


def failed_record(index: int, error: str, **extra: Any) -> dict[str, Any]:
    """The manifest record of an episode that did not finish (``extra``: e.g. its traceback)."""
    return {"episode": index, "file": None, "status": "failed", "error": error, **extra}


# ----- episode files ---------------------------------------------------------------------------
def write_episode(out_dir: str | Path, index: int, arrays: dict[str, np.ndarray], attrs: dict[str, Any],
                  frames: np.ndarray | None = None, frame_t: np.ndarray | None = None) -> str:
    """Write episode ``index`` atomically (temporary name, then rename); returns its file name.

    arrays: the recorded columns, written in their order; attrs: scalar or JSON-able
    attributes (``params``, ``decision``, ``metrics`` dicts are stored as JSON text);
    frames: RGB frames, shape (f, h, w, 3) uint8, stored gzip-compressed one frame per chunk,
    with their times ``frame_t`` [s], shape (f,). No timestamps: equal episodes give equal bytes.
    """
    import h5py

    name = episode_name(index)
    final = Path(out_dir) / name
    tmp = temporary_name(final)
    try:
        if entry_kind(tmp) != "missing":
            os.unlink(tmp)  # a stale name of a killed process with this pid (a link: only the link goes)
        with h5py.File(tmp, "x", libver="latest") as f:  # exclusive creation: never through a link
            for key, arr in arrays.items():
                f.create_dataset(key, data=arr, track_times=False)
            if frames is not None and len(frames):
                f.create_dataset("frames", data=frames, track_times=False, compression="gzip", compression_opts=4,
                                 chunks=(1,) + frames.shape[1:])
                f.create_dataset("frame_t", data=frame_t, track_times=False)
            for k, v in attrs.items():
                f.attrs[k] = json.dumps(v, sort_keys=True) if k in JSON_ATTRS else v
        _fsync(tmp)
        os.replace(tmp, final)
    except (OSError, RuntimeError) as err:  # h5py reports a full disk as either
        if entry_kind(tmp) == "file":
            os.unlink(tmp)
        raise StorageError(final, err) from None
    return name


def _fsync(path: Path) -> None:
    """Flush a file just written to disk (before it is renamed into place)."""
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def episode_record(path: Path, digest: str | None = None,
                   limits: tuple[float | None, float | None] = (None, None)) -> dict | None:
    """Rebuild the manifest record of a finished episode file, its status, reason and quality flags
    included; an unreadable file is set aside (renamed ``<name>.damaged-<k>``; None).

    The flags are those the file stores (``status``, ``reason``, ``quality_issues``); a file written
    before they were stored gets them recomputed from its metrics with ``limits`` (the spec's
    max_sensor_model_rms [cable weights] and max_hf_energy, :func:`~bullet_dlo.data.quality.quality_limits`)
    and the wrist-sensor check. Links, directories and FIFOs are never followed or opened.
    With ``digest``, a file written for another spec raises ParameterError (never mixed in).
    """
    try:
        attrs = read_attrs(path)
    except Exception:  # noqa: BLE001 - a corrupt or planted entry is set aside and re-run
        set_aside(path)
        return None
    if digest is not None and "spec_digest" in attrs and str(attrs["spec_digest"]) != digest:
        raise ParameterError(f"{path} was captured with another spec (digest {attrs['spec_digest']} vs "
                             f"{digest}); use another directory")
    try:
        return record_from_attrs(attrs, path.name, limits)
    except (KeyError, TypeError, ValueError):
        set_aside(path)
        return None


def read_attrs(path: Path) -> dict[str, Any]:
    """The attributes of the episode file ``path`` (JSON ones parsed), read without following a link
    or opening anything but a regular file."""
    import h5py

    with h5py.File(io.BytesIO(read_regular(path)), "r") as f:
        return {k: json.loads(v) if k in JSON_ATTRS else v for k, v in f.attrs.items()}


def record_from_attrs(attrs: dict[str, Any], name: str,
                      limits: tuple[float | None, float | None] = (None, None)) -> dict[str, Any]:
    """The manifest record of an episode from its file's attributes (see :func:`episode_record`)."""
    t_bad = float(attrs["time_to_instability"])
    stable = bool(attrs["stable"])
    metrics = attrs["metrics"]
    if "status" in attrs:  # stored by the episode: exactly what the live record said
        reason = str(attrs.get("reason", "")) or None
        issues = list(attrs.get("quality_issues", []))
    else:
        reason = _final_reason(attrs) if not stable else None
        issues = _recomputed(attrs, limits) if stable else []
    rec = episode_result(int(attrs["episode"]), name, stable, None if t_bad < 0 else t_bad, reason,
                         attrs["params"], attrs["decision"], metrics, issues)
    if "status" in attrs and str(attrs["status"]) in ("ok", "flagged") and rec["status"] != attrs["status"]:
        rec["status"] = str(attrs["status"])
    return rec


def _recomputed(attrs: dict[str, Any], limits: tuple[float | None, float | None]) -> list[str]:
    """Quality reasons of a file that does not store them, from its metrics and the cable's drawn mass."""
    from bullet_dlo.data.quality import recomputed_issues

    mass = (attrs.get("params") or {}).get("mass")
    if not isinstance(mass, (int, float)):
        return []
    return recomputed_issues(attrs["metrics"], float(mass) * GRAVITY, *limits)


def _final_reason(attrs: dict[str, Any]) -> str | None:
    """Why an unstable episode stopped, if its file says (a rollout's ``final_info``)."""
    try:
        info = json.loads(attrs.get("final_info", "{}"))
    except (TypeError, ValueError):
        return None
    reason = info.get("reason") if isinstance(info, dict) else None
    return str(reason) if reason else None


def set_aside(path: Path) -> Path | None:
    """Rename a damaged directory entry to ``<name>.damaged-<k>`` (kept for inspection, out of the way
    of the re-run); returns the new name (None when nothing is there)."""
    if entry_kind(path) == "missing":
        return None
    k = 1
    while entry_kind(path.with_name(f"{path.name}.damaged-{k}")) != "missing":
        k += 1
    target = path.with_name(f"{path.name}.damaged-{k}")
    try:
        os.rename(path, target)
    except OSError as err:
        raise StorageError(path, err) from None
    return target


# ----- manifest and directory ------------------------------------------------------------------
def read_manifest(out: Path, strict: bool = False) -> dict[int, dict]:
    """Manifest records by episode index (the last line of an episode wins).

    A line cut by a kill (not JSON, or not a record with an integer ``episode`` and a ``status``)
    is skipped: its episode is reconciled from its file or re-run. With ``strict`` such a line
    raises ParameterError naming it, except a torn last line (the normal trace of a kill).
    """
    records: dict[int, dict] = {}
    path = out / MANIFEST
    if entry_kind(path) == "missing":
        return records
    try:
        text = read_regular(path).decode("utf-8")
    except (ParameterError, OSError, UnicodeDecodeError) as err:
        raise ParameterError(f"{path} cannot be read as UTF-8 text: {err}") from None
    lines = text.splitlines()
    for number, line in enumerate(lines, 1):
        rec = _record(line)
        if rec is None:
            torn = number == len(lines) and not text.endswith("\n")
            if strict and line.strip() and not torn:
                raise ParameterError(f"{path} line {number} is not a manifest record (a JSON object with an "
                                     f"integer episode >= 0 and a status): {line[:60]!r}")
            continue
        records[rec["episode"]] = rec
    return records


def _record(line: str) -> dict | None:
    """The manifest record on ``line``, or None when the line is not one."""
    try:
        rec = json.loads(line)
    except json.JSONDecodeError:
        return None
    ok = (isinstance(rec, dict) and isinstance(rec.get("episode"), int) and not isinstance(rec["episode"], bool)
          and rec["episode"] >= 0 and rec.get("status") in STATUSES)
    return rec if ok else None


def repair_manifest(out: Path) -> int:
    """Drop the lines of the manifest that are no record (a line cut by a kill), atomically; returns
    how many were dropped. Their episodes are then rebuilt from their files or re-run."""
    path = out / MANIFEST
    if entry_kind(path) == "missing":
        return 0
    lines = read_regular(path).decode("utf-8", errors="replace").splitlines()
    good = [line for line in lines if _record(line) is not None]
    if len(good) == len(lines):
        return 0
    atomic_write_bytes(path, "".join(line + "\n" for line in good).encode("utf-8"))
    return len(lines) - len(good)


def append_manifest(out: Path, record: dict) -> dict:
    """Append one record and flush it to disk before returning; returns the record as written.

    The record of a finished episode gets its file's facts (:data:`FILE_FACTS`: size [B], sha256,
    library version, spec digest) unless it has them. The manifest is opened without following a
    link; a failed write raises :class:`~bullet_dlo.data.safeio.StorageError` (a torn line it may
    leave is dropped by the next resume, and the episode's record rebuilt from its file).
    """
    path = out / MANIFEST
    if record.get("file") and "sha256" not in record:
        record = {**record, **file_facts(out / record["file"]), "version": version(),
                  "spec_digest": _digest(out)}
    line = json.dumps(record, sort_keys=True, default=float) + "\n"
    try:
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK
                     | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as err:
        raise StorageError(path, _link_error(path, err)) from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise StorageError(path, OSError(errno.EINVAL, f"it is a {entry_kind(path)}, not a regular file"))
    try:
        with os.fdopen(fd, "a") as fh:
            if _ends_mid_line(fd):
                fh.write("\n")  # a line cut by a kill: start a fresh one, or both lines are lost
            fh.write(line)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as err:
        raise StorageError(path, err) from None
    return record


def _digest(out: Path) -> str | None:
    """The spec digest of the capture directory ``out`` (None when it has no readable spec file)."""
    try:
        return read_spec_file(out)["digest"]
    except ParameterError:
        return None


def _link_error(path: Path, err: OSError) -> OSError:
    """``err``, or a clearer one when ``path`` is a link (O_NOFOLLOW's ELOOP)."""
    if err.errno == errno.ELOOP:
        return OSError(errno.ELOOP, "it is a symbolic link (not followed; remove it)")
    return err


def _ends_mid_line(fd: int) -> bool:
    """True if the open file ``fd`` is non-empty and its last byte is not a newline."""
    size = os.fstat(fd).st_size
    return size > 0 and os.pread(fd, 1, size - 1) != b"\n"


def is_capture_dir(root: Path) -> bool:
    """True if ``root`` holds a capture (its spec file)."""
    return (root / SPEC_FILE).is_file()


def spec_digest(spec: dict) -> str:
    """The digest of a spec in its stored dict form, as :meth:`CaptureSpec.digest` (sample keys under their
    names before :data:`~bullet_dlo.config.capture.RENAMED`) and ``RolloutSpec.digest`` (a ``rollout`` key)
    compute it."""
    if "rollout" not in spec and isinstance(spec.get("sample"), dict):
        old = {new: before for before, new in RENAMED.items()}
        spec = {**spec, "sample": {old.get(k, k): v for k, v in spec["sample"].items()}}
    return hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]


def read_spec_file(out: Path) -> dict:
    """The parsed ``capture.json`` of ``out`` (never read through a link); ParameterError when it is damaged,
    or when its spec does not hash to its digest (edited after the capture)."""
    path = out / SPEC_FILE
    try:
        meta = json.loads(read_regular(path).decode("utf-8"))
    except (NotARegularFile, OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ParameterError(f"{path} is damaged ({type(err).__name__}); the spec of this capture directory is "
                             "unknown: capture into a new directory") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("digest"), str):
        raise ParameterError(f"{path} holds no spec digest; the spec of this capture directory is unknown: "
                             "capture into a new directory")
    if not isinstance(meta.get("spec"), dict) or spec_digest(meta["spec"]) != meta["digest"]:
        found = spec_digest(meta["spec"]) if isinstance(meta.get("spec"), dict) else "no spec"
        raise ParameterError(f"{path}: its spec does not match its digest {meta['digest']} ({found}): it was edited "
                             "after the capture, and its episodes belong to the spec the digest names; restore it")
    planned = meta.get("episodes")
    if planned is not None and not (isinstance(planned, int) and not isinstance(planned, bool) and planned >= 0):
        raise ParameterError(f"{path}: episodes must be the planned episode count (an integer >= 0), got "
                             f"{planned!r}")
    return meta


def planned_episodes(meta: dict) -> int | None:
    """How many episodes (0..N-1) the captures into a directory asked for, from its ``capture.json``
    (None: written before the count was stored)."""
    return meta.get("episodes")


def _write_spec_file(out: Path, digest: str, spec: dict, episodes: int | None) -> None:
    meta = {"digest": digest, "spec": spec, "version": version()}
    if episodes is not None:
        meta["episodes"] = int(episodes)
    atomic_write_bytes(out / SPEC_FILE, json.dumps(meta, indent=2, default=str).encode("utf-8"))


@contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on the capture directory ``out`` (a ``.lock`` file, ``fcntl.flock``):
    a second capture or resume into it refuses instead of running every episode twice. The lock
    goes with the process, so a killed capture never leaves it behind."""
    import fcntl

    path = out / LOCK_FILE
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags, 0o644)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise ParameterError(f"{path} is a symbolic link; a capture never writes through one: remove it") from None
        raise StorageError(path, err) from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        os.close(fd)
        what = "a hard link to another file" if stat.S_ISREG(info.st_mode) else f"a {entry_kind(path)}"
        raise ParameterError(f"{path} is {what}, not the capture's own lock file: remove it")
    fh = os.fdopen(fd, "r+")
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.seek(0)
        holder = fh.read(32).strip() or "another process"
        fh.close()
        raise ParameterError(f"--out {out} is in use by another capture (pid {holder}); wait for it to finish "
                             "or capture into another directory") from None
    try:
        try:
            fh.seek(0)
            fh.truncate()
            fh.write(str(os.getpid()))
            fh.flush()
        except OSError as err:
            raise StorageError(path, err) from None
        yield
    finally:
        fh.close()


def prepare(spec: CaptureSpec, out: Path, resume: bool, damaged: list | None = None,
            episodes: int | None = None) -> dict[int, dict]:
    """Claim ``out`` for ``spec`` (or check it holds this spec), clean temporaries, reconcile finished
    files whose manifest line was lost; returns the manifest records. ``episodes``: the N of this run,
    stored in ``capture.json`` (the largest asked for) so that ``dataset verify`` names episodes that vanished.

    A directory whose ``capture.json`` is missing or damaged while it holds episodes is refused:
    its spec is unknown, and mixing two specs in one directory is never allowed. On resume every
    recorded episode is verified (:func:`~bullet_dlo.data.integrity.verify_records`): a missing,
    damaged, foreign or swapped one is set aside (``<name>.damaged-<k>``), left out of the returned
    records so that it is re-run, and its :class:`~bullet_dlo.data.integrity.Problem` appended to
    ``damaged``.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise StorageError(out, err) from None
    meta = out / SPEC_FILE
    if entry_kind(meta) != "missing":
        old = read_spec_file(out)
        if old["digest"] != spec.digest():
            raise ParameterError(f"{out} holds a capture of a different spec (digest {old['digest']} vs "
                                 f"{spec.digest()}); use another directory")
        if not resume and (read_manifest(out) or any(out.glob("episode_*.h5"))):
            raise ParameterError(f"{out} already holds episodes of this spec; pass --resume to continue")
        if episodes is not None:
            planned = max(episodes, max(read_manifest(out), default=-1) + 1)
            if old.get("episodes") is None or old["episodes"] < planned:
                _write_spec_file(out, old["digest"], old["spec"], planned)  # the plan grows, never shrinks
    else:
        if entry_kind(out / MANIFEST) != "missing" or any(out.glob("episode_*.h5")):
            raise ParameterError(f"{out} holds episodes but no {SPEC_FILE}: their spec is unknown; capture into "
                                 "a new directory")
        # a kill leaves either no spec file or a whole one
        _write_spec_file(out, spec.digest(), json.loads(json.dumps(spec.to_dict(), default=str)), episodes)
    for tmp in out.glob("*.tmp-*"):
        if entry_kind(tmp) in ("file", "symbolic link"):
            tmp.unlink()  # a link goes, never what it points to
    repair_manifest(out)
    records = read_manifest(out)
    if resume:
        from bullet_dlo.data.integrity import verify_records

        for problem in verify_records(out, records, spec.digest()).problems:
            set_aside(out / episode_name(problem.episode))
            records.pop(problem.episode, None)
            if damaged is not None:
                damaged.append(problem)
    from bullet_dlo.data.quality import quality_limits

    limits = quality_limits(spec)
    for path in sorted(out.glob("episode_*.h5")):
        index = _file_index(path)
        if index is None or path.name != episode_name(index):
            continue
        if index not in records or records[index].get("status") == "failed":
            rec = episode_record(path, spec.digest(), limits)
            if rec is not None:
                records[index] = append_manifest(out, rec)
    return records


def _file_index(path: Path) -> int | None:
    """Episode index from a file name ``episode_000012.h5`` (None for other names)."""
    digits = path.stem.split("_")[-1]
    return int(digits) if digits.isdigit() else None
