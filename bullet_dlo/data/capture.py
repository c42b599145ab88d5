"""Capturing a domain-randomised force dataset: the coordinator.

:func:`capture` runs episodes 0..N-1 of a :class:`~bullet_dlo.config.capture.CaptureSpec`
into a directory (layout in :mod:`bullet_dlo.data.storage`), on a local process pool or Ray
(:mod:`bullet_dlo.data.runners`). Episode i depends only on (seed, i), so the files are the
same whatever the number of workers or the backend. Only this process writes the manifest.
With ``resume`` finished episodes are kept, temporary files removed and the rest re-run; a
crashed episode is retried ``retries`` times and then recorded as failed with its error;
a killed worker is replaced and its episode re-run. Nothing is lost or hidden: the directory
is locked while a capture writes into it, its spec digest must match (a missing or damaged
``capture.json`` is refused), and the result lists every failed or missing episode. Planning (the stability policy) is in :mod:`bullet_dlo.data.plan`,
one episode's run in :mod:`bullet_dlo.data.episode`, reading in :mod:`bullet_dlo.data.reader`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.schema import LIMITS, output_dir
from bullet_dlo.core.validate import ParameterError, check_int
from bullet_dlo.data.plan import cable_spec, plan_episode
from bullet_dlo.data.reader import Dataset, load_episode
from bullet_dlo.data.runners import RUNNERS, Task
from bullet_dlo.data.storage import append_manifest, locked, prepare, read_manifest

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
    failed_episodes: tuple[int, ...] = ()
    missing_episodes: tuple[int, ...] = ()  # asked for but without a record: must stay empty

    @property
    def complete(self) -> bool:
        """True when every episode asked for finished (ok or flagged)."""
        return not self.failed_episodes and not self.missing_episodes

    @property
    def episodes_per_second(self) -> float:
        return self.ran / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def capture(spec: CaptureSpec, out: str | Path, episodes: int, *, workers: int = 1, backend: str = "local",
            resume: bool = False, progress: bool = True, retries: int = 1, task: Task | None = None) -> CaptureResult:
    """Capture episodes 0..episodes-1 of ``spec`` into ``out`` with ``workers`` processes (see module doc).

    Every input is checked before any episode runs (counts, the output path, episode 0's cable).
    ``task`` replaces the episode function (tests). Raises ParameterError for bad input, a
    directory in use by another capture, or one holding another (or an unknown) spec.
    """
    if backend not in RUNNERS:
        raise ParameterError(f"--backend must be local or ray, got {backend!r}")
    episodes = check_int("--episodes", episodes, 1, LIMITS["episodes"])
    workers = check_int("--workers", workers, 1, LIMITS["workers"])
    retries = check_int("retries", retries, 0, 100)
    out = output_dir("--out", out)
    first = spec.draw(0)
    if first["n_masses"] == "auto":
        first["n_masses"] = 10  # a placeholder: each episode resolves its own
    cable_spec(first)  # a drawn cable the core refuses fails here, not in N x (1 + retries) episodes
    out.mkdir(parents=True, exist_ok=True)
    with locked(out):
        return _capture_locked(spec, out, episodes, workers, backend, resume, progress, retries, task)


def _capture_locked(spec: CaptureSpec, out: Path, episodes: int, workers: int, backend: str, resume: bool,
                    progress: bool, retries: int, task: Task | None) -> CaptureResult:
    """:func:`capture` once ``out`` is locked."""
    from tqdm import tqdm

    records = prepare(spec, out, resume)
    todo = [i for i in range(episodes) if records.get(i, {}).get("status") not in ("ok", "flagged")]
    tries = {i: 0 for i in todo}
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc="episodes", unit="ep", disable=not progress)
    tic = time.perf_counter()
    spec_dict = spec.to_dict()
    ran = 0
    while todo:
        pending, todo = todo, []
        for index, rec in RUNNERS[backend](spec_dict, pending, str(out), workers, task=task):
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
    failed = tuple(i for i in range(episodes) if i in final and final[i]["status"] == "failed")
    missing = tuple(i for i in range(episodes) if i not in final)
    return CaptureResult(out, len(statuses), ran, len(failed), statuses.count("flagged"), wall, failed, missing)
