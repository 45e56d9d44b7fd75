"""`swingbench sweep SPEC`: a grid of adapter options x seeds x cases, one accuracy run per point.

The paper chose its network size, N_u and N_f by an "extensive investigation"; a sweep runs such a
grid and writes one row per accuracy measurement of every run. Sweeps measure accuracy and
training cost only: several runs share the machine's cores, so no query latency is measured here
(the latency suite of `swingbench run` runs alone).

SPEC is a JSON file::

    {
      "solver": "torch-pinn",              # a registered adapter (required)
      "config": "default",                 # one of its named configs (default "default")
      "cases": ["smib-inference"],         # harness.cases.CASES names (default ["smib-inference"])
      "seeds": [0, 1, 2],                  # only for adapters that train (a `seed` option);
                                           # default [0]; adapters without one take no "seeds"
      "grid": {"width": [10, 20],          # option -> the values to sweep (non-empty lists);
               "n_f": [2000, 8000]},       # the runs are their cartesian product
      "options": {"max_iterations": 500},  # fixed option overrides for every run (default {})
      "description": "free text"           # optional, copied into the metadata
    }

Every key of "grid" and "options" must be an option of the adapter (`SOLVERS[name].OPTIONS`);
"seed" is set through "seeds" and "threads" is fixed at 1 (each run gets one core). Every grid
point is checked by constructing the adapter (which validates the option values) before any run
starts; a bad spec stops with a message naming the key.

Each run is `run_task(SweepTask)`: a pure function of a small picklable task (adapter, config,
options, seed, case, threads=1), executed in a worker process. It pins the worker to one thread
(OMP/BLAS environment variables and threadpoolctl, `torch.set_num_threads(1)` when torch is loaded,
and XLA_FLAGS before jax can be imported), builds the adapter, fits it (`harness.runner.fit_or_load`:
trained models come from the model cache unless --retrain, with the training cost recorded when
they were trained), runs `harness.suites.accuracy.accuracy` and returns plain dict rows: one per
accuracy measurement, with the swept values as `p_<option>` columns, `fit_s`, `iterations`,
`loss`, `task_s` (wall time of the whole run) and `status`. A run that raises returns one row with
`status: "failed: ..."` and the sweep goes on.

Executors (one task function, only the executor differs): by default joblib's loky backend with
--workers processes of 1 thread each; with --scheduler ADDRESS an existing dask.distributed
cluster (its workers should run 1 thread each, e.g. `dask worker ADDRESS --nthreads 1`, and have
swingbench installed), with --dask-local a LocalCluster of --workers processes, 1 thread each.

Output in --out: rows.jsonl (appended as results arrive: an interrupted sweep keeps its finished
runs; --resume skips them), then, written atomically, sweep.csv (tidy: every row), sweep.md (per
grid point and case: median and [min, max] over seeds of the relative L2 error of delta and omega
against the DOP853 reference, median fit seconds, runs ok/failed) and metadata.json.

This module imports only the standard library at the top: it is imported by the CLI and unpickled
in fresh workers, where the thread settings must come before numpy, torch or jax are loaded.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import math
import os
import re
import socket
import sys
import time
import traceback
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["SweepSpec", "SweepTask", "add_parser", "cmd_sweep", "load_spec", "parse_spec", "run_sweep",
           "run_task", "summary_table"]

SPEC_KEYS = ("solver", "config", "cases", "seeds", "grid", "options", "description")
DEFAULT_CASES = ("smib-inference",)
# Set by the sweep, never by a spec: the seed comes from "seeds", every run gets `threads` = 1.
RESERVED_OPTIONS = {"seed": 'set seeds with the top-level "seeds" list',
                    "threads": "every sweep run uses 1 thread"}
# Worker-side defaults for adapters that have these options (a spec may override "progress").
WORKER_OPTIONS = {"threads": 1, "progress": False}
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
              "VECLIB_MAXIMUM_THREADS", "BLIS_NUM_THREADS")
KEY_COLUMNS = ("case", "solver", "config", "variant", "seed")


# --------------------------------------------------------------------------------------------- spec

@dataclass(frozen=True)
class SweepTask:
    """One run: picklable, plain values only. `options` are every override (fixed and swept) as
    sorted (name, value) pairs, `swept` the names of the grid options, `point` the index of the
    grid point in the spec's product order."""

    solver: str
    config: str
    options: tuple[tuple[str, Any], ...]
    seed: int | None
    case: str
    point: int = 0
    swept: tuple[str, ...] = ()
    threads: int = 1
    retrain: bool = False
    cache_dir: str | None = ".cache/models"

    @property
    def variant(self) -> str:
        return ",".join(f"{k}={v}" for k, v in self.options)

    def key(self) -> tuple:
        """What identifies the run in rows.jsonl (the KEY_COLUMNS)."""
        return (self.case, self.solver, self.config, self.variant, -1 if self.seed is None else self.seed)

    def base_row(self) -> dict:
        """The run's identifying columns, without importing anything."""
        values = dict(self.options)
        return {"suite": "accuracy", "case": self.case, "solver": self.solver, "config": self.config,
                "variant": self.variant, "seed": -1 if self.seed is None else self.seed,
                "point": self.point, **{f"p_{name}": _plain(values[name]) for name in self.swept},
                "threads": self.threads}

    @property
    def label(self) -> str:
        swept = dict(self.options)
        point = ",".join(f"{k}={swept[k]}" for k in self.swept)
        seed = "" if self.seed is None else f" seed={self.seed}"
        return f"{self.solver}[{self.config}{',' if point else ''}{point}]{seed} {self.case}"


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: see the module docstring for the JSON format."""

    solver: str
    config: str = "default"
    cases: tuple[str, ...] = DEFAULT_CASES
    seeds: tuple[int | None, ...] = (None,)
    grid: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    options: tuple[tuple[str, Any], ...] = ()
    description: str = ""

    def points(self) -> list[dict[str, Any]]:
        """The grid points (option name -> value) in product order; one empty point without a grid."""
        names = [name for name, _ in self.grid]
        return [dict(zip(names, values)) for values in itertools.product(*(v for _, v in self.grid))]

    def tasks(self, retrain: bool = False, cache_dir: str | None = ".cache/models") -> list[SweepTask]:
        """Every run: for each case, grid point and seed."""
        swept = tuple(name for name, _ in self.grid)
        out = []
        for case in self.cases:
            for index, point in enumerate(self.points()):
                options = tuple(sorted({**dict(self.options), **point}.items()))
                out.extend(SweepTask(self.solver, self.config, options, seed, case, index, swept,
                                     retrain=retrain, cache_dir=cache_dir) for seed in self.seeds)
        return out

    def as_json(self) -> dict:
        return {"solver": self.solver, "config": self.config, "cases": list(self.cases),
                "seeds": [s for s in self.seeds if s is not None],
                "grid": {k: [_plain(v) for v in values] for k, values in self.grid},
                "options": {k: _plain(v) for k, v in self.options}, "description": self.description}


def _plain(value: Any) -> Any:
    """A JSON-friendly value (tuples -> lists)."""
    return [_plain(v) for v in value] if isinstance(value, (tuple, list)) else value


def _frozen(value: Any) -> Any:
    """A JSON value as the adapters take it and hashable: lists -> tuples."""
    return tuple(_frozen(v) for v in value) if isinstance(value, list) else value


def _check_value(where: str, value: Any) -> Any:
    if isinstance(value, dict):
        raise ValueError(  # noqa: TRY004 - a spec error
            f"{where}: a value must be a number, string, boolean, null or list, got an object")
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{where}: a value must be finite, got {value!r}")
    if isinstance(value, list):
        for item in value:
            _check_value(where, item)
    return _frozen(value)


def parse_spec(raw: Mapping[str, Any], check: bool = True) -> SweepSpec:
    """Validate a spec (the parsed JSON) and return it; ValueError names the bad key. With `check`,
    each grid point's adapter is constructed once (not fitted) so bad option values fail here."""
    from harness.cases import CASES
    from solvers import SOLVERS, UNAVAILABLE

    if not isinstance(raw, Mapping):
        raise ValueError(f"a sweep spec must be a JSON object, got {type(raw).__name__}")  # noqa: TRY004
    unknown = [k for k in raw if k not in SPEC_KEYS]
    if unknown:
        raise ValueError(f"unknown key(s) {', '.join(map(repr, unknown))}; known: {', '.join(SPEC_KEYS)}")

    solver = raw.get("solver")
    if not isinstance(solver, str) or not solver:
        raise ValueError(f"'solver' must be the name of an adapter ({', '.join(SOLVERS)}), got {solver!r}")
    if solver not in SOLVERS:
        raise ValueError(f"'solver': unknown solver {solver!r}; known: {', '.join(SOLVERS)}")
    cls = SOLVERS[solver]
    if cls is None:
        raise ValueError(f"'solver': {solver} is not available here ({UNAVAILABLE[solver]})")

    config = raw.get("config", "default")
    if not isinstance(config, str) or config not in cls.CONFIGS:
        raise ValueError(f"'config': unknown config {config!r} for {solver}; "
                         f"known: {', '.join(cls.CONFIGS)}")

    cases = raw.get("cases", list(DEFAULT_CASES))
    if not isinstance(cases, list) or not cases:
        raise ValueError(f"'cases' must be a non-empty list of case names ({', '.join(CASES)}), "
                         f"got {cases!r}")
    for case in cases:
        if not isinstance(case, str) or case not in CASES:
            raise ValueError(f"'cases': unknown case {case!r}; known: {', '.join(CASES)}")
    if len(set(cases)) != len(cases):
        raise ValueError(f"'cases' lists a case twice: {cases!r}")

    trains = "seed" in cls.OPTIONS
    if "seeds" in raw and not trains:
        raise ValueError(f"'seeds': {solver} takes no seed (it does not train); drop 'seeds'")
    seeds = raw.get("seeds", [0]) if trains else [None]
    if trains:
        if not isinstance(seeds, list) or not seeds:
            raise ValueError(f"'seeds' must be a non-empty list of integers, got {seeds!r}")
        for seed in seeds:
            if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
                raise ValueError(f"'seeds': each seed must be an integer >= 0, got {seed!r}")
        if len(set(seeds)) != len(seeds):
            raise ValueError(f"'seeds' lists a seed twice: {seeds!r}")

    def check_options(section: str, mapping: Any) -> dict:
        if not isinstance(mapping, dict):
            raise ValueError(  # noqa: TRY004 - a spec error
                f"'{section}' must be an object of option -> value, got {mapping!r}")
        for name in mapping:
            if name in RESERVED_OPTIONS:
                raise ValueError(f"'{section}': option {name!r} cannot be set in a sweep "
                                 f"({RESERVED_OPTIONS[name]})")
            if name not in cls.OPTIONS:
                raise ValueError(f"'{section}': unknown option {name!r} for {solver}; "
                                 f"known: {', '.join(k for k in cls.OPTIONS if k not in RESERVED_OPTIONS)}")
        return mapping

    options = check_options("options", raw.get("options", {}))
    grid_raw = check_options("grid", raw.get("grid", {}))
    grid = []
    for name, values in grid_raw.items():
        if name in options:
            raise ValueError(f"'grid': option {name!r} is also fixed in 'options'; set it in one place")
        if not isinstance(values, list) or not values:
            raise ValueError(f"'grid': {name!r} must be a non-empty list of values, got {values!r}")
        frozen = tuple(_check_value(f"'grid': {name!r}", v) for v in values)
        if len(set(map(repr, frozen))) != len(frozen):
            raise ValueError(f"'grid': {name!r} lists a value twice: {values!r}")
        grid.append((name, frozen))
    fixed = tuple(sorted((k, _check_value(f"'options': {k!r}", v)) for k, v in options.items()))

    description = raw.get("description", "")
    if not isinstance(description, str):
        raise ValueError(f"'description' must be a string, got {description!r}")  # noqa: TRY004
    spec = SweepSpec(solver, config, tuple(cases), tuple(seeds), tuple(grid), fixed, description)
    if check:
        _check_points(spec)
    return spec


def _check_points(spec: SweepSpec) -> None:
    """Construct (not fit) the adapter once per grid point: it rejects bad option values."""
    from harness.cases import CASES
    from solvers import make_solver

    case = CASES[spec.cases[0]]
    for point in spec.points():
        options = {**dict(spec.options), **point}
        if spec.seeds[0] is not None:
            options["seed"] = spec.seeds[0]
        try:
            make_solver(spec.solver, case, spec.config, **options)
        except (ValueError, TypeError) as exc:
            where = ", ".join(f"{k}={v!r}" for k, v in point.items()) or "the fixed options"
            raise ValueError(f"'grid' point {where}: {exc}") from None


def load_spec(path: Path, check: bool = True) -> SweepSpec:
    """Read and validate a spec file; ValueError names the file and the bad key."""
    path = Path(path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the sweep spec: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON: {exc}") from None
    try:
        return parse_spec(raw, check=check)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


# ------------------------------------------------------------------------------------------- worker

@contextlib.contextmanager
def pinned_threads(n: int) -> Iterator[None]:
    """Pin this process to `n` threads for the duration: OMP/BLAS environment variables, PJRT_NPROC
    (the size of XLA's CPU pool) and XLA_FLAGS (read by libraries loaded from now on: XLA's backend
    must not have started yet), threadpoolctl for the BLAS/OpenMP pools already loaded;
    `limit_torch` does torch once it is imported. The environment and limits are restored
    afterwards (what was loaded inside keeps its setting)."""
    saved = {var: os.environ.get(var) for var in (*THREAD_ENV, "PJRT_NPROC", "XLA_FLAGS")}
    for var in (*THREAD_ENV, "PJRT_NPROC"):
        os.environ[var] = str(n)
    flags = re.sub(r"(--)?xla_cpu_multi_thread_eigen=\S*", "", os.environ.get("XLA_FLAGS", ""))
    os.environ["XLA_FLAGS"] = " ".join([*flags.split(), "--xla_cpu_multi_thread_eigen=false"])
    torch_before = _torch_threads()
    try:
        with contextlib.ExitStack() as stack:
            try:
                from threadpoolctl import threadpool_limits
            except ImportError:  # pragma: no cover - a dependency of swingbench
                pass
            else:
                stack.enter_context(threadpool_limits(n))
            yield
    finally:
        for var, value in saved.items():
            if value is None:
                os.environ.pop(var, None)
            else:
                os.environ[var] = value
        if torch_before is not None:
            sys.modules["torch"].set_num_threads(torch_before)


def _torch_threads() -> int | None:
    torch = sys.modules.get("torch")
    return torch.get_num_threads() if torch is not None else None


def limit_torch(n: int) -> None:
    """`torch.set_num_threads(n)` (and inter-op threads where still allowed) if torch is loaded."""
    torch = sys.modules.get("torch")
    if torch is None:
        return
    torch.set_num_threads(n)
    with contextlib.suppress(RuntimeError):  # only allowed before any inter-op work
        torch.set_num_interop_threads(n)


def _blas_threads() -> int | None:
    try:
        from threadpoolctl import threadpool_info
    except ImportError:  # pragma: no cover
        return None
    counts = [info.get("num_threads") for info in threadpool_info() if info.get("num_threads")]
    return max(counts) if counts else None


def _failure(exc: BaseException) -> str:
    return f"failed: {type(exc).__name__}: {exc}"


def run_task(task: SweepTask) -> list[dict]:
    """Run one sweep point in this process on `task.threads` threads: build, fit (or load from the
    model cache), measure accuracy; no latency. Returns plain dict rows; never raises for a
    failing run (one row with status "failed: ...")."""
    start = time.perf_counter()
    base = {**task.base_row(), "worker": f"{socket.gethostname()}:{os.getpid()}"}
    fit: dict = {}
    with pinned_threads(task.threads):
        try:
            from harness.cases import CASES
            from harness.runner import fit_or_load
            from harness.runs import Settings, SolverSpec
            from harness.suites.accuracy import accuracy
            from solvers import SOLVERS

            limit_torch(task.threads)  # the registry may have imported torch
            spec = SolverSpec(task.solver, task.config, task.options, task.seed)
            case = CASES[task.case]
            cls = SOLVERS.get(task.solver)
            worker_options = {**WORKER_OPTIONS, "threads": task.threads}
            extra = {k: v for k, v in worker_options.items()
                     if cls is not None and k in cls.OPTIONS and k not in dict(task.options)}
            solver = spec.make(case, **extra)
            limit_torch(task.threads)  # an adapter may import torch when built
            settings = Settings(name="sweep", threads=task.threads, retrain=task.retrain,
                                cache_dir=None if task.cache_dir is None else Path(task.cache_dir))
            report = fit_or_load(solver, settings)
            fit = {"fit_s": report.seconds, "iterations": report.iterations, "loss": report.loss,
                   "fit_message": report.message}
            rows = accuracy(solver, case, settings)
            blas = _blas_threads()
        except Exception as exc:  # noqa: BLE001 - a failed run is a row, the sweep goes on
            print(f"[swingbench sweep] {task.label}: {_failure(exc)}", file=sys.stderr)
            traceback.print_exc()
            return [{**base, **fit, "status": _failure(exc), "task_s": time.perf_counter() - start}]
    task_s = time.perf_counter() - start
    return [{**base, **fit, "status": "ok", **row, "task_s": task_s, "blas_threads": blas} for row in rows]


# ---------------------------------------------------------------------------------------- executors

def _joblib_results(tasks: list[SweepTask], workers: int) -> Iterator[list[dict]]:
    """Rows of each run as it finishes, from loky worker processes of 1 thread each. If the pool
    itself breaks (a worker killed), the runs not yet returned become failed rows."""
    from joblib import Parallel, delayed, parallel_config

    done: set[tuple] = set()
    try:
        with parallel_config(backend="loky", inner_max_num_threads=1):
            parallel = Parallel(n_jobs=workers, return_as="generator_unordered", batch_size=1,
                                pre_dispatch="n_jobs")
            for rows in parallel(delayed(run_task)(task) for task in tasks):
                done.add(_row_key(rows[0]))
                yield rows
    except Exception as exc:  # noqa: BLE001 - e.g. TerminatedWorkerError: record, do not lose rows
        print(f"[swingbench sweep] the joblib pool failed: {_failure(exc)}", file=sys.stderr)
        for task in tasks:
            if task.key() not in done:
                yield [{**task.base_row(), "status": f"{_failure(exc)} (executor)"}]


def _dask_results(tasks: list[SweepTask], client) -> Iterator[list[dict]]:
    """Rows of each run as it finishes, from a dask.distributed client; a task that raises on the
    cluster's side (e.g. KilledWorker) becomes a failed row."""
    from distributed import as_completed

    futures = client.map(run_task, tasks, pure=False, retries=0)
    owner = {future.key: task for future, task in zip(futures, tasks)}
    try:
        for future in as_completed(futures):
            task = owner[future.key]
            try:
                rows = future.result()
            except Exception as exc:  # noqa: BLE001
                rows = [{**task.base_row(), "status": f"{_failure(exc)} (executor)"}]
            future.release()
            yield rows
    finally:
        client.cancel([f for f in futures if not f.done()])


@contextlib.contextmanager
def _dask_client(scheduler: str | None, workers: int) -> Iterator[Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise SystemExit("--scheduler/--dask-local need dask.distributed: "
                         "pip install 'swingbench[dask]'") from None
    if scheduler is not None:
        try:
            client = Client(scheduler)
        except (OSError, ValueError) as exc:
            raise SystemExit(f"swingbench sweep: cannot connect to the dask scheduler {scheduler}: {exc}") from None
        with client:
            threads = client.nthreads()
            if any(n > 1 for n in threads.values()):
                print(f"[swingbench sweep] warning: dask workers with more than 1 thread ({threads}); runs on "
                      "one worker share its cores and their fit times contend", file=sys.stderr)
            yield client
        return
    env = {var: "1" for var in THREAD_ENV}
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      env=env) as cluster, Client(cluster) as client:
        yield client


def _row_key(row: Mapping) -> tuple:
    return tuple(row.get(k) for k in KEY_COLUMNS)


def _progress_bar(total: int, enabled: bool | None):
    if not (sys.stderr.isatty() if enabled is None else enabled):
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="run", file=sys.stderr, dynamic_ncols=True)


def run_sweep(
    tasks: list[SweepTask], store, *, workers: int = 2, scheduler: str | None = None,
    dask_local: bool = False, progress: bool | None = None,
) -> dict[str, int]:
    """Run `tasks` on the chosen executor (joblib loky by default, dask with `scheduler` or
    `dask_local`), appending each run's rows to `store` as they arrive. Returns counts of runs:
    {"ok", "failed", "executor_failed"} (the last: lost to the executor, e.g. a killed worker)."""
    bar = _progress_bar(len(tasks), progress)
    counts = {"ok": 0, "failed": 0, "executor_failed": 0}
    with contextlib.ExitStack() as stack:
        if scheduler is not None or dask_local:
            client = stack.enter_context(_dask_client(scheduler, workers))
            results = _dask_results(tasks, client)
        else:
            results = _joblib_results(tasks, workers)
        stack.callback(results.close)
        for rows in results:
            store.extend(rows)
            status = str(rows[0].get("status", ""))
            kind = "ok" if status == "ok" else "executor_failed" if status.endswith("(executor)") else "failed"
            counts[kind] += 1
            if bar:
                bar.update(1)
                bar.set_postfix(failed=counts["failed"] + counts["executor_failed"], refresh=False)
    if bar:
        bar.close()
    return counts


# ------------------------------------------------------------------------------------------ summary

def summary_table(frame) -> Any:
    """Per case and grid point: runs ok/failed, median and [min, max] over seeds of rel. L2 of delta
    and omega against the reference, median fit seconds. A pandas DataFrame in grid order."""
    import pandas as pd

    if frame.empty:
        return pd.DataFrame()
    params = [c for c in frame.columns if c.startswith("p_")]
    groups = ["case", "solver", "config", "point"]
    runs = frame.drop_duplicates(subset=list(KEY_COLUMNS))
    ok = runs["status"] == "ok"
    runs = runs.assign(ok=ok, failed=~ok, fit_s=runs.reindex(columns=["fit_s"])["fit_s"].where(ok))
    table = runs.groupby(groups, sort=False).agg(
        **{p: (p, "first") for p in params}, runs_ok=("ok", "sum"), failed=("failed", "sum"),
        fit_s_median=("fit_s", "median"))
    good = frame[frame["status"] == "ok"].reindex(columns=[*groups, "quantity", "against", "rel_l2"])
    good = good[good["against"] == "reference"]
    for quantity in ("delta", "omega"):
        stats = good[good["quantity"] == quantity].groupby(groups, sort=False)["rel_l2"].agg(
            ["median", "min", "max"])
        stats.columns = [f"{quantity}_rel_l2_{s}" for s in stats.columns]
        table = table.join(stats, how="left")
    table = table.reset_index().sort_values(["case", "point"], kind="stable")
    return table.drop(columns=["point"]).reset_index(drop=True)


def _markdown(table, meta: dict) -> str:
    if table.empty:
        return "No rows.\n"

    def fmt(x: Any) -> str:
        return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.3g}"

    keep = [c for c in table.columns if c in ("case", "solver", "config") or c.startswith("p_")]
    shown = table[keep].copy()
    shown.columns = [c.removeprefix("p_") for c in shown.columns]
    shown["runs ok / failed"] = [f"{int(a)} / {int(b)}" for a, b in zip(table["runs_ok"], table["failed"])]
    for quantity in ("delta", "omega"):
        cols = [f"{quantity}_rel_l2_{s}" for s in ("median", "min", "max")]
        shown[f"{quantity} rel. L2, median [min, max]"] = [
            f"{fmt(m)} [{fmt(lo)}, {fmt(hi)}]" if not math.isnan(m) else ""
            for m, lo, hi in table[cols].itertuples(index=False)]
    shown["fit (s), median"] = [fmt(x) for x in table["fit_s_median"]]
    header = (f"Sweep of {meta.get('date', '?')} on {meta.get('cpu', '?')}, commit {meta.get('commit', '?')}: "
              f"{meta.get('runs', '?')} runs on {meta.get('executor', '?')}, 1 thread per run. Relative L2 on "
              "the 100 x 201 grid against DOP853 at 1e-12, over seeds; fit seconds measured with other runs "
              "sharing the cores (cached models report the cost recorded when trained). No latency is "
              "measured in a sweep.\n\n")
    return header + shown.to_markdown(index=False) + "\n"


def write_outputs(store, out: Path, meta: dict) -> str:
    """sweep.csv (every row, tidy) and sweep.md from `store`, atomically; returns the Markdown."""
    import pandas as pd

    from harness.store import atomic_write

    frame = pd.DataFrame(store.rows())
    if not frame.empty:
        # tidy: scalars only; list-valued measurements (whole trajectories) stay in rows.jsonl,
        # list-valued swept options become their JSON text
        listy = [c for c in frame.columns if frame[c].map(lambda v: isinstance(v, (list, tuple, dict))).any()]
        frame = frame.drop(columns=[c for c in listy if not c.startswith("p_")]).assign(**{
            c: frame[c].map(lambda v: json.dumps(v) if isinstance(v, (list, tuple)) else v)
            for c in listy if c.startswith("p_")})
        front = [c for c in ("suite", *KEY_COLUMNS, "point") if c in frame.columns]
        params = sorted(c for c in frame.columns if c.startswith("p_"))
        rest = [c for c in frame.columns if c not in front and c not in params]
        frame = frame[[*front, *params, *rest]]
    atomic_write(out / "sweep.csv", frame.to_csv(index=False))
    markdown = _markdown(summary_table(frame), meta)
    atomic_write(out / "sweep.md", markdown)
    return markdown


# ---------------------------------------------------------------------------------------------- CLI

HELP = "run a grid of adapter options x seeds x cases (accuracy and training cost, no latency)"
EPILOG = """\
SPEC (JSON):
  {"solver": "torch-pinn", "config": "default", "cases": ["smib-inference"],
   "seeds": [0, 1, 2], "grid": {"width": [10, 20], "n_f": [2000, 8000]},
   "options": {"max_iterations": 500}}

  solver    a registered adapter (required)
  config    one of its named configs (default "default")
  cases     case names (default ["smib-inference"])
  seeds     integers, only for adapters that train (default [0])
  grid      option -> non-empty list of values; runs = product(grid) x seeds x cases
  options   option overrides fixed for every run
  description  free text
Keys of grid and options must be options of the adapter; "seed" and "threads" are set by the sweep.

Each run builds the adapter, fits it (from the model cache unless --retrain) and measures accuracy
on the 100 x 201 grid, in a worker process pinned to 1 thread. No latency is measured: runs share
the cores (run `swingbench run --suite latency` alone for that). Rows are appended to
OUT/rows.jsonl as runs finish; OUT/sweep.csv, OUT/sweep.md and OUT/metadata.json at the end."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the `sweep` sub-command to `subparsers` (from `ArgumentParser.add_subparsers`)."""
    sweep = subparsers.add_parser(
        "sweep", help=HELP, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run SPEC's grid of option values x seeds x cases, one accuracy run per point, "
                    "locally with joblib (loky, --workers processes of 1 thread) or on Dask.")
    sweep.add_argument("spec", type=Path, metavar="SPEC", help="sweep specification, a JSON file (format below)")
    sweep.add_argument("--out", type=Path, default=Path("results/sweep"),
                       help="output folder (default results/sweep)")
    sweep.add_argument("--workers", type=int, default=2,
                       help="worker processes of 1 thread each, for joblib and --dask-local (default 2)")
    where = sweep.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="run on this dask.distributed scheduler (e.g. tcp://host:8786) instead of joblib; "
                            "give its workers 1 thread each")
    where.add_argument("--dask-local", action="store_true",
                       help="run on a local dask.distributed cluster of --workers processes, 1 thread each")
    sweep.add_argument("--resume", action="store_true",
                       help="keep OUT/rows.jsonl and run only what it does not hold yet (failed runs run again)")
    sweep.add_argument("--retrain", action="store_true", help="train again even if a cached model exists")
    sweep.add_argument("--dry-run", action="store_true", help="validate SPEC, print the runs and exit")
    sweep.add_argument("--progress", choices=["auto", "on", "off"], default="auto",
                       help="progress bar on stderr (auto: only on a terminal)")
    return sweep


def cmd_sweep(args: argparse.Namespace) -> int:
    """`swingbench sweep`: 0 when the sweep finished (failed runs are rows), 1 if the executor broke."""
    if args.workers < 1:
        raise SystemExit("--workers must be >= 1")
    try:
        spec = load_spec(args.spec)
    except ValueError as exc:
        raise SystemExit(f"swingbench sweep: {exc}") from None
    tasks = spec.tasks(retrain=args.retrain)
    if args.dry_run:
        for task in tasks:
            print(task.label)
        print(f"[swingbench sweep] {len(tasks)} runs", file=sys.stderr)
        return 0

    from harness.report import metadata
    from harness.store import RowStore, atomic_write

    store = RowStore(args.out)
    if args.resume:  # keep the finished runs; failed ones run again (their rows are dropped)
        kept = [r for r in store.rows() if not str(r.get("status", "")).startswith("failed")]
        atomic_write(store.path, "".join(json.dumps(r, allow_nan=True) + "\n" for r in kept))
        done = {_row_key(r) for r in kept}
        todo = [t for t in tasks if t.key() not in done]
    else:
        store.clear()
        todo = tasks
    executor = (f"dask scheduler {args.scheduler}" if args.scheduler else
                f"dask LocalCluster, {args.workers} worker process(es)" if args.dask_local else
                f"joblib loky, {args.workers} worker process(es)")
    meta = {**metadata(1), "command": "sweep", "spec": spec.as_json(), "spec_file": str(args.spec),
            "runs": len(tasks), "executor": executor, "workers": args.workers, "argv": sys.argv[1:]}
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2, default=str))
    print(f"[swingbench sweep] {len(todo)} of {len(tasks)} runs on {executor}", file=sys.stderr)
    counts = {"ok": 0, "failed": 0, "executor_failed": 0}
    if todo:
        progress = {"auto": None, "on": True, "off": False}[args.progress]
        counts = run_sweep(todo, store, workers=args.workers, scheduler=args.scheduler,
                           dask_local=args.dask_local, progress=progress)
    markdown = write_outputs(store, args.out, meta)
    print(markdown)
    print(f"[swingbench sweep] {counts['ok']} ok, {counts['failed']} failed, {counts['executor_failed']} lost to "
          f"the executor; wrote {args.out}/", file=sys.stderr)
    return 1 if counts["executor_failed"] else 0
