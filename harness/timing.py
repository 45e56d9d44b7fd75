"""Wall-clock measurement: warm calls, repeats, medians, pinned threads."""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator
from typing import Any, NamedTuple

import numpy as np

__all__ = ["THREAD_ENV", "Timing", "blas_threads", "pin_threads", "time_call"]

THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


def pin_threads(n: int) -> None:
    """Pin BLAS/OpenMP and XLA to `n` threads (torch: the adapter's `threads` option). Environment
    variables only take effect in libraries not yet loaded, so call this first thing in a process
    (the CLI and asv do). XLA sizes its CPU pool from PJRT_NPROC when its backend starts (see
    `solvers.pinn.jax_pinn`, which sets it again from its own `threads` option)."""
    for var in THREAD_ENV:
        os.environ[var] = str(n)
    os.environ["SWINGBENCH_THREADS"] = str(n)
    os.environ["PJRT_NPROC"] = str(n)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        pass
    else:
        threadpool_limits(n)


@contextlib.contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """BLAS on `n` threads inside the block (None: as pinned). For adapters whose queries are
    fastest with another BLAS thread count than the run's (`AbstractSolver.blas_threads`)."""
    if n is None:
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=n, user_api="blas"):
        yield


class Timing(NamedTuple):
    """Seconds per call over `repeats` warm calls: median, 25th and 75th percentiles, minimum."""

    median_s: float
    q25_s: float
    q75_s: float
    min_s: float
    repeats: int


def time_call(
    fn: Callable[[], Any], *, warmup: int = 1, min_repeats: int = 5, max_repeats: int = 1000,
    budget_s: float = 1.0, slow_s: float = float("inf"),
) -> Timing:
    """Time `fn()` after `warmup` untimed calls: at least `min_repeats` calls, then more until
    `budget_s` seconds are spent or `max_repeats` are done. Each call is timed on its own with
    `time.perf_counter`, so the statistics describe single calls, not a batch average. A call whose
    warm-up took more than `slow_s` seconds is timed once (`repeats` says so)."""
    for _ in range(warmup):
        start = time.perf_counter()
        fn()
        if time.perf_counter() - start > slow_s:
            min_repeats = max_repeats = 1
    samples: list[float] = []
    spent = 0.0
    while len(samples) < min_repeats or (spent < budget_s and len(samples) < max_repeats):
        start = time.perf_counter()
        fn()
        elapsed = time.perf_counter() - start
        samples.append(elapsed)
        spent += elapsed
    arr = np.asarray(samples)
    q25, median, q75 = np.percentile(arr, [25, 50, 75])
    return Timing(float(median), float(q25), float(q75), float(arr.min()), arr.size)
