"""Capturing a domain-randomised force dataset: the coordinator.

:func:`capture` runs episodes 0..N-1 of a :class:`~bullet_dlo.config.capture.CaptureSpec`
into a directory (layout in :mod:`bullet_dlo.data.storage`), on a local process pool or Ray
(:mod:`bullet_dlo.data.runners`). Episode i depends only on (seed, i), so the files are the
same whatever the number of workers or the backend. Only this process writes the manifest.
With ``resume`` finished episodes are kept, temporary files removed and the rest re-run; a
crashed episode is retried ``retries`` times and then recorded as failed with its error;
a killed worker is replaced and its episode re-run. Nothing is lost or hidden: the directory
is locked while a capture writes into it, its spec digest must match (a missing or damaged
``capture.json`` is refused), and the result lists every failed or missing episode. A resume
verifies every recorded episode file against its manifest line and re-runs the missing, damaged,
foreign or swapped ones (named in ``rerun_damaged``). SIGINT and SIGTERM stop a capture within
~0.1 s: finished episodes are recorded, the rest cancelled, and :class:`CaptureInterrupted` is
raised (exit status 128 + the signal's number by convention). A write failure (full disk,
read-only folder) stops it the same way with a :class:`~bullet_dlo.data.safeio.StorageError`. Planning (the stability policy) is in :mod:`bullet_dlo.data.plan`,
one episode's run in :mod:`bullet_dlo.data.episode`, reading in :mod:`bullet_dlo.data.reader`.
"""
from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from bullet_dlo.config.capture import CaptureSpec
from bullet_dlo.config.schema import LIMITS, output_dir
from bullet_dlo.core.validate import ParameterError, check_int
from bullet_dlo.data.plan import cable_spec, plan_episode
from bullet_dlo.data.reader import Dataset, load_episode
from bullet_dlo.data.runners import RUNNERS, Task
from bullet_dlo.data.safeio import StorageError
from bullet_dlo.data.storage import append_manifest, locked, prepare, read_manifest

# Dataset, load_episode and plan_episode are re-exported: this module held them before the split
__all__ = ["CaptureInterrupted", "CaptureResult", "StopSignal", "capture", "Dataset", "load_episode",
           "plan_episode"]


class StopSignal(threading.Event):
    """Set by SIGINT or SIGTERM (see :func:`stop_on_signals`); ``signum`` says which (0: set otherwise)."""

    signum: int = 0


class CaptureInterrupted(Exception):
    """A capture stopped by a signal after recording ``recorded`` episodes in ``out`` this run."""

    def __init__(self, signum: int, out: Path, recorded: int):
        self.signum, self.out, self.recorded = signum, out, recorded
        name = signal.Signals(signum).name if signum else "a stop request"
        super().__init__(f"interrupted by {name}: {recorded} episode(s) finished and recorded in {out} this run; "
                         "bullet-dlo capture ... --resume continues")

    @property
    def exit_code(self) -> int:
        """128 + the signal's number (130 for SIGINT, 143 for SIGTERM), the shells' convention."""
        return 128 + (self.signum or signal.SIGINT)


@contextmanager
def stop_on_signals(stop: StopSignal | None = None) -> Iterator[StopSignal]:
    """While inside, SIGINT and SIGTERM set ``stop`` (a new :class:`StopSignal` if None) instead of
    raising wherever the program happens to be (inside an import, which may swallow it); the previous
    handlers come back on exit. Outside the main thread nothing is installed."""
    stop = stop if stop is not None else StopSignal()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum: int, _frame) -> None:
        stop.signum = signum
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


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
    rerun_damaged: tuple[str, ...] = ()  # recorded episodes found missing or damaged on resume, and re-run

    @property
    def complete(self) -> bool:
        """True when every episode asked for finished (ok or flagged)."""
        return not self.failed_episodes and not self.missing_episodes

    @property
    def episodes_per_second(self) -> float:
        return self.ran / self.wall_time_s if self.wall_time_s > 0 else float("nan")


def capture(spec: CaptureSpec, out: str | Path, episodes: int, *, workers: int = 1, backend: str = "local",
            resume: bool = False, progress: bool = True, retries: int = 1, task: Task | None = None,
            stop: StopSignal | None = None) -> CaptureResult:
    """Capture episodes 0..episodes-1 of ``spec`` into ``out`` with ``workers`` processes (see module doc).

    Every input is checked before any episode runs (counts, the output path, episode 0's cable).
    ``task`` replaces the episode function (tests). ``stop``: an event that stops the capture when
    set (the command line's, installed before its imports); without it SIGINT/SIGTERM handlers
    are installed for the call. Raises ParameterError for bad input, a directory in use by another
    capture, or one holding another (or an unknown) spec; :class:`CaptureInterrupted` when stopped;
    :class:`~bullet_dlo.data.safeio.StorageError` when a file cannot be written.
    """
    with stop_on_signals(stop) as stop:
        return _capture(spec, out, episodes, workers, backend, resume, progress, retries, task, stop)


def _capture(spec: CaptureSpec, out: str | Path, episodes: int, workers: int, backend: str, resume: bool,
             progress: bool, retries: int, task: Task | None, stop: StopSignal) -> CaptureResult:
    """:func:`capture` with its stop event installed."""
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
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise StorageError(out, err) from None
    with locked(out):
        return _capture_locked(spec, out, episodes, workers, backend, resume, progress, retries, task, stop)


def _capture_locked(spec: CaptureSpec, out: Path, episodes: int, workers: int, backend: str, resume: bool,
                    progress: bool, retries: int, task: Task | None, stop: StopSignal) -> CaptureResult:
    """:func:`capture` once ``out`` is locked."""
    from tqdm import tqdm

    damaged: list = []
    records = prepare(spec, out, resume, damaged, episodes)
    todo = [i for i in range(episodes) if records.get(i, {}).get("status") not in ("ok", "flagged")]
    tries = {i: 0 for i in todo}
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc="episodes", unit="ep", disable=not progress)
    tic = time.perf_counter()
    spec_dict = spec.to_dict()
    ran = 0
    write_error: dict | None = None
    try:
        while todo and not stop.is_set():
            pending, todo = todo, []
            for index, rec in RUNNERS[backend](spec_dict, pending, str(out), workers, task=task, stop=stop):
                if rec.get("write_error"):  # the directory failed, not the episode: stop, record nothing
                    write_error = write_error or rec
                    stop.set()
                    continue
                if rec["status"] == "failed" and tries[index] < retries:
                    tries[index] += 1
                    todo.append(index)
                    continue
                try:
                    records[index] = append_manifest(out, rec)
                except StorageError as err:
                    raise StorageError(err.path, err.cause, f"{ran} episode(s) recorded this run; bullet-dlo "
                                       "capture ... --resume recovers the rest") from None
                ran += 1
                bar.update(1)
    finally:
        bar.close()
    if write_error is not None:
        raise StorageError(write_error.get("path", out), write_error.get("cause", write_error["error"]),
                           f"{ran} episode(s) recorded this run; free the disk or fix the folder, then "
                           "bullet-dlo capture ... --resume")
    if stop.is_set():
        raise CaptureInterrupted(stop.signum, out, ran)
    wall = time.perf_counter() - tic
    final = read_manifest(out)
    statuses = [final[i]["status"] for i in range(episodes) if i in final]
    failed = tuple(i for i in range(episodes) if i in final and final[i]["status"] == "failed")
    missing = tuple(i for i in range(episodes) if i not in final)
    return CaptureResult(out, len(statuses), ran, len(failed), statuses.count("flagged"), wall, failed, missing,
                         tuple(str(p) for p in damaged))
