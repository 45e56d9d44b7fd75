"""Which solver specifications a run measures, from the names and texts it is given: every
registered adapter or those named, in their configs, per seed (`default_specs`); option overrides
("KEY=VALUE", `parse_option`) set on the specs whose adapter has them (`with_options`); the PINNs
the verdict suite measures ("NAME" or "NAME:CONFIG", `parse_verdict_pinns`). Each refuses a bad
name with a one-line ValueError; the command line turns it into its usage error."""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import replace
from typing import Any

from harness.settings import DEFAULT, Settings, SolverSpec
from solvers import INTERFACE, SOLVERS, UNAVAILABLE

__all__ = ["default_specs", "parse_option", "parse_verdict_pinns", "with_options"]


def default_specs(
    solvers: Iterable[str] | None = None, configs: Iterable[str] | None = None,
    settings: Settings = DEFAULT,
) -> list[SolverSpec]:
    """Every registered adapter (installed or not: missing ones become 'skipped' rows) in each of
    its named configs (`configs`, or those without a mark in `settings.omit_marks`), plain and in
    each of its `VARIANTS`; adapters that train once per seed of `settings.seeds`; and, when no
    adapters are named, the do-nothing adapter that times the interface (latency only)."""
    names = list(SOLVERS) if solvers is None else list(solvers)
    unknown = [n for n in names if n not in SOLVERS]
    if unknown:
        raise ValueError(f"unknown solver(s) {', '.join(unknown)}; known: {', '.join(SOLVERS)}")
    specs = []
    for name in names:
        cls = SOLVERS[name]
        if cls is None:
            specs.append(SolverSpec(name))
            continue
        for config in cls.CONFIGS:
            if config not in configs if configs is not None else cls.marks(config) & set(settings.omit_marks):
                continue
            variants = [(), *(tuple(sorted(v.items())) for v in cls.VARIANTS)]
            if cls.trains:
                # the run's budget trains a model per case; one trained for every case keeps its own
                budget = tuple(sorted((k, v) for k, v in settings.pinn_options.items()
                                      if k in cls.OPTIONS and cls.trained_per_case))
                for variant in variants:  # the plain spec first: it trains, its variants reuse the model
                    specs.extend(SolverSpec(name, config, tuple(sorted(budget + variant)), seed)
                                 for seed in settings.seeds)
                continue
            specs.extend(SolverSpec(name, config, variant) for variant in variants)
    if solvers is None:
        specs.append(SolverSpec(INTERFACE))
    return specs


def parse_option(text: str) -> tuple[str, Any]:
    """"KEY=VALUE" -> (KEY, VALUE), VALUE read as JSON where it is JSON ("100" -> 100, "null" ->
    None, "[0.1, 2]" -> a list) and as text otherwise ("lbfgs")."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise ValueError(f"an option override is KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def parse_verdict_pinns(texts: Iterable[str]) -> tuple[tuple[str, tuple[str, ...], tuple[()]], ...]:
    """`Settings.verdict_pinns` from "NAME" (every named config of adapter NAME) or "NAME:CONFIG"
    texts, one entry per adapter in the order first named, its configs in the order given.
    ValueError, one line, for an unknown or uninstalled adapter, one that does not train
    (`trains`) or an unknown config."""
    configs: dict[str, list[str]] = {}
    for text in texts:
        name, sep, config = text.partition(":")
        if name not in SOLVERS:
            raise ValueError(f"{text}: unknown solver {name!r}; known: {', '.join(SOLVERS)}")
        cls = SOLVERS[name]
        if cls is None:
            raise ValueError(f"{text}: {name} is not available ({UNAVAILABLE[name]})")
        if not cls.trains:
            raise ValueError(f"{text}: {name} does not train; the verdict suite measures adapters that do (trains)")
        if sep and config not in cls.CONFIGS:
            raise ValueError(f"{text}: unknown config {config!r} of {name}; known: {', '.join(cls.CONFIGS)}")
        chosen = configs.setdefault(name, [])
        chosen.extend(c for c in ([config] if sep else cls.CONFIGS) if c not in chosen)
    return tuple((name, tuple(chosen), ()) for name, chosen in configs.items())


def with_options(specs: Iterable[SolverSpec], overrides: dict[str, Any]) -> list[SolverSpec]:
    """`specs` with `overrides` set in the options of every spec whose adapter has the option (its
    variant then shows them). ValueError when an override is an option of none of the specs'
    adapters. The values are checked where every option is, on every case it runs on: by building
    each unit's adapter before measuring (`harness.run.runner.check_units`)."""
    specs = list(specs)
    known = {key for spec in specs if SOLVERS.get(spec.solver) for key in SOLVERS[spec.solver].OPTIONS}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ValueError(f"option(s) {', '.join(unknown)} belong to none of the selected adapters")
    out = []
    for spec in specs:
        cls = SOLVERS.get(spec.solver)
        mine = {k: v for k, v in overrides.items() if cls is not None and k in cls.OPTIONS}
        if mine:
            spec = replace(spec, options=tuple(sorted({**dict(spec.options), **mine}.items())))
        out.append(spec)
    return out
