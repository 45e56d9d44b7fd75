"""`swingbench run --verdict-pinn NAME[:CONFIG]`: any trained adapter, a plugin's (an installed
distribution's entry point, as in tests/test_plugins.py) included, gets verdicts by the verdict
suite's rules; bad names are one line and exit 2."""

from __future__ import annotations

import importlib
import json
import sys
from dataclasses import replace
from pathlib import Path

import pytest

import solvers
from harness.cli import main
from harness.run.plan import plan
from harness.run.selection import default_specs, parse_verdict_pinns
from harness.settings import QUICK
from harness.store import RowStore
from harness.suites import SUITES
from harness.usage import EXIT_USAGE
from systems.cases import SMIB_INFERENCE
from tests.test_plugins import install, python

SETTINGS = replace(QUICK, cache_dir=None, verdict_seeds=(0, 1), verdict_rounds=1, verdict_pairs=3,
                   throughput_sizes=(1,), t1_values_s=(10.0,), points_batch=0)


# The plugin `tinyverdict`: "tiny-pinn" trains in no time and answers the reference scaled by
# 1 + 1e-4 (seed + 1), a relative error of that size; "tiny-rival", a compiled classical adapter,
# the reference scaled by 1 + rtol.
PLUGIN = '''
from typing import ClassVar

from solvers.base import AbstractSolver, FitReport
from solvers.classical.common import ToleranceOptions
from solvers.options import NonNegativeInt, OptionSchema
from systems.reference import reference


class SeedOptions(OptionSchema):
    seed: NonNegativeInt = 0


class TinyPinn(AbstractSolver):
    name: ClassVar[str] = "tiny-pinn"
    SCHEMA = SeedOptions
    CONFIGS: ClassVar[dict] = {"default": {}, "other": {}}
    trains = True

    def _fit(self):
        return FitReport(0.0, iterations=1, loss=1e-8)

    def _solve(self, t, P1):
        delta, omega = reference(self.case, t, P1)
        scale = 1.0 + 1e-4 * (self.options["seed"] + 1)
        return delta * scale, omega * scale

    def _identify(self, obs):
        return self.case.m, self.case.d, 0, False, "tiny-pinn does not identify"


class TinyRival(AbstractSolver):
    name: ClassVar[str] = "tiny-rival"
    SCHEMA = ToleranceOptions
    compiled = has_tolerance = True

    def _fit(self):
        return None

    def _solve(self, t, P1):
        delta, omega = reference(self.case, t, P1)
        return delta * (1.0 + self.options["rtol"]), omega * (1.0 + self.options["rtol"])

    def _identify(self, obs):
        return self.case.m, self.case.d, 0, False, "tiny-rival does not identify"
'''
# A run in a process of its own with the plugin installed, tiny-rival the only compiled ODE rival (the
# classical surrogates as they are) and the quick settings small enough for a test.
RUN = """
import sys
from dataclasses import replace

import harness.settings
from harness.cli import main
from harness.suites import _matching

harness.settings.QUICK = replace(harness.settings.QUICK, cache_dir=None, verdict_seeds=(0, 1),
                                 verdict_rounds=1, verdict_pairs=3, throughput_sizes=(1,),
                                 t1_values_s=(10.0,), points_batch=0)
families = _matching._families
_matching._families = lambda case, settings, surrogates=False: (
    families(case, settings, True) if surrogates else [("tiny-rival", "default", ())])
sys.exit(main(sys.argv[1:]))
"""


def plugin_site(folder: Path) -> Path:
    """`folder` holding the plugin `tinyverdict`, installed (its dist-info, its entry points)."""
    install(folder, "tinyverdict", {"tiny-pinn": "tinyverdict:TinyPinn", "tiny-rival": "tinyverdict:TinyRival"},
            {"tinyverdict/__init__.py": PLUGIN})
    return folder


@pytest.fixture
def tiny(monkeypatch, tmp_path):
    """The plugin's adapters in this process's registry, as its entry points would put them."""
    monkeypatch.syspath_prepend(str(plugin_site(tmp_path / "site")))
    module = importlib.import_module("tinyverdict")
    monkeypatch.setitem(sys.modules, "tinyverdict", module)  # forgotten again after the test
    monkeypatch.setitem(solvers.SOLVERS, "tiny-pinn", module.TinyPinn)
    monkeypatch.setitem(solvers.SOLVERS, "tiny-rival", module.TinyRival)


@pytest.mark.slow
def test_a_plugin_that_trains_gets_verdict_rows_for_every_seed_against_a_matched_rival(tmp_path):
    site = plugin_site(tmp_path / "site")
    run = python(["-c", RUN, "run", "--quick", "--suite", "verdict", "--solver", "tiny-pinn", "--case", "smib-inference",
                  "--verdict-pinn", "tiny-pinn:default", "--progress", "off", "--out", "out"], [site], tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    rows = [r for r in RowStore(tmp_path / "out", create=False).read().rows if r.get("suite") == "verdict"]
    assert {r["config"] for r in rows} == {"default"} and {r["pinn_seed"] for r in rows} == {0, 1}
    assert {r["query"] for r in rows} == {"grid 100x201", "1 trajectories x 201 times", "single point t1=10 s"}
    for r in rows:
        assert r["status"] == "ok" and r["rival"].startswith("tiny-rival [default") and r["samples"] == 3
        assert r["rival_rel_l2_delta"] <= r["pinn_rel_l2_delta"] and r["ratio_low"] <= r["ratio"] <= r["ratio_high"]
        assert r["surrogate_label"] in {"PINN faster", "classical faster", "tie", "no rival"}
    assert json.loads((tmp_path / "out" / "metadata.json").read_text())["version_tinyverdict"] == "0.1"


def test_without_the_flag_the_verdict_suite_measures_the_jax_pinn_alone_with_it_the_configs_named(tiny):
    specs = default_specs(["tiny-pinn"], None, SETTINGS)
    assert SETTINGS.verdict_pinns == (("jax-pinn", ("default", "marching", "fault-marching"), ()),)
    assert not plan(specs, [SMIB_INFERENCE], [SUITES["verdict"]], SETTINGS).units
    named = replace(SETTINGS, verdict_pinns=parse_verdict_pinns(["tiny-pinn:other", "tiny-pinn:default"]))
    assert named.verdict_pinns == (("tiny-pinn", ("other", "default"), ()),)
    assert parse_verdict_pinns(["tiny-pinn"]) == (("tiny-pinn", ("default", "other"), ()),)
    one = replace(SETTINGS, verdict_pinns=parse_verdict_pinns(["tiny-pinn:default"]))
    chosen = plan(specs, [SMIB_INFERENCE], [SUITES["verdict"]], one)
    assert [(u.spec.config, u.spec.seed) for u in chosen.units] == [("default", 0)]
    assert [s.spec.config for s in chosen.not_run] == ["other"]
    assert chosen.not_run[0].reason.startswith("skipped: verdict measures the run's verdict PINNs only (tiny-pinn default")


@pytest.mark.parametrize("argv,message", [
    (["--verdict-pinn", "nope"], "swingbench run: --verdict-pinn nope: unknown solver 'nope'; known: scipy-rk45"),
    (["--verdict-pinn", "tiny-rival"], "swingbench run: --verdict-pinn tiny-rival: tiny-rival does not train"),
    (["--verdict-pinn", "tiny-pinn:bogus"],
     "swingbench run: --verdict-pinn tiny-pinn:bogus: unknown config 'bogus' of tiny-pinn; known: default, other"),
    (["--verdict-pinn", "tiny-pinn", "--solver", "tiny-rival"],
     "swingbench run: --verdict-pinn tiny-pinn (default, other) is not among the selected solvers and configs"),
])
def test_an_unknown_untrained_or_unselected_adapter_or_config_is_one_line_and_exit_2(tiny, argv, message, tmp_path,
                                                                                        capsys):
    with pytest.raises(SystemExit) as info:
        main(["run", "--quick", "--suite", "verdict", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert info.value.code == EXIT_USAGE and err.count("\n") == 1 and err.startswith(message)
    assert not (tmp_path / "out").exists()
