"""`swingbench run --verdict-pinn NAME[:CONFIG]`: any trained adapter, one registered from outside
included, gets verdicts by the verdict suite's rules; bad names are one line and exit 2."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import pytest

import harness.runs
import solvers
from harness.cli import main
from harness.plan import plan
from harness.runs import QUICK, default_specs, parse_verdict_pinns
from harness.store import RowStore
from harness.suites import SUITES, _matching
from harness.usage import EXIT_USAGE
from solvers.base import AbstractSolver, FitReport
from solvers.classical import ToleranceOptions
from solvers.options import NonNegativeInt, OptionSchema
from systems.cases import SMIB_INFERENCE
from systems.reference import reference

SETTINGS = replace(QUICK, cache_dir=None, verdict_seeds=(0, 1), verdict_rounds=1, verdict_pairs=3,
                   throughput_sizes=(1,), t1_values_s=(10.0,), points_batch=0)


class SeedOptions(OptionSchema):
    seed: NonNegativeInt = 0


class TinyPinn(AbstractSolver):
    """Trains in no time: the reference scaled by 1 + 1e-4 (seed + 1), a relative error of that size."""

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
    """A compiled classical rival whose relative error is its rtol: the reference scaled by 1 + rtol."""

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


@pytest.fixture
def tiny(monkeypatch):
    """tiny-pinn in the registry as an adapter from outside would be, tiny-rival the only compiled
    rival, and the quick settings small enough for a test."""
    monkeypatch.setitem(solvers.SOLVERS, TinyPinn.name, TinyPinn)
    monkeypatch.setitem(solvers.SOLVERS, TinyRival.name, TinyRival)
    monkeypatch.setattr(_matching, "_families", lambda case, settings: [(TinyRival.name, "default", ())])
    monkeypatch.setattr(harness.runs, "QUICK", SETTINGS)


def test_a_trained_adapter_named_gets_verdict_rows_for_every_seed_against_a_matched_rival(tiny, tmp_path):
    out = tmp_path / "out"
    assert main(["run", "--quick", "--suite", "verdict", "--solver", "tiny-pinn", "--case", "smib-inference",
                 "--verdict-pinn", "tiny-pinn:default", "--progress", "off", "--out", str(out)]) == 0
    rows = [r for r in RowStore(out, create=False).read().rows if r.get("suite") == "verdict"]
    measured = [r for r in rows if r["status"] == "ok"]
    assert {r["config"] for r in measured} == {"default"} and {r["pinn_seed"] for r in measured} == {0, 1}
    assert {r["query"] for r in measured} == {"grid 100x201", "1 trajectories x 201 times", "single point t1=10 s"}
    for r in measured:
        assert r["rival"].startswith("tiny-rival [default") and r["samples"] == 3
        assert r["rival_rel_l2_delta"] <= r["pinn_rel_l2_delta"] and r["ratio_low"] <= r["ratio"] <= r["ratio_high"]


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
