"""The size of XLA's CPU thread pool, for every adapter that computes on JAX (the JAX PINN,
diffrax): one process-wide setting, made in one place.

XLA's CPU thread pool is sized when the backend starts (at the first computation, not at
`import jax`), from the environment variable PJRT_NPROC. Checked with jax 0.10.2 by counting the
process's threads: PJRT_NPROC changes the pool, set before the first computation even after
`import jax`; "intra_op_parallelism_threads=N" in XLA_FLAGS changes nothing (it is not an XLA
flag; an unknown "--xla_..." flag there aborts the process). `configure_threads` sets
PJRT_NPROC = threads, adds --xla_cpu_multi_thread_eigen=false to XLA_FLAGS (Eigen matmuls on the
calling thread) and turns jax_cpu_enable_async_dispatch off if the backend has not started yet
(process-wide settings); if it has, it returns a note for the adapter's message.
"""

from __future__ import annotations

import os

import jax

__all__ = ["configure_threads"]

_threads_started: list[int] = []  # the thread count XLA started with, once known


def configure_threads(threads: int) -> str:
    """Size XLA's CPU thread pool before the backend starts; return a note if it is too late."""
    from jax._src import xla_bridge

    if not xla_bridge.backends_are_initialized():
        os.environ["PJRT_NPROC"] = str(threads)
        flags = os.environ.get("XLA_FLAGS", "")
        if "xla_cpu_multi_thread_eigen" not in flags:
            os.environ["XLA_FLAGS"] = f"{flags} --xla_cpu_multi_thread_eigen=false".strip()
        # Run small computations on the calling thread: we always wait for the result, and the
        # hand-off to a worker thread cost ~30 us of a 1-point query (measured: 57 -> 16 us).
        jax.config.update("jax_cpu_enable_async_dispatch", False)
        jax.devices("cpu")  # start the backend now, with these settings
        _threads_started.append(threads)
        return ""
    started = str(_threads_started[0]) if _threads_started else os.environ.get("PJRT_NPROC", "default")
    if started != str(threads):
        return f"XLA had already started with {started} threads; threads={threads} not applied"
    return ""
