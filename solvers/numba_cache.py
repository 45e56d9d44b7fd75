"""Compile every numba kernel of the project once, into numba's on-disk cache (`cache=True`).

`make setup` runs `python -m solvers.numba_cache`, so that the first test run or benchmark does not
spend a minute compiling: a cached kernel loads in a fraction of a second. What a kernel costs to
compile is still preparation wherever it happens (an adapter's `fit`), never query time. Kernels
that numba cannot cache (the parallel ones of `solvers.numba_kernels`) compile in each process.
"""

from __future__ import annotations

import sys
import time

__all__ = ["main"]


def main() -> int:
    try:
        import numba  # noqa: F401
    except ImportError:
        print("numba not installed: nothing to compile", file=sys.stderr)
        return 0
    import numpy as np

    from systems.cases import SMIB_INFERENCE
    from systems.model import smib_system
    from solvers import numba_kernels
    from solvers.numba_rk import system_array

    start = time.perf_counter()
    system = system_array(smib_system(SMIB_INFERENCE))
    options = np.array([1e-3, 1e-6, 0.1, 1000.0])
    for method in numba_kernels.METHODS.values():
        for sens in (False, True):
            numba_kernels.kernel(method, sens, False, 1)(np.array([0.0, 1.0]), np.full((2, 1), 0.1), system, options)
    try:
        from solvers.pinn.compiled import NumbaEvaluator
        from solvers.pinn.spec import Architecture, PinnConfig
    except ImportError:  # the PINN package needs scipy only; be safe all the same
        pass
    else:
        NumbaEvaluator(Architecture.of(PinnConfig(), SMIB_INFERENCE), threads=2)
    print(f"numba kernels compiled into the cache in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
