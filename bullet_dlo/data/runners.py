"""Running episodes in parallel: a local process pool or Ray tasks.

A runner takes the spec (its dict form, cheap to send to workers), the episode indices and the
output directory, and yields ``(index, record)`` as episodes finish, in any order. Records of
episodes that crashed are ``failed`` records; the coordinator decides about retries.
"""
from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterator

from bullet_dlo.core.validate import ParameterError
from bullet_dlo.data.storage import failed_record

Runner = Callable[[dict, list[int], str, int], Iterator[tuple[int, dict]]]


def _episode_task() -> Callable[[dict, int, str], dict]:
    # imported when a run starts: reading a dataset must not load PyBullet
    from bullet_dlo.data.episode import run_episode_safely

    return run_episode_safely


def run_local(spec_dict: dict, indices: list[int], out: str, workers: int) -> Iterator[tuple[int, dict]]:
    """Process pool (spawned workers); a crashed worker (BrokenProcessPool) is replaced and its
    episodes re-submitted once; an episode whose worker dies twice is recorded as failed."""
    task = _episode_task()
    remaining = list(indices)
    crashes = {i: 0 for i in indices}
    while remaining:
        with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
            futures = {pool.submit(task, spec_dict, i, out): i for i in remaining}
            finished: set[int] = set()
            try:
                for fut in as_completed(futures):
                    i = futures[fut]
                    finished.add(i)
                    yield i, fut.result()
            except BrokenProcessPool:
                pass
        lost = [i for i in remaining if i not in finished]
        for i in lost:
            crashes[i] += 1
        for i in [i for i in lost if crashes[i] > 1]:
            yield i, failed_record(i, "worker process died twice")
        remaining = [i for i in lost if crashes[i] <= 1]


def run_ray(spec_dict: dict, indices: list[int], out: str, workers: int) -> Iterator[tuple[int, dict]]:
    """Ray tasks (``ray.init()`` joins RAY_ADDRESS if set, else starts a local instance with ``workers`` CPUs);
    a task whose worker died is retried once by Ray, then recorded as failed."""
    try:
        import ray
    except ImportError:
        raise ParameterError("backend 'ray' needs Ray: pip install 'bullet_dlo[ray]'") from None
    if not ray.is_initialized():
        ray.init(num_cpus=None if os.environ.get("RAY_ADDRESS") else workers, include_dashboard=False,
                 log_to_driver=False)
    task = ray.remote(max_retries=1)(_episode_task())
    refs = {task.remote(spec_dict, i, out): i for i in indices}
    while refs:
        done, _ = ray.wait(list(refs), num_returns=1)
        for ref in done:
            i = refs.pop(ref)
            try:
                yield i, ray.get(ref)
            except Exception as err:  # noqa: BLE001 - e.g. the worker node died
                yield i, failed_record(i, f"{type(err).__name__}: {err}")


RUNNERS: dict[str, Runner] = {"local": run_local, "ray": run_ray}
