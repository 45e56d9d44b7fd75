"""The JSON spec of `swingbench sweep` (`harness.cli.sweep`) and its validation.

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
option values, those that depend on the case too: `harness.run.runner.check_units`) before any run
starts, --dry-run included; a bad spec stops with one line naming the key (exit status 2).

This module imports only the standard library at the top: `harness.cli.sweep`, which the CLI imports
to build its parser, imports it.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["SweepSpec", "load_spec", "parse_spec", "sweep_settings"]

SPEC_KEYS = ("solver", "config", "cases", "seeds", "grid", "options", "description")
DEFAULT_CASES = ("smib-inference",)
# Set by the sweep, never by a spec: the seed comes from "seeds", every run gets `threads` = 1.
RESERVED_OPTIONS = {"seed": 'set seeds with the top-level "seeds" list',
                    "threads": "every sweep run uses 1 thread"}


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
        """Every run as a `harness.run.plan.Unit`: for each case, grid point and seed, in that order."""
        from harness.run.plan import Unit
        from harness.settings import SolverSpec
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


def sweep_settings(retrain: bool = False):
    """The settings every run of a sweep has: 1 thread (runs share the cores)."""
    from harness.settings import Settings

    return Settings(name="sweep", threads=1, retrain=retrain)


def _check_points(spec: SweepSpec) -> None:
    """Construct (not fit) the adapter of every grid point on every case, as its runs will be
    (`harness.run.runner.check_units`; the first seed: a seed cannot make options invalid): it rejects
    bad option values, those invalid on one case only too."""
    from harness.run.runner import check_units

    points = spec.points()

    def describe(unit) -> str:
        point = points[dict(unit.columns)["point"]]
        where = ", ".join(f"{k}={v!r}" for k, v in point.items()) or "the fixed options"
        return f"point {where} on case {unit.case.name}" if len(spec.cases) > 1 else f"point {where}"

    try:
        check_units([u for u in spec.units() if u.spec.seed == spec.seeds[0]], sweep_settings(), describe)
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
