"""Verifying a capture directory's episode files against what their manifest lines say.

Each finished episode's manifest line holds its file's ``size`` [B] and ``sha256`` (and the
library ``version`` and ``spec_digest``; :func:`bullet_dlo.data.storage.append_manifest`).
:func:`verify_records` checks every recorded episode and names each one that is:

- ``missing``: no entry at its name;
- ``not a file``: a symbolic link (never followed), a directory, a FIFO (never opened) or a device;
- ``damaged``: another size (truncated, extended) or other bytes (flipped), or not a readable episode;
- ``swapped``: it holds another episode (the bytes recorded for episode j, or its ``episode`` attribute);
- ``foreign``: it was captured for another spec (its ``spec_digest`` attribute);
- ``non-finite``: a numeric column holds NaN or inf (a stable episode never records one; scanned in
  blocks of rows even when the sha256 matches: a file re-hashed after an edit, or an old line).

It also compares the records with the episodes planned (``capture.json``'s ``episodes``, N: 0..N-1;
for a directory written before the count was stored, 0 up to the highest recorded): an episode
without a record (an interrupted capture not yet resumed, or a line and file removed) is ``missing``
from the report, which is then not ok ("incomplete: k of N episodes, missing i, j").

Lines written before hashes were recorded are checked as far as they can be
(a regular file that opens as an episode of this number and spec) and counted in ``unhashed``:
their bytes cannot be verified. ``dataset verify``, ``dataset summary``, :class:`~bullet_dlo.data.reader.Dataset`
and ``capture --resume`` (which re-runs what it finds) rely on it.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

from bullet_dlo.data.safeio import NotARegularFile, entry_kind, read_regular, sha256
from bullet_dlo.data.storage import JSON_ATTRS, episode_name


@dataclass(frozen=True)
class Problem:
    """What is wrong with recorded episode ``episode`` (file ``file``): ``kind`` (missing, not a file,
    damaged, swapped, foreign) and a one-line ``detail``."""

    episode: int
    file: str
    kind: str
    detail: str

    def __str__(self) -> str:
        return f"episode {self.episode} ({self.file}): {self.kind}: {self.detail}"


@dataclass
class VerifyReport:
    """Outcome of :func:`verify_records`: ``checked`` recorded episode files, ``hashed`` of them
    against a recorded sha256, ``unhashed`` only for form (old lines), the ``problems`` and the
    episode files on disk without a record (``unrecorded``: a resume rebuilds their records)."""

    checked: int = 0
    hashed: int = 0
    unhashed: int = 0
    problems: list[Problem] = field(default_factory=list)
    unrecorded: list[str] = field(default_factory=list)
    planned: int | None = None  # episodes 0..planned-1 asked for (None: not stored, gaps only are found)
    missing: list[int] = field(default_factory=list)  # planned episodes without any record
    recorded: int = 0  # planned episodes with a record (any status)

    @property
    def ok(self) -> bool:
        return not self.problems and not self.missing

    def incomplete(self) -> str | None:
        """``incomplete: k of N episodes recorded, missing i, j`` (None when none is missing)."""
        if not self.missing:
            return None
        shown = ", ".join(map(str, self.missing[:10])) + (f", ... (+{len(self.missing) - 10})"
                                                          if len(self.missing) > 10 else "")
        total = self.planned if self.planned is not None else f"at least {self.recorded + len(self.missing)}"
        return f"incomplete: {self.recorded} of {total} episodes recorded, missing {shown}"

    def lines(self) -> list[str]:
        """The report for a terminal: one line per problem, the missing episodes, then a note on unhashed and
        unrecorded files and on a plan that was not stored."""
        out = [f"  {p}" for p in self.problems]
        if self.missing:
            out.append(f"  {self.incomplete()} (bullet-dlo capture ... --resume runs them)")
        if self.planned is None:
            out.append("  note: capture.json does not store how many episodes were planned (written before it "
                       "did): only gaps below the highest recorded episode can be found; a resume stores it")
        if self.unhashed:
            out.append(f"  note: {self.unhashed} episode(s) have no recorded sha256 (written before manifest "
                       "lines carried hashes): checked to be readable episodes of this number and spec; their bytes cannot "
                       "be verified")
        if self.unrecorded:
            out.append(f"  note: {len(self.unrecorded)} episode file(s) have no manifest record "
                       f"({', '.join(self.unrecorded[:5])}{', ...' if len(self.unrecorded) > 5 else ''}); "
                       "capture --resume rebuilds them")
        return out


def verify_records(root: Path, records: dict[int, dict], digest: str | None, full: bool = True,
                   planned: int | None = None) -> VerifyReport:
    """Check the file of every finished (ok or flagged) record in ``records`` (by episode) under
    ``root`` (see the module doc); ``digest``: the directory's spec digest; ``planned``: the number of
    episodes asked for (None: unknown). With ``full`` False only what needs no reading is checked
    (presence, kind, size): cheap, for opening a large dataset."""
    report = VerifyReport(planned=planned)
    span = planned if planned is not None else max(records, default=-1) + 1
    report.missing = [i for i in range(span) if i not in records]
    report.recorded = sum(1 for i in records if i < span)
    hashes = {r["sha256"]: i for i, r in records.items() if isinstance(r.get("sha256"), str)}
    for index, rec in sorted(records.items()):
        if rec.get("status") not in ("ok", "flagged"):
            continue
        report.checked += 1
        problem = check_record(root, index, rec, digest, hashes, full)
        if problem is not None:
            report.problems.append(problem)
        elif "sha256" in rec:
            report.hashed += full
        else:
            report.unhashed += 1
    recorded = {episode_name(i) for i, r in records.items() if r.get("status") in ("ok", "flagged")}
    report.unrecorded = sorted(p.name for p in root.glob("episode_*.h5") if p.name not in recorded)
    return report


def check_record(root: Path, index: int, rec: dict, digest: str | None, hashes: dict[str, int],
                 full: bool = True) -> Problem | None:
    """The problem with record ``rec`` of episode ``index`` (None: its file is what the record says)."""
    name = episode_name(index)
    if rec.get("file") != name:
        return Problem(index, str(rec.get("file")), "foreign", f"the record names {rec.get('file')!r}, not {name}")
    path = root / name
    kind = entry_kind(path)
    if kind == "missing":
        return Problem(index, name, "missing", "no file")
    if kind != "file":
        return Problem(index, name, "not a file", f"a {kind} ({'not followed' if kind == 'symbolic link' else 'not opened'})")
    size = path.lstat().st_size
    if isinstance(rec.get("size"), int) and size != rec["size"]:
        return Problem(index, name, "damaged", f"{size} B, recorded {rec['size']} B "
                       f"({'truncated' if size < rec['size'] else 'extended'})")
    if not full:
        return None
    try:
        data = read_regular(path)
    except NotARegularFile as err:
        return Problem(index, name, "not a file", f"a {err.kind}")
    except OSError as err:
        return Problem(index, name, "damaged", f"cannot be read ({err.strerror})")
    if isinstance(rec.get("sha256"), str):
        found = sha256(data)
        if found == rec["sha256"]:
            return nonfinite_problem(index, name, data, rec)
        other = hashes.get(found)
        if other is not None and other != index:
            return Problem(index, name, "swapped", f"holds the bytes recorded for episode {other}")
    return content_problem(index, name, data, digest, "sha256" in rec) or nonfinite_problem(index, name, data, rec)


ROWS_PER_BLOCK = 4096
"""Rows of a column read at a time by :func:`nonfinite_columns` (bounded memory on long episodes)."""


def nonfinite_columns(data: bytes) -> dict[str, int]:
    """The float columns of an episode file (given as bytes) holding NaN or inf, with how many values each."""
    import h5py
    import numpy as np

    bad: dict[str, int] = {}

    def scan(name: str, obj) -> None:
        if not isinstance(obj, h5py.Dataset) or obj.dtype.kind not in "fc" or obj.size == 0:
            return
        if obj.ndim == 0:
            count = int(not np.isfinite(obj[()]))
        else:
            count = sum(int(np.count_nonzero(~np.isfinite(obj[i:i + ROWS_PER_BLOCK])))
                        for i in range(0, obj.shape[0], ROWS_PER_BLOCK))
        if count:
            bad[name] = count

    with h5py.File(io.BytesIO(data), "r") as f:
        f.visititems(scan)
    return bad


def nonfinite_problem(index: int, name: str, data: bytes, rec: dict) -> Problem | None:
    """A ``non-finite`` problem when a column of a stable episode holds NaN or inf (None otherwise; an episode
    stopped as unstable, ``time_to_instability`` set, may hold them and is flagged already)."""
    if rec.get("time_to_instability") is not None:
        return None
    try:
        bad = nonfinite_columns(data)
    except Exception as err:  # noqa: BLE001 - any parse failure is damage, named
        return Problem(index, name, "damaged", f"not a readable episode file ({type(err).__name__})")
    if not bad:
        return None
    shown = ", ".join(f"{k} ({n} value{'s' if n > 1 else ''})" for k, n in sorted(bad.items()))
    return Problem(index, name, "non-finite", f"NaN or inf in {shown}")


def content_problem(index: int, name: str, data: bytes, digest: str | None, hashed: bool) -> Problem | None:
    """Why the bytes ``data`` of episode ``index`` are not its episode (None only for an unhashed
    record whose file reads as episode ``index`` of ``digest``)."""
    try:
        attrs = episode_attrs(data)
        episode = int(attrs["episode"])
    except Exception as err:  # noqa: BLE001 - any parse failure is damage, named
        return Problem(index, name, "damaged", f"not a readable episode file ({type(err).__name__})")
    if episode != index:
        return Problem(index, name, "swapped", f"holds episode {episode}")
    file_digest = attrs.get("spec_digest")
    if digest is not None and file_digest is not None and str(file_digest) != digest:
        return Problem(index, name, "foreign", f"captured with another spec (digest {file_digest}, this "
                       f"directory's {digest})")
    if hashed:
        return Problem(index, name, "damaged", "its bytes differ from its recorded sha256")
    return None


def episode_attrs(data: bytes) -> dict:
    """The attributes of an episode file given as bytes (JSON ones parsed)."""
    import json

    import h5py

    with h5py.File(io.BytesIO(data), "r") as f:
        return {k: json.loads(v) if k in JSON_ATTRS else v for k, v in f.attrs.items()}
