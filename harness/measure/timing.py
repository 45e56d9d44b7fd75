"""Wall-clock measurement: warm calls, repeats, medians, pinned threads."""

from __future__ import annotations

import contextlib
import os
import re
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any, NamedTuple

import numpy as np

__all__ = ["THREAD_ENV", "Timing", "blas_threads", "pin_threads", "pinned_threads", "time_call"]

THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
              "VECLIB_MAXIMUM_THREADS", "BLIS_NUM_THREADS")
_PINNED_ENV = (*THREAD_ENV, "SWINGBENCH_THREADS", "PJRT_NPROC", "XLA_FLAGS")


def pin_threads(n: int) -> None:
    """Pin this process to `n` threads: the OMP/BLAS environment variables, PJRT_NPROC (the size of
    XLA's CPU pool) and, for 1 thread, XLA_FLAGS without Eigen's thread pool, all read by libraries
    loaded (XLA: started) from now on, so call this first thing in a process (the CLI, asv and the
    runner's workers do); threadpoolctl for the BLAS/OpenMP pools already loaded, and torch when it
    is imported. The adapters' own `threads` options are set by the runner from the same number."""
    for var in (*THREAD_ENV, "SWINGBENCH_THREADS", "PJRT_NPROC"):
        os.environ[var] = str(n)
    if n == 1:
        flags = re.sub(r"(--)?xla_cpu_multi_thread_eigen=\S*", "", os.environ.get("XLA_FLAGS", "")).split()
        os.environ["XLA_FLAGS"] = " ".join([*flags, "--xla_cpu_multi_thread_eigen=false"])
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a dependency of swingbench
        pass
    else:
        threadpool_limits(n)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n)


@contextlib.contextmanager
def pinned_threads(n: int) -> Iterator[None]:
    """`pin_threads(n)` for the duration of the block; the environment, the BLAS/OpenMP limits and
    torch's thread count are restored afterwards (a library loaded inside keeps its setting)."""
    saved = {var: os.environ.get(var) for var in _PINNED_ENV}
    torch = sys.modules.get("torch")
    torch_before = torch.get_num_threads() if torch is not None else None
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover
        limits = contextlib.nullcontext()
    else:
        limits = threadpool_limits(None)  # records the current limits, restored on exit
    try:
        with limits:
            pin_threads(n)
            yield
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value
        if torch_before is not None:
            sys.modules["torch"].set_num_threads(torch_before)


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
    warm-up took more than `slow_s` seconds is timed once (`repeats` says so), unless that timed
    call is itself under `slow_s`: then the warm-up was a cold start (a compilation, a cache
    filled) and the call is timed as any other."""
    wanted = (min_repeats, max_repeats)
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
        if len(samples) == 1 and elapsed <= slow_s:
            min_repeats, max_repeats = wanted
    arr = np.asarray(samples)
    q25, median, q75 = np.percentile(arr, [25, 50, 75])
    return Timing(float(median), float(q25), float(q75), float(arr.min()), arr.size)
