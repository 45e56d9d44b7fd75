"""diffrax's explicit Runge-Kutta solvers under jax.jit (CPU, float64) on the n-machine swing
equation (`systems.model.accelerations`), all P1 in one compiled call."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any, ClassVar, Literal, NamedTuple

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from solvers.base import AbstractSolver, Estimate, FitReport, SolveError, StepCount
from solvers.classical.common import (
    TOLERANCE_CONFIGS,
    TOLERANCE_MARKS,
    ObservationLayout,
    PointGroups,
    ToleranceOptions,
    at_query_times,
    check_step,
    identify_least_squares,
    points_by_p1,
    search_boxes,
)
from solvers.classical.diffrax_faults import switched
from solvers.options import PositiveFloat, PositiveInt
from solvers.threads import configure_threads
from systems.cases import Case, Observations
from systems.model import Coupling, accelerations, coupling

__all__ = ["DiffraxODE"]

METHODS = {"tsit5": diffrax.Tsit5, "dopri5": diffrax.Dopri5, "dopri8": diffrax.Dopri8}
# Sizes of t and P1 compiled as they are (the latency suite's queries); any other size is padded up
# to the next of these or of the powers of two, so arbitrary queries compile a few shapes, not one each.
EXACT_SIZES = (1, 10, 100, 201, 1000, 10000)


def bucket(n: int) -> int:
    """The compiled size that holds `n` entries: the smallest of EXACT_SIZES and 2**k that is >= n."""
    return min([s for s in EXACT_SIZES if s >= n] + [1 << max(n - 1, 0).bit_length()])


def _pad(x: np.ndarray, size: int) -> np.ndarray:
    """`x` repeated at its last entry up to `size` (sorted times stay non-decreasing)."""
    return x if x.size == size else np.concatenate([x, np.full(size - x.size, x[-1])])


class Structure(NamedTuple):
    """What the compiled code of a case depends on besides the traced m, d, p_m and controls: the
    coupling coefficients (`systems.model.Coupling` as nested tuples, p.u.) and the initial state
    y0 = [delta0 (n) rad, omega0 (n) rad/s]. Hashable, so cases that differ only in m, d or p_m
    (identification's trial cases, `Case.with_params`) share one compilation."""

    C: tuple[tuple[float, ...], ...]
    S: tuple[tuple[float, ...], ...]
    c_inf: tuple[float, ...]
    s_inf: tuple[float, ...]
    y0: tuple[float, ...]

    @classmethod
    def of(cls, case: Case) -> Structure:
        k = coupling(case)
        return cls(tuple(map(tuple, k.C.tolist())), tuple(map(tuple, k.S.tolist())), tuple(k.c_inf.tolist()),
                   tuple(k.s_inf.tolist()), case.delta0 + case.omega0)

    @property
    def n(self) -> int:
        return len(self.c_inf)


def _machines_first(M: jax.Array, v: jax.Array) -> jax.Array:
    """M v for v of shape (n, ...): machines on the first axis, the batch after them."""
    return jnp.tensordot(M, v, axes=1)


def _vector_field(structure: Structure):
    """f(t, y, (P, m, d)) of the n-machine swing equation; y (2n, ...) = [delta_1..n, omega_1..n]
    (rad, rad/s), P (n, ...) p.u., m and d (n,) p.u.: `systems.model.accelerations` with machines
    on the FIRST axis (the stacked batch of P1 trails it), so a stacked solve is one (2n, n_p) state."""
    n = structure.n
    # numpy float64 constants, made jax arrays when traced (under jax.enable_x64: converted here,
    # outside it, they would become float32)
    C, S, c_inf, s_inf = (np.asarray(x, np.float64) for x in structure[:4])

    def field(t, y, args):
        P, m, d = args
        column = (n,) + (1,) * (y.ndim - 1)  # (n,) coefficients broadcast against (n, ...) states
        k = Coupling(C, S, c_inf.reshape(column), s_inf.reshape(column))
        acc = accelerations(k, m.reshape(column), d.reshape(column), y[:n], y[n:], P,
                            sin=jnp.sin, cos=jnp.cos, matvec=_machines_first)
        return jnp.concatenate([y[n:], acc])

    return field


def phase_solver(structure: Structure, method: str, adaptive: bool, max_steps: int, count: bool = False):
    """solve(y0, m, d, rtol, atol, dt, t, P) -> (ys (n_t, 2n, ...), ok): the system of `structure`
    (its coupling; the initial state is y0, (2n, ...) like P's trailing axes) from time 0 to t[-1],
    saved at t (sorted, s), P (n, ...) p.u.: one trajectory, or (n, n_p) stacked. Traceable.
    `count`: (the accepted steps, ok) in place of (ys, ok)."""
    term = diffrax.ODETerm(_vector_field(structure))
    solver = METHODS[method]()

    def solve(y0, m, d, rtol, atol, dt, t, P):
        control = diffrax.PIDController(rtol=rtol, atol=atol) if adaptive else diffrax.ConstantStepSize()
        sol = diffrax.diffeqsolve(
            term, solver, 0.0, t[-1], None if adaptive else dt, y0, args=(P, m, d),
            saveat=diffrax.SaveAt(ts=t), stepsize_controller=control, max_steps=max_steps,
            adjoint=diffrax.ForwardMode(), throw=False,
        )
        return sol.stats["num_accepted_steps"] if count else sol.ys, sol.result == diffrax.RESULTS.successful

    return solve


@functools.lru_cache(maxsize=4)
def _step_counter(structure: Structure, method: str, adaptive: bool, max_steps: int):
    """Jitted count(m (n,), d (n,), p_m (n,), rtol, atol, dt, t (1,) s, p1) -> (accepted steps, ok)
    of one trajectory from time 0 to t[0] with generator-1 power p1 (p.u.), stepped as `_compiled`'s
    values step it (the saved times do not change diffrax's steps)."""
    solve_from = phase_solver(structure, method, adaptive, max_steps, count=True)
    y0 = np.array(structure.y0)

    def count(m, d, p_m, rtol, atol, dt, t, p1):
        return solve_from(jnp.asarray(y0), m, d, rtol, atol, dt, t, jnp.concatenate([p1[None], p_m[1:]]))

    return jax.jit(count)


@functools.lru_cache(maxsize=16)
def _compiled(structure: Structure, method: str, batch: str, adaptive: bool, max_steps: int):
    """Jitted (values, sensitivities) for one system and solver. Tolerances, step, m, d and p_m are
    arguments, not constants, so a tolerance sweep (or another config, or a trial (m, d)) reuses the
    compiled code.

    values(m (n,), d (n,), p_m (n,), rtol, atol, dt, t (n_t,) sorted, P1 (n_p,))
        -> (y (n_p, n_t, 2n) = [delta_1..n, omega_1..n], ok (n_p,));
    sensitivities(m (n,), d (n,), ...) -> (y, ok, dy/d(m, d) (n_p, n_t, 2n, 2n), columns m_1..n, d_1..n);
    points(m, d, p_m, rtol, atol, dt, T (n_g, k) each row sorted, P1 (n_g,)) -> (y (n_g, k, 2n), ok
    (n_g,)): one trajectory per row, to that row's last time, each with its own steps (jax.vmap).
    Mechanical powers as `Case.powers`: generator 1 (index 0) gets P1, the others p_m.
    """
    n = structure.n
    solve_from = phase_solver(structure, method, adaptive, max_steps)
    y0_one = np.array(structure.y0)

    def solve(m, d, rtol, atol, dt, t, P):  # P (n, ...): one trajectory, or (n, n_p) stacked
        y0 = jnp.broadcast_to(y0_one.reshape((2 * n,) + (1,) * (P.ndim - 1)), (2 * n,) + P.shape[1:])
        return solve_from(y0, m, d, rtol, atol, dt, t, P)  # ys (n_t, 2n, ...)

    def powers_of(P1, p_m):  # (n, n_p): row 0 is P1, row k the constant p_m[k] (Case.powers, machines first)
        return jnp.concatenate([P1[None, :], jnp.broadcast_to(p_m[1:, None], (n - 1, P1.size))])

    def values(m, d, p_m, rtol, atol, dt, t, P1):
        powers = powers_of(P1, p_m)
        if batch == "stacked":
            ys, ok = solve(m, d, rtol, atol, dt, t, powers)
            y = jnp.transpose(ys, (2, 0, 1))  # (n_t, 2n, n_p) -> (n_p, n_t, 2n)
        else:
            y, ok = jax.vmap(lambda p: solve(m, d, rtol, atol, dt, t, p), in_axes=1)(powers)  # (n_p, n_t, 2n)
        ok = ok & jnp.all(jnp.isfinite(y), axis=(1, 2))
        return y, ok

    def of_md(md, p_m, rtol, atol, dt, t, P1):
        y, ok = values(md[:n], md[n:], p_m, rtol, atol, dt, t, P1)
        return y, (y, ok)

    def sensitivities(m, d, p_m, rtol, atol, dt, t, P1):
        # forward mode: 2n tangents through the solver (diffrax.ForwardMode), one per parameter
        jac, (y, ok) = jax.jacfwd(of_md, has_aux=True)(jnp.concatenate([m, d]), p_m, rtol, atol, dt, t, P1)
        return y, ok & jnp.all(jnp.isfinite(jac), axis=(1, 2, 3)), jac

    def points(m, d, p_m, rtol, atol, dt, T, P1):
        y, ok = jax.vmap(lambda times, p: solve(m, d, rtol, atol, dt, times, p),
                         in_axes=(0, 1))(T, powers_of(P1, p_m))  # (n_g, k, 2n)
        return y, ok & jnp.all(jnp.isfinite(y), axis=(1, 2))

    return jax.jit(values), jax.jit(sensitivities), jax.jit(points)


@functools.lru_cache(maxsize=16)
def _compiled_fault(on: Structure, post: Structure, method: str, adaptive: bool, max_steps: int):
    """Jitted values(m, d, p_m, rtol, atol, dt, t (n_t,) sorted, T_c (n_c,)) -> (y (n_c, n_t, 2n),
    ok (n_c,)) of a fault case, `on` and `post` its phases' structures (`diffrax_faults.switched`):
    the signature of `_compiled`'s values, the clearing times in place of P1."""
    return jax.jit(switched(np.array(on.y0), phase_solver(on, method, adaptive, max_steps),
                            phase_solver(post, method, adaptive, max_steps)))


Method = Literal[tuple(METHODS)]  # one of the keys of METHODS


class DiffraxOptions(ToleranceOptions):
    method: Method = "dopri8"
    dt: PositiveFloat | None = None  # s; None: adaptive; <= the case's t_final (`check_step`, by the adapter)
    batch: Literal["stacked", "vmap"] = "stacked"
    max_steps: PositiveInt = 16384
    threads: PositiveInt = 2


class DiffraxODE(AbstractSolver):
    """diffrax Tsit5 / Dopri5 / Dopri8 with PID step-size control (or a constant step), jitted, float64.

    The state is [delta_1..n, omega_1..n] (rad, rad/s) with the machines on the first axis inside
    the compiled code; queries return the contract's (len(P1), len(t), n) arrays. Generator 1's
    mechanical power is P1, the others' the case's p_m (`Case.powers`).

    Options: method ("dopri8", "dopri5", "tsit5"); rtol, atol (defaults 1e-3, 1e-6: ode45's; PID
    control on the RMS norm of the whole state); dt (None: adaptive; a step in s, at most the
    case's t_final: constant step, rtol and atol unused); batch: "stacked" (the default: one system
    of 2 * len(P1) states, one step size for all) or "vmap" (jax.vmap of one-trajectory solves,
    each with its own steps; the batched while loop runs until the slowest finishes and masks the
    others); max_steps (a solve that needs more fails with SolveError); m_bounds, d_bounds (p.u.),
    the search box of `identify` (default: the case's per-machine boxes); threads: XLA's CPU
    threads (process-wide, applied if XLA has not started yet).

    Measured on 2 cores, SMIB, 100 x 201 grid, Dopri8, jitted: stacked 0.92 ms at rtol 1e-6 (rel. L2
    3.3e-7), vmap 3.2 ms (4.5e-7); vmap is 3-4x slower at every tolerance and method tried, as
    the few steps (~20) are cheap next to the batched loop's masking and per-trajectory saving.
    Dopri8 is the default method: at rtol 1e-6 it equals Dopri5 and Tsit5 in time (~0.9 ms, most
    of which is diffrax's per-step and per-saved-time loop overhead), and it needs 4-5x fewer steps
    at the tight tolerances identification uses.

    Output times: SaveAt(ts=sorted unique t); t and P1 are padded (repeating the last value) to
    the compiled sizes of `bucket` (the latency suite's sizes exactly, else the next power of two),
    and `fit` compiles the benchmark's shapes (201 times x 1, 10, 100, 1000, 10000 P1; one time x
    one P1, on [0, t_final]). The tolerances, dt, m, d and p_m are traced arguments: every config
    and every case of one `Structure` (coupling and initial state) shares the compiled code.
    `identify` estimates every machine's m and d, differentiating through the solver (jax.jacfwd
    over the 2n parameters, diffrax.ForwardMode()) for the Jacobian of the least squares, compiled
    once per padded observation layout.
    A fault case (P1 the clearing time t_c s): the fault-on phase once for every t_c of a query,
    then each post-fault phase from its state at t_c with its own steps, in one compiled call
    whatever `batch` (`solvers.classical.diffrax_faults`); solve_points one call per distinct t_c.
    """

    name: ClassVar[str] = "diffrax"
    compiled: ClassVar[bool] = True
    SCHEMA = DiffraxOptions
    CONFIGS = TOLERANCE_CONFIGS
    CONFIG_MARKS = TOLERANCE_MARKS
    has_tolerance = True
    takes_threads = True
    handles_faults = True
    counts_steps = True
    QUERY_OPTIONS = frozenset({"threads"})  # its `batch` changes identification's error control: not here
    FIT_SHAPES: ClassVar[tuple[tuple[int, int], ...]] = (
        (201, 100), (201, 1), (201, 10), (201, 1000), (201, 10000), (1, 1),
    )
    # `fit` compiles the FIT_SHAPES whose states (n_t x n_p x 2n float64) fit in this many bytes;
    # larger ones compile on first use. Running every shape held 4.2 GB at 54 machines and more
    # than 16 GiB at 260 (10,000 trajectories: 8.4 GB of states alone), measured.
    FIT_MAX_BYTES: ClassVar[int] = 2**30
    # `fit` compiles solve_points for these numbers of pairs, every P1 distinct (the latency suite's
    # batches of scattered points); other layouts compile on first use.
    FIT_POINTS: ClassVar[tuple[int, ...]] = (1000, 10000)
    # solve_points' padded output (distinct P1 x times of the largest group x 2n float64) above this
    # takes one call per distinct P1 instead of one over all of them
    POINTS_MAX_BYTES: ClassVar[int] = 2**28

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """A constant step sweeps dt; an adaptive one the tolerances (the base class's sweep)."""
        if self.options["dt"] is not None:
            # Dopri8 reaches the reference's 1e-12 at dt = 0.2 s already: the curve starts coarse
            return self.step_sweep((1.0, 0.5, 0.2, 0.1, 0.05, 0.02), rtols)
        return super().precision_sweep(rtols)

    def _check_options(self) -> None:
        """The step rule that depends on the case, numba-rk's (the rest is `DiffraxOptions`)."""
        check_step(self.name, self.options["dt"], self.case)

    def _functions(self, structure: Structure):
        o = self.options
        return _compiled(structure, o["method"], o["batch"], o["dt"] is None, int(o["max_steps"]))

    def _controls(self) -> tuple[float, float, float]:
        o = self.options
        return float(o["rtol"]), float(o["atol"]), float(o["dt"] or 0.0)

    def _fit(self) -> FitReport:
        note = configure_threads(self.options["threads"])
        case, o = self.case, self.options
        if case.fault is None:
            self._values, _, self._points = self._functions(Structure.of(case))
        else:
            self._values = _compiled_fault(Structure.of(case.phase("on")), Structure.of(case.phase("post")),
                                           o["method"], o["dt"] is None, int(o["max_steps"]))
        with jax.enable_x64(True):  # device arrays once: converting them cost ~20 us of every query
            self._fixed = tuple(jnp.asarray(x, jnp.float64)
                                for x in (case.m, case.d, case.p_m, *self._controls()))
        p1 = 0.5 * (case.p1_min + case.p1_max)
        grid = np.linspace(0.0, case.t_final, 201)
        with jax.enable_x64(True):
            for n_t, n_p in self.FIT_SHAPES:  # compile and run once; a failure shows in solve
                if bucket(n_t) * bucket(n_p) * 2 * case.n * 8 > self.FIT_MAX_BYTES:
                    continue
                t = grid[:n_t] if n_t > 1 else grid[-1:]
                # padded as `_run` pads a query of this size, so that the query finds this compilation
                y, _ = self._values(*self._fixed, _pad(t, bucket(n_t)), np.full(bucket(n_p), p1))
                y.block_until_ready()
        for n_s in self.FIT_POINTS if case.fault is None else ():  # as many distinct P1 as pairs, one time each
            if bucket(n_s) * 2 * case.n * 8 <= self.FIT_MAX_BYTES:
                self._solve_points(np.zeros(n_s), np.linspace(case.p1_min, case.p1_max, n_s))
        return FitReport(seconds=0.0, message=note)

    def _run(self, times: np.ndarray, P1: np.ndarray) -> np.ndarray:
        """States (len(P1), len(times), 2n) = [delta_1..n, omega_1..n] (rad, rad/s) at sorted unique
        `times` (s); SolveError naming a failed P1."""
        n_t, n_p = times.size, P1.size
        with jax.enable_x64(True):
            y, ok = self._values(*self._fixed, _pad(times, bucket(n_t)), _pad(P1, bucket(n_p)))
        ok = np.asarray(ok)[:n_p]
        if not ok.all():
            self._fail(times[-1], P1, ok)
        return np.asarray(y)[:n_p, :n_t]

    def _fail(self, t_end: float, P1: np.ndarray, ok: np.ndarray) -> None:
        """Raise SolveError naming the first failed P1 (stacked: the first that fails alone on
        [0, t_end] s, the query's span)."""
        symbol = self.case.scenario.symbol
        if self.options["batch"] == "stacked" and self.case.fault is None and P1.size > 1:
            for p1 in P1:
                self._run(np.array([t_end]), np.array([p1]))  # raises for a P1 that fails on its own
            where = f"one of P1 in [{P1.min():g}, {P1.max():g}] (the stacked solve)"
        else:
            where = f"{symbol}={P1[np.argmin(ok)]:g}"
        raise SolveError(f"{self.name}: integration failed at {where}: max_steps="
                         f"{self.options['max_steps']} reached or the state is not finite")

    def _step_count(self, p1: float) -> StepCount:
        """diffrax's accepted steps (`sol.stats`) of one trajectory over [0, t_final] s, from a
        solve compiled for counting (`_step_counter`, compiled on the first call); diffrax does not
        report its evaluations."""
        o = self.options
        count = _step_counter(Structure.of(self.case), o["method"], o["dt"] is None, int(o["max_steps"]))
        with jax.enable_x64(True):
            steps, ok = count(*self._fixed, jnp.array([self.case.t_final]), jnp.asarray(p1, jnp.float64))
        if not bool(ok):
            self._fail(self.case.t_final, np.array([p1]), np.array([False]))
        return StepCount(int(steps))

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if t.size == 1 or np.all(t[1:] > t[:-1]):
            y = self._run(t, P1)
        else:
            y = at_query_times(lambda times: self._run(times, P1), t)
        n = self.case.n
        return y[..., :n], y[..., n:]

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (n_s, n) rad and rad/s, at the pairs (t[i] s, P1[i] p.u.): one
        compiled call over the distinct P1 (`_compiled`'s points), each trajectory to the last time
        of its pairs, its times and the number of distinct P1 padded to `bucket` sizes; one call per
        distinct P1 (`points_by_p1`) when that padded output would exceed `POINTS_MAX_BYTES`."""
        groups, n = PointGroups.of(t, P1), self.case.n
        if self.case.fault is not None:
            return points_by_p1(self._solve, t, P1, n)
        rows, width = bucket(groups.P1.size), bucket(int(np.diff(groups.starts).max()))
        if rows * width * 2 * n * 8 > self.POINTS_MAX_BYTES:
            return points_by_p1(self._solve, t, P1, n)
        with jax.enable_x64(True):
            y, ok = self._points(*self._fixed, groups.padded_times(t, rows, width), _pad(groups.P1, rows))
        ok = np.asarray(ok)[:groups.P1.size]
        if not ok.all():
            raise SolveError(f"{self.name}: integration failed at P1={groups.P1[np.argmin(ok)]:g}: max_steps="
                             f"{self.options['max_steps']} reached or the state is not finite")
        y = groups.scatter(np.asarray(y))
        return y[:, :n], y[:, n:]

    def _identify(self, obs: Observations) -> Estimate:
        note = configure_threads(self.options["threads"])
        case, n = self.case, self.case.n
        values, sensitivities, _ = self._functions(Structure.of(case))
        layout = ObservationLayout.of(obs)
        n_p, n_t = layout.P1.size, layout.t.size
        with jax.enable_x64(True):
            t = jnp.asarray(_pad(layout.t, bucket(n_t)))
            p1 = jnp.asarray(_pad(layout.P1, bucket(n_p)))
            p_m = jnp.asarray(case.p_m, jnp.float64)
        controls = self._controls()

        def simulate(m: np.ndarray, d: np.ndarray, with_jacobian: bool):
            with jax.enable_x64(True):
                m, d = jnp.asarray(m, jnp.float64), jnp.asarray(d, jnp.float64)
                if with_jacobian:
                    y, ok, jac = sensitivities(m, d, p_m, *controls, t, p1)
                else:
                    (y, ok), jac = values(m, d, p_m, *controls, t, p1), None
            if not np.asarray(ok)[:n_p].all():
                raise SolveError(f"{self.name}: integration failed at m={np.asarray(m).tolist()}, "
                                 f"d={np.asarray(d).tolist()}, one of P1 in "
                                 f"[{layout.P1.min():g}, {layout.P1.max():g}]")
            y = np.asarray(y)[:n_p, :n_t]
            if jac is None:
                return y[..., :n], y[..., n:], None, None
            jac = np.asarray(jac)[:n_p, :n_t]  # (n_p, n_t, 2n states, 2n parameters)
            return y[..., :n], y[..., n:], jac[:, :, :n], jac[:, :, n:]

        est = identify_least_squares(
            simulate, obs, layout, *search_boxes(case, self.options), analytic_jacobian=True,
            rtol=self.options["rtol"],
        )
        return est._replace(message=f"{est.message} {note}".strip())
