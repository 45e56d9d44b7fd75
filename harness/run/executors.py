"""Where the runner's units run: in this process, in joblib worker processes, or on a Dask cluster.

An executor is a callable `(jobs, settings) -> iterator of (unit, work, rows)`, where `jobs` are
(unit, units of work to do) pairs; it yields each unit of work's rows as they arrive, or
`(unit, work, None)` for each one it lost (a killed worker, a broken pool). Only the in-process
executor streams a unit's suites one by one; workers return a unit's rows together. The
in-process one, `inline`, is the runner's default, so it lives in `harness.run.runner` (this module
builds on the runner, never the other way) and is listed here with the others.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any

from harness.measure.timing import THREAD_ENV
from harness.run.plan import Unit
from harness.run.runner import inline, run_unit_in_worker
from harness.settings import Settings

__all__ = ["ExecutorUnavailable", "choose", "dask", "dask_client", "inline", "joblib"]

Jobs = list[tuple[Unit, tuple[str, ...]]]


class ExecutorUnavailable(RuntimeError):
    """The executor asked for cannot be had (Dask is not installed, its scheduler cannot be
    reached), found before any unit runs: bad input to a command, which says so as its usage error."""


def _lost(job: tuple[Unit, tuple[str, ...]], why: str) -> Iterator[tuple[Unit, str, None]]:
    unit, todo = job
    print(f"[swingbench] {unit.label}: lost to the executor ({why}); --resume runs it", file=sys.stderr)
    for work in todo:
        yield unit, work, None


def joblib(workers: int):
    """joblib's loky backend: `workers` processes, each pinned to the run's threads."""

    def run(jobs: Jobs, settings: Settings) -> Iterator[tuple[Unit, str, list[dict] | None]]:
        from joblib import Parallel, delayed, parallel_config

        returned: set[int] = set()
        try:
            with parallel_config(backend="loky", inner_max_num_threads=settings.threads):
                parallel = Parallel(n_jobs=workers, return_as="generator_unordered", batch_size=1,
                                    pre_dispatch="n_jobs")
                calls = (delayed(_indexed)(i, unit, settings, todo) for i, (unit, todo) in enumerate(jobs))
                for index, parts in parallel(calls):
                    returned.add(index)
                    for work, rows in parts:
                        yield jobs[index][0], work, rows
        except Exception as exc:  # noqa: BLE001 - e.g. TerminatedWorkerError: the rest is lost, not failed
            for index, job in enumerate(jobs):
                if index not in returned:
                    yield from _lost(job, f"{type(exc).__name__}: {exc}")

    return run


def _indexed(index: int, unit: Unit, settings: Settings, todo: tuple[str, ...]) -> tuple[int, list]:
    return index, run_unit_in_worker(unit, settings, todo)


def dask(client: Any):
    """A dask.distributed `client`'s workers (give them 1 thread each for a sweep)."""

    def run(jobs: Jobs, settings: Settings) -> Iterator[tuple[Unit, str, list[dict] | None]]:
        from distributed import as_completed

        futures = [client.submit(run_unit_in_worker, unit, settings, todo, pure=False, retries=0)
                   for unit, todo in jobs]
        owner = {future.key: job for future, job in zip(futures, jobs)}
        try:
            for future in as_completed(futures):
                job = owner[future.key]
                try:
                    parts = future.result()
                except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker
                    yield from _lost(job, f"{type(exc).__name__}: {exc}")
                    continue
                finally:
                    future.release()
                for work, rows in parts:
                    yield job[0], work, rows
        finally:
            client.cancel([f for f in futures if not f.done()])

    return run


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int, threads: int = 1) -> Iterator[Any]:
    """A client of the scheduler at `scheduler`, or of a LocalCluster of `workers` processes with
    `threads` threads each when `scheduler` is None. `ExecutorUnavailable` when Dask is missing or the
    scheduler cannot be reached."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ExecutorUnavailable("--scheduler/--dask-local need dask.distributed: "
                                  "pip install 'swingbench[dask]'") from None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, ValueError) as exc:
            raise ExecutorUnavailable(f"cannot connect to the dask scheduler {scheduler}: {exc}") from None
        with client:
            counts = client.nthreads()
            if any(n > threads for n in counts.values()):
                print(f"[swingbench] warning: dask workers with more than {threads} thread(s) ({counts}); "
                      "runs on one worker share its cores and their times contend", file=sys.stderr)
            yield client
        return
    env = {var: str(threads) for var in THREAD_ENV}
    with LocalCluster(n_workers=workers, threads_per_worker=threads, processes=True, dashboard_address=None,
                      env=env) as cluster, Client(cluster) as client:
        yield client


@contextlib.contextmanager
def choose(scheduler: str | None, dask_local: bool, workers: int, threads: int = 1,
           local: Any = None) -> Iterator[Any]:
    """The executor the command line names: the Dask scheduler at `scheduler`, a LocalCluster of
    `workers` processes (`dask_local`), or else `local` (None: `inline`, this process).
    `ExecutorUnavailable` on entering it when the Dask one cannot be had."""
    if scheduler is None and not dask_local:
        yield local or inline
        return
    with dask_client(scheduler, workers, threads) as client:
        yield dask(client)
