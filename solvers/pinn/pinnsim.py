"""The PINNSim adapter (`pinnsim`, Stiasny, Zhang & Chatzivasileiadis, EPSR 235, 2024): one
component PINN of a classical machine against a polynomial bus voltage (`solvers.pinn.component`),
trained once for every machine of every case, coupled through the network at a fixed step
(`solvers.pinn.simulator`).

The component network is trained on what the options say (domain, architecture, data, seed,
budget), not on the case: `fit` loads it from `component_dir` when a network of those options was
trained before (its training seconds in the fit message), else trains and stores it there. A case
whose machines fall outside the trained domain (mu, kappa or p on the machine's own beta = E / x'd)
is refused when the adapter is built, naming the parameter.

A fault case (`systems.cases.Fault`, P1 the clearing time t_c s) runs on the fault-on and
post-fault networks' impedances from their reduced forms and the tie admittances the fault keeps
(`solvers.pinn.simulator_faults`), with steps whose edges fall on 0 and t_c; the config "faults"
trains the network on a domain that holds a faulted network's terminal voltages and its swings (the
default domain's v0 >= 0.85 p.u. does not: such a case is refused there when built).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from threadpoolctl import threadpool_limits

from solvers.base import LARGE_SYSTEMS, AbstractSolver, FitReport, PartialSolveError, SolveError
from solvers.identification import Estimate
from solvers.pinn.component import INPUTS, Component, Domain, train
from solvers.pinn.pinnsim_options import FAULT_CONFIG, FAULT_DOMAIN, H_MAX, STEP_SWEEP, PinnSimOptions
from solvers.pinn.simulator import query_function, simulate_function
from solvers.pinn.simulator_faults import (
    POST_FAULT,
    Schedule,
    fault_schedule,
    impedances,
    tie_admittances,
    uniform_schedule,
)
from solvers.pinn.simulator_newton import CG_TOL_FLOAT32
from solvers.threads import configure_threads
from systems.cases import FAULT_SCENARIO, NETWORK, STEP_SCENARIO, Case, Observations

__all__ = ["FAULT_DOMAIN", "H_MAX", "STEP_SWEEP", "PinnSim", "PinnSimOptions", "machine_parameters"]

def _bucket(count: int) -> int:
    """The padded number of P1 a simulation compiles for: the next power of two up to 16, then the
    next multiple of 16 (at most 2x the work; a handful of compiled shapes)."""
    return 1 << (count - 1).bit_length() if count <= 16 else -(-count // 16) * 16


# A query's dense output evaluates every machine's network at every (P1, time) or point at once; its
# largest buffer holds 800 bytes an evaluation (case9241pegase's grid, 112 x 201 x 1445 of them, asked
# for 26.0 GB). A query is split into calls of at most this many bytes of that buffer.
EVALUATION_BYTES, QUERY_BYTES = 800, 2**30


def _chunk(count: int, per_item: int) -> int:
    """How many of `count` items (times, or points) one query call takes, each item `per_item`
    network evaluations: all where they fit in `QUERY_BYTES`, else a fixed number (>= 1; the calls
    padded to it compile once)."""
    return max(1, min(count, QUERY_BYTES // (EVALUATION_BYTES * max(per_item, 1))))


def _padded(values: np.ndarray, size: int) -> np.ndarray:
    """`values` (non-empty) padded to `size` with its last value (a compiled shape reused)."""
    return np.concatenate([values, np.full(size - values.size, values[-1])])


def _pieces(values: np.ndarray, size: int) -> list[tuple[slice, np.ndarray]]:
    """`values` in pieces of `size`, the last `_padded`: (the piece's slice of values, the padded
    piece)."""
    return [(slice(start, min(start + size, values.size)), _padded(values[start:start + size], size))
            for start in range(0, values.size, size)]


def machine_parameters(case: Case) -> dict[str, np.ndarray]:
    """Each machine on its own beta = E |y| (p.u.): mu = m / beta (s^2/rad), kappa = d / beta (s/rad),
    beta, and w = y E (complex p.u.), y its tie admittance (`tie_admittances`)."""
    y = tie_admittances(case)
    assert y is not None
    E = np.asarray(case.E, np.float64)
    beta = E * np.abs(y)
    return {"mu": np.asarray(case.m) / beta, "kappa": np.asarray(case.d) / beta, "beta": beta, "w": y * E}


class PinnSim(AbstractSolver):
    """PINNSim on JAX, float64: each machine a component PINN, the network solved at each step of h
    by Gauss-Newton on its voltage polynomials. Network step cases with a carried network, and (config
    "faults") fault cases that keep their machines' tie admittances. Shapes as the contract:
    (len(P1), len(t), n) and (n_s, n)."""

    name: ClassVar[str] = "pinnsim"
    SCHEMA = PinnSimOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = {"default": {}, "faults": FAULT_CONFIG}
    CASE_KINDS: ClassVar[dict[str, frozenset[str]]] = {config: frozenset({NETWORK}) for config in CONFIGS}
    CASE_SCENARIOS: ClassVar[dict[str, frozenset]] = {"default": frozenset({STEP_SCENARIO}),
                                                      "faults": frozenset({FAULT_SCENARIO})}
    # training takes minutes: make bench leaves them out unless named, as the other large-system configs
    CONFIG_MARKS: ClassVar[dict[str, frozenset[str]]] = {config: frozenset({LARGE_SYSTEMS}) for config in CONFIGS}
    trains: ClassVar[bool] = True
    trained_per_case: ClassVar[bool] = False  # one component network serves every case
    identifies: ClassVar[bool] = False
    handles_faults: ClassVar[bool] = True  # where the domain holds the faulted terminal voltages (`_check_fault`)
    takes_threads: ClassVar[bool] = True
    compiled: ClassVar[bool] = True
    QUERY_OPTIONS: ClassVar[frozenset[str]] = frozenset({"threads", "component_dir"})

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """The step h, coarsest first, as many points as the run sweeps tolerances (`STEP_SWEEP`)."""
        return [{"h": float(h)} for h in STEP_SWEEP[:len(rtols)]]

    def _check_options(self) -> None:
        options, case = self.options, self.case
        if not 0.0 < options["h"] <= H_MAX:
            raise ValueError(f"{self.name}: option h={options['h']!r} s is outside (0, h_max = {H_MAX}] s")
        for h in options["retry_h"]:
            if not h <= H_MAX:
                raise ValueError(f"{self.name}: option retry_h has a step {h!r} s outside (0, h_max = {H_MAX}] s")
        if not options["cg_forcing"] < 1.0:
            raise ValueError(f"{self.name}: option cg_forcing={options['cg_forcing']!r} must be below 1 (CG's "
                             "normal residual relative to its start)")
        if options["cg_dtype"] == "float32" and options["cg_tol"] < CG_TOL_FLOAT32:
            raise ValueError(f"{self.name}: option cg_tol={options['cg_tol']!r} is below what complex64 products resolve "
                             f"(cg_dtype float32): use cg_tol >= {CG_TOL_FLOAT32:g}")
        if options["collocation"] < 2:
            raise ValueError(f"{self.name}: option collocation must be at least 2 (4 n unknowns, 2 n equations a point)")
        if case.kind != NETWORK or tie_admittances(case) is None:
            raise ValueError(f"{self.name} is made for multi-machine cases that carry their network (a fault case: "
                             f"its machines' tie admittances); case {case.name!r} is a {case.kind} case"
                             + ("" if tie_admittances(case) is not None else " without one"))
        if not options["v0_min"] < options["v0_max"]:
            raise ValueError(f"{self.name}: options v0_min={options['v0_min']!r} and v0_max={options['v0_max']!r} p.u. "
                             "are no range")
        self.domain = Domain(h=options["net_h"], slip=options["slip_max"], theta2=options["theta2_max"],
                             v0=(options["v0_min"], options["v0_max"]), v1=options["v1_max"], v2=options["v2_max"])
        if case.fault is not None:
            self._check_fault()
        params = machine_parameters(case)
        P = case.powers(np.array([case.p1_min, case.p1_max]))
        checks = {"mu": params["mu"][None], "kappa": params["kappa"][None], "p": P / params["beta"]}  # (rows, n)
        for name, values in checks.items():
            low, high = getattr(self.domain, name)
            outside = ((values < low) | (values > high)).any(axis=0)
            if outside.any():
                k = int(np.argmax(outside))
                raise ValueError(f"{self.name}: case {case.name!r} machine {k + 1} has {name} in "
                                 f"[{values[:, k].min():.4g}, {values[:, k].max():.4g}], outside the trained domain "
                                 f"[{low}, {high}]")

    def _check_fault(self) -> None:
        """A fault case whose fault-on terminal voltages at t = 0 (from the equilibrium) fall outside
        the domain's v0 is refused here, naming the config that trains for them, and one that faults
        a machine's own terminal bus (the Gauss-Newton matrix singular: that angle drops out)."""
        case, (low, high) = self.case, self.domain.v0
        w = machine_parameters(case)["w"]
        v = np.abs(impedances(case)[0] @ (w * np.exp(1j * np.asarray(case.delta0))))
        if v.min() <= 1e-9 * v.max():
            raise ValueError(f"{self.name}: case {case.name!r} faults machine {int(v.argmin())}'s terminal bus (its "
                             "voltage 0, its angle undetermined in the Gauss-Newton step): not supported")
        if v.min() < low or v.max() > high:
            raise ValueError(f"{self.name}: case {case.name!r} has fault-on terminal voltages in [{v.min():.4g}, "
                             f"{v.max():.4g}] p.u. at t = 0, outside the trained domain's v0 [{low}, {high}] p.u.; "
                             f"config 'faults' trains a domain for fault cases")

    def _training(self) -> dict[str, Any]:
        keys = ("net_h", "form", "hidden_layers", "width", "trajectories", "times", "n_f", "physics_weight",
                "rate_weight", "max_iterations", "max_seconds", "seed")
        return {key: self.options[key] for key in keys}

    def component_key(self) -> str:
        """The stem of the trained network's files: what it was trained on (the options of
        `_training`, the domain) and the code and library versions that make it."""
        source = b"".join((Path(__file__).parent / name).read_bytes() for name in ("component.py", "optim.py",
                                                                                   "architecture.py"))
        payload = json.dumps({"training": self._training(), "domain": repr(self.domain), "jax": jax.__version__,
                              "numpy": np.__version__, "code": hashlib.sha256(source).hexdigest()}, sort_keys=True)
        return "component-" + hashlib.sha256(payload.encode()).hexdigest()[:16]

    def _component(self) -> tuple[Component, str, float]:
        """The component network, how it was had, and its training seconds when loaded from the
        cache (0 when trained here: then they are this fit's)."""
        options = self.options
        path = None if options["component_dir"] is None else Path(options["component_dir"]) / self.component_key()
        if path is not None and path.with_name(path.name + ".json").is_file():
            component = Component.load(path)
            if component.domain == self.domain and component.form == options["form"]:
                trained_s = float(component.record.get("seconds", float("nan")))
                return component, (f"component network loaded from {path} (trained once in {trained_s:.1f} s, "
                                   "counted in fit_s)"), trained_s
        with threadpool_limits(limits=1, user_api="blas"):
            component, result = train(self.domain, width=options["width"], depth=options["hidden_layers"],
                                      seed=options["seed"], trajectories=options["trajectories"],
                                      times=options["times"], n_f=options["n_f"],
                                      physics_weight=options["physics_weight"], rate_weight=options["rate_weight"],
                                      max_iterations=options["max_iterations"], max_seconds=options["max_seconds"],
                                      form=options["form"])
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            component.save(path)
        return component, f"component network trained in {component.record['seconds']:.1f} s ({result.message})", 0.0

    def _fit(self) -> FitReport:
        threads = configure_threads(self.options["threads"])
        component, how, trained_s = self._component()
        self.component = component
        params = machine_parameters(self.case)
        self._beta = params["beta"]
        with jax.enable_x64(True):
            self._theta = jnp.asarray(component.theta)
            self._machines = {"mu": jnp.asarray(params["mu"]), "kappa": jnp.asarray(params["kappa"]),
                              "w": jnp.asarray(params["w"]), "Z": jnp.asarray(impedances(self.case))}
        h = self.options["h"]
        self._simulate(h, h, np.array([self.case.p1_max]), check=False)  # compile one shape (one step)
        record = component.record
        return FitReport(seconds=0.0, iterations=int(record.get("iterations", 0)), loss=float(record.get("loss", np.nan)),
                         message="; ".join(filter(None, (threads, how))), reused_s=trained_s)

    def _schedule(self, h: float, t_max: float, P1: np.ndarray) -> Schedule:
        """The steps of every P1 (padded) to at least t_max and the horizon: h (s) each on a step
        case; on a fault case aligned with 0 and each t_c, counts fixed by the case's range of t_c
        (and any t_c or t beyond it) so that a query in the range compiles once (`fault_schedule`)."""
        case = self.case
        t_end = max(case.t_final, t_max)
        if case.fault is None:
            return uniform_schedule(P1.size, h, max(1, int(np.ceil(t_end / h - 1e-9))))
        return fault_schedule(P1, h, t_end, max(case.p1_max, float(P1.max())), min(case.p1_min, float(P1.min())))

    def _simulate(self, h: float, t_max: float, P1: np.ndarray, check: bool = True) -> tuple[
            Any, Any, Any, int, np.ndarray, tuple[list, np.ndarray] | None]:
        """(p, starts, coef, the last step simulated, the steps' edges (n_P padded, K + 1) s, the
        failure) of every P1 over the steps of h (s) that reach t_max (`_schedule`). The failure
        (`_check`, None without `check` or when every step held): per P1 the one-line message of its
        first failed step (a CG or Newton failure or a machine that leaves the trained domain,
        naming the step, its start and phase, and P1; None where none failed) and that step's start
        (s). One compiled function a padded count of P1 (`_bucket`) serves every number of steps up
        to the horizon."""
        options, case = self.options, self.case
        padded = _padded(P1, _bucket(P1.size))
        schedule = self._schedule(h, t_max, padded)
        steps = schedule.steps_to(t_max, h)
        run = simulate_function(self.component, h, schedule.lengths.shape[1], options["collocation"],
                                options["max_newton"], options["newton_tol"], options["newton"], options["cg_tol"],
                                options["max_cg"], options["cg_forcing"], options["cg_dtype"])
        p = case.powers(padded) / self._beta
        with jax.enable_x64(True):
            p_j = jnp.asarray(p)
            starts, coef, iterations, size, excess, column, cg, cg_residual = run(
                self._theta, self._machines, p_j, jnp.asarray(case.delta0), jnp.asarray(case.omega0), steps,
                jnp.asarray(schedule.lengths), jnp.asarray(schedule.phase))
        size, excess = np.asarray(size)[:P1.size, :steps], np.asarray(excess)[:P1.size, :steps]
        newton = np.asarray(iterations)[:P1.size, :steps]
        cg, cg_residual = np.asarray(cg)[:P1.size, :steps], np.asarray(cg_residual)[:P1.size, :steps]
        self.stats = {"steps": steps, "newton_mean": float(newton.mean()), "newton_max": int(newton.max()),
                      "cg_mean": float(cg.mean()), "cg_max": int(cg.max())}  # CG: a step's sum over its Newton
        failure = self._check(P1, schedule, np.asarray(iterations), size, excess, np.asarray(column),
                              cg_residual) if check else None
        return p_j, starts, coef, steps - 1, schedule.edges, failure

    def _check(self, P1: np.ndarray, schedule: Schedule, iterations: np.ndarray, size: np.ndarray,
               excess: np.ndarray, column: np.ndarray, cg_residual: np.ndarray) -> tuple[list, np.ndarray] | None:
        """None when every step of every P1 held, else per P1 the one-line message of its first failed
        step (`_simulate`; its CG, else its Newton, else a machine out of the domain; None where
        none failed) and its held time (len(P1),) s: the start of its first failed step (its state
        there is the last step's end), inf where none failed."""
        options, symbol = self.options, self.case.scenario.symbol
        unsolved = ~(cg_residual <= 1.0) & (options["newton"] == "matrix-free")
        failed, outside = ~(size <= options["newton_tol"]), excess > 0
        bad = unsolved | failed | outside
        if not bad.any():
            return None
        first = bad.argmax(axis=1)  # each P1's first failed step (0 where none: masked below)
        held = np.where(bad.any(axis=1), schedule.edges[np.arange(P1.size), first], np.inf)

        def message(i: int, k: int) -> str:
            phase = "" if self.case.fault is None else \
                (" post-fault" if schedule.phase[k] == POST_FAULT else " fault-on")
            where = f"at{phase} step {k + 1} (t = {schedule.edges[i, k]:g} s) for {symbol} = {float(P1[i])!r}"
            if unsolved[i, k]:
                return (f"{self.name}: CG did not converge {where} within max_cg = {options['max_cg']} iterations: "
                        f"normal residual {cg_residual[i, k]:.3g} times its tolerance (cg_forcing "
                        f"{options['cg_forcing']:g} of its start, cg_tol {options['cg_tol']:g} of |J| |r|)")
            if failed[i, k]:
                return (f"{self.name}: Gauss-Newton did not converge {where} after {int(iterations[i, k])} "
                        f"iterations: last update {size[i, k]:.3g} > newton_tol {options['newton_tol']:g}")
            return f"{self.name}: {where} a machine's {INPUTS[int(column[i, k])]} leaves the component's trained domain"

        return [message(i, int(first[i])) if bad[i].any() else None for i in range(P1.size)], held

    def _attempts(self, t_max: float, P1: np.ndarray) -> tuple[list[tuple[Any, tuple]], np.ndarray, np.ndarray,
                                                                  str | None, np.ndarray]:
        """Every P1 simulated at h, and those that failed again at each step of retry_h in turn (a
        step met before is skipped) (`_simulate` to t_max s): the attempts [(query functions of its
        step, (p, starts, coef, last, edges))], and per P1 the attempt it is answered from (the one
        that held longest; the first of equals) and its row in that attempt (len(P1),) int each; the
        failure's message (None where every P1 held throughout at some step, else the first refused
        P1's, from the attempt it is answered from, naming that attempt's step when there were
        several) and each P1's held time (len(P1),) s (inf where one held throughout)."""
        steps = list(dict.fromkeys((self.options["h"], *self.options["retry_h"])))
        held, owner, local = np.full(P1.size, -np.inf), np.zeros(P1.size, int), np.zeros(P1.size, int)
        reason: list[str | None] = [None] * P1.size
        attempts, rows = [], np.arange(P1.size)
        for h in steps:
            p, starts, coef, last, edges, failure = self._simulate(h, t_max, P1[rows])
            got, why = (np.full(rows.size, np.inf), [None] * rows.size) if failure is None else (failure[1], failure[0])
            for j in np.flatnonzero(got > held[rows]):
                i = rows[j]
                held[i], owner[i], local[i] = got[j], len(attempts), j
                reason[i] = None if why[j] is None else why[j] + (f" (at h = {h:g} s; steps tried {steps})"
                                                                  if len(steps) > 1 else "")
            attempts.append((query_function(self.component, h), (p, starts, coef, last, edges)))
            rows = rows[np.isfinite(held[rows])]
            if not rows.size:
                return attempts, owner, local, None, held
        return attempts, owner, local, reason[int(rows[0])], held

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The trajectories on t; a P1 that fails at h and at every step of retry_h raises
        `PartialSolveError`: each P1's angles at the times before its first failed step (of the
        attempt that held longest), NaN from that step's start on."""
        attempts, owner, local, message, held = self._attempts(float(t.max()), P1)
        both = np.empty((2, P1.size, t.size, self.case.n))
        with jax.enable_x64(True):
            for k, ((grid, _), (p, starts, coef, last, edges)) in enumerate(attempts):
                mine = owner == k
                if mine.any():
                    for part, times in _pieces(t, _chunk(t.size, p.shape[0] * self.case.n)):
                        out = grid(self._theta, self._machines, p, starts, coef, last, jnp.asarray(edges),
                                   jnp.asarray(times))
                        both[:, mine, part] = np.asarray(out)[:, local[mine], :part.stop - part.start]
        delta, omega = both[0], both[1]
        if message is not None:
            raise PartialSolveError(message, np.where(t[None, :, None] < held[:, None, None], delta, np.nan), held)
        return delta, omega

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values, which = np.unique(P1, return_inverse=True)
        attempts, owner, local, message, _ = self._attempts(float(t.max()), values)
        if message is not None:
            raise SolveError(message)
        both = np.empty((2, t.size, self.case.n))
        with jax.enable_x64(True):
            for k, ((_, points), (p, starts, coef, last, edges)) in enumerate(attempts):
                mine = np.flatnonzero(owner[which] == k)  # the points of the P1 values answered from attempt k
                if mine.size:
                    size = _chunk(mine.size, self.case.n)
                    size = _bucket(size) if size == mine.size else size  # few shapes
                    for part, chosen in _pieces(mine, size):
                        out = points(self._theta, self._machines, p, starts, coef, last, jnp.asarray(edges),
                                     jnp.asarray(local[which[chosen]]), jnp.asarray(t[chosen]))
                        both[:, mine[part]] = np.asarray(out)[:, :part.stop - part.start]
        return both[0], both[1]

    def _identify(self, obs: Observations) -> Estimate:
        raise ValueError(f"{self.name} does not identify m and d: its machines' parameters are inputs of one trained "
                         "network, fixed by the case")
