"""Compile every numba kernel of the project once, into numba's on-disk cache (`cache=True`).

`make setup` runs `python -m solvers.numba_cache`, so that the first test run or benchmark does not
spend a minute compiling: a cached kernel loads in a fraction of a second. What a kernel costs to
compile is still preparation wherever it happens (an adapter's `fit`), never query time. The
kernels of `solvers.numba_kernels` are compiled per number of machines n: here the SMIB's (n = 1);
an n-machine case compiles its own on first use, into the same cache.
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

    from solvers import numba_kernels, trapezoid_kernels
    from solvers.numba_points import points_kernel
    from systems.cases import SMIB_INFERENCE

    start = time.perf_counter()
    # the SMIB's kernels (n = 1): serial, with and without sensitivities, and the parallel
    # forward ones (numba-rk's variant parallel=True); its points kernels, serial and parallel
    system = numba_kernels.system_array(SMIB_INFERENCE)
    options = np.array([1e-3, 1e-6, 0.1, 1000.0])
    for method in numba_kernels.METHODS.values():
        for sens, parallel in ((False, False), (True, False), (False, True)):
            kernel = numba_kernels.kernel(method, sens, parallel, 1)
            kernel(np.array([0.0, 1.0]), np.full(2, 0.1), system, numba_kernels.NO_NETWORK, options)
        for parallel in (False, True):  # numba-rk's solve_points: two pairs of one P1
            points_kernel(method, parallel, 1)(np.array([0.0, 1.0]), np.array([0, 1]), np.array([0, 2]),
                                               np.array([0.1]), system, numba_kernels.NO_NETWORK, options)
    for parallel in (False, True):  # trapezoid's kernel, one for solve and solve_points: two P1, two times
        trapezoid_kernels.run_kernel(parallel)(np.array([0.0, 0.1]), np.array([0, 1, 0, 1]), np.array([0, 2, 4]),
                                               np.full(2, 0.1), system, np.array([0.05, 1e-10, 20.0]), False)
    try:
        from solvers.pinn.architecture import Architecture
        from solvers.pinn.compiled import NumbaEvaluator
        from solvers.pinn.config import PinnConfig
    except ImportError:  # the PINN package needs scipy only; be safe all the same
        pass
    else:
        NumbaEvaluator(Architecture.of(PinnConfig(), SMIB_INFERENCE), threads=2)
    print(f"numba kernels compiled into the cache in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
