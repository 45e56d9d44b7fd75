"""The classical reduced-order surrogate: a POD basis of numba-rk trajectories, its modal
coefficients interpolated in P1 and t, queried by numba (`solvers.classical.kernels.pod`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar, NamedTuple

import numpy as np

from solvers.base import AbstractSolver, Estimate, FitReport
from solvers.classical.kernels import pod as kernels
from solvers.classical.numba_rk import NumbaRK
from solvers.classical.snapshots import chebyshev_nodes, pod_modes
from solvers.options import Fraction, NonNegativeInt, OptionSchema, PositiveFloat, PositiveInt, int_at_least
from systems.cases import STEP_SCENARIO, Observations, Scenario
from systems.model import accelerations, coupling

__all__ = ["SNAPSHOT_SWEEP", "PodSpline", "PodSplineOptions", "lobatto_nodes"]

SNAPSHOT_SWEEP = (5, 9, 17, 33)  # n_snapshots of the work-precision curve, coarsest first
ATOL_PER_RTOL = 1e-3  # the snapshots' atol = rtol x this (the tolerance sweeps' rule)
AtLeastTwo = int_at_least(2)


def lobatto_nodes(low: float, high: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """`count` >= 2 Chebyshev-Lobatto nodes (the extrema of T_{count-1}, both ends included) on
    [low, high], ascending, and their barycentric weights (-1)^j, halved at the ends (Berrut and
    Trefethen 2004, the second form: any common factor cancels)."""
    nodes = chebyshev_nodes(low, high, count)
    j = np.arange(count)
    weights = np.where(j % 2 == 0, 1.0, -1.0)
    weights[0] *= 0.5
    weights[-1] *= 0.5
    return nodes, weights


class PodSplineOptions(OptionSchema):
    """The options of `PodSpline` (its docstring says what each does)."""

    seed: NonNegativeInt = 0
    n_snapshots: AtLeastTwo = 17
    n_times: AtLeastTwo = 2000
    k: PositiveInt | None = None
    energy: Fraction = 1.0 - 1e-14
    rtol: PositiveFloat = 1e-10


class Interpolant(NamedTuple):
    """One quantity's interpolant, the arguments of `solvers.classical.kernels.pod.grid` after h, nodes and
    weights: values, slopes (n_times, n_snapshots, k), basis_t (k, n), mean (n,)."""

    values: np.ndarray
    slopes: np.ndarray
    basis_t: np.ndarray
    mean: np.ndarray


def interpolant(x: np.ndarray, rate: np.ndarray, k: int | None, energy: float) -> tuple[Interpolant, int, float]:
    """The interpolant of trajectories `x` (S, n_times, n) whose time derivatives are `rate`:
    the mean over snapshots and times per machine subtracted, `pod_modes` of the rest; with the
    number of modes and the energy they leave out."""
    n = x.shape[-1]
    mean = x.reshape(-1, n).mean(axis=0)
    modes, left_out = pod_modes((x - mean).reshape(-1, n), k, energy)
    values = np.ascontiguousarray(((x - mean) @ modes).transpose(1, 0, 2))
    slopes = np.ascontiguousarray((rate @ modes).transpose(1, 0, 2))
    return Interpolant(values, slopes, np.ascontiguousarray(modes.T), mean), modes.shape[1], left_out


class PodSpline(AbstractSolver):
    """A reduced-order surrogate of a step case, fitted to numba-rk trajectories; no integration at
    query time.

    `fit` integrates `n_snapshots` trajectories with numba-rk (dop853, rtol `rtol`, atol rtol x
    `ATOL_PER_RTOL`; its network form by its own rule) at the Chebyshev-Lobatto nodes of
    [p1_min, p1_max], with dense output at `n_times` uniform knots on [0, t_final] s (2000 by
    default: the knots miss the standard grids' times, so that the accuracy suite measures the
    interpolation in t). The angles and the speeds get a POD basis each: the mean over snapshots
    and times per machine subtracted, the `k` leading modes of the SVD (None: the fewest that keep
    `energy` of the squared singular values; the fit report gives both counts and what they leave
    out). The modal coefficients are interpolated by the polynomial of degree n_snapshots - 1
    through the nodes in P1 (barycentric) and by cubic Hermite pieces between the knots in t,
    with the exact derivatives: the speeds' projections for the angles', the swing equation's
    accelerations for the speeds'. A query is `solvers.classical.kernels.pod`' compiled evaluation.
    Queries outside [0, t_final] x [p1_min, p1_max] are refused unless `extrapolate=True`.
    Deterministic: `seed` is accepted (every adapter that trains has one) and changes nothing.
    It does not identify m and d (its model holds the case's), nor integrate fault cases.
    """

    name: ClassVar[str] = "pod-spline"
    SCHEMA = PodSplineOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = {"default": {}}
    CASE_SCENARIOS: ClassVar[dict[str, frozenset[Scenario]]] = {"default": frozenset({STEP_SCENARIO})}
    bounded_domain: ClassVar[bool] = True
    trains: ClassVar[bool] = True
    identifies: ClassVar[bool] = False
    compiled: ClassVar[bool] = True
    classical_surrogate: ClassVar[bool] = True
    # its queries' two matrix products on one BLAS thread: wscc9's grid at 17 snapshots took 0.42 ms
    # on one and 47 ms on two (OpenBLAS's threads waiting on each other, 2 loaded cores)
    blas_threads: ClassVar[int | None] = 1

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """The coarsest len(rtols) of `SNAPSHOT_SWEEP` (n_snapshots), as many points as the run
        sweeps tolerances."""
        return [{"n_snapshots": count} for count in SNAPSHOT_SWEEP[:len(rtols)]]

    def _check_options(self) -> None:
        """A range of P1 to interpolate over, and at most as many modes as the snapshots have."""
        case, options = self.case, self.options
        if not case.p1_min < case.p1_max:
            raise ValueError(f"{self.name}: case {case.name} has a single P1 = {case.p1_min} p.u. "
                             "(p1_min = p1_max): nothing to interpolate")
        most = min(case.n, options["n_snapshots"] * options["n_times"])
        if options["k"] is not None and options["k"] > most:
            raise ValueError(f"{self.name}: option k must be <= min(n machines, n_snapshots x n_times) = {most} "
                             f"on case {case.name}, got {options['k']!r}")

    def _fit(self) -> FitReport:
        """Snapshots, the two bases and their interpolants, and the kernels compiled (or loaded
        from numba's cache) on a one-point query."""
        case, options = self.case, self.options
        self._nodes, self._weights = lobatto_nodes(case.p1_min, case.p1_max, options["n_snapshots"])
        knots = np.linspace(0.0, case.t_final, options["n_times"])
        self._h = float(knots[1])
        rk = NumbaRK(case, rtol=options["rtol"], atol=options["rtol"] * ATOL_PER_RTOL)
        network = rk.fit().message
        traj = rk.solve(knots, self._nodes)
        rate = accelerations(coupling(case), np.asarray(case.m), np.asarray(case.d), traj.delta, traj.omega,
                             case.powers(self._nodes)[:, None, :])
        self._delta, k_delta, out_delta = interpolant(traj.delta, traj.omega, options["k"], options["energy"])
        self._omega, k_omega, out_omega = interpolant(traj.omega, rate, options["k"], options["energy"])
        self._solve(knots[:1], self._nodes[:1])
        self._solve_points(knots[:1], self._nodes[:1])
        message = (f"{options['n_snapshots']} numba-rk snapshots x {options['n_times']} times (rtol "
                   f"{options['rtol']:g}); delta {k_delta} modes (energy left out {out_delta:.1e}), "
                   f"omega {k_omega} modes ({out_omega:.1e})")
        # the loss POD minimises: the fraction of the snapshots' squared deviation from the mean the
        # bases leave out (the larger of the two)
        return FitReport(seconds=0.0, loss=max(out_delta, out_omega),
                         message=f"{message}; {network}" if network else message)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        where = (self._h, self._nodes, self._weights)
        return kernels.grid(t, P1, *where, *self._delta), kernels.grid(t, P1, *where, *self._omega)

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        where = (self._h, self._nodes, self._weights)
        return kernels.points(t, P1, *where, *self._delta), kernels.points(t, P1, *where, *self._omega)

    def _identify(self, obs: Observations) -> Estimate:
        raise NotImplementedError(f"{self.name} does not identify: its model is fitted to the case's own m and d")
