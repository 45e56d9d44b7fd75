"""What a run measures: solver specifications (adapter, named config, seed, option overrides) and
the settings of a run (budgets, seeds, pairs, noise levels, the `Limits` a unit may run under), with
the presets QUICK, DEFAULT and FULL. Which specs a run makes from the names it is given is
`harness.run.selection`'s."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

from solvers import make_solver
from solvers.base import ABLATION, DEFAULT_CONFIG, LARGE_SYSTEMS, SWEEP_POINT, AbstractSolver
from systems.cases import IDENTIFICATION_PAIRS, NETWORK_CASES, SMIB, SMIB_IDENTIFICATION, Case
from systems.faults import FAULT_CASES

__all__ = ["DEFAULT", "FULL", "NO_LIMITS", "PAPER_PAIR", "QUICK", "Limits", "Settings", "SolverSpec"]


class Limits(NamedTuple):
    """Wall-clock seconds and resident memory (MiB) a call may use; None: no limit."""

    seconds: float | None = None
    rss_mb: float | None = None


NO_LIMITS = Limits()


@dataclass(frozen=True)
class SolverSpec:
    """One row label of the tables: an adapter, one of its named configs, option overrides and,
    for adapters that train, a seed."""

    solver: str
    config: str = DEFAULT_CONFIG
    options: tuple[tuple[str, Any], ...] = ()
    seed: int | None = None

    @property
    def variant(self) -> str:
        """The option overrides as text ("" when none), e.g. "batch=stacked"."""
        return ",".join(f"{k}={v}" for k, v in self.options)

    @property
    def label(self) -> str:
        extra = "".join(f",{part}" for part in (self.variant, "" if self.seed is None else f"seed={self.seed}") if part)
        return f"{self.solver}[{self.config}{extra}]"

    def make(self, case: Case, **extra: Any) -> AbstractSolver:
        options = {**dict(self.options), **extra}
        if self.seed is not None:
            options["seed"] = self.seed
        return make_solver(self.solver, case, self.config, **options)

    def key(self) -> dict[str, Any]:
        """The columns that identify this spec in a row."""
        return {"solver": self.solver, "config": self.config, "variant": self.variant,
                "seed": -1 if self.seed is None else self.seed}


# The (m, d) of the paper's own identification case, the only one it published ode45 data for: pair 0
# of every run that identifies more than the quick run's single pair, so that every such run also
# identifies from the paper's data (see harness.suites.identification).
PAPER_PAIR: tuple[float, float] = (SMIB_IDENTIFICATION.m[0], SMIB_IDENTIFICATION.d[0])


# The fault cases of `make bench` (and, wscc9's, of the quick run): every suite and the CCT on the
# textbook contingencies of wscc9 and kundur4; the ten of ieee39 run in `swingbench run --suite cct`.
BENCH_FAULT_CASES = (*FAULT_CASES["wscc9"], *FAULT_CASES["kundur4"])
# Levenberg-Marquardt iterations per window of the fault PINNs (`fault-marching`) in `make bench`
# (the config's own budget, 2000 a window within 300 s, is what --full and a run naming it use).
FAULT_ITERATIONS = 150

# The scaling suite's cases, by number of machines: the published systems, then pandapower's
# MATPOWER / PGLib cases with machine data by rule (systems.family).
SCALING_CASES = ("wscc9", "ieee39", "case118", "case300", "case1354pegase", "case2869pegase")
# PINNs in a scaling run: a fixed budget of Levenberg-Marquardt iterations per time-marching window
# and no wall-clock limit, so that their preparation cost shows how training grows with N.
SCALING_PINN_OPTIONS = {"max_iterations": 100, "max_seconds": None}
# What one unit of the scaling suite (build, fit, queries of one adapter on one case) may take.
SCALING_UNIT_LIMITS = Limits(seconds=1800.0, rss_mb=16384.0)


@dataclass(frozen=True)
class Settings:
    """Knobs of a run. Timings are medians of warm repeats within `latency_budget_s` seconds per
    measurement (at least `min_repeats`; a call over `max_call_s` is timed once); a latency query
    estimated to take longer than `max_query_s` is skipped with a row that says so. Adapters that
    train run once per seed in `seeds` (on a multi-machine case the first only: `harness.run.plan`);
    `pinn_options` override their budgets (iterations, so that a seed gives the same network on a
    busy machine). Latency:
    `throughput_sizes` trajectories of 201 times, the single point at each of `t1_values_s`, and
    `points_batch` scattered single points in one call.
    Work-precision sweeps `wp_rtols`; on the multi-machine cases an adapter that is not compiled
    sweeps `network_wp_rtols` (None: `wp_rtols`). Configs with a mark (`solvers.base.CONFIG_MARKS`)
    in `omit_marks` run only when the command line names them; on the fault cases, those with a mark
    in `fault_omit_marks` likewise (every suite records a skipped row for them), and every config of
    the adapters in `fault_omit_solvers`. Identification runs over `pairs` x
    `noise_levels` (relative Gaussian noise, `noise_draws` draws of it at each level above 0: the
    coverage of the 95 % intervals is measured over them) with `n_u` samples, except for configs
    with a mark in `skip_identify_marks`.
    `threads` is recorded with the results. `cases` are the run's forward cases when the command
    line names none; on the multi-machine ones each adapter runs the configs made for them
    (`AbstractSolver.CASE_KINDS`), and identification runs only with configs declared to identify
    networks (`IDENTIFIES_NETWORKS`: at ode45's tolerances a classical identification there is both
    slow, minutes with 2n unknowns, and biased by the integration error: 10-14 % on wscc9,
    measured) on `network_identify_cases` at `network_noise_levels` (with 1 % noise scipy-rk45
    took 520 s on wscc9, measured); `case_pinn_options` gives a case's PINN fits their budget
    (iterations per window, `harness.run.plan`). The verdict suite (`harness.suites.verdict`) measures
    the PINNs of `verdict_pinns` ((adapter, configs, options its spec has): by default the JAX PINN,
    `swingbench run --verdict-pinn` sets any trained adapters, `harness.run.selection.parse_verdict_pinns`; the
    suite times each of its query paths itself), each trained from `verdict_seeds`, against their rivals matched on
    the sweeps of `verdict_rtols` (half decades: a rival is at most ~3x more accurate in rtol
    than it needs to be; from 3e-2, coarser than ode45's 1e-3, so that a sweep point lies within
    3x of a PINN's error: ieee39's PINN speeds err by ~0.09, dopri's at rtol 1e-2 by 0.016 and at
    3e-2 by 0.053, measured; a fixed-step adapter sweeps its own steps, `step_sweep`), in
    `verdict_rounds` rounds of `verdict_pairs` interleaved pairs of samples; a seed whose error in
    the angles (relative L2) is not finite or exceeds `verdict_gate` counts as a loss. `unit_limits` (None: none) runs each unit in a fresh process under a
    wall-clock and a memory limit (`harness.run.runner.run_unit`); a run of the scaling suite uses
    `scaling_unit_limits`, on `scaling_cases` when the command line names none, querying a grid
    of `scaling_n_p1` x `scaling_n_t`, PINNs with `scaling_pinn_options` (`for_scaling`). The cct
    suite runs on `cct_cases` when the command line names none; a surrogate's CCT search queries
    clearing times every `cct_surrogate_step_s` s in one batch (`harness.suites.cct`). Which
    spec runs on which case and suite, and why the rest does not, is `harness.run.plan.plan`'s."""

    name: str = "default"
    threads: int = 2
    latency_budget_s: float = 1.0
    min_repeats: int = 5
    max_call_s: float = 3.0
    max_query_s: float = 30.0
    seeds: tuple[int, ...] = (0, 1, 2)
    pinn_options: dict = field(default_factory=dict)
    throughput_sizes: tuple[int, ...] = (1, 10, 100, 1000, 10000)
    t1_values_s: tuple[float, ...] = (1.0, 2.0, 5.0, 10.0, 20.0)
    points_batch: int = 10000
    points_distinct_p1: int = 100
    pairs: tuple[tuple[float, float], ...] = (PAPER_PAIR, *IDENTIFICATION_PAIRS)
    noise_levels: tuple[float, ...] = (0.0, 0.01)
    noise_draws: int = 1
    n_u: int = 100
    skip_identify_marks: tuple[str, ...] = ()
    wp_rtols: tuple[float, ...] = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    network_wp_rtols: tuple[float, ...] | None = None
    omit_marks: tuple[str, ...] = ()
    fault_omit_marks: tuple[str, ...] = ()
    fault_omit_solvers: tuple[str, ...] = ()
    cache_dir: Path | None = Path(".cache/models")
    partial_dir: Path | None = None  # where a unit of a suite marked `checkpoints` keeps its rows so far (the runner's)
    retrain: bool = False
    cases: tuple[str, ...] = ("smib-inference", *NETWORK_CASES, *BENCH_FAULT_CASES)
    case_pinn_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    network_noise_levels: tuple[float, ...] = (0.0,)
    network_identify_cases: tuple[str, ...] = NETWORK_CASES
    unit_limits: Limits | None = None
    scaling_cases: tuple[str, ...] = SCALING_CASES
    scaling_n_p1: int = 4
    scaling_n_t: int = 101
    scaling_unit_limits: Limits = SCALING_UNIT_LIMITS
    scaling_pinn_options: dict = field(default_factory=lambda: dict(SCALING_PINN_OPTIONS))
    verdict_pinns: tuple[tuple[str, tuple[str, ...], tuple[tuple[str, Any], ...]], ...] = (
        ("jax-pinn", ("default", "marching", "fault-marching"), ()),)
    verdict_rtols: tuple[float, ...] = (3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 1e-8, 1e-9, 1e-10)
    verdict_seeds: tuple[int, ...] = (0, 1, 2)
    verdict_rounds: int = 2
    verdict_pairs: int = 4
    verdict_gate: float = 1e-2
    cct_cases: tuple[str, ...] = tuple(name for names in FAULT_CASES.values() for name in names)
    cct_surrogate_step_s: float = 1e-2

    def verdict_pinn(self, spec: SolverSpec) -> bool:
        """Whether the verdict suite measures `spec`: its adapter and config are those of an entry
        of `verdict_pinns` and its options include that entry's."""
        return self._verdict(spec.solver, spec.config, dict(spec.options))

    def verdict_model(self, solver: AbstractSolver) -> bool:
        """`verdict_pinn` of a built adapter (its name, config and options): whether a suite
        measures each seed of `verdict_seeds` of it."""
        return self._verdict(solver.name, solver.config, solver.options)

    def _verdict(self, name: str, config: str, options: dict) -> bool:
        return any(name == solver and config in configs and all(options.get(k) == v for k, v in wanted)
                   for solver, configs, wanted in self.verdict_pinns)

    def sweep_rtols(self, compiled: bool, case: Case) -> tuple[float, ...]:
        """The tolerances of a work-precision sweep of an adapter (`compiled` or not) on `case`."""
        if case.kind == SMIB or compiled or self.network_wp_rtols is None:
            return self.wp_rtols
        return self.network_wp_rtols

    def for_scaling(self) -> Settings:
        """These settings for a run of the scaling suite alone: each unit under
        `scaling_unit_limits`, PINN budgets `scaling_pinn_options` (iterations, not seconds), and
        the configs made for large systems (`LARGE_SYSTEMS`) not omitted."""
        return replace(self, unit_limits=self.scaling_unit_limits, case_pinn_options={},
                       pinn_options={**self.pinn_options, **self.scaling_pinn_options},
                       omit_marks=tuple(m for m in self.omit_marks if m != LARGE_SYSTEMS))

    def given(self, options: Mapping[str, Any]) -> Settings:
        """These settings for adapter `options` given on the command line: no case's training
        budget (`case_pinn_options`) overrides them, also where a value equals the run-wide one
        (`pinn_options`), which the planner could not tell from the default."""
        return replace(self, case_pinn_options={case: {k: v for k, v in budget.items() if k not in options}
                                                for case, budget in self.case_pinn_options.items()})

    @property
    def quick(self) -> bool:
        return self.name == "quick"


# make bench-quick (CI's smoke run of every suite): the SMIB and wscc9, one seed, PINNs of 150
# iterations (wscc9's time-marching: 10 a window), small timing budgets and sweeps (on wscc9 two
# tolerances for the Python-driven adapters); the ablations and the configs for large systems left
# out, as in make bench, and the configs that are a point of their adapter's sweep (`tight`: the
# sweep reaches it); no multi-machine identification; the cct suite on the wscc9 and kundur4 fault
# cases, a surrogate's batch of clearing times 10 ms apart (bisection then narrows it to 1 ms).
QUICK = Settings(
    name="quick", latency_budget_s=0.1, min_repeats=3, max_call_s=0.5, max_query_s=5.0, seeds=(0,),
    pinn_options={"max_iterations": 150, "id_max_iterations": 150}, throughput_sizes=(1, 100),
    case_pinn_options={"wscc9": {"max_iterations": 10, "max_seconds": None, "id_max_iterations": 100},
                       FAULT_CASES["wscc9"][0]: {"max_iterations": 10, "max_seconds": None}},
    t1_values_s=(1.0, 10.0, 20.0), points_batch=1000, cases=("smib-inference", "wscc9", FAULT_CASES["wscc9"][0]),
    verdict_seeds=(0,),
    verdict_rtols=(1e-3, 1e-5, 1e-7, 1e-9), omit_marks=(ABLATION, LARGE_SYSTEMS, SWEEP_POINT),
    network_identify_cases=(), pairs=IDENTIFICATION_PAIRS[4:5], noise_levels=(0.0,), wp_rtols=(1e-3, 1e-6, 1e-9),
    network_wp_rtols=(1e-3, 1e-6), cct_cases=(*FAULT_CASES["wscc9"], *FAULT_CASES["kundur4"]),
)
# make bench: every suite on the SMIB, the three multi-machine cases and the fault cases of wscc9 and
# kundur4 (BENCH_FAULT_CASES) within about an hour and a half on 2
# cores (the measured durations are in docs/notebook.md). The cuts that buy it: one seed (--full:
# five); the configs marked as ablations (the two-output PINNs) and those for large systems only when
# named (--config); 0.25 s of repeats per timing, at least 3 (a call of 1 ms is timed ~250 times,
# one of 0.1 s 3 times); scipy RK45 identified once (not again for its batch mode, which changes its
# queries only); a latency query estimated over 10 s skipped (a row says so); on the multi-machine
# cases the Python-driven adapters sweep three tolerances (the compiled ones all eight: the verdicts
# compare with them); the SMIB identified at the paper's own case only (m = 0.25, d = 0.15, also from
# the paper's ode45 data), at both noise levels. Multi-machine cases: PINNs (their configs made for
# networks) train within the stated wall-clock budget per case (the 5- and 10-minute training
# targets are measured apart, see the README), on the fault cases FAULT_ITERATIONS a window; on the
# fault cases the configs that are a point of their adapter's precision sweep (`tight`: 3.7 of the
# 20 minutes of wscc9's fault case, results/faults) left out, the sweep measures them; the torch PINN
# left out on the fault cases (its fault-marching trained 9.6 of the bench's 121 minutes there; the
# verdicts measure the JAX PINN); identification noise-free, on wscc9 only (each
# classical adapter takes 1-80 s there; on kundur4 and ieee39 minutes more per adapter). --full runs
# everything: every seed and config, the paper's case and the 10 pairs, both noise levels, the
# identification of every multi-machine case, every sweep, PINNs within their configs' own budgets.
DEFAULT = Settings(
    seeds=(0,),
    latency_budget_s=0.25,
    min_repeats=3,
    max_query_s=10.0,
    omit_marks=(ABLATION, LARGE_SYSTEMS),
    fault_omit_marks=(SWEEP_POINT,),
    fault_omit_solvers=("torch-pinn",),
    pairs=(PAPER_PAIR,),
    skip_identify_marks=(ABLATION,),
    network_wp_rtols=(1e-3, 1e-6, 1e-9),
    case_pinn_options={**{case: {"max_iterations": iterations, "max_seconds": None, "id_max_iterations": 600}
                          for case, iterations in (("wscc9", 100), ("kundur4", 100), ("ieee39", 60))},
                       **{case: {"max_iterations": FAULT_ITERATIONS, "max_seconds": None} for case in BENCH_FAULT_CASES}},
    network_identify_cases=("wscc9",),
)
FULL = Settings(name="full", seeds=(0, 1, 2, 3, 4), max_call_s=60.0, max_query_s=600.0,
                network_noise_levels=(0.0, 0.01),
                case_pinn_options={case: {"max_iterations": 300, "max_seconds": None} for case in NETWORK_CASES})
