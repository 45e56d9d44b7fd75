"""numba-compiled explicit Runge-Kutta (RK4, Dormand-Prince 5(4), DOP853) on the n-machine swing
equation, the loop over P1 inside compiled code; the kernels are in `solvers.classical.kernels.rk`
(the packed system in `solvers.classical.kernels.layout`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar, Literal

import numba
import numpy as np

from solvers.base import AbstractSolver, Estimate, FitReport, SolveError, StepCount
from solvers.classical.common import (
    SPARSE_FROM_MACHINES,
    TOLERANCE_CONFIGS,
    TOLERANCE_MARKS,
    NetworkForm,
    ObservationLayout,
    PointGroups,
    ToleranceOptions,
    check_step,
    identify_least_squares,
    keeps_network_sparse,
    search_boxes,
)
from solvers.classical.kernels import rk
from solvers.classical.kernels.layout import (
    NO_NETWORK,
    STATUS,
    TOO_MANY_STEPS,
    D,
    M,
    check_threads,
    system_array,
)
from solvers.classical.kernels.rk_faults import fault_kernel
from solvers.classical.kernels.rk_points import points_kernel
from solvers.options import PositiveFloat, PositiveInt, StrictBool
from systems.cases import Observations
from systems.sparse_network import LUFactors, lu_factors

COARSE_TOLERANCES = (1e-6, 1e-9)  # rtol, atol of the start grid of identify
RK4_STEPS = (0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)  # s, the work-precision sweep of rk4
# s, the coarser steps of a verdict's sweep (its tolerances over COARSE_RTOL): the SMIB's angles err
# by 5e-5 at 0.5 s and 8e-4 at 1 s (1e-6 at 0.2 s), measured; on the networks finite but far off
RK4_COARSE_STEPS = (1.0, 0.5, 0.3)


Method = Literal[tuple(rk.METHODS)]  # one of the keys of `rk.METHODS`


class NumbaRKOptions(ToleranceOptions):
    method: Method = "dop853"
    dt: PositiveFloat = 0.1  # s; <= the case's t_final (`check_step`, by the adapter)
    max_steps: PositiveInt = 100_000
    parallel: StrictBool = False
    threads: PositiveInt = 2  # <= numba's NUMBA_NUM_THREADS (checked by the adapter)
    network: NetworkForm = "auto"


class NumbaRK(AbstractSolver):
    """Explicit Runge-Kutta compiled with numba, one trajectory per P1 (each with its own steps).

    Options: method "dop853" (default: 8th order, 7th-order dense output, a clone of scipy's
    DOP853), "dopri5" (scipy's RK45: Dormand-Prince 5(4), quartic dense output) or "rk4" (classic,
    fixed step, cubic Hermite output); rtol, atol (adaptive methods; ode45's 1e-3, 1e-6 by
    default); dt (s, rk4: ceil(t / dt) equal steps); max_steps (per trajectory); parallel (P1 over
    numba threads, prange, for more than one P1, and solve_points' distinct P1) with `threads`
    of them; network ("reduced", "sparse" or "auto", the default: sparse from
    `SPARSE_FROM_MACHINES` machines on a case that carries its network); m_bounds, d_bounds
    (p.u.; default the case's per-machine boxes), the search box of `identify`, which integrates
    the forward sensitivities d(delta, omega)/d(m_1..n, d_1..n) along (the analytic Jacobian of
    the least squares) on the reduced network whatever the option (its start grid is ranked in the
    option's form).
    The right-hand side is the case's n-machine swing equation (`systems.model`), its network
    Kron-reduced (dense coupling, ~4 n^2 multiply-adds) or kept sparse (`systems.sparse_network`:
    two sparse triangular solves); P1 is generator 1's mechanical power, the other machines run
    at their p_m. A fault case (`Case.fault`, P1 the clearing time t_c s) integrates the fault-on
    phase once for every t_c of a call and each post-fault phase from its own state at t_c
    (`solvers.classical.kernels.rk_faults`), on the reduced networks.
    """

    name: ClassVar[str] = "numba-rk"
    compiled: ClassVar[bool] = True
    handles_faults: ClassVar[bool] = True
    counts_steps: ClassVar[bool] = True
    SCHEMA = NumbaRKOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = {**TOLERANCE_CONFIGS, "rk4": {"method": "rk4"}}
    CONFIG_MARKS = TOLERANCE_MARKS
    has_tolerance = True
    takes_threads = True
    QUERY_OPTIONS = frozenset({"threads"})
    # P1 over numba's threads: ~1.9x faster on the grid on an idle machine, 20-50x slower when other
    # processes load the cores (measured, 2 cores); runs measure both, the verdicts take the faster.
    VARIANTS = ({"parallel": True},)

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """rk4: a sweep of its step `RK4_STEPS` (s, `step_sweep`), `RK4_COARSE_STEPS` for tolerances
        over COARSE_RTOL; else the tolerance sweep."""
        if self.options["method"] == "rk4":
            return self.step_sweep(RK4_STEPS, rtols, RK4_COARSE_STEPS)
        return super().precision_sweep(rtols)

    def _check_options(self) -> None:
        """The rules that depend on the case and the machine (the rest is `NumbaRKOptions`)."""
        options = self.options
        check_step(self.name, options["dt"], self.case)
        keeps_network_sparse(self.name, options["network"], self.case, SPARSE_FROM_MACHINES)
        check_threads(self.name, options["threads"])

    def _prepare(self, sensitivities: bool = False) -> None:
        """Packed system and options, and the compiled kernels (numba compiles, or loads from its
        cache, on the first call of each: here, on tiny inputs); the sensitivity kernel only when
        `sensitivities` (identification): its right-hand side costs ~n^3 (2n tangents of an n x n
        coupling), minutes at 1445 machines even on the tiny warm-up; it takes the reduced network
        (`_reduced`) whatever the option."""
        options, n = self.options, self.case.n
        method = rk.METHODS[options["method"]]
        if self.case.fault is not None:
            self._prepare_fault(method)
            return
        if not hasattr(self, "_system"):
            sparse = keeps_network_sparse(self.name, options["network"], self.case, SPARSE_FROM_MACHINES)
            self._system = system_array(self.case, sparse)
            self._net = lu_factors(self.case.network, self.case.E) if sparse else NO_NETWORK
            self._options = np.array([options["rtol"], options["atol"], options["dt"], options["max_steps"]],
                                     np.float64)
            self._serial = rk.kernel(method, False, False, n)
            self._batch = rk.kernel(method, False, options["parallel"], n)
            self._points = points_kernel(method, options["parallel"], n)
            for run in (self._serial, self._batch):
                self._warm(run, self._system, self._net)
            self._solve_points(np.array([0.1, 0.0, 0.1]), np.array([self.case.p1_min, self.case.p1_min, 0.0]))
        if sensitivities and not hasattr(self, "_sensitivities"):
            self._reduced = self._system if self._net is NO_NETWORK else system_array(self.case)
            self._sensitivities = rk.kernel(method, True, options["parallel"], n)
            self._warm(self._sensitivities, self._reduced, NO_NETWORK)

    def _prepare_fault(self, method: int) -> None:
        """A fault case's packed systems (each phase's), options and compiled kernel (warmed on a
        grid and on points of two clearing times)."""
        if hasattr(self, "_system"):
            return
        case, options = self.case, self.options
        self._system, self._post = system_array(case.phase("on")), system_array(case.phase("post"))
        self._net = NO_NETWORK
        self._options = np.array([options["rtol"], options["atol"], options["dt"], options["max_steps"]], np.float64)
        self._fault = fault_kernel(method, options["parallel"], case.n)
        t, t_c = np.array([0.0, 0.1, 0.05]), np.array([0.05, 0.02, 0.0])
        self._solve(t, t_c)
        self._solve_points(t, t_c)

    def _warm(self, run, system: np.ndarray, net: LUFactors) -> None:
        run(np.array([0.0, 0.1]), np.full(2, self.case.p1_min), system, net, self._options)

    def _fit(self) -> FitReport:
        """Compile (`_prepare`); the report says which form of a network the kernels integrate."""
        self._prepare()
        net = self._net
        if net is NO_NETWORK:
            return FitReport(seconds=0.0, message="" if self.case.network is None else "network: reduced")
        return FitReport(seconds=0.0, message=f"network: sparse ({net.l_inv.size} buses, nnz(L + U) {net.nnz})")

    def _run(self, run, t: np.ndarray, P1: np.ndarray, system: np.ndarray, net: LUFactors,
             options: np.ndarray) -> np.ndarray:
        """States (n_blocks, len(P1), len(t), n) from the kernel `run` (`rk.kernel`:
        [0] delta, [1] omega, then the sensitivities), or SolveError naming P1."""
        if run is not self._serial:
            numba.set_num_threads(self.options["threads"])
        states, failed, status = run(t, P1, system, net, options)
        if failed >= 0:
            self._failed(P1[failed], status)
        return states

    def _failed(self, p1: float, status: int) -> None:
        """Raise the SolveError of a trajectory of scenario parameter `p1` (P1 p.u. or t_c s)."""
        raise SolveError(f"{self.name}: integration failed at {self.case.scenario.symbol}={p1:g}: {STATUS[status]}")

    def _switched(self, t: np.ndarray, order: np.ndarray, starts: np.ndarray, T_c: np.ndarray,
                  shared: bool) -> np.ndarray:
        """States (2, len(T_c) or 1 with `shared`, len(t), n) of a fault case from the kernel of
        `rk_faults.fault_kernel` (its groups), or SolveError naming t_c."""
        if self.options["parallel"]:
            numba.set_num_threads(self.options["threads"])
        states, failed, status = self._fault(t, order, starts, T_c, self._system, self._post, self._net,
                                             self._options, shared)
        if failed >= 0:
            self._failed(T_c[failed], status)
        return states

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.case.fault is not None:
            order = np.argsort(t, kind="stable")
            states = self._switched(t, np.tile(order, P1.size), np.arange(P1.size + 1) * t.size, P1, False)
            return states[0], states[1]
        run = self._serial if P1.size == 1 else self._batch
        states = self._run(run, t, P1, self._system, self._net, self._options)
        return states[0], states[1]

    def _step_count(self, p1: float) -> StepCount:
        """rk4: ceil(t_final / dt) steps of 4 evaluations. An adaptive method's kernel does not
        count: it stops (TOO_MANY_STEPS) when a trajectory needs more accepted steps than the
        option max_steps, so the least max_steps with which the one-point query at t_final
        succeeds is its number of accepted steps (doubling, then bisection: ~2 log2(steps)
        trajectories); its evaluations, rejected steps included, are not counted."""
        t, P1 = np.array([self.case.t_final]), np.array([p1])
        if self.options["method"] == "rk4":
            steps = math.ceil(self.case.t_final / self.options["dt"])
            return StepCount(steps, 4 * steps)

        def succeeds(max_steps: int) -> bool:
            options = self._options.copy()
            options[3] = max_steps
            _, failed, status = self._serial(t, P1, self._system, self._net, options)
            if failed >= 0 and status != TOO_MANY_STEPS:
                self._failed(p1, status)
            return failed < 0

        limit = int(self.options["max_steps"])
        if not succeeds(limit):
            self._failed(p1, TOO_MANY_STEPS)
        low, high = 0, 1  # low fails (no step at all reaches t_final > 0), high is tried next
        while high < limit and not succeeds(high):
            low, high = high, min(2 * high, limit)
        while high - low > 1:
            middle = (low + high) // 2
            low, high = (low, middle) if succeeds(middle) else (middle, high)
        return StepCount(high)

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (n_s, n) rad and rad/s, at the pairs (t[i] s, P1[i] p.u.): one
        compiled call (`rk_points.points_kernel`), one trajectory per distinct P1 integrated to
        the last time of its pairs (a P1 of one pair: to that pair's t, as a one-point `solve`)."""
        groups = PointGroups.of(t, P1)
        if self.case.fault is not None:
            states = self._switched(t, groups.order, groups.starts, groups.P1, True)
            return states[0, 0], states[1, 0]
        if self.options["parallel"]:
            numba.set_num_threads(self.options["threads"])
        states, failed, status = self._points(t, groups.order, groups.starts, groups.P1, self._system,
                                              self._net, self._options)
        if failed >= 0:
            self._failed(groups.P1[failed], status)
        return states[0], states[1]

    def _identify(self, obs: Observations) -> Estimate:
        """Least squares over every machine's (m, d) with the sensitivity Jacobian. The start grid
        is ranked by plain simulations at rtol, atol no tighter than `COARSE_TOLERANCES`; the
        refinement integrates the sensitivities along at the configured tolerances and keeps them
        for the Jacobian at the same (m, d), which least squares asks for right after the
        residual."""
        self._prepare(sensitivities=True)
        layout = ObservationLayout.of(obs)
        coarse = self._options.copy()
        coarse[:2] = np.maximum(coarse[:2], COARSE_TOLERANCES)
        last: dict[str, Any] = {}

        def with_params(system: np.ndarray, m: np.ndarray, d: np.ndarray) -> np.ndarray:
            system = system.copy()
            system[:, M], system[:, D] = m, d
            return system

        def rank_starts(m: np.ndarray, d: np.ndarray, with_jacobian: bool):
            states = self._run(self._batch, layout.t, layout.P1, with_params(self._system, m, d), self._net, coarse)
            return states[0], states[1], None, None

        def simulate(m: np.ndarray, d: np.ndarray, with_jacobian: bool):
            key = (m.tobytes(), d.tobytes())
            if last.get("md") != key:
                last["md"] = key
                last["states"] = self._run(self._sensitivities, layout.t, layout.P1,
                                           with_params(self._reduced, m, d), NO_NETWORK, self._options)
            states = last["states"]
            if not with_jacobian:
                return states[0], states[1], None, None
            # blocks 2 + 2j, 3 + 2j: d delta / d p_j, d omega / d p_j -> (n_p, n_t, n, 2n), p_j last
            return states[0], states[1], np.moveaxis(states[2::2], 0, -1), np.moveaxis(states[3::2], 0, -1)

        return identify_least_squares(simulate, obs, layout, *search_boxes(self.case, self.options),
                                      analytic_jacobian=True, rank_starts=rank_starts,
                                      rtol=self.options["rtol"])
