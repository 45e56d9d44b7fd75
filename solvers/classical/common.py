"""Machinery shared by the ODE-solver adapters: the step rule, search boxes, batching over P1 and
least-squares identification from scattered observations."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Literal, NamedTuple, Protocol, TypeVar

import numpy as np
from scipy.optimize import least_squares

from solvers.base import IDENTIFIES_NETWORKS, SWEEP_POINT, SolveError
from solvers.identification import Estimate, gauss_newton_covariance
from solvers.options import Bounds, OptionSchema, PositiveFloat
from systems.cases import Case, Observations
from systems.model import Coupling, coupling

T = TypeVar("T")

__all__ = ["SPARSE_FROM_MACHINES", "TOLERANCE_CONFIGS", "TOLERANCE_MARKS", "NetworkForm", "ObservationLayout",
           "PointGroups", "PointsByP1", "StackedStates", "ToleranceOptions", "at_query_times", "check_step", "identify_least_squares",
           "keeps_network_sparse", "points_by_p1", "rhs_args", "run_batch", "search_boxes", "which_p1"]

# The form of the network an adapter integrates: "reduced" (Kron-reduced to the machines, the dense
# coupling of `systems.model`), "sparse" (kept as the bus admittance matrix, `systems.sparse_network`)
# or "auto" (by the case's size: `keeps_network_sparse`).
NetworkForm = Literal["auto", "reduced", "sparse"]
# network="auto": the network kept sparse from this many machines (when the case carries it). One
# core, numba-rk dop853, 4 P1 x 101 times: the forms within 30 % of each other at 54 and 69 machines
# (case118, case300), the sparse one 2-3x faster at 260 and 8-10x at 1445 (docs/scaling.md).
SPARSE_FROM_MACHINES = 100


class ToleranceOptions(OptionSchema):
    """The options every tolerance-controlled ODE adapter has: rtol, atol (defaults 1e-3, 1e-6:
    MATLAB ode45's, which made the paper's data) and m_bounds, d_bounds (p.u.), the search box of
    `identify`: a pair (low, high) for every machine, or None (the default) for the case's own
    boxes (`Case.m_box`, `Case.d_box`)."""

    rtol: PositiveFloat = 1e-3
    atol: PositiveFloat = 1e-6
    m_bounds: Bounds | None = None
    d_bounds: Bounds | None = None


def check_step(owner: str, dt: float | None, case: Case) -> None:
    """The rule of a fixed step `dt` (s; None: adaptive, no rule) on `case`, one for every adapter
    with a step option: at most the case's horizon t_final. A longer step is not the step an
    integration of that case takes (numba-rk's rk4 takes one step of t_final instead, diffrax clips
    the step at the end), so the rows would name a step that was never used. Raises ValueError, one
    line starting with `owner` and naming the option, the value and the case."""
    if dt is not None and dt > case.t_final:
        raise ValueError(f"{owner}: option dt must be <= t_final = {case.t_final} s, the horizon of case "
                         f"{case.name}, got {dt!r}")


def keeps_network_sparse(owner: str, form: str, case: Case, sparse_from: int) -> bool:
    """Whether `owner` integrates `case` with its network kept sparse: the option `form`
    (`NetworkForm`); "auto" is sparse from `sparse_from` machines when the case carries its network
    (`Case.network`), else reduced. "sparse" on a case without one is a ValueError naming the case."""
    if form == "sparse" and case.network is None:
        raise ValueError(f"{owner}: option network='sparse' needs a case that carries its network; "
                         f"case {case.name} has none (it is given reduced only)")
    if form == "auto":
        return case.network is not None and case.n >= sparse_from
    return form == "sparse"


def search_boxes(case: Case, options: dict) -> tuple[np.ndarray, np.ndarray]:
    """(m_box, d_box), each (n, 2) p.u.: the options' pairs for every machine, else the case's."""
    boxes = []
    for key, own in (("m_bounds", case.m_box), ("d_bounds", case.d_box)):
        pair = options.get(key)
        boxes.append(np.array(own if pair is None else [pair] * case.n, np.float64))
    return boxes[0], boxes[1]


# "default" is the schema's defaults; "tight" is for identification and for comparing at high accuracy.
TOLERANCE_CONFIGS = {
    "default": {},
    "tight": {"rtol": 1e-10, "atol": 1e-12},
}
# "tight" identifies multi-machine cases (at ode45's tolerances the integration error biases the 2n
# estimates) and, setting only the swept tolerances, is a point of the default config's sweep.
TOLERANCE_MARKS = {"tight": frozenset({IDENTIFIES_NETWORKS, SWEEP_POINT})}


def rhs_args(case: Case, P: np.ndarray) -> tuple[Coupling, np.ndarray, np.ndarray, np.ndarray]:
    """The arguments after (t, y) of the scipy adapters' right-hand sides: the case's coupling, m
    and d (n,) p.u., and each trajectory's mechanical powers P (n_b, n) p.u."""
    return coupling(case), np.asarray(case.m), np.asarray(case.d), P


def which_p1(P1: np.ndarray, symbol: str = "P1") -> str:
    """The trajectories a failed integration of the batch `P1` (the scenario parameter, named
    `symbol`: `Case.scenario`) was for, for its error: "P1=0.13" for one, "one of P1 in
    [0.08, 0.18]" for several."""
    return f"{symbol}={P1[0]:g}" if P1.size == 1 else f"one of {symbol} in [{P1.min():g}, {P1.max():g}]"


def at_query_times(run: Callable[[np.ndarray], np.ndarray], t: np.ndarray) -> np.ndarray:
    """`run(times)` on the sorted unique query times t (s), its time axis (the second) then put back
    in the order of t, repeats included: integrators step forward through sorted output times."""
    times, order = np.unique(t, return_inverse=True)
    return run(times)[:, order]


def run_batch(run: Callable[[np.ndarray], T], P1: np.ndarray) -> T:
    """`run(P1)` for the whole batch; if it raises SolveError, rerun one P1 at a time so that the
    error names the trajectory that fails (costs time only on failure)."""
    try:
        return run(P1)
    except SolveError:
        if P1.size == 1:
            raise
        for p1 in P1:
            run(P1[P1 == p1][:1])
        raise


class PointGroups(NamedTuple):
    """The pairs (t[i] s, P1[i] p.u.) of a points query grouped by P1: the distinct P1 (n_g,)
    ascending, `order` (n_s,) int64, the pair indices group after group and by time within a
    group (ties in input order), and `starts` (n_g + 1,) int64, group g being
    order[starts[g]:starts[g + 1]]. One trajectory per group serves every pair of it."""

    P1: np.ndarray
    order: np.ndarray
    starts: np.ndarray

    @classmethod
    def of(cls, t: np.ndarray, P1: np.ndarray) -> PointGroups:
        """Groups of the pairs of the 1-D arrays t (s) and P1 (p.u.) of one length n_s >= 1."""
        order = np.argsort(t, kind="stable")
        order = order[np.argsort(P1[order], kind="stable")]  # by P1, by time within one P1
        p1 = P1[order]
        starts = np.concatenate(([0], np.flatnonzero(p1[1:] != p1[:-1]) + 1, [p1.size]))
        return cls(p1[starts[:-1]], order, starts)

    def _cells(self) -> tuple[np.ndarray, np.ndarray]:
        """(group, position in the group) of each entry of `order`, int64 (n_s,) each."""
        sizes = np.diff(self.starts)
        group = np.repeat(np.arange(sizes.size), sizes)
        return group, np.arange(group.size) - self.starts[group]

    def padded_times(self, t: np.ndarray, rows: int, width: int) -> np.ndarray:
        """(rows, width) s: row g < n_g the times of group g ascending, repeated at its last up to
        `width` (>= the largest group); rows from n_g copy the last group's (a compiled size of a
        batch over groups). `t` (n_s,) the pairs' times in input order."""
        group, position = self._cells()
        times = np.empty((rows, width))
        times[:self.P1.size] = t[self.order[self.starts[1:] - 1], None]  # each group's last time
        times[group, position] = t[self.order]
        times[self.P1.size:] = times[self.P1.size - 1]
        return times

    def scatter(self, values: np.ndarray) -> np.ndarray:
        """Per-pair values (n_s, ...) in input order from per-group ones (>= n_g, >= the largest
        group, ...) at the positions of `padded_times`."""
        group, position = self._cells()
        out = np.empty((self.order.size, *values.shape[2:]), values.dtype)
        out[self.order] = values[group, position]
        return out


def points_by_p1(solve: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
                 t: np.ndarray, P1: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(delta, omega), each (n_s, n) rad and rad/s, at the pairs (t[i] s, P1[i] p.u.), 1-D arrays
    of one length n_s: one `solve(times, p1)` per distinct P1 (an adapter's `_solve`: (1, n_t, n)
    arrays at the sorted unique `times` of that P1's pairs, `p1` of shape (1,)), so a P1 shared by
    many pairs is one integration, and a P1 of one pair is that pair's own integration."""
    groups = PointGroups.of(t, P1)
    order, starts = groups.order, groups.starts.tolist()
    delta, omega = np.empty((t.size, n)), np.empty((t.size, n))
    for g in range(groups.P1.size):
        pairs = order[starts[g]:starts[g + 1]]
        if pairs.size == 1:
            d, o = solve(t[pairs], groups.P1[g:g + 1])
            delta[pairs], omega[pairs] = d[0], o[0]
            continue
        times, back = np.unique(t[pairs], return_inverse=True)
        d, o = solve(times, groups.P1[g:g + 1])
        delta[pairs], omega[pairs] = d[0, back], o[0, back]
    return delta, omega


class _Solves(Protocol):
    case: Case

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class PointsByP1:
    """Mixin of the classical adapters (listed before `AbstractSolver`): `solve_points` by one
    integration per distinct P1 (`points_by_p1`) instead of one per pair."""

    def _solve_points(self: _Solves, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (n_s, n), at the pairs (t[i] s, P1[i] p.u.): `points_by_p1`."""
        return points_by_p1(self._solve, t, P1, self.case.n)


class _States(Protocol):
    def _states(self, case: Case, y0: np.ndarray, P: np.ndarray, t: np.ndarray, failed: str) -> np.ndarray: ...


class StackedStates:
    """Mixin of the adapters that integrate a batch of trajectories from given states in one call,
    `_states(case, y0 (n_b, 2n), P (n_b, n), t, failed) -> y (n_b, len(t), 2n)` (`failed` names
    the scenario values in a SolveError): a step case's trajectories from its initial state, and
    one phase of a fault case (`solvers.classical.fault_phases.PhaseIntegrator`)."""

    def _integrate(self: _States, case: Case, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (len(P1), len(t), n), at sorted unique times t >= 0 (s)."""
        y0 = np.tile(np.array(case.delta0 + case.omega0), (P1.size, 1))
        y = self._states(case, y0, case.powers(P1), t, which_p1(P1))
        return y[..., :case.n], y[..., case.n:]

    def _phase(self: _States, phase: Case, y0: np.ndarray, t: np.ndarray, T_c: np.ndarray) -> np.ndarray:
        """`solvers.classical.fault_phases.PhaseIntegrator`: one phase of a fault case from y0 (n_b, 2n)."""
        P = np.tile(np.asarray(phase.p_m), (y0.shape[0], 1))
        return self._states(phase, y0, P, t, which_p1(T_c, "t_c"))


class ObservationLayout(NamedTuple):
    """Scattered samples as a (P1, t) grid: sorted unique t (s) and P1, and the index of each
    sample in them, so one batched simulation on the grid serves every sample."""

    t: np.ndarray
    P1: np.ndarray
    t_index: np.ndarray
    p1_index: np.ndarray

    @classmethod
    def of(cls, obs: Observations) -> ObservationLayout:
        t, t_index = np.unique(obs.t, return_inverse=True)
        p1, p1_index = np.unique(obs.P1, return_inverse=True)
        return cls(t, p1, t_index, p1_index)

    def pick(self, grid: np.ndarray) -> np.ndarray:
        """Values at the samples from an array of shape (len(P1), len(t), ...): (n_s, ...)."""
        return grid[self.p1_index, self.t_index]


# Simulator for identification: (m (n,), d (n,), with_jacobian) -> (delta, omega, d delta/d(m, d),
# d omega/d(m, d)) on the layout's grid, arrays (n_p, n_t, n) and (n_p, n_t, n, 2n) (columns
# m_1..n, d_1..n); jacobians None unless asked for.
Simulator = Callable[
    [np.ndarray, np.ndarray, bool], tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]
]


def identify_least_squares(
    simulate: Simulator, obs: Observations, layout: ObservationLayout,
    m_box: np.ndarray, d_box: np.ndarray, analytic_jacobian: bool,
    n_start: int = 6, xtol: float = 1e-12, diff_step: float | None = None,
    rank_starts: Simulator | None = None, rtol: float = 0.0,
) -> Estimate:
    """Least squares over theta = (log m_1..n, log d_1..n) of the misfit in every machine's delta
    (and omega when observed).

    The misfit of an oscillation has local minima in m (the frequency), so the start is the best
    point of an `n_start` x `n_start` grid: point (i, j) puts every machine's log m at the i-th and
    log d at the j-th of `n_start` evenly spaced interior points of its own box (`m_box`, `d_box`,
    (n, 2) p.u.); then a trust-region Gauss-Newton (`scipy.optimize.least_squares`) refines all 2n,
    with the simulator's sensitivities when `analytic_jacobian` (else finite differences with the
    relative step `diff_step`, scipy's default when None). `rank_starts` (default `simulate`) ranks
    the start grid: a cheaper, looser simulator may do, since only the order of the misfits matters.
    Returns the `Estimate` (iterations: simulations) with the Gauss-Newton covariance of theta from
    least squares' Jacobian at the solution (the analytic one, or the finite differences) and the
    misfit: s^2 (J^T J)^-1, s^2 = ||r||^2 / (n_values - 2n) pooled over delta and omega, plus the
    simulator's own error taken as `rtol` (its relative tolerance) x ||observations||
    (`gauss_newton_covariance`'s model_error).
    """
    with_omega = obs.omega is not None
    target = np.concatenate([obs.delta.ravel(), obs.omega.ravel()]) if with_omega else obs.delta.ravel()
    n = obs.delta.shape[1]
    n_sim = 0

    def misfit(theta: np.ndarray, want_jac: bool = False, run: Simulator = simulate):
        nonlocal n_sim
        n_sim += 1
        params = np.exp(theta)
        delta, omega, jd, jo = run(params[:n], params[n:], want_jac)
        r = layout.pick(delta).ravel()
        if with_omega:
            r = np.concatenate([r, layout.pick(omega).ravel()])
        if not want_jac:
            return r - target
        jac = layout.pick(jd).reshape(-1, 2 * n)
        if with_omega:
            jac = np.concatenate([jac, layout.pick(jo).reshape(-1, 2 * n)])
        return jac * params  # chain rule for the log parameters

    boxes = np.log(np.concatenate([np.asarray(m_box, np.float64), np.asarray(d_box, np.float64)]))  # (2n, 2)
    lower, upper = boxes[:, 0], boxes[:, 1]
    grid = np.array([np.linspace(lo, hi, n_start + 2)[1:-1] for lo, hi in boxes])  # (2n, n_start)
    starts = [np.concatenate([grid[:n, i], grid[n:, j]]) for i in range(n_start) for j in range(n_start)]
    costs = [np.sum(misfit(theta, run=rank_starts or simulate) ** 2) for theta in starts]
    theta0 = starts[int(np.nanargmin(costs))]

    jac = (lambda theta: misfit(theta, want_jac=True)) if analytic_jacobian else "2-point"
    result = least_squares(
        misfit, theta0, jac=jac, bounds=(lower, upper), xtol=xtol, ftol=1e-15, gtol=1e-15,
        x_scale=1.0, max_nfev=200, diff_step=None if analytic_jacobian else diff_step,
    )
    params = np.exp(result.x)
    cov, dof, condition = gauss_newton_covariance(result.jac, result.fun, rtol * float(np.linalg.norm(target)))
    return Estimate(params[:n], params[n:], n_sim, bool(result.success), str(result.message), cov, dof, condition,
                    (np.asarray(m_box, np.float64), np.asarray(d_box, np.float64)))


def identify_by_simulation(
    integrate: Callable[[Case, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]], case: Case,
    obs: Observations, options: dict,
) -> Estimate:
    """`identify_least_squares` around `integrate(case, t, P1)` -> (delta, omega), each
    (len(P1), len(t), n), at sorted unique times: the case with trial (m, d), Jacobian by finite
    differences; the search box and `rtol` from the adapter's `options`.

    The difference step is sqrt(rtol) (relative, in log m and log d): a solution computed to
    `rtol` is a noisy function of (m, d), and a step of scipy's default 1.5e-8 turns that noise into
    a meaningless Jacobian (measured, scipy-odeint at rtol 1e-3, N_u = 100 noise-free samples:
    m and d off by 3 % and 18 %; with sqrt(rtol), 0.13 % and 0.08 %). A larger step would bias the
    fit of noisy data (the fixed point is where J_approx^T r = 0)."""
    layout = ObservationLayout.of(obs)
    rtol = options["rtol"]

    def simulate(m: np.ndarray, d: np.ndarray, with_jacobian: bool):
        delta, omega = integrate(dataclasses.replace(case, m=tuple(m), d=tuple(d)), layout.t, layout.P1)
        return delta, omega, None, None

    return identify_least_squares(simulate, obs, layout, *search_boxes(case, options), analytic_jacobian=False,
                                  diff_step=float(np.sqrt(max(rtol, np.finfo(float).eps))), rtol=rtol)
