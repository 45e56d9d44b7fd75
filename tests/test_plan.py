"""The planner (`harness.run.plan`): make bench's selection of units is what it was before the planner
read declarations; SMIB or network is the case's kind; capabilities are declared, and the
declarations agree with the adapters' options."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from harness.run.plan import FIT, Unit, left_out, not_on_case, plan
from harness.run.runner import run_unit
from harness.run.selection import default_specs
from harness.settings import DEFAULT, FULL, QUICK, SolverSpec
from harness.suites import DEFAULT_SUITES, SUITES, identification_case
from solvers import SOLVERS, make_solver
from solvers.base import (
    ABLATION,
    CONFIG_MARKS,
    IDENTIFIES_NETWORKS,
    LARGE_SYSTEMS,
    SWEEP_POINT,
    AbstractSolver,
)
from systems.cases import CASES, NETWORK, SMIB, SMIB_IDENTIFICATION, SMIB_INFERENCE, smib_case
from systems.faults import FAULT_CASES

# Every unit of work of make bench's plans, as the harness chose them before the planner (the
# runner's plan with `Settings.measures`, the identification and work-precision suites' own checks):
# [case, solver, config, variant, seed, work, what it records] where the last is "run", the
# "skipped: ..." status of its one row, or "no rows" (a config that is a point of its adapter's
# precision sweep: work-precision recorded nothing for it). Recorded once by running that code, and
# recorded again (commit of issue 21) when make bench deliberately changed: the verdict suite's units
# of the JAX PINN with its compiled query path, and the multi-machine PINNs' budgets in iterations
# per window (`Settings.case_pinn_options`) where they were seconds; and bench-quick's cuts (no
# ablations, configs for large systems or sweep points such as `tight`, no network identification).
# Recorded again when the trapezoid adapter joined the registry: its units added, every other entry
# as it was; and when the PINNs' `marching-large` (a config for large systems) joined: its units
# added to the full and scaling runs, every other entry as it was; and when the fault cases of wscc9 and
# kundur4 joined make bench and the quick run (wscc9's), with the cct suite among the default suites:
# their units added, and a cct entry (skipped: fault cases only) of each step case's unit, every
# other entry as it was (checked when recorded); and when make bench left the sweep points (`tight`) out
# on the fault cases (`Settings.fault_omit_marks`): those entries skipped, their fits gone, every other
# entry as it was (checked when recorded); and when pod-spline and reduced-pinn joined the registry,
# with the `identifies` capability: their units added, every other entry as it was (checked when
# recorded); and when the PINNs' `fault-split` (marked an ablation of `fault-marching`) joined: its
# units added to the full run, every other entry as it was; and when pinnsim joined: likewise (both re-recorded by
# `tests/record_plan_before.py NAME`, which asserts it); and when make bench left torch-pinn out on
# the fault cases (`Settings.fault_omit_solvers`): those entries skipped, their fits gone, every
# other entry as it was (checked when recorded); and when pinnsim's `faults` config (made for fault
# cases, for large systems) joined: its units added to the full run, every other entry as it was (by
# `tests/record_plan_before.py pinnsim faults`).
BEFORE = json.loads((Path(__file__).parent / "data" / "plan_before.json").read_text())

RUNS = {
    "default": (DEFAULT, DEFAULT_SUITES, DEFAULT.cases, None),
    "quick": (QUICK, DEFAULT_SUITES, QUICK.cases, None),
    "full": (FULL, DEFAULT_SUITES, FULL.cases, None),
    # the configs make bench leaves out unless the command line names them (--config)
    "default --config": (DEFAULT, DEFAULT_SUITES, ("smib-inference", "wscc9"),
                         ["default", "two-outputs", "paper-two-outputs", "adams"]),
    "scaling": (DEFAULT.for_scaling(), ("scaling",), ("smib-inference", "wscc9"), None),
}

needs_every_adapter = pytest.mark.skipif(any(SOLVERS[name] is None for name in SOLVERS),
                                         reason="the recorded plans are of every adapter installed")


def planned(run: str):
    """The plan of `run` (`RUNS`) and its works as the file lists them: [case, solver, config,
    variant, seed, work, "run" or the skipped status]."""
    settings, suites, cases, configs = RUNS[run]
    result = plan(default_specs(None, configs, settings), [CASES[name] for name in cases],
                  [SUITES[name] for name in suites], settings)
    works = []
    for unit in result.units:
        skipped = dict(unit.skipped)
        for work in unit.works():
            key = unit.work_key(work)
            works.append([key["case"], key["solver"], key["config"], key["variant"], key["seed"], work,
                          skipped.get(work, "run")])
    return result, works


@needs_every_adapter
@pytest.mark.parametrize("run", list(RUNS))
def test_make_bench_plans_the_units_it_planned_before(run):
    result, works = planned(run)
    assert works == [entry for entry in BEFORE[run] if entry[-1] != "no rows"]
    # what recorded no rows is not run now, and the plan says why
    not_run = {(s.case.name, s.spec.solver, s.spec.config, s.spec.variant, s.spec.key()["seed"], s.suite)
               for s in result.not_run}
    rowless = [tuple(entry[:6]) for entry in BEFORE[run] if entry[-1] == "no rows"]
    assert all(entry in not_run for entry in rowless)
    assert all(s.reason.startswith("skipped: ") for s in result.not_run)


def test_a_smib_built_by_smib_case_plans_as_a_smib_without_a_list():
    heavy = smib_case("smib-heavy", m=0.8, d=0.3, b=0.2, delta0=0.1, omega0=0.1, t_final=20.0,
                      p1_min=0.08, p1_max=0.18)
    assert heavy.kind == SMIB and CASES["wscc9"].kind == NETWORK and SMIB_INFERENCE.kind == SMIB
    assert identification_case(heavy) is SMIB_IDENTIFICATION and identification_case(CASES["wscc9"]).name == "wscc9"
    marching, single = SolverSpec("jax-pinn", "marching", seed=0), SolverSpec("jax-pinn", "default", seed=0)
    if SOLVERS["jax-pinn"] is None:
        pytest.skip("jax not installed")
    assert not_on_case(single, heavy, DEFAULT) is None
    assert "not made for smib cases" in not_on_case(marching, heavy, DEFAULT)
    assert not_on_case(marching, CASES["wscc9"], DEFAULT) is None
    assert "not made for network cases" in not_on_case(single, CASES["wscc9"], DEFAULT)
    assert "first seed only" in not_on_case(replace(marching, seed=1), CASES["wscc9"], replace(DEFAULT, seeds=(0, 1)))
    result = plan([single, marching], [heavy], [SUITES[name] for name in DEFAULT_SUITES], DEFAULT)
    assert {(u.case.name, u.spec.config) for u in result.units} == {("smib-heavy", "default"),
                                                                     ("smib-identification", "default")}
    assert DEFAULT.sweep_rtols(False, heavy) == DEFAULT.wp_rtols  # the SMIB's full sweep


@pytest.mark.parametrize("name", list(SOLVERS))
def test_declared_capabilities_agree_with_the_adapters_options(name):
    """The harness reads declarations only; here, once, they are checked against the options that
    carry them: a seed to train from, rtol and atol, threads, save and load."""
    cls = SOLVERS[name]
    if cls is None:
        pytest.skip(f"{name} is not installed")
    options = set(cls.OPTIONS)
    assert cls.trains == ("seed" in options)
    assert cls.has_tolerance == ({"rtol", "atol"} <= options)
    assert cls.takes_threads == ("threads" in options)
    assert cls.can_save == (callable(getattr(cls, "save", None)) and callable(getattr(cls, "load", None)))
    assert cls.QUERY_OPTIONS <= options
    assert not cls.classical_surrogate or (cls.trains and cls.compiled)
    for config in cls.CONFIGS:
        assert cls.marks(config) <= CONFIG_MARKS
        # a point of the sweep: a config that sets only the options its sweep sets (built on a
        # case of the scenario it is made for: a config made for fault cases alone refuses a step)
        case = (SMIB_INFERENCE if cls.made_for(config, SMIB) else CASES["wscc9"] if cls.made_for(config, NETWORK)
                else CASES[FAULT_CASES["wscc9"][0]])
        solver = make_solver(name, case, config)
        sweep = solver.precision_sweep((1e-3,))
        covered = bool(sweep) and bool(cls.CONFIGS[config]) and set(cls.CONFIGS[config]) <= set(sweep[0])
        assert (SWEEP_POINT in cls.marks(config)) == covered, config
    assert any(cls.made_for(config, NETWORK) for config in cls.CONFIGS)


@needs_every_adapter
def test_make_bench_selects_configs_by_their_marks_and_names_none():
    marks = {(name, config): SOLVERS[name].marks(config) for name in SOLVERS for config in SOLVERS[name].CONFIGS}
    omitted = {key for key, m in marks.items() if m & {ABLATION, LARGE_SYSTEMS}}
    assert {(s.solver, s.config) for s in default_specs(None, None, DEFAULT)}.isdisjoint(omitted)
    assert {(s.solver, s.config) for s in default_specs(None, None, DEFAULT.for_scaling())} >= {
        key for key, m in marks.items() if LARGE_SYSTEMS in m}
    assert any(IDENTIFIES_NETWORKS in m for m in marks.values())


class Unbuildable(AbstractSolver):
    """Registered only while a test runs: building it fails, so a unit that builds it says so."""

    name = "unbuildable"

    def _check_options(self):
        raise RuntimeError("built")

    def _fit(self):
        return None

    def _solve(self, t, P1):
        raise NotImplementedError

    def _identify(self, obs):
        raise NotImplementedError


def test_a_suite_the_settings_leave_out_is_one_skipped_row_of_its_unit_and_builds_nothing(monkeypatch):
    monkeypatch.setitem(SOLVERS, "unbuildable", Unbuildable)
    why = "skipped: not identified in this test"
    unit = Unit(SMIB_IDENTIFICATION, SolverSpec("unbuildable"), ("identification",),
                skipped=(("identification", why),))
    assert unit.works() == ["identification"]
    ((work, (row,)),) = list(run_unit(unit, QUICK, unit.works()))
    assert work == "identification" and row["status"] == why and row["suite"] == "identification"
    assert {"case", "solver", "config", "variant", "seed", "trains", "worker", "work_s"} <= set(row)
    # beside a suite that runs, the fit is for that suite only, and the skip keeps its place
    both = replace(unit, suites=("accuracy", "identification"))
    assert both.works() == [FIT, "accuracy", "identification"]


def test_make_bench_leaves_the_sweep_points_out_on_fault_cases_only_unless_named():
    fault, step = CASES["wscc9-bus8-line8-9"], CASES["wscc9"]
    tight, default = SolverSpec("numba-rk", "tight"), SolverSpec("numba-rk", "default")
    latency = SUITES["latency"]
    assert "not run on fault cases" in left_out(tight, fault, latency, DEFAULT)
    assert left_out(tight, step, latency, DEFAULT) is None
    assert left_out(default, fault, latency, DEFAULT) is None
    assert left_out(tight, fault, latency, replace(DEFAULT, fault_omit_marks=())) is None


def test_make_bench_leaves_torch_out_on_fault_cases_only_unless_named():
    fault, step = CASES["wscc9-bus8-line8-9"], CASES["wscc9"]
    torch, jax = SolverSpec("torch-pinn", "fault-marching", seed=0), SolverSpec("jax-pinn", "fault-marching", seed=0)
    latency = SUITES["latency"]
    assert "torch-pinn not run on fault cases" in left_out(torch, fault, latency, DEFAULT)
    assert left_out(replace(torch, config="marching"), step, latency, DEFAULT) is None
    assert left_out(jax, fault, latency, DEFAULT) is None
    assert left_out(torch, fault, latency, FULL) is None


def test_query_path_variants_skip_identification_which_does_not_depend_on_them():
    from harness.run.plan import plan
    from harness.suites import DEFAULT_SUITES, SUITES
    from systems.cases import SMIB_INFERENCE as forward

    specs = default_specs(["jax-pinn"], ["default"], replace(DEFAULT, seeds=(0,)))
    units = {(unit.case.name, unit.spec.variant): list(unit.suites)
             for unit in plan(specs, [forward], [SUITES[name] for name in DEFAULT_SUITES]).units}
    assert units[("smib-identification", "")] == ["identification"]
    assert ("smib-identification", "query=numba") not in units
    # cct is listed for the step case too: its unit records it as skipped (fault cases only)
    assert units[("smib-inference", "query=numba")] == ["accuracy", "cct", "latency", "work_precision"]
    assert units[("smib-inference", "")] == ["accuracy", "cct", "latency", "verdict", "work_precision"]
    # an adapter's own query options (scipy RK45's batch mode) likewise; diffrax's batch changes
    # its identification's error control, so its variant identifies
    specs = [SolverSpec("scipy-rk45", options=(("batch", "stacked"),)), SolverSpec("diffrax", options=(("batch", "vmap"),))]
    units = {(unit.case.name, unit.spec.solver): list(unit.suites)
             for unit in plan(specs, [forward], [SUITES[name] for name in DEFAULT_SUITES]).units}
    assert ("smib-identification", "scipy-rk45") not in units
    assert units[("smib-identification", "diffrax")] == ["identification"]


def test_a_case_s_training_budget_applies_to_its_pinn_units_only():
    from harness.run.plan import plan
    from harness.suites import SUITES
    from systems.cases import CASES
    from systems.cases import SMIB_INFERENCE as forward

    settings = replace(DEFAULT, seeds=(0,), case_pinn_options={"wscc9": {"max_iterations": 90, "max_seconds": None}})
    specs = default_specs(["jax-pinn", "numba-rk", "pinnsim"], ["marching", "default"], settings)
    units = plan(specs, [forward, CASES["wscc9"]], list(SUITES.values()), settings).units
    budget = {(u.case.name, u.spec.solver, u.spec.config): dict(u.spec.options).get("max_iterations") for u in units}
    assert budget[("wscc9", "jax-pinn", "marching")] == 90
    assert budget[("wscc9", "pinnsim", "default")] is None  # trained once for every case: its own budget
    # nor does a run-wide budget (the scaling suite's, --quick's) retrain it
    scaling = default_specs(["jax-pinn", "pinnsim"], ["marching", "default"], DEFAULT.for_scaling())
    assert {s.solver: dict(s.options).get("max_iterations") for s in scaling} == {"jax-pinn": 100, "pinnsim": None}
    assert budget[("smib-inference", "jax-pinn", "default")] is None  # no budget named for the SMIB
    assert budget[("wscc9", "numba-rk", "default")] is None  # classical adapters do not train
    assert {u.spec.variant for u in units if u.case.name == "wscc9" and u.spec.solver == "jax-pinn"} == {
        "max_iterations=90,max_seconds=None", "max_iterations=90,max_seconds=None,query=numba"}


def test_an_option_given_on_the_command_line_wins_over_the_case_s_budget(monkeypatch, tmp_path):
    """`--quick --option max_iterations=150` trains wscc9's PINN 150 iterations a window, though 150
    is also quick's run-wide value and wscc9's quick budget is 10 (the planner alone took the given
    value for the default and put the budget in its place)."""
    import harness.run.plan
    from harness.cli import main

    seen = {}

    def stop(specs, cases, suites, settings):
        seen["units"] = plan(specs, cases, suites, settings).units
        raise SystemExit(0)

    monkeypatch.setattr(harness.run.plan, "plan", stop)
    assert QUICK.pinn_options["max_iterations"] == 150 and QUICK.case_pinn_options["wscc9"]["max_iterations"] == 10
    argv = ["run", "--quick", "--suite", "accuracy", "--case", "wscc9", "--solver", "jax-pinn", "--config", "marching",
            "--out", str(tmp_path / "out")]
    for extra, iterations in (([], 10), (["--option", "max_iterations=150"], 150), (["--option", "max_iterations=40"], 40)):
        with pytest.raises(SystemExit):
            main([*argv, *extra])
        assert {dict(u.spec.options)["max_iterations"] for u in seen["units"]} == {iterations}, extra
