"""Reading a capture directory: episodes, filtered by status, parameters and quality, and a summary.

Typical use::

    ds = Dataset("out/capture")
    for record in ds.select(where=lambda p: p["robot"] == "panda", max_hf_energy=0.05):
        ep = ds.load(record)          # ep["wrench_world"]: (k, 2, 6), ep["cable_x"]: (k, n, 3)
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.quality import plot_quality
from bullet_dlo.data.storage import JSON_ATTRS, is_capture_dir, read_manifest, read_spec_file

OLD_TARE_TILT = 0.01
"""[rad] A gripper tilt above which an episode recorded with the old sensor-frame tare is warned about."""


def load_episode(path: str | Path) -> dict[str, Any]:
    """All arrays of an episode file plus ``params``, ``decision``, ``metrics`` and its other attributes
    (see :mod:`bullet_dlo.data.episode` for the columns)."""
    import h5py

    with h5py.File(path, "r") as f:
        out: dict[str, Any] = {k: f[k][()] for k in f.keys()}
        for k, v in f.attrs.items():
            out[k] = json.loads(v) if k in JSON_ATTRS else v
    return out


class Dataset:
    """A capture directory: its manifest records (sorted by episode) and episode files.

    A damaged ``capture.json`` or manifest line raises ParameterError naming it (a torn last
    line, the trace of a killed capture, is skipped: ``bullet-dlo capture --resume`` repairs it).
    """

    def __init__(self, root: str | Path):
        self.root = Path(root)
        if not is_capture_dir(self.root):
            raise ParameterError(f"{self.root} is not a capture directory (no capture.json)")
        self.spec = read_spec_file(self.root)
        self.records = [r for _, r in sorted(read_manifest(self.root, strict=True).items())]

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
        """The episode file of a manifest record (see :func:`load_episode`)."""
        return load_episode(self.root / record["file"])

    def old_tare_episodes(self, tilt: float = OLD_TARE_TILT) -> list[int]:
        """Episodes recorded before payload compensation (no ``sensor_compensation`` attribute: the hand's
        weight was tared in the sensor frame) whose grippers tilted by more than ``tilt`` [rad] from
        their first pose: their wrist forces are off by up to the hand's weight times the tilt."""
        import h5py
        import numpy as np

        out = []
        for r in self.records:
            path = self.root / str(r.get("file") or "")
            if r["status"] == "failed" or not path.is_file():
                continue
            with h5py.File(path, "r") as f:
                if "sensor_compensation" in f.attrs or "ee_quat" not in f:
                    continue
                q = np.asarray(f["ee_quat"], dtype=float)  # (k, 2, 4) x, y, z, w
            x, y, z, w = (q[..., i] for i in range(4))
            approach = np.stack([2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)], axis=-1)
            cos = np.clip(np.sum(approach * approach[:1], axis=-1), -1.0, 1.0)  # against the first row
            if len(q) and float(np.arccos(cos).max()) > tilt:
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
                "decisions": decisions, "old_tare_tilted": self.old_tare_episodes()}
