"""asv benchmarks of swingbench: every adapter of the `solvers.SOLVERS` registry, measured with the
harness's own queries, metrics and observations (see `benchmarks/_common.py`).

Run with `make asv` (results kept under .asv/results) or `make asv-quick` (each benchmark once,
small training budgets, nothing saved). Threads are pinned here, before any benchmark module
imports the registry and with it torch or jax, so that their thread pools start at this size.
"""

from harness.measure.timing import pin_threads

THREADS = 2  # the harness's Settings.threads; `_common` checks that they agree

pin_threads(THREADS)
