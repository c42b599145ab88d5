"""Running episodes in parallel: a local process pool or Ray tasks.

A runner takes the spec (its dict form, cheap to send to workers), the episode indices and the
output directory, and yields ``(index, record)`` as episodes finish, in any order; it yields
exactly one record per index. Records of episodes that crashed are ``failed`` records; the
coordinator decides about retries. ``task`` replaces the episode function (tests use it to
kill workers on purpose); it must be importable by name in a spawned process.

Local workers watch their parent: when the coordinator dies (even by SIGKILL) they exit
within ``PARENT_POLL_S`` instead of running on as orphans that write files no manifest lists.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterator

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.storage import failed_record

Task = Callable[[dict, int, str], dict]
Runner = Callable[..., Iterator[tuple[int, dict]]]
SHARED_ROUNDS = 2  # broken pool rounds before lost episodes run one per pool
PARENT_POLL_S = 0.5  # [s] how often a local worker checks that its coordinator is alive


def _episode_task() -> Callable[[dict, int, str], dict]:
    # imported when a run starts: reading a dataset must not load PyBullet
    from bullet_dlo.data.episode import run_episode_safely

    return run_episode_safely


def watch_parent(parent: int) -> None:
    """Worker initializer: exit this process as soon as ``parent`` (the coordinator's pid) is gone."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(3)  # orphaned: the coordinator will not record anything this worker writes

    threading.Thread(target=watch, name="watch-parent", daemon=True).start()


def run_local(spec_dict: dict, indices: list[int], out: str, workers: int,
              task: Task | None = None) -> Iterator[tuple[int, dict]]:
    """Process pool (spawned workers). When a worker dies the pool breaks and every episode it had
    not returned is lost: those are re-run. A broken pool cannot say whose worker died, so after
    ``SHARED_ROUNDS`` broken rounds the rest run one per pool; an episode whose worker dies twice
    alone is recorded as failed (an innocent episode that shared a pool is never blamed)."""
    task = task or _episode_task()
    remaining = list(indices)
    deaths = {i: 0 for i in indices}
    rounds = 0
    while remaining:
        isolated = rounds >= SHARED_ROUNDS
        groups = [[i] for i in remaining] if isolated else [remaining]
        lost: list[int] = []
        for group in groups:
            yield from _pool_round(task, spec_dict, group, out, workers, lost)
        if isolated:
            for i in lost:
                deaths[i] += 1
        for i in [i for i in lost if deaths[i] >= 2]:
            yield i, failed_record(i, "worker process died twice")
        remaining = [i for i in lost if deaths[i] < 2]
        rounds += 1


def _pool_round(task: Task, spec_dict: dict, group: list[int], out: str, workers: int,
                lost: list[int]) -> Iterator[tuple[int, dict]]:
    """Run ``group`` on one pool, yielding records as they come; episodes without one go to ``lost``."""
    with ProcessPoolExecutor(max_workers=min(workers, len(group)), mp_context=mp.get_context("spawn"),
                             initializer=watch_parent, initargs=(os.getpid(),)) as pool:
        futures = {pool.submit(task, spec_dict, i, out): i for i in group}
        for fut in as_completed(futures):
            i = futures[fut]
            try:
                record = fut.result()
            except BrokenProcessPool:
                lost.append(i)  # its worker died, or another one and the pool broke: re-run
                continue
            yield i, record  # finished only once its record is in hand: a killed episode is never lost


def run_ray(spec_dict: dict, indices: list[int], out: str, workers: int,
            task: Task | None = None) -> Iterator[tuple[int, dict]]:
    """Ray tasks (``ray.init()`` joins RAY_ADDRESS if set, else starts a local instance with ``workers`` CPUs);
    a task whose worker died is retried once by Ray, then recorded as failed."""
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
        done, _ = ray.wait(list(refs), num_returns=1)
        for ref in done:
            i = refs.pop(ref)
            try:
                yield i, ray.get(ref)
            except Exception as err:  # noqa: BLE001 - e.g. the worker node died
                yield i, failed_record(i, f"{type(err).__name__}: {err}")


RUNNERS: dict[str, Runner] = {"local": run_local, "ray": run_ray}
