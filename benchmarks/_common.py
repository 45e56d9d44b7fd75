"""What the asv benchmarks share: the harness's settings, specs and cases, the parameter grid
(solver x config) and the two expensive preparations that run once per asv run (`setup_cache`).

Nothing here is a second implementation of a measurement. Timings call the adapters' own `fit`,
`solve` and `identify` on the harness's queries (`harness.suites.latency.queries`) and observations
(`harness.suites.identification.observations`); errors are the rows of the harness's suites
(`harness.suites.accuracy.accuracy`, `harness.suites.identification.identification`, which compute
them with `harness.metrics` against `systems.reference`); trained models go through the harness's
model cache (`harness.runner.fit_or_load`).

Parameters: `solver` is every name of the registry `solvers.SOLVERS`; `config` is every label of
`harness.runs.default_specs` (the adapter's named config plus its option overrides other than the
training budget, e.g. "default,batch=stacked"). A pair that the harness does not run, or an adapter
whose optional dependency is missing, is skipped (asv: NotImplementedError in setup); a pair whose
preparation failed fails (RuntimeError in setup), so `asv run` exits non-zero.

Quick mode: `SWINGBENCH_ASV_QUICK=1` (set by `make asv-quick`; asv itself does not tell a
benchmark that it runs with --quick) selects the harness's QUICK settings and small budgets.
"""

from __future__ import annotations

import os
import sys
import traceback
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import THREADS
from systems.cases import SMIB_INFERENCE, Observations
from harness.runner import fit_or_load
from harness.runs import DEFAULT, QUICK, Settings, SolverSpec, default_specs
from harness.suites import SUITES
from harness.suites.accuracy import accuracy
from harness.suites.identification import identification, pair_observations
from harness.suites.latency import T1_S, queries
from solvers import SOLVERS, UNAVAILABLE
from solvers.base import AbstractSolver

__all__ = [
    "FIT_BUDGET", "FORWARD_CASE", "IDENTIFICATION_CASE", "PARAMS", "PARAM_NAMES", "QUICK_MODE",
    "SETTINGS", "SETUP_CACHE_TIMEOUT", "SKIP_PARAMS", "SPECS", "cached_entry", "fit_options",
    "forward_queries", "identification_observations", "identify_all", "spec_for", "train_and_score",
    "warm_solver",
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
SETUP_CACHE_TIMEOUT = 900.0 if QUICK_MODE else 3600.0

# The forward case is the CLI's default (`swingbench run --case smib-inference`); identification
# runs on the case of its suite, with the (m, d) pair and noise level of the harness's quick run.
FORWARD_CASE = SMIB_INFERENCE
IDENTIFICATION_CASE = SUITES["identification"].case


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
    skip_identify_configs=(),
    cache_dir=_repo_root() / ".cache" / "models",
)


def _config_label(spec: SolverSpec) -> str:
    """The spec's named config with its option overrides other than the training budget."""
    extra = [f"{k}={v}" for k, v in spec.options if k not in SETTINGS.pinn_options]
    return ",".join([spec.config, *extra])


# (solver, config label) -> the harness's spec: the one list `swingbench run` uses, first seed only.
SPECS: dict[tuple[str, str], SolverSpec] = {}
for _spec in default_specs(settings=SETTINGS):
    SPECS.setdefault((_spec.solver, _config_label(_spec)), _spec)

PARAM_NAMES = ["solver", "config"]
PARAMS = [list(SOLVERS), list(dict.fromkeys(config for _, config in SPECS))]
# Pairs of an installed adapter that the harness does not run (e.g. scipy-odeint with batch=stacked):
# asv skips them without running setup or printing a line (`skip_params`); `spec_for` raises
# NotImplementedError for them too. Pairs of an adapter that is not installed are skipped in setup,
# with the reason ("skipped: torch not installed") in asv's output.
SKIP_PARAMS = [(solver, config) for solver in PARAMS[0] for config in PARAMS[1]
               if SOLVERS.get(solver) is not None and (solver, config) not in SPECS]


def spec_for(solver: str, config: str) -> SolverSpec:
    """The harness's spec for a parameter pair; NotImplementedError (asv: skipped) when the adapter
    is not installed or the pair is not one the harness runs."""
    if SOLVERS.get(solver) is None:
        raise NotImplementedError(f"{solver}: {UNAVAILABLE.get(solver, 'not registered')}")
    try:
        return SPECS[(solver, config)]
    except KeyError:
        raise NotImplementedError(f"{solver} is not run with config {config!r}") from None


def cached_entry(cache: dict, solver: str, config: str) -> dict:
    """The `setup_cache` result for a parameter pair: skipped as `spec_for` says, RuntimeError (asv:
    failed) when its preparation failed."""
    spec = spec_for(solver, config)
    entry = cache.get((solver, config))
    if entry is None:
        raise RuntimeError(f"{spec.label}: setup_cache has no result for it")
    if "error" in entry:
        raise RuntimeError(f"{spec.label}: preparation failed in setup_cache: {entry['error']}")
    return entry


def _failure(spec: SolverSpec, exc: BaseException) -> dict:
    traceback.print_exc()
    print(f"[swingbench asv] {spec.label}: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    return {"error": f"{type(exc).__name__}: {exc}"}


def _installed_specs():
    return [(key, spec) for key, spec in SPECS.items() if SOLVERS.get(spec.solver) is not None]


def train_and_score() -> dict:
    """Once per asv run (`setup_cache` of the forward benchmarks): fit every installed spec on the
    forward case through the harness's model cache (an adapter that trains is trained with
    SETTINGS' budget and saved, or loaded when a model of the same config, options, seed, case and
    code version is there) and score it with the accuracy suite against the tight reference.
    Returns {(solver, config): {"fit_s", "fit_message", "rel_l2_delta", "rel_l2_omega"} or {"error"}}."""
    out = {}
    for key, spec in _installed_specs():
        try:
            solver = spec.make(FORWARD_CASE)
            report = fit_or_load(solver, SETTINGS)
            rows = accuracy(solver, FORWARD_CASE, SETTINGS)
        except Exception as exc:  # noqa: BLE001 - one spec's failure fails its benchmarks only
            out[key] = _failure(spec, exc)
            continue
        scores = {f"rel_l2_{row['quantity']}": row["rel_l2"] for row in rows if row["against"] == "reference"}
        out[key] = {"fit_s": report.seconds, "fit_message": report.message, **scores}
        print(f"[swingbench asv] {spec.label}: fit {report.seconds:.3g} s {report.message}".rstrip(),
              file=sys.stderr)
    return out


def identify_all() -> dict:
    """Once per asv run (`setup_cache` of the identification errors): the identification suite for
    every installed spec over SETTINGS' (m, d) pairs and noise levels. Returns
    {(solver, config): {"m_rel_error", "d_rel_error" (the worst over the rows), "rows"} or {"error"}}."""
    out = {}
    for key, spec in _installed_specs():
        try:
            rows = identification(spec.make(IDENTIFICATION_CASE), IDENTIFICATION_CASE, SETTINGS)
        except Exception as exc:  # noqa: BLE001
            out[key] = _failure(spec, exc)
            continue
        out[key] = {"m_rel_error": max(row["m_rel_error"] for row in rows),
                    "d_rel_error": max(row["d_rel_error"] for row in rows), "rows": rows}
    return out


def forward_queries() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(t, P1) of the latency suite's queries that asv times: "grid" (100 x 201), "single point"
    (t1 = T1_S = 10 s, the middle P1) and "one trajectory" (201 times, the middle P1)."""
    chosen = {}
    for kind, _name, t, P1 in queries(FORWARD_CASE, SETTINGS):
        if kind == "grid":
            chosen.setdefault("grid", (t, P1))
        elif kind == "single point" and t.size == 1 and t[0] == T1_S:
            chosen.setdefault("single point", (t, P1))
        elif kind == "throughput" and P1.size == 1:
            chosen.setdefault("one trajectory", (t, P1))
    missing = {"grid", "single point", "one trajectory"} - set(chosen)
    if missing:
        raise RuntimeError(f"harness.suites.latency.queries has no {', '.join(sorted(missing))} query")
    return chosen


_WARM: dict[tuple[str, str], tuple[AbstractSolver, set[str]]] = {}


def warm_solver(cache: dict, solver: str, config: str, query: str) -> tuple[AbstractSolver, np.ndarray, np.ndarray]:
    """A fitted adapter (loaded from the model cache that `train_and_score` filled) that has answered
    `query` once (JIT compilation, integrator build), and the query's (t, P1). Kept for the process:
    asv re-runs setup before every timed call, and a warm adapter stays warm."""
    cached_entry(cache, solver, config)
    spec = SPECS[(solver, config)]
    if (solver, config) not in _WARM:
        adapter = spec.make(FORWARD_CASE)
        fit_or_load(adapter, SETTINGS)
        _WARM[(solver, config)] = (adapter, set())
    adapter, warmed = _WARM[(solver, config)]
    t, P1 = forward_queries()[query]
    if query not in warmed:
        adapter.solve(t, P1)
        warmed.add(query)
    return adapter, t, P1


def fit_options(spec: SolverSpec) -> dict[str, Any]:
    """FIT_BUDGET restricted to the options the spec's adapter has."""
    options = SOLVERS[spec.solver].OPTIONS
    return {k: v for k, v in FIT_BUDGET.items() if k in options}


def identification_observations() -> Observations:
    """The observations of the identification suite's first row: the first (m, d) pair of
    SETTINGS.pairs and first noise level."""
    return pair_observations(IDENTIFICATION_CASE, SETTINGS, 0, SETTINGS.noise_levels[0])
