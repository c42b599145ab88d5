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
    """Process pool (spawned workers); a crashed worker (BrokenProcessPool) is replaced and its
    episodes re-submitted once; an episode whose worker dies twice is recorded as failed."""
    task = task or _episode_task()
    remaining = list(indices)
    crashes = {i: 0 for i in indices}
    while remaining:
        with ProcessPoolExecutor(max_workers=min(workers, len(remaining)), mp_context=mp.get_context("spawn"),
                                 initializer=watch_parent, initargs=(os.getpid(),)) as pool:
            futures = {pool.submit(task, spec_dict, i, out): i for i in remaining}
            finished: set[int] = set()
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    record = fut.result()
                except BrokenProcessPool:
                    continue  # its worker died (or the pool broke): re-submitted below
                finished.add(i)  # only once its record is in hand: a killed episode is never lost
                yield i, record
        lost = [i for i in remaining if i not in finished]
        for i in lost:
            crashes[i] += 1
        for i in [i for i in lost if crashes[i] > 1]:
            yield i, failed_record(i, "worker process died twice")
        remaining = [i for i in lost if crashes[i] <= 1]


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
