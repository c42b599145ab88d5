"""Capturing a domain-randomised force dataset: the coordinator.

:func:`capture` runs episodes 0..N-1 of a :class:`~bullet_dlo.config.capture.CaptureSpec`
into a directory (layout in :mod:`bullet_dlo.data.storage`), on a local process pool or Ray
(:mod:`bullet_dlo.data.runners`). Episode i depends only on (seed, i), so the files are the
same whatever the number of workers or the backend. Only this process writes the manifest.
With ``resume`` finished episodes are kept, temporary files removed and the rest re-run; a
crashed episode is retried ``retries`` times and then recorded as failed with its error;
a killed worker is replaced. Planning (the stability policy) is in :mod:`bullet_dlo.data.plan`,
one episode's run in :mod:`bullet_dlo.data.episode`, reading in :mod:`bullet_dlo.data.reader`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.plan import plan_episode
from bullet_dlo.data.reader import Dataset, load_episode
from bullet_dlo.data.runners import RUNNERS
from bullet_dlo.data.storage import append_manifest, prepare, read_manifest

# Dataset, load_episode and plan_episode are re-exported: this module held them before the split
__all__ = ["CaptureResult", "capture", "Dataset", "load_episode", "plan_episode"]


@dataclass
class CaptureResult:
    """Outcome of a capture: ``done`` episodes in ``out`` (``failed`` and ``flagged`` among them),
    ``ran`` of them by this call, in ``wall_time_s`` [s]."""

    out: Path
    done: int
    ran: int
    failed: int
    flagged: int
    wall_time_s: float

    @property
    def episodes_per_second(self) -> float:
        return self.ran / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def capture(spec: CaptureSpec, out: str | Path, episodes: int, *, workers: int = 1, backend: str = "local",
            resume: bool = False, progress: bool = True, retries: int = 1) -> CaptureResult:
    """Capture episodes 0..episodes-1 of ``spec`` into ``out`` with ``workers`` processes (see module doc)."""
    from tqdm import tqdm

    if backend not in RUNNERS:
        raise ParameterError(f"backend must be local or ray, got {backend!r}")
    if episodes < 1 or workers < 1:
        raise ParameterError("episodes and workers must be >= 1")
    out = Path(out)
    records = prepare(spec, out, resume)
    todo = [i for i in range(episodes) if records.get(i, {}).get("status") not in ("ok", "flagged")]
    tries = {i: 0 for i in todo}
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc="episodes", unit="ep", disable=not progress)
    tic = time.perf_counter()
    spec_dict = spec.to_dict()
    ran = 0
    while todo:
        pending, todo = todo, []
        for index, rec in RUNNERS[backend](spec_dict, pending, str(out), workers):
            if rec["status"] == "failed" and tries[index] < retries:
                tries[index] += 1
                todo.append(index)
                continue
            append_manifest(out, rec)
            records[index] = rec
            ran += 1
            bar.update(1)
    bar.close()
    wall = time.perf_counter() - tic
    final = read_manifest(out)
    statuses = [final[i]["status"] for i in range(episodes) if i in final]
    return CaptureResult(out, len(statuses), ran, statuses.count("failed"), statuses.count("flagged"), wall)
