"""`swingbench sweep SPEC`: a grid of adapter options x seeds x cases, one accuracy run per point.

The paper chose its network size, N_u and N_f by an "extensive investigation"; a sweep runs such a
grid and writes one row per accuracy measurement of every run. Sweeps measure accuracy and
training cost only: several runs share the machine's cores, so no query latency is measured here
(the latency suite of `swingbench run` runs alone).

SPEC is a JSON file::

    {
      "solver": "torch-pinn",              # a registered adapter (required)
      "config": "default",                 # one of its named configs (default "default")
      "cases": ["smib-inference"],         # systems.cases.CASES names (default ["smib-inference"])
      "seeds": [0, 1, 2],                  # only for adapters that train (`trains`);
                                           # default [0]; other adapters take no "seeds"
      "grid": {"width": [10, 20],          # option -> the values to sweep (non-empty lists);
               "n_f": [2000, 8000]},       # the runs are their cartesian product
      "options": {"max_iterations": 500},  # fixed option overrides for every run (default {})
      "description": "free text"           # optional, copied into the metadata
    }

Every key of "grid" and "options" must be an option of the adapter (`SOLVERS[name].OPTIONS`);
"seed" is set through "seeds" and "threads" is fixed at 1 (each run gets one core). Every grid
point is checked on every case by constructing its adapter as the run will (which validates the
option values, those that depend on the case too: `harness.runner.check_units`) before any run
starts, --dry-run included; a bad spec stops with one line naming the key (exit status 2).

Each run is one unit of `harness.runner` (the runner of `swingbench run`: one row store, one
resume rule, one thread-pinning helper, one progress bar): the adapter is built, fitted
(`harness.runner.fit_or_load`: trained models come from the model cache unless --retrain) and its
accuracy measured (`harness.suites.accuracy`), in a worker process pinned to 1 thread. Its rows are a
`fit` row (fit_s, iterations, loss) and the accuracy rows, with the swept values as `p_<option>`
columns and the grid point's index as `point`. A run that raises gives `failed: ...` rows and the
sweep goes on.

Executors (`harness.executors`, only the executor differs): by default joblib's loky backend with
--workers processes of 1 thread each; with --scheduler ADDRESS an existing dask.distributed
cluster (its workers should run 1 thread each, e.g. `dask worker ADDRESS --nthreads 1`, and have
swingbench installed), with --dask-local a LocalCluster of --workers processes, 1 thread each.

Exit status: 0 when every run was measured (a declared skip counts as measured), 1 when a unit of
work failed (one line names the runs and where their rows are) or the executor lost some, 2 for a
bad spec or option, 130 on Ctrl-C.

Output in --out: rows.jsonl (each run recorded as it finishes: an interrupted sweep keeps its
finished runs; --resume runs only the rest), then, written atomically, sweep.csv (tidy: every row),
sweep.md (per grid point and case: median and [min, max] over seeds of the relative L2 error of delta
and omega against the DOP853 reference, median fit seconds, runs ok/failed) and metadata.json.

This module imports only the standard library at the top: the CLI imports it to build its parser.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["SweepSpec", "add_parser", "cmd_sweep", "load_spec", "parse_spec", "summary_table"]

SPEC_KEYS = ("solver", "config", "cases", "seeds", "grid", "options", "description")
DEFAULT_CASES = ("smib-inference",)
# Set by the sweep, never by a spec: the seed comes from "seeds", every run gets `threads` = 1.
RESERVED_OPTIONS = {"seed": 'set seeds with the top-level "seeds" list',
                    "threads": "every sweep run uses 1 thread"}


# --------------------------------------------------------------------------------------------- spec

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

    def units(self) -> list:
        """Every run as a `harness.runner.Unit`: for each case, grid point and seed, in that order."""
        from harness.runner import Unit
        from harness.runs import SolverSpec
        from systems.cases import CASES

        swept = [name for name, _ in self.grid]
        out = []
        for case in self.cases:
            for index, point in enumerate(self.points()):
                options = tuple(sorted({**dict(self.options), **point}.items()))
                columns = (("point", index), *((f"p_{name}", _plain(point[name])) for name in swept))
                out.extend(Unit(CASES[case], SolverSpec(self.solver, self.config, options, seed), ("accuracy",),
                                columns) for seed in self.seeds)
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
    from solvers import SOLVERS, UNAVAILABLE
    from systems.cases import CASES

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

    trains = cls.trains
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


def _settings(retrain: bool = False):
    """The settings every run of a sweep has: 1 thread (runs share the cores)."""
    from harness.runs import Settings

    return Settings(name="sweep", threads=1, retrain=retrain)


def _check_points(spec: SweepSpec) -> None:
    """Construct (not fit) the adapter of every grid point on every case, as its runs will be
    (`harness.runner.check_units`; the first seed: a seed cannot make options invalid): it rejects
    bad option values, those invalid on one case only too."""
    from harness.runner import check_units

    points = spec.points()

    def describe(unit) -> str:
        point = points[dict(unit.columns)["point"]]
        where = ", ".join(f"{k}={v!r}" for k, v in point.items()) or "the fixed options"
        return f"point {where} on case {unit.case.name}" if len(spec.cases) > 1 else f"point {where}"

    try:
        check_units([u for u in spec.units() if u.spec.seed == spec.seeds[0]], _settings(), describe)
    except ValueError as exc:
        raise ValueError(f"'grid' {exc}") from None


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


# ------------------------------------------------------------------------------------------ summary

def summary_table(frame) -> Any:
    """Per case and grid point: runs ok/failed, median and [min, max] over seeds of rel. L2 of delta
    and omega against the reference, median fit seconds. A pandas DataFrame in grid order."""
    import pandas as pd

    if frame.empty:
        return pd.DataFrame()
    params = [c for c in frame.columns if c.startswith("p_")]
    groups = ["case", "solver", "config", "point"]
    accuracy = frame[frame["suite"] == "accuracy"]
    runs = accuracy.groupby([*groups, "variant", "seed"], sort=False, dropna=False)["status"].agg(
        lambda s: (s == "ok").all()).rename("ok").reset_index()
    fits = frame[(frame["suite"] == "fit") & (frame["status"] == "ok")].reindex(columns=[*groups, "fit_s"])
    table = runs.groupby(groups, sort=False).agg(runs_ok=("ok", "sum"), failed=("ok", lambda s: int((~s).sum())))
    table = frame.groupby(groups, sort=False)[params].first().join(table, how="right")
    table = table.join(fits.groupby(groups, sort=False)["fit_s"].median().rename("fit_s_median"), how="left")
    good = accuracy[accuracy["status"] == "ok"].reindex(columns=[*groups, "quantity", "against", "rel_l2"])
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

    from harness.store import UNIT_COLUMNS, atomic_write

    frame = pd.DataFrame(store.rows())
    if not frame.empty:
        # tidy: scalars only; list-valued measurements (whole trajectories) stay in rows.jsonl,
        # list-valued swept options become their JSON text
        listy = [c for c in frame.columns if frame[c].map(lambda v: isinstance(v, (list, tuple, dict))).any()]
        frame = frame.drop(columns=[c for c in listy if not c.startswith("p_")]).assign(**{
            c: frame[c].map(lambda v: json.dumps(v) if isinstance(v, (list, tuple)) else v)
            for c in listy if c.startswith("p_")})
        front = [c for c in (*UNIT_COLUMNS, "point") if c in frame.columns]
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
                       help="keep OUT/rows.jsonl and run only the runs it does not record as complete (a failed "
                            "run is a result: it is kept)")
    sweep.add_argument("--retrain", action="store_true", help="train again even if a cached model exists")
    sweep.add_argument("--dry-run", action="store_true", help="validate SPEC, print the runs and exit")
    sweep.add_argument("--progress", choices=["auto", "on", "off"], default="auto",
                       help="progress bar on stderr (auto: only on a terminal)")
    return sweep


def cmd_sweep(args: argparse.Namespace) -> int:
    """`swingbench sweep`: 0 when every run was measured, 1 when a unit of work failed (its rows
    say why; one line names them) or the executor lost some (`--resume` runs them), 2 (a
    `UsageError`) for a bad spec, 130 on Ctrl-C."""
    from harness.usage import UsageError

    if args.workers < 1:
        raise UsageError("swingbench sweep: --workers must be >= 1")
    try:
        spec = load_spec(args.spec)
    except ValueError as exc:
        raise UsageError(f"swingbench sweep: {exc}") from None
    units = spec.units()
    if args.dry_run:
        for unit in units:
            print(unit.label)
        print(f"[swingbench sweep] {len(units)} runs", file=sys.stderr)
        return 0

    from harness import executors
    from harness.provenance import metadata
    from harness.runner import execute, interrupted_message, open_results, outcome
    from harness.store import atomic_write

    store, contents = open_results(args.out, args.resume, "sweep", same={"spec": spec.as_json()})
    settings = _settings(args.retrain)
    executor = (f"dask scheduler {args.scheduler}" if args.scheduler else
                f"dask LocalCluster, {args.workers} worker process(es)" if args.dask_local else
                f"joblib loky, {args.workers} worker process(es)")
    meta = {**metadata(1), "command": "sweep", "spec": spec.as_json(), "spec_file": str(args.spec),
            "runs": len(units), "executor": executor, "workers": args.workers, "argv": getattr(args, "argv", sys.argv[1:])}
    atomic_write(args.out / "metadata.json", json.dumps(meta, indent=2, default=str))
    done = contents.completed if contents else set()
    print(f"[swingbench sweep] {len(units)} runs on {executor}"
          + (f"; {len(done)} unit(s) of work already recorded" if done else ""), file=sys.stderr)
    progress = {"auto": None, "on": True, "off": False}[args.progress]
    try:
        with executors.choose(args.scheduler, args.dask_local, args.workers,
                              local=executors.joblib(args.workers)) as run:
            counts = execute(units, settings, store, run, progress=progress, done=done)
    except KeyboardInterrupt:
        print(interrupted_message(store, getattr(args, "argv", sys.argv[1:])), file=sys.stderr)
        return 130
    markdown = write_outputs(store, args.out, meta)
    print(markdown)
    print(f"[swingbench sweep] units of work: {counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} "
          f"failed, {counts['lost']} lost to the executor; wrote {args.out}/", file=sys.stderr)
    return outcome(store.rows(), store.path, counts["lost"])
