"""What the asv benchmarks share: the harness's settings, specs and cases, the parameter grid
(case x solver x config) and the two expensive preparations that run once per asv run
(`setup_cache`).

Nothing here is a second implementation of a measurement. Timings call the adapters' own `fit`,
`solve` and `identify` on the harness's queries (`harness.suites.latency.queries`) and observations
(`harness.suites.identification.pair_observations`); errors are the rows of the harness's suites
(`harness.suites.accuracy.accuracy`, `harness.suites.identification.identification`, which compute
them with `harness.measure.metrics` against `systems.reference`); trained models go through the harness's
model cache (`harness.model_cache.fit_or_load`).

Parameters: `case` is every forward case of the run's settings (`SETTINGS.cases`: the SMIB
"smib-inference" and the multi-machine networks of `systems.grids`); the identification benchmarks
identify on that case's identification case (`harness.suites.identification_case`: the SMIB's
"smib-identification" with the run's (m, d) pairs, a network itself with its own parameters as the
truth). `solver` is every name of the registry `solvers.SOLVERS`; `config` is every label of
`harness.run.selection.default_specs` (the adapter's named config plus its option overrides other than the
training budget, e.g. "default,batch=stacked"). A triple that the harness does not run (a pair it
does not run, or a spec that the planner leaves off the case, `harness.run.plan.not_on_case`, e.g. a
PINN config not made for networks on a network) is skipped without a process (asv `skip_params`); an
adapter whose optional dependency is missing is skipped in setup (NotImplementedError, with the
reason in asv's output). A case that fails to build (see `CASE_ERRORS`) or a triple whose
preparation failed fails its own benchmarks (RuntimeError in setup), so `asv run` exits non-zero.

The cases are built when this module is imported: asv imports the benchmarks once in its
forkserver, which every benchmark process is forked from, so a network's power flow (and the
import of pandapower) is paid once per run rather than once per benchmark.

Quick mode: `SWINGBENCH_ASV_QUICK=1` (set by `make asv-quick`; asv itself does not tell a
benchmark that it runs with --quick) selects the harness's QUICK settings with small budgets, on the
SMIB only (`smib-inference`): it checks that every benchmark runs, and a multi-machine grid costs some
adapters a minute a call. `make asv` measures every case.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import THREADS
from harness.model_cache import fit_or_load
from harness.run.plan import left_out, not_on_case
from harness.run.selection import default_specs
from harness.settings import DEFAULT, QUICK, Settings, SolverSpec
from harness.suites import SUITES, identification_case
from harness.suites.accuracy import COI_DELTA, accuracy
from harness.suites.identification import identification, pair_observations
from harness.suites.latency import T1_S, queries
from solvers import SOLVERS, UNAVAILABLE
from solvers.base import AbstractSolver
from systems.cases import CASES, Case, Observations

__all__ = [
    "CASE_ERRORS", "COI", "COI_SKIP_PARAMS", "FIT_BUDGET", "FORWARD", "FORWARD_SKIP_PARAMS",
    "IDENTIFICATION", "IDENTIFICATION_SKIP_PARAMS", "PARAMS", "PARAM_NAMES", "QUICK_MODE",
    "SETTINGS", "SETUP_CACHE_TIMEOUT", "SPECS", "Measured", "cached_entry", "cached_observations",
    "case_for", "fit_options", "forward_queries", "identification_observations", "identify_all",
    "spec_for", "train_and_score", "warm_solver",
]

QUICK_MODE = os.environ.get("SWINGBENCH_ASV_QUICK", "").strip().lower() not in ("", "0", "false", "no")

# Iterations of each model that an adapter which trains (a PINN) fits for the forward benchmarks and
# of each of its identifications (the PINNs' max_iterations and id_max_iterations; iterations, not
# seconds, so a model is the same on a busy machine): modest, so that a full asv run stays short.
TRAIN_ITERATIONS = 20 if QUICK_MODE else 400
# Budget of one timed `fit()` (time_fit, peakmem_fit): a fixed number of iterations, so that the time
# says how fast an adapter compiles and trains. Keys an adapter lacks are dropped.
FIT_BUDGET: dict[str, Any] = {
    "max_iterations": 5 if QUICK_MODE else 50,
    "progress": False,
}


def _repo_root() -> Path:
    """asv runs benchmarks in a temporary directory and names the folder of asv.conf.json in
    ASV_CONF_DIR; outside asv, the current directory."""
    return Path(os.environ.get("ASV_CONF_DIR") or Path.cwd())


_BASE = QUICK if QUICK_MODE else DEFAULT
SETTINGS: Settings = replace(
    _BASE,
    threads=THREADS,
    seeds=_BASE.seeds[:1],
    pinn_options={"max_iterations": TRAIN_ITERATIONS, "id_max_iterations": TRAIN_ITERATIONS, "progress": False},
    pairs=QUICK.pairs,
    noise_levels=QUICK.noise_levels,
    skip_identify_marks=(),
    omit_marks=(),  # asv tracks every config, the ablations (two-output PINNs) too
    cache_dir=_repo_root() / ".cache" / "models",
    # `make asv-quick` (CI) checks that every benchmark runs, on the SMIB: a multi-machine grid takes
    # scipy-rk45 [tight] ~60 s a call (the unit tests run every adapter on wscc9; `make asv`, every case)
    **({"cases": ("smib-inference",)} if QUICK_MODE else {}),
)
# One `setup_cache` (every spec on every case: fits, accuracy, identifications) may take this long
# (s): the budget of one case's preparation (900 s quick, 3600 s otherwise) per forward case.
SETUP_CACHE_TIMEOUT = (900.0 if QUICK_MODE else 3600.0) * len(SETTINGS.cases)


def _build_cases(names: tuple[str, ...]) -> tuple[dict[str, Case], dict[str, str]]:
    """name -> Case for every forward case that builds, and name -> why for those that do not (a
    network whose data or power flow fails): such a case fails its own benchmarks only."""
    built, errors = {}, {}
    for name in names:
        try:
            built[name] = CASES[name]
        except Exception as exc:  # noqa: BLE001 - one case's failure fails its benchmarks only
            traceback.print_exc()
            errors[name] = f"{type(exc).__name__}: {exc}"
            print(f"[swingbench asv] case {name}: cannot be built: {errors[name]}", file=sys.stderr)
    return built, errors


_CASES, CASE_ERRORS = _build_cases(SETTINGS.cases)


def case_for(name: str) -> Case:
    """The forward case `name`; RuntimeError (asv: failed) when it could not be built."""
    if name in CASE_ERRORS:
        raise RuntimeError(f"case {name} cannot be built: {CASE_ERRORS[name]}")
    return _CASES[name]


def _config_label(spec: SolverSpec) -> str:
    """The spec's named config with its option overrides other than the training budget."""
    extra = [f"{k}={v}" for k, v in spec.options if k not in SETTINGS.pinn_options]
    return ",".join([spec.config, *extra])


# (solver, config label) -> the harness's spec: the one list `swingbench run` uses, first seed only.
SPECS: dict[tuple[str, str], SolverSpec] = {}
for _spec in default_specs(settings=SETTINGS):
    SPECS.setdefault((_spec.solver, _config_label(_spec)), _spec)

PARAM_NAMES = ["case", "solver", "config"]
PARAMS = [list(SETTINGS.cases), list(SOLVERS), list(dict.fromkeys(config for _, config in SPECS))]


@dataclass(frozen=True)
class Measured:
    """What a group of benchmarks measures for a forward case: the case it runs on (`case_of`: the
    forward case itself, or its identification case) and whether it runs on that forward case at
    all (`runs_on`; `why_not` says why not)."""

    case_of: Callable[[Case], Case]
    runs_on: Callable[[Case], bool]
    why_not: str = ""


FORWARD = Measured(lambda case: case, lambda case: True)
# Identification of a network fits 2n parameters by repeated simulation of every sampled P1: up to
# minutes a call for some adapters (wscc9, 2 busy cores: scipy-rk45 tight ~110 s, scipy-odeint
# ~400 s), and the benchmarks identify three times (setup_cache, warm-up, timed). `make asv-quick`
# identifies on the single-machine case only; `make asv` on every case.
IDENTIFICATION = Measured(identification_case, lambda case: not QUICK_MODE or case.n == 1,
                          "quick mode identifies on single-machine cases only")
# The angles relative to the centre of inertia: a system without an infinite bus only.
COI = Measured(lambda case: case, lambda case: not case.has_infinite_bus,
               "angles relative to the centre of inertia are measured without an infinite bus only")


def _skip_params(measured: Measured) -> list[tuple[str, str, str]]:
    """The triples of an installed adapter that asv skips without a process (`skip_params`): a
    (solver, config) pair the harness does not run (e.g. scipy-odeint with batch=stacked), every
    triple of a forward case that `measured` does not run on, and a spec that the planner leaves
    off the case measured (`harness.run.plan.not_on_case`, e.g. a PINN config not made for networks
    on a network). A case that could not be built skips nothing: its benchmarks fail in setup. Adapters
    that are not installed are skipped in setup instead, with the reason ("skipped: torch not
    installed") in asv's output."""
    skipped = []
    for name in PARAMS[0]:
        case = _CASES.get(name)
        for solver in PARAMS[1]:
            if SOLVERS.get(solver) is None:
                continue
            for config in PARAMS[2]:
                spec = SPECS.get((solver, config))
                if spec is None or (case is not None and (
                        not measured.runs_on(case) or not_on_case(spec, measured.case_of(case), SETTINGS) is not None)):
                    skipped.append((name, solver, config))
    return skipped


FORWARD_SKIP_PARAMS = _skip_params(FORWARD)
IDENTIFICATION_SKIP_PARAMS = _skip_params(IDENTIFICATION)
COI_SKIP_PARAMS = _skip_params(COI)


def spec_for(case: str, solver: str, config: str, measured: Measured = FORWARD) -> SolverSpec:
    """The harness's spec for a parameter triple; NotImplementedError (asv: skipped) when the adapter
    is not installed, the pair is not one the harness runs, `measured` does not run on the case or
    the planner leaves the spec off the case measured (`harness.run.plan.not_on_case`); RuntimeError
    (asv: failed) when the case could not be built."""
    if SOLVERS.get(solver) is None:
        raise NotImplementedError(f"{solver}: {UNAVAILABLE.get(solver, 'not registered')}")
    spec = SPECS.get((solver, config))
    if spec is None:
        raise NotImplementedError(f"{solver} is not run with config {config!r}")
    forward = case_for(case)
    if not measured.runs_on(forward):
        raise NotImplementedError(f"{case}: {measured.why_not}")
    target = measured.case_of(forward)
    reason = not_on_case(spec, target, SETTINGS)
    if reason is not None:
        raise NotImplementedError(f"{spec.label} on {target.name}: {reason}")
    return spec


def cached_entry(cache: dict, case: str, solver: str, config: str, measured: Measured = FORWARD) -> dict:
    """The `setup_cache` result for a parameter triple: skipped or failed as `spec_for` says,
    skipped when the run's settings leave its suite out there (`harness.run.plan.left_out`),
    RuntimeError (asv: failed) when its preparation failed."""
    spec = spec_for(case, solver, config, measured)
    entry = cache.get((case, solver, config))
    if entry is None:
        raise RuntimeError(f"{spec.label} on {case}: setup_cache has no result for it")
    if "skipped" in entry:
        raise NotImplementedError(f"{spec.label} on {case}: {entry['skipped']}")
    if "error" in entry:
        raise RuntimeError(f"{spec.label} on {case}: preparation failed in setup_cache: {entry['error']}")
    return entry


def _failure(spec: SolverSpec, case: Case, exc: BaseException) -> dict:
    traceback.print_exc()
    print(f"[swingbench asv] {spec.label} on {case.name}: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    return {"error": f"{type(exc).__name__}: {exc}"}


def _measured(measured: Measured) -> list[tuple[tuple[str, str, str], SolverSpec, Case]]:
    """((case, solver, config), spec, the case measured) of every installed spec that `SETTINGS`
    measures on every forward case that built and that `measured` runs on, in the run's order."""
    out = []
    for name, case in _CASES.items():
        if not measured.runs_on(case):
            continue
        target = measured.case_of(case)
        out += [((name, *key), spec, target) for key, spec in SPECS.items()
                if SOLVERS.get(spec.solver) is not None and not_on_case(spec, target, SETTINGS) is None]
    return out


def train_and_score() -> dict:
    """Once per asv run (`setup_cache` of the forward benchmarks): fit every installed spec that the
    run measures on each forward case through the harness's model cache (an adapter that trains is
    trained with SETTINGS' budget and saved, or loaded when a model of the same config, options,
    seed, case and code version is there) and score it with the accuracy suite against the tight
    reference. Returns {(case, solver, config): {"fit_s", "fit_message", "rel_l2_delta",
    "rel_l2_omega", and "rel_l2_delta_coi" on a case without an infinite bus} or {"error"}}."""
    names = {"delta": "rel_l2_delta", "omega": "rel_l2_omega", COI_DELTA: "rel_l2_delta_coi"}
    out = {}
    for key, spec, case in _measured(FORWARD):
        try:
            solver = spec.make(case)
            report = fit_or_load(solver, SETTINGS)
            rows = accuracy(solver, case, SETTINGS)
        except Exception as exc:  # noqa: BLE001 - one spec's failure fails its benchmarks only
            out[key] = _failure(spec, case, exc)
            continue
        scores = {names[row["quantity"]]: row["rel_l2"] for row in rows
                  if row["against"] == "reference" and row["quantity"] in names}
        out[key] = {"fit_s": report.seconds, "fit_message": report.message, **scores}
        print(f"[swingbench asv] {spec.label} on {case.name}: fit {report.seconds:.3g} s {report.message}".rstrip(),
              file=sys.stderr)
    return out


def identify_all() -> dict:
    """Once per asv run (`setup_cache` of the identification benchmarks): the observations that
    `time_identify` identifies from on each forward case's identification case (their reference
    costs a network a minute, once here rather than in every benchmark process), and the
    identification suite for every installed spec that the run measures there (the SMIB's over
    SETTINGS' (m, d) pairs, a network's on its own parameters; SETTINGS' noise levels). Returns
    {("observations", case): Observations (or ("observations failed", case): why),
    (case, solver, config): {"m_rel_error", "d_rel_error" (the worst over machines and rows), "rows"}
    or {"error"}}, keyed by the forward case."""
    out: dict = {}
    for name in (name for name, case in _CASES.items() if IDENTIFICATION.runs_on(case)):
        try:
            out[("observations", name)] = identification_observations(name)
        except Exception as exc:  # noqa: BLE001 - one case's failure fails its benchmarks only
            traceback.print_exc()
            out[("observations failed", name)] = f"{type(exc).__name__}: {exc}"
    for key, spec, case in _measured(IDENTIFICATION):
        reason = left_out(spec, case, SUITES["identification"], SETTINGS, ("those declared to identify networks",))
        if reason is not None:
            out[key] = {"skipped": reason}
            continue
        try:
            rows = identification(spec.make(case), case, SETTINGS)
        except Exception as exc:  # noqa: BLE001
            out[key] = _failure(spec, case, exc)
            continue
        out[key] = {"m_rel_error": max(row["m_rel_error"] for row in rows),
                    "d_rel_error": max(row["d_rel_error"] for row in rows), "rows": rows}
    return out


_QUERIES: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}


def forward_queries(case: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(t, P1) of the latency suite's queries on a forward case that asv times: "grid" (100 x 201),
    "single point" (t1 = T1_S = 10 s, within every case's horizon; the middle P1) and "one
    trajectory" (201 times, the middle P1)."""
    if case not in _QUERIES:
        chosen = {}
        for kind, _name, t, P1 in queries(case_for(case), SETTINGS):
            if kind == "grid":
                chosen.setdefault("grid", (t, P1))
            elif kind == "single point" and t.size == 1 and t[0] == T1_S:
                chosen.setdefault("single point", (t, P1))
            elif kind == "throughput" and P1.size == 1:
                chosen.setdefault("one trajectory", (t, P1))
        missing = {"grid", "single point", "one trajectory"} - set(chosen)
        if missing:
            raise RuntimeError(f"harness.suites.latency.queries has no {', '.join(sorted(missing))} query on {case}")
        _QUERIES[case] = chosen
    return _QUERIES[case]


_WARM: dict[tuple[str, str, str], tuple[AbstractSolver, set[str]]] = {}


def warm_solver(cache: dict, case: str, solver: str, config: str, query: str,
                ) -> tuple[AbstractSolver, np.ndarray, np.ndarray]:
    """A fitted adapter on a forward case (loaded from the model cache that `train_and_score`
    filled) that has answered `query` once (JIT compilation, integrator build), and the query's
    (t, P1). Kept for the process: asv re-runs setup before every timed call, and a warm adapter
    stays warm."""
    cached_entry(cache, case, solver, config)
    key = (case, solver, config)
    if key not in _WARM:
        adapter = SPECS[(solver, config)].make(case_for(case))
        fit_or_load(adapter, SETTINGS)
        _WARM[key] = (adapter, set())
    adapter, warmed = _WARM[key]
    t, P1 = forward_queries(case)[query]
    if query not in warmed:
        adapter.solve(t, P1)
        warmed.add(query)
    return adapter, t, P1


def fit_options(spec: SolverSpec) -> dict[str, Any]:
    """FIT_BUDGET restricted to the options the spec's adapter has."""
    options = SOLVERS[spec.solver].OPTIONS
    return {k: v for k, v in FIT_BUDGET.items() if k in options}


def cached_observations(cache: dict, case: str) -> Observations:
    """The observations of `identification_observations` on a forward case that `identify_all`
    prepared in `setup_cache`; RuntimeError (asv: failed) when that failed."""
    if ("observations failed", case) in cache:
        raise RuntimeError(f"{case}: observations failed in setup_cache: {cache[('observations failed', case)]}")
    if ("observations", case) not in cache:
        raise RuntimeError(f"{case}: setup_cache has no observations for it")
    return cache[("observations", case)]


def identification_observations(case: str) -> Observations:
    """The observations of the identification suite's first row on a forward case's identification
    case: its first truth (the first (m, d) pair of SETTINGS.pairs on the SMIB, a network's own
    parameters) at the first noise level, every machine's angle at SETTINGS.n_u samples."""
    return pair_observations(identification_case(case_for(case)), SETTINGS, 0, SETTINGS.noise_levels[0])
