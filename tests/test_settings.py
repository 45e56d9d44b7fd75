"""The settings of a run (`harness.settings`) and the specs it makes (`harness.run.selection`): the sweeps
and budgets of make bench, option overrides."""

from __future__ import annotations

from dataclasses import replace

import pytest

from harness.run.selection import default_specs
from harness.settings import DEFAULT, QUICK
from systems.cases import SMIB_INFERENCE


def test_default_specs_cover_configs_and_batch_modes():
    labels = [spec.label for spec in default_specs(["scipy-rk45"])]
    assert labels == ["scipy-rk45[default]", "scipy-rk45[default,batch=stacked]",
                      "scipy-rk45[tight]", "scipy-rk45[tight,batch=stacked]"]
    with pytest.raises(ValueError, match="unknown solver"):
        default_specs(["nope"])


def test_omitted_configs_run_only_when_named():
    from solvers.base import IDENTIFIES_NETWORKS

    omitting = replace(DEFAULT, omit_marks=(IDENTIFIES_NETWORKS,))  # scipy-rk45's tight is marked so
    assert [s.config for s in default_specs(["scipy-rk45"], None, omitting)] == ["default", "default"]
    assert {s.config for s in default_specs(["scipy-rk45"], ["tight"], omitting)} == {"tight"}


def test_python_driven_adapters_sweep_fewer_tolerances_on_networks_only():
    from systems.cases import CASES

    settings = replace(DEFAULT, wp_rtols=(1e-3, 1e-4, 1e-5), network_wp_rtols=(1e-3,))
    assert settings.sweep_rtols(False, CASES["wscc9"]) == (1e-3,)
    assert settings.sweep_rtols(True, CASES["wscc9"]) == settings.wp_rtols
    assert settings.sweep_rtols(False, SMIB_INFERENCE) == settings.wp_rtols
    assert replace(settings, network_wp_rtols=None).sweep_rtols(False, CASES["wscc9"]) == settings.wp_rtols


def test_option_overrides_reach_the_adapters_that_have_them_and_are_validated():
    from harness.run.selection import parse_option, with_options

    assert parse_option("max_iterations=100") == ("max_iterations", 100)
    assert parse_option("optimizer=lbfgs") == ("optimizer", "lbfgs")
    assert parse_option("max_seconds=null") == ("max_seconds", None)
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_option("rtol")
    from harness.run.plan import plan
    from harness.run.runner import check_units
    from harness.suites import SUITES

    specs = default_specs(["scipy-rk45", "numba-rk"], ["default"])
    tuned = with_options(specs, {"batch": "stacked"})
    assert {s.variant for s in tuned if s.solver == "scipy-rk45"} == {"batch=stacked"}
    assert [s.variant for s in tuned if s.solver == "numba-rk"] == [s.variant for s in specs if s.solver == "numba-rk"]
    with pytest.raises(ValueError, match="none of the selected adapters"):
        with_options(specs, {"width": 3})
    units = plan(with_options(specs, {"batch": "sideways"}), [SMIB_INFERENCE], [SUITES["accuracy"]], QUICK).units
    with pytest.raises(ValueError, match=r"^scipy-rk45\[default,batch=sideways\] smib-inference: scipy-rk45: "
                                         "option batch must be one of"):
        check_units(units, QUICK)


def test_pinn_training_is_bounded_by_iterations_unless_a_time_budget_is_given():
    from solvers.pinn.config import PinnConfig

    config = PinnConfig()
    assert config.max_seconds is None and config.deadline(5.0) == float("inf")
    assert PinnConfig(id_max_seconds=2.0).deadline(5.0, identification=True) == 7.0
    with pytest.raises(ValueError, match="max_seconds"):
        PinnConfig(max_seconds=0.0)


def test_make_bench_trains_every_network_pinn_for_iterations_not_seconds():
    from harness.run.plan import plan
    from harness.suites import SUITES
    from systems.cases import CASES, NETWORK_CASES

    specs = default_specs(["jax-pinn", "torch-pinn"], settings=DEFAULT)
    units = plan(specs, [CASES[name] for name in NETWORK_CASES], list(SUITES.values()), DEFAULT).units
    assert units
    for unit in units:
        options = unit.spec.make(unit.case).options  # the config's own max_seconds included
        assert options["max_seconds"] is None and options["id_max_seconds"] is None, unit.label
        assert options["max_iterations"] == DEFAULT.case_pinn_options[unit.case.name]["max_iterations"]
