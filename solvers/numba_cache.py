"""Compile every numba kernel variant the tests use once, into numba's on-disk cache (`cache=True`).

`make setup` runs `python -m solvers.numba_cache`, so that the first test run or benchmark does not
spend minutes compiling: a cached kernel loads in a fraction of a second. What a kernel costs to
compile is still preparation wherever it happens (an adapter's `fit`), never query time.

numba compiles a kernel once per signature: the types of its arguments, array layouts included (a
strided view such as `t[::2]` is another variant than a contiguous array: `strided`), and for
numba-rk's kernels (`solvers.classical.kernels.rk`) also per number of machines n and network form
(`net` a `LUFactors` or `NO_NETWORK`). Here: the SMIB's kernels (n = 1), the trapezoid's (one for
every n), and through the adapters' own preparation those of the network sizes the tests use
(`PREPARED_KERNELS`), pod-spline's query kernels and the PINN query evaluator. Another n or variant
compiles its own on first use, into the same cache.
"""

from __future__ import annotations

import sys
import time
from typing import NamedTuple

import numpy as np

__all__ = ["PREPARED_KERNELS", "Prepared", "main", "strided"]


class Prepared(NamedTuple):
    """numba-rk's kernels of one case and configuration: serial, batch and points kernels (its
    `fit`); the sensitivities' with `sensitivities`; and with `strided_points` the points kernel of
    a strided t (a test's `solve_points(t[::2], ...)`)."""

    case: str
    method: str
    parallel: bool = False
    network: str = "reduced"
    sensitivities: bool = False
    strided_points: bool = False


# The kernels `main` compiles beyond the SMIB's: those the tests compile (wscc9 and its fault case:
# n = 3, ieee39: n = 10), so that `make test` in a fresh clone loads them from the cache instead of
# compiling them inside its 3-minute budget.
PREPARED_KERNELS = (
    Prepared("wscc9", "rk4", sensitivities=True, strided_points=True),
    *(Prepared("wscc9", method, sensitivities=True) for method in ("dopri5", "dop853")),
    Prepared("wscc9", "dop853", parallel=True),
    Prepared("wscc9", "dop853", network="sparse"),
    Prepared("wscc9", "rk4", network="sparse", strided_points=True),
    Prepared("ieee39", "rk4", strided_points=True),
    Prepared("ieee39", "rk4", network="sparse", strided_points=True),
    Prepared("wscc9-bus8-line8-9", "dop853"),  # a fault case: `solvers.classical.kernels.rk_faults`' kernel
)


def strided(x: np.ndarray) -> np.ndarray:
    """The values of `x` as a strided view (numba's layout "A"), not a contiguous array."""
    return np.repeat(x, 2)[::2]


def _smib_kernels() -> None:
    """The SMIB's numba-rk kernels (n = 1): serial, with and without sensitivities, and the parallel
    forward ones (numba-rk's variant parallel=True); its points kernels, serial and parallel; the
    trapezoid's kernels, compiled once for every n, and its fault cases'."""
    from solvers.classical.kernels import layout, rk, trapezoid, trapezoid_faults
    from solvers.classical.kernels.rk_points import points_kernel
    from systems.cases import SMIB_INFERENCE

    system = layout.system_array(SMIB_INFERENCE)
    options = np.array([1e-3, 1e-6, 0.1, 1000.0])
    for method in rk.METHODS.values():
        for sens, parallel in ((False, False), (True, False), (False, True)):
            kernel = rk.kernel(method, sens, parallel, 1)
            kernel(np.array([0.0, 1.0]), np.full(2, 0.1), system, layout.NO_NETWORK, options)
        for parallel in (False, True):  # numba-rk's solve_points: two pairs of one P1
            points_kernel(method, parallel, 1)(np.array([0.0, 1.0]), np.array([0, 1]), np.array([0, 2]),
                                               np.array([0.1]), system, layout.NO_NETWORK, options)
    groups = (np.array([0.0, 0.1]), np.array([0, 1, 0, 1]), np.array([0, 2, 4]))  # two groups of two times
    for parallel in (False, True):  # trapezoid's kernel, one for solve and solve_points
        trapezoid.run_kernel(parallel)(*groups, np.full(2, 0.1), system, np.array([0.05, 1e-10, 20.0]), False)
        # its fault cases' kernel (every n), the SMIB's system as both phases
        trapezoid_faults.fault_kernel(parallel)(*groups, np.full(2, 0.05), system, system,
                                                np.array([0.05, 1e-10, 20.0]), False)


def _network_kernels() -> None:
    """numba-rk's kernels of `PREPARED_KERNELS`, wscc9's trapezoid with the sparse network (serial
    and parallel), and pod-spline's query kernels (contiguous and strided t and P1)."""
    from solvers.classical.kernels import layout, rk
    from solvers.classical.numba_rk import NumbaRK
    from solvers.classical.pod_spline import PodSpline
    from solvers.classical.trapezoid import Trapezoid
    from systems.cases import CASES

    for prepared in PREPARED_KERNELS:
        case = CASES[prepared.case]
        solver = NumbaRK(case, method=prepared.method, parallel=prepared.parallel, network=prepared.network)
        solver.fit()
        t, P1 = np.array([0.0, 0.1]), np.full(2, case.p1_min)
        if prepared.sensitivities:  # identify's kernel, on the reduced network
            rk.kernel(rk.METHODS[prepared.method], True, prepared.parallel, case.n)(
                t, P1, layout.system_array(case), layout.NO_NETWORK, np.array([1e-3, 1e-6, 0.1, 1000.0]))
        if prepared.strided_points:
            solver.solve_points(strided(t), P1)
    for parallel in (False, True):
        Trapezoid(CASES["wscc9"], network="sparse", parallel=parallel, threads=1).fit()
    wscc9 = CASES["wscc9"]
    pod = PodSpline(wscc9, n_snapshots=2, n_times=2)  # its kernels, one for every n (5 s to compile)
    pod.fit()
    t, P1 = np.array([0.0, 0.1]), np.array([wscc9.p1_min, wscc9.p1_max])
    pod.solve(strided(t), P1)
    pod.solve(t, strided(P1))


def _pinn_kernels() -> None:
    """The PINN query evaluator (one set of kernels for every architecture), on contiguous and
    strided P1."""
    try:
        from solvers.pinn.architecture import Architecture
        from solvers.pinn.compiled import NumbaEvaluator
        from solvers.pinn.config import PinnConfig
    except ImportError:  # the PINN package needs scipy only; be safe all the same
        return
    from systems.cases import CASES, SMIB_INFERENCE

    smib = NumbaEvaluator(Architecture.of(PinnConfig(), SMIB_INFERENCE), threads=2)
    smib(np.array([0.0, 1.0]), strided(np.array([SMIB_INFERENCE.p1_min, SMIB_INFERENCE.p1_max])))
    NumbaEvaluator(Architecture.of(PinnConfig(), CASES["wscc9"]), threads=2)


def main() -> int:
    try:
        import numba  # noqa: F401
    except ImportError:
        print("numba not installed: nothing to compile", file=sys.stderr)
        return 0
    start = time.perf_counter()
    _smib_kernels()
    _pinn_kernels()
    _network_kernels()
    print(f"numba kernels compiled into the cache in {time.perf_counter() - start:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
