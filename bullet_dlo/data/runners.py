"""Running episodes in parallel: a local process pool or Ray tasks.

A runner takes the spec (its dict form, cheap to send to workers), the episode indices and the
output directory, and yields ``(index, record)`` as episodes finish, in any order; it yields
exactly one record per index. Records of episodes that crashed are ``failed`` records; the
coordinator decides about retries. ``task`` replaces the episode function (tests use it to
kill workers on purpose); it must be importable by name in a spawned process.

Local workers watch their parent: when the coordinator dies (even by SIGKILL) they exit
within ``PARENT_POLL_S`` instead of running on as orphans that write files no manifest lists.

Stopping: a runner given a ``stop`` event (set by the coordinator's SIGINT/SIGTERM handler) checks
it every ``STOP_POLL_S``; once set it yields the records of episodes already finished, cancels the
queued ones, terminates its workers and returns. Workers ignore SIGINT (a Ctrl-C reaches the
whole process group): the coordinator alone decides what to stop and what to record.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterator

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.safeio import StorageError
from bullet_dlo.data.storage import failed_record

Task = Callable[[dict, int, str], dict]
Runner = Callable[..., Iterator[tuple[int, dict]]]
SHARED_ROUNDS = 2  # broken pool rounds before lost episodes run one per pool
PARENT_POLL_S = 0.5  # [s] how often a local worker checks that its coordinator is alive
STOP_POLL_S = 0.1  # [s] how often a runner checks its stop event


def _episode_task() -> Callable[[dict, int, str], dict]:
    # imported when a run starts: reading a dataset must not load PyBullet
    from bullet_dlo.data.episode import run_episode_safely

    return run_episode_safely


def watch_parent(parent: int) -> None:
    """Worker initializer: exit this process as soon as ``parent`` (the coordinator's pid) is gone;
    ignore SIGINT (the coordinator stops the workers it wants stopped)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(3)  # orphaned: the coordinator will not record anything this worker writes

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


def run_local(spec_dict: dict, indices: list[int], out: str, workers: int, task: Task | None = None,
              stop: threading.Event | None = None) -> Iterator[tuple[int, dict]]:
    """Process pool (spawned workers). When a worker dies the pool breaks and every episode it had
    not returned is lost: those are re-run. A broken pool cannot say whose worker died, so after
    ``SHARED_ROUNDS`` broken rounds the rest run one per pool; an episode whose worker dies twice
    alone is recorded as failed (an innocent episode that shared a pool is never blamed).
    A set ``stop`` ends the run (see the module doc): unfinished episodes get no record."""
    task = task or _episode_task()
    stop = stop or threading.Event()
    remaining = list(indices)
    deaths = {i: 0 for i in indices}
    rounds = 0
    while remaining and not stop.is_set():
        isolated = rounds >= SHARED_ROUNDS
        groups = [[i] for i in remaining] if isolated else [remaining]
        lost: list[int] = []
        for group in groups:
            if stop.is_set():
                return
            yield from _pool_round(task, spec_dict, group, out, workers, lost, stop)
        if stop.is_set():
            return
        if isolated:
            for i in lost:
                deaths[i] += 1
        for i in [i for i in lost if deaths[i] >= 2]:
            yield i, failed_record(i, "worker process died twice")
        remaining = [i for i in lost if deaths[i] < 2]
        rounds += 1


def _pool_round(task: Task, spec_dict: dict, group: list[int], out: str, workers: int, lost: list[int],
                stop: threading.Event) -> Iterator[tuple[int, dict]]:
    """Run ``group`` on one pool, yielding records as they come; episodes without one go to ``lost``.
    When ``stop`` is set: the finished ones are yielded, the rest cancelled and the workers terminated."""
    pool = ProcessPoolExecutor(max_workers=min(workers, len(group)), mp_context=mp.get_context("spawn"),
                               initializer=watch_parent, initargs=(os.getpid(),))
    try:
        futures = {pool.submit(task, spec_dict, i, out): i for i in group}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=STOP_POLL_S, return_when=FIRST_COMPLETED)
            for fut in done:
                i = futures[fut]
                try:
                    record = fut.result()
                except BrokenProcessPool:
                    lost.append(i)  # its worker died, or another one and the pool broke: re-run
                    continue
                except StorageError as err:  # a task without run_episode_safely's net
                    record = failed_record(i, str(err), write_error=True, path=str(err.path), cause=err.cause)
                yield i, record  # finished only once its record is in hand: a killed episode is never lost
            if stop.is_set():
                for fut in pending:  # finished while we looked: recorded, not re-run
                    if fut.done() and not fut.cancelled() and fut.exception() is None:
                        yield futures[fut], fut.result()
                return
    finally:
        _stop_pool(pool)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Shut ``pool`` down now: queued episodes cancelled, running workers terminated (their temporary
    files are removed by the next resume), without waiting for anything still running."""
    processes = list(getattr(pool, "_processes", {}).values())  # the executor has no public handle on them
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        if proc.is_alive():
            proc.terminate()
    for proc in processes:
        proc.join(timeout=5.0)
    if manager is not None:
        # Python < 3.12 races at exit: its atexit hook wakes a manager thread that may be closing
        # its pipe at that moment ("handle is closed", a traceback after a clean stop). Once the
        # workers are gone the thread ends within a poll; waiting here leaves nothing to race.
        manager.join(timeout=5.0)


def run_ray(spec_dict: dict, indices: list[int], out: str, workers: int, task: Task | None = None,
            stop: threading.Event | None = None) -> Iterator[tuple[int, dict]]:
    """Ray tasks (``ray.init()`` joins RAY_ADDRESS if set, else starts a local instance with ``workers`` CPUs);
    a task whose worker died is retried once by Ray, then recorded as failed. A set ``stop`` cancels
    the tasks not yet finished."""
    try:
        import ray
    except ImportError:
        raise ParameterError("backend 'ray' needs Ray: pip install 'bullet_dlo[ray]'") from None
    if not ray.is_initialized():
        ray.init(num_cpus=None if os.environ.get("RAY_ADDRESS") else workers, include_dashboard=False,
                 log_to_driver=False)
    remote = ray.remote(max_retries=1)(task or _episode_task())
    refs = {remote.remote(spec_dict, i, out): i for i in indices}
    while refs:
        if stop is not None and stop.is_set():
            for ref in refs:
                ray.cancel(ref, force=True)
            return
        done, _ = ray.wait(list(refs), num_returns=1, timeout=STOP_POLL_S)
        for ref in done:
            i = refs.pop(ref)
            try:
                yield i, ray.get(ref)
            except Exception as err:  # noqa: BLE001 - e.g. the worker node died
                yield i, failed_record(i, f"{type(err).__name__}: {err}")


RUNNERS: dict[str, Runner] = {"local": run_local, "ray": run_ray}
