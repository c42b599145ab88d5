"""Reading a capture directory: episodes, filtered by status, parameters and quality, and a summary.

Typical use::

    ds = Dataset("out/capture")
    for record in ds.select(where=lambda p: p["robot"] == "panda", max_hf_energy=0.05):
        ep = ds.load(record)          # ep["wrench_world"]: (k, 2, 6), ep["cable_x"]: (k, n, 3)

Nothing is trusted unchecked: opening a dataset checks that every recorded episode file is there,
a regular file of its recorded size (:class:`DamagedDataset` names each one that is not);
:meth:`Dataset.load` parses only bytes whose sha256 matches the manifest line; :meth:`Dataset.verify`
hashes them all (:mod:`bullet_dlo.data.integrity`). No link is followed and no FIFO opened.
"""
from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any, Callable

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.quality import plot_quality
from bullet_dlo.data.integrity import Problem, VerifyReport, check_record, verify_records
from bullet_dlo.data.safeio import read_regular
from bullet_dlo.data.storage import (
    JSON_ATTRS,
    episode_name,
    is_capture_dir,
    planned_episodes,
    read_manifest,
    read_spec_file,
)

OLD_TARE_TILT = 0.01
"""[rad] A gripper tilt above which an episode recorded with the old sensor-frame tare is warned about."""
JOINT_REACTION_RATE = 0.1
"""[rad/s] A gripper turn rate above which an episode whose wrist forces came from Bullet's joint reaction is
warned about (its error, about 0.15 N s^2 times the rate squared on the Panda, reaches ~1.5 mN, 0.5 % of a
30 g cable's weight, near 0.1 rad/s)."""


class DamagedDataset(ParameterError):
    """Recorded episodes whose files are missing, damaged, foreign or swapped: ``problems`` names each."""

    def __init__(self, root: Path, problems: list[Problem]):
        shown = "; ".join(str(p) for p in problems[:5]) + (f"; ... (+{len(problems) - 5})" if len(problems) > 5 else "")
        super().__init__(f"{len(problems)} episode(s) of {root} failed verification: {shown}; "
                         "bullet-dlo capture ... --resume re-runs them")
        self.problems = problems


def load_episode(path: str | Path) -> dict[str, Any]:
    """All arrays of an episode file plus ``params``, ``decision``, ``metrics`` and its other attributes
    (see :mod:`bullet_dlo.data.episode` for the columns). Only a regular file is read (a directory,
    a FIFO or a device raises ParameterError; a link given here is the caller's own choice)."""
    path = Path(path)
    return parse_episode(read_regular(path.resolve()))


def parse_episode(data: bytes) -> dict[str, Any]:
    """The arrays and attributes of an episode file given as bytes (see :func:`load_episode`)."""
    import h5py

    with h5py.File(io.BytesIO(data), "r") as f:
        out: dict[str, Any] = {k: f[k][()] for k in f.keys()}
        for k, v in f.attrs.items():
            out[k] = json.loads(v) if k in JSON_ATTRS else v
    return out


class Dataset:
    """A capture directory: its manifest records (sorted by episode) and episode files.

    A damaged ``capture.json`` or manifest line raises ParameterError naming it (a torn last
    line, the trace of a killed capture, is skipped: ``bullet-dlo capture --resume`` repairs it).
    A recorded episode file that is missing, not a regular file or not of its recorded size raises
    :class:`DamagedDataset` naming every such episode (``check=False``: open anyway, e.g. to
    :meth:`verify` it; :meth:`load` still checks each file it reads).
    """

    def __init__(self, root: str | Path, check: bool = True):
        self.root = Path(root)
        try:
            is_dir = is_capture_dir(self.root)
        except OSError as err:  # e.g. a name too long
            raise ParameterError(f"dataset directory {str(root)[:80]!r}: {err.strerror}") from None
        if not is_dir:
            raise ParameterError(f"{self.root} is not a capture directory (no capture.json)")
        self.spec = read_spec_file(self.root)
        self._by_episode = read_manifest(self.root, strict=True)
        self.records = [r for _, r in sorted(self._by_episode.items())]
        if check:
            report = verify_records(self.root, self._by_episode, self.spec["digest"], full=False)
            if report.problems:
                raise DamagedDataset(self.root, report.problems)

    @property
    def planned(self) -> int | None:
        """How many episodes (0..N-1) the captures into this directory asked for (None: not stored)."""
        return planned_episodes(self.spec)

    def verify(self) -> VerifyReport:
        """Every recorded episode file hashed and checked against its manifest line, its columns scanned
        for NaN and inf, the records compared with the planned episodes (see :mod:`bullet_dlo.data.integrity`)."""
        return verify_records(self.root, self._by_episode, self.spec["digest"], planned=self.planned)

    def missing(self) -> list[int]:
        """Planned episodes without a record (cheap: no file is read; see :meth:`verify`)."""
        return verify_records(self.root, self._by_episode, self.spec["digest"], full=False,
                              planned=self.planned).missing

    def select(self, status: str | None = "ok", where: Callable[[dict], bool] | None = None,
               max_hf_energy: float | None = None) -> list[dict]:
        """Manifest records with ``status`` (None: any), ``where(params)`` true, hf energy below the bound."""
        out = []
        for r in self.records:
            if status is not None and r["status"] != status:
                continue
            if where is not None and not where(r.get("params", {})):
                continue
            if max_hf_energy is not None and not r.get("metrics", {}).get("hf_energy", 1.0) <= max_hf_energy:
                continue
            out.append(r)
        return out

    def load(self, record: dict) -> dict[str, Any]:
        """The episode file of a manifest record (see :func:`load_episode`), read once and parsed only
        when it is that episode's file: its recorded size and sha256 (old lines: its episode number
        and spec). :class:`DamagedDataset` otherwise."""
        return parse_episode(self._checked_bytes(record))

    def _checked_bytes(self, record: dict) -> bytes:
        """The bytes of a record's episode file, verified (see :meth:`load`)."""
        from bullet_dlo.data.integrity import content_problem
        from bullet_dlo.data.safeio import NotARegularFile, sha256

        index = int(record["episode"])
        if record.get("status") not in ("ok", "flagged"):
            raise ParameterError(f"episode {index} of {self.root} has no file (status {record.get('status')})")
        problem = check_record(self.root, index, record, self.spec["digest"], {}, full=False)
        if problem is None:
            name = episode_name(index)
            try:
                data = read_regular(self.root / name)
            except NotARegularFile as err:
                raise DamagedDataset(self.root, [Problem(index, name, "not a file", f"a {err.kind}")]) from None
            if isinstance(record.get("sha256"), str) and sha256(data) == record["sha256"]:
                return data
            problem = content_problem(index, name, data, self.spec["digest"], "sha256" in record)
            if problem is None:
                return data
        raise DamagedDataset(self.root, [problem])

    def old_tare_episodes(self, tilt: float = OLD_TARE_TILT) -> list[int]:
        """Episodes recorded before payload compensation (no ``sensor_compensation`` attribute: the hand's
        weight was tared in the sensor frame) whose grippers tilted by more than ``tilt`` [rad] from
        their first pose: their wrist forces are off by up to the hand's weight times the tilt."""
        import numpy as np

        def tilted(t, q) -> bool:
            x, y, z, w = (q[..., i] for i in range(4))
            approach = np.stack([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)], axis=-1)
            cos = np.clip(np.sum(approach * approach[:1], axis=-1), -1.0, 1.0)  # against the first row
            return float(np.arccos(cos).max()) > tilt

        return self._episodes_without("sensor_compensation", tilted)

    def joint_reaction_episodes(self, rate: float = JOINT_REACTION_RATE) -> list[int]:
        """Episodes whose wrist forces came from Bullet's joint reaction (no ``sensor_transmitted``
        attribute) and whose grippers turned faster than ``rate`` [rad/s] between recorded rows: the
        reaction counts the hand's velocity-product terms twice, a load growing as the turn rate squared
        (a Panda hand turned 90 degrees in 0.7 s read 1.7 N off)."""
        import numpy as np

        def fast(t, q) -> bool:
            if len(q) < 2:
                return False
            dots = np.abs(np.sum(q[1:] * q[:-1], axis=-1)).clip(0.0, 1.0)  # (k-1, 2): |<q_i, q_i+1>|
            turn = 2.0 * np.arccos(dots)  # [rad] between rows, per arm
            dt = np.diff(np.asarray(t, dtype=float))[:, None]
            return bool(np.any(turn > rate * np.where(dt > 0, dt, np.inf)))

        return self._episodes_without("sensor_transmitted", fast)

    def _episodes_without(self, attribute: str, test) -> list[int]:
        """Episodes (not failed, not damaged) whose file lacks ``attribute`` and for which ``test(t, ee_quat)``
        holds (t [s] (k,), grasp-frame quaternions x, y, z, w (k, 2, 4))."""
        import h5py
        import numpy as np

        out = []
        for r in self.records:
            if r["status"] == "failed":
                continue
            try:
                data = self._checked_bytes(r)
            except ParameterError:
                continue  # damaged: reported by verify, not read
            with h5py.File(io.BytesIO(data), "r") as f:
                if attribute in f.attrs or "ee_quat" not in f or "t" not in f:
                    continue
                q = np.asarray(f["ee_quat"], dtype=float)
                t = np.asarray(f["t"], dtype=float)
            if len(q) and test(t, q):
                out.append(int(r["episode"]))
        return out

    def summary(self, png: str | Path | None = None) -> dict:
        """Counts by status, flagged runs with their time of instability, the range each drawn
        parameter covered, counts of stability decisions; quality histograms into ``png`` if given."""
        statuses = [r["status"] for r in self.records]
        numeric: dict[str, list] = {}
        for r in self.records:
            for k, v in (r.get("params") or {}).items():
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    numeric.setdefault(k, []).append(v)
        coverage = {k: [float(min(v)), float(max(v))] for k, v in numeric.items() if min(v) != max(v)}
        flagged = [{"episode": r["episode"], "time_to_instability": r.get("time_to_instability"),
                    "reason": r.get("reason")} for r in self.records if r["status"] == "flagged"]
        decisions: dict[str, int] = {}
        for r in self.records:
            action = (r.get("decision") or {}).get("action", "n/a")
            key = action.split(" ")[0] if action else "none"
            decisions[key] = decisions.get(key, 0) + 1
        if png is not None:
            plot_quality(self.records, png)
        quality = sum(1 for r in flagged if str(r["reason"]).startswith("quality"))
        return {"episodes": len(self.records), "ok": statuses.count("ok"), "flagged": statuses.count("flagged"),
                "flagged_for_quality": quality,
                "failed": statuses.count("failed"), "flagged_runs": flagged, "coverage": coverage,
                "decisions": decisions, "old_tare_tilted": self.old_tare_episodes(),
                "joint_reaction_turned": self.joint_reaction_episodes()}
