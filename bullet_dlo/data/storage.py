"""A capture directory on disk: atomic HDF5 episode files, the manifest, the spec it belongs to.

Layout of a capture directory::

    capture.json            the spec and its digest: a directory never mixes specs
    .lock                   held (flock) by the capture writing into the directory
    manifest.jsonl          one JSON record per finished episode (written by the coordinator only)
    episode_000012.h5       one file per episode, written as ``*.h5.tmp-<pid>`` and renamed when complete

A manifest record holds ``episode``, ``file``, ``status`` (ok | flagged | failed), ``error``,
``time_to_instability``, ``reason``, ``params``, ``decision`` and ``metrics``. A finished
episode file carries everything needed to rebuild its record, so a manifest line lost to a
kill is recovered from the file.
"""
from __future__ import annotations

import json
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError

MANIFEST = "manifest.jsonl"
SPEC_FILE = "capture.json"
LOCK_FILE = ".lock"
STATUSES = ("ok", "flagged", "failed")
JSON_ATTRS = ("params", "decision", "metrics")  # episode attributes stored as JSON text


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
    tmp = final.with_suffix(f".h5.tmp-{os.getpid()}")
    with h5py.File(tmp, "w", libver="latest") as f:
        for key, arr in arrays.items():
            f.create_dataset(key, data=arr, track_times=False)
        if frames is not None and len(frames):
            f.create_dataset("frames", data=frames, track_times=False, compression="gzip", compression_opts=4,
                             chunks=(1,) + frames.shape[1:])
            f.create_dataset("frame_t", data=frame_t, track_times=False)
        for k, v in attrs.items():
            f.attrs[k] = json.dumps(v, sort_keys=True) if k in JSON_ATTRS else v
    os.replace(tmp, final)
    return name


def episode_record(path: Path, digest: str | None = None) -> dict | None:
    """Rebuild the manifest record of a finished episode file; an unreadable file is deleted (None).

    With ``digest``, a file written for another spec raises ParameterError (never mixed in).
    """
    import h5py

    try:
        with h5py.File(path, "r") as f:
            a = f.attrs
            if digest is not None and "spec_digest" in a and str(a["spec_digest"]) != digest:
                raise ParameterError(f"{path} was captured with another spec (digest {a['spec_digest']} vs "
                                     f"{digest}); use another directory")
            t_bad = float(a["time_to_instability"])
            return episode_result(int(a["episode"]), path.name, bool(a["stable"]), None if t_bad < 0 else t_bad,
                                  None, *(json.loads(a[k]) for k in JSON_ATTRS))
    except ParameterError:
        raise
    except Exception:  # noqa: BLE001 - a corrupt file is re-run
        path.unlink(missing_ok=True)
        return None


# ----- manifest and directory ------------------------------------------------------------------
def read_manifest(out: Path, strict: bool = False) -> dict[int, dict]:
    """Manifest records by episode index (the last line of an episode wins).

    A line cut by a kill (not JSON, or not a record with an integer ``episode`` and a ``status``)
    is skipped: its episode is reconciled from its file or re-run. With ``strict`` such a line
    raises ParameterError naming it, except a torn last line (the normal trace of a kill).
    """
    records: dict[int, dict] = {}
    path = out / MANIFEST
    if not path.is_file():
        return records
    try:
        text = path.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as err:
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
    if not path.is_file():
        return 0
    lines = path.read_bytes().decode("utf-8", errors="replace").splitlines()
    good = [line for line in lines if _record(line) is not None]
    if len(good) == len(lines):
        return 0
    tmp = path.with_suffix(f".jsonl.tmp-{os.getpid()}")
    with open(tmp, "w") as fh:
        fh.write("".join(line + "\n" for line in good))
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    return len(lines) - len(good)


def append_manifest(out: Path, record: dict) -> None:
    """Append one record and flush it to disk before returning."""
    path = out / MANIFEST
    with open(path, "a") as fh:
        if _ends_mid_line(path):
            fh.write("\n")  # a line cut by a kill: start a fresh one, or both lines are lost
        fh.write(json.dumps(record, sort_keys=True, default=float) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def _ends_mid_line(path: Path) -> bool:
    """True if the file is non-empty and its last byte is not a newline."""
    with open(path, "rb") as fh:
        if fh.seek(0, os.SEEK_END) == 0:
            return False
        fh.seek(-1, os.SEEK_END)
        return fh.read(1) != b"\n"


def is_capture_dir(root: Path) -> bool:
    """True if ``root`` holds a capture (its spec file)."""
    return (root / SPEC_FILE).is_file()


def read_spec_file(out: Path) -> dict:
    """The parsed ``capture.json`` of ``out``; ParameterError when it is damaged."""
    path = out / SPEC_FILE
    try:
        meta = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ParameterError(f"{path} is damaged ({type(err).__name__}); the spec of this capture directory is "
                             "unknown: capture into a new directory") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("digest"), str):
        raise ParameterError(f"{path} holds no spec digest; the spec of this capture directory is unknown: "
                             "capture into a new directory")
    return meta


@contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on the capture directory ``out`` (a ``.lock`` file, ``fcntl.flock``):
    a second capture or resume into it refuses instead of running every episode twice. The lock
    goes with the process, so a killed capture never leaves it behind."""
    import fcntl

    path = out / LOCK_FILE
    fh = open(path, "a+")
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.seek(0)
        holder = fh.read().strip() or "another process"
        fh.close()
        raise ParameterError(f"--out {out} is in use by another capture (pid {holder}); wait for it to finish "
                             "or capture into another directory") from None
    try:
        fh.seek(0)
        fh.truncate()
        fh.write(str(os.getpid()))
        fh.flush()
        yield
    finally:
        fh.close()


def prepare(spec: CaptureSpec, out: Path, resume: bool) -> dict[int, dict]:
    """Claim ``out`` for ``spec`` (or check it holds this spec), clean temporaries, reconcile finished
    files whose manifest line was lost; returns the manifest records.

    A directory whose ``capture.json`` is missing or damaged while it holds episodes is refused:
    its spec is unknown, and mixing two specs in one directory is never allowed.
    """
    out.mkdir(parents=True, exist_ok=True)
    meta = out / SPEC_FILE
    if meta.exists():
        old = read_spec_file(out)
        if old["digest"] != spec.digest():
            raise ParameterError(f"{out} holds a capture of a different spec (digest {old['digest']} vs "
                                 f"{spec.digest()}); use another directory")
        if not resume and (read_manifest(out) or any(out.glob("episode_*.h5"))):
            raise ParameterError(f"{out} already holds episodes of this spec; pass --resume to continue")
    else:
        if (out / MANIFEST).exists() or any(out.glob("episode_*.h5")):
            raise ParameterError(f"{out} holds episodes but no {SPEC_FILE}: their spec is unknown; capture into "
                                 "a new directory")
        tmp = meta.with_suffix(f".json.tmp-{os.getpid()}")
        tmp.write_text(json.dumps({"digest": spec.digest(), "spec": spec.to_dict(), "version": version()},
                                  indent=2, default=str))
        os.replace(tmp, meta)  # atomic: a kill leaves either no spec file or a whole one
    for tmp in out.glob("*.tmp-*"):
        tmp.unlink()
    repair_manifest(out)
    records = read_manifest(out)
    for path in sorted(out.glob("episode_*.h5")):
        index = _file_index(path)
        if index is None:
            continue
        if index not in records or records[index].get("status") == "failed":
            rec = episode_record(path, spec.digest())
            if rec is not None:
                append_manifest(out, rec)
                records[index] = rec
    return records


def _file_index(path: Path) -> int | None:
    """Episode index from a file name ``episode_000012.h5`` (None for other names)."""
    digits = path.stem.split("_")[-1]
    return int(digits) if digits.isdigit() else None
