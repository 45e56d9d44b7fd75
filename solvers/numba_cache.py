"""Compile every numba kernel of the project once, into numba's on-disk cache (`cache=True`).

`make setup` runs `python -m solvers.numba_cache`, so that the first test run or benchmark does not
spend a minute compiling: a cached kernel loads in a fraction of a second. What a kernel costs to
compile is still preparation wherever it happens (an adapter's `fit`), never query time. The
kernels of `solvers.classical.kernels.rk` are compiled per number of machines n: here the SMIB's (n = 1)
and, through numba-rk's own preparation, those of the paper's network sizes that the tests and the
tests use (`PREPARED_KERNELS`); another n or variant compiles its own on first use, into the same
cache.
"""

from __future__ import annotations

import sys
import time

__all__ = ["PREPARED_KERNELS", "main"]

# numba-rk's kernels that `main` compiles beyond the SMIB's, as (case, method, parallel,
# sensitivities): those the tests compile (wscc9 and its fault case: n = 3, ieee39: n = 10), so that `make test` in a
# fresh clone loads them from the cache instead of compiling them inside its 3-minute budget.
PREPARED_KERNELS = (
    *(("wscc9", method, False, True) for method in ("rk4", "dopri5", "dop853")),
    ("wscc9", "dop853", True, False),
    ("ieee39", "rk4", False, False),
    ("wscc9-bus8-line8-9", "dop853", False, False),  # a fault case: `solvers.classical.kernels.rk_faults`' kernel
)


def _network_kernels() -> None:
    """numba-rk's kernels of `PREPARED_KERNELS` (through its own preparation: serial, batch and
    points kernels, and the sensitivities' where named), wscc9's with the sparse network (numba-rk's
    and the trapezoid's, serial and parallel), pod-spline's query kernels, and the PINN query
    evaluator of wscc9's architecture."""
    from solvers.classical.numba_rk import NumbaRK
    from solvers.classical.pod_spline import PodSpline
    from solvers.classical.trapezoid import Trapezoid
    from systems.cases import CASES

    for name, method, parallel, sensitivities in PREPARED_KERNELS:
        solver = NumbaRK(CASES[name], method=method, parallel=parallel, network="reduced")
        solver.fit()
        if sensitivities:
            solver._prepare(sensitivities=True)
    NumbaRK(CASES["wscc9"], network="sparse").fit()
    PodSpline(CASES["wscc9"], n_snapshots=2, n_times=2).fit()  # its kernels, one for every n (5 s to compile)
    for parallel in (False, True):
        Trapezoid(CASES["wscc9"], network="sparse", parallel=parallel, threads=1).fit()
    try:
        from solvers.pinn.architecture import Architecture
        from solvers.pinn.compiled import NumbaEvaluator
        from solvers.pinn.config import PinnConfig
    except ImportError:
        return
    NumbaEvaluator(Architecture.of(PinnConfig(), CASES["wscc9"]), threads=2)


def main() -> int:
    try:
        import numba  # noqa: F401
    except ImportError:
        print("numba not installed: nothing to compile", file=sys.stderr)
        return 0
    import numpy as np

    from solvers.classical.kernels import layout, rk, trapezoid_faults
    from solvers.classical.kernels import trapezoid as trapezoid_kernels
    from solvers.classical.kernels.rk_points import points_kernel
    from systems.cases import SMIB_INFERENCE

    start = time.perf_counter()
    # the SMIB's kernels (n = 1): serial, with and without sensitivities, and the parallel
    # forward ones (numba-rk's variant parallel=True); its points kernels, serial and parallel
    system = layout.system_array(SMIB_INFERENCE)
    options = np.array([1e-3, 1e-6, 0.1, 1000.0])
    for method in rk.METHODS.values():
        for sens, parallel in ((False, False), (True, False), (False, True)):
            kernel = rk.kernel(method, sens, parallel, 1)
            kernel(np.array([0.0, 1.0]), np.full(2, 0.1), system, layout.NO_NETWORK, options)
        for parallel in (False, True):  # numba-rk's solve_points: two pairs of one P1
            points_kernel(method, parallel, 1)(np.array([0.0, 1.0]), np.array([0, 1]), np.array([0, 2]),
                                               np.array([0.1]), system, layout.NO_NETWORK, options)
    for parallel in (False, True):  # trapezoid's kernel, one for solve and solve_points: two P1, two times
        trapezoid_kernels.run_kernel(parallel)(np.array([0.0, 0.1]), np.array([0, 1, 0, 1]), np.array([0, 2, 4]),
                                               np.full(2, 0.1), system, np.array([0.05, 1e-10, 20.0]), False)
        # its fault cases' kernel (every n), the SMIB's system as both phases
        trapezoid_faults.fault_kernel(parallel)(np.array([0.0, 0.1]), np.array([0, 1, 0, 1]), np.array([0, 2, 4]),
                                                np.full(2, 0.05), system, system, np.array([0.05, 1e-10, 20.0]), False)
    try:
        from solvers.pinn.architecture import Architecture
        from solvers.pinn.compiled import NumbaEvaluator
        from solvers.pinn.config import PinnConfig
    except ImportError:  # the PINN package needs scipy only; be safe all the same
        pass
    else:
        NumbaEvaluator(Architecture.of(PinnConfig(), SMIB_INFERENCE), threads=2)
    _network_kernels()
    print(f"numba kernels compiled into the cache in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
