"""Adapters from outside the repository: a distribution that declares the entry-point group
`swingbench.solvers` is listed, run, reported and benchmarked with no edit to swingbench.

The plugin is "installed" without pip: a package and its `.dist-info` folder (METADATA,
entry_points.txt) in a folder put on PYTHONPATH of a subprocess, which is all
`importlib.metadata` reads."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# scipy's DOP853 on the swing equation (any number of machines), every P1 of a call in one stacked
# system: ~1e-9 rad on the SMIB and a fraction of a second for the paper's grid. It does not
# identify (an estimate that says so).
TINY = '''
from typing import ClassVar

import numpy as np
from scipy.integrate import solve_ivp

from solvers.base import AbstractSolver
from systems.model import accelerations, coupling


class Tiny(AbstractSolver):
    """DOP853 at rtol 1e-8, all P1 of a query stacked."""

    name: ClassVar[str] = "tiny"

    def _fit(self):
        self._k = coupling(self.case)
        self._m, self._d = np.asarray(self.case.m), np.asarray(self.case.d)

    def _integrate(self, t, P1):
        """delta, omega (len(P1), len(t), n) at sorted unique times t."""
        n, P = self.case.n, self.case.powers(P1)

        def rhs(_, y):
            delta, omega = y.reshape(2, P1.size, n)
            return np.concatenate([omega, accelerations(self._k, self._m, self._d, delta, omega, P)]).ravel()

        y0 = np.concatenate([np.tile(self.case.delta0, (P1.size, 1)), np.tile(self.case.omega0, (P1.size, 1))])
        if t[-1] == 0.0:
            y = np.repeat(y0.ravel()[:, None], t.size, axis=1)
        else:
            y = solve_ivp(rhs, (0.0, t[-1]), y0.ravel(), method="DOP853", t_eval=t, rtol=1e-8, atol=1e-10).y
        y = y.reshape(2, P1.size, n, t.size).transpose(0, 1, 3, 2)
        return y[0], y[1]

    def _solve(self, t, P1):
        times, where = np.unique(t, return_inverse=True)
        delta, omega = self._integrate(times, P1)
        return delta[:, where], omega[:, where]

    def _solve_points(self, t, P1):
        times, where = np.unique(t, return_inverse=True)
        delta, omega = self._integrate(times, P1)
        pair = np.arange(t.size)
        return delta[pair, where], omega[pair, where]

    def _identify(self, obs):
        return self.case.m, self.case.d, 0, False, "tiny does not identify"
'''
MISSING = "import swingbench_no_such_package  # noqa: F401\n"


def install(site: Path, dist: str, entry_points: dict[str, str], modules: dict[str, str],
            group: str = "swingbench.solvers") -> None:
    """A distribution `dist` 0.1 in folder `site`: its modules and a dist-info with its entry points
    in `group`."""
    for relative, source in modules.items():
        path = site / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
    info = site / f"{dist}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1\n")
    lines = "".join(f"{name} = {value}\n" for name, value in entry_points.items())
    (info / "entry_points.txt").write_text(f"[{group}]\n{lines}")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """A folder holding the plugin `tinyplugin`: adapter "tiny", and "tiny-missing", whose module
    imports a package that is not installed."""
    site = tmp_path_factory.mktemp("site")
    install(site, "tinyplugin", {"tiny": "tinyplugin:Tiny", "tiny-missing": "tinyplugin.missing:Gone"},
            {"tinyplugin/__init__.py": TINY, "tinyplugin/missing.py": MISSING})
    return site


def python(args: list[str], sites: list[Path], cwd: Path, **env: str) -> subprocess.CompletedProcess:
    """`python args` in `cwd` with the folders `sites` and this checkout first on the path."""
    environ = {**os.environ, "PYTHONPATH": os.pathsep.join([*map(str, sites), str(ROOT)]), **env}
    return subprocess.run([sys.executable, *args], cwd=cwd, env=environ, capture_output=True, text=True,
                          timeout=600, check=False)


REGISTRY_PROBE = textwrap.dedent("""
    import json, sys
    from solvers import SOLVERS, UNAVAILABLE, make_solver, plugin_distribution
    from systems.cases import SMIB_INFERENCE
    names = list(SOLVERS)
    imported_by_listing = "tinyplugin" in sys.modules
    solver = make_solver("tiny", SMIB_INFERENCE)
    print(json.dumps({
        "names": names, "imported_by_listing": imported_by_listing,
        "heavy": sorted(m for m in ("torch", "jax") if m in sys.modules),
        "class": type(solver).__module__ + ":" + type(solver).__name__,
        "missing": SOLVERS["tiny-missing"], "why": UNAVAILABLE.get("tiny-missing"),
        "distribution": plugin_distribution("tiny"), "builtin": plugin_distribution("scipy-rk45"),
    }))
""")


def test_a_plugin_is_registered_lazily_and_a_missing_dependency_is_a_skip(site, tmp_path):
    out = python(["-c", REGISTRY_PROBE], [site], tmp_path)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got["names"][:2] == ["scipy-rk45", "scipy-odeint"] and got["names"][-2:] == ["tiny", "tiny-missing"]
    assert not got["imported_by_listing"] and got["heavy"] == []  # one adapter imports only itself
    assert got["class"] == "tinyplugin:Tiny"
    assert got["missing"] is None and got["why"] == "skipped: swingbench_no_such_package not installed"
    assert got["distribution"] == "tinyplugin" and got["builtin"] is None


def test_a_plugin_cannot_take_a_built_in_name(site, tmp_path):
    other = tmp_path / "other"
    install(other, "clashing", {"scipy-rk45": "tinyplugin:Tiny"}, {})
    probe = "from solvers import SOLVERS; print(SOLVERS['scipy-rk45'].__module__)"
    out = python(["-c", probe], [site, other], tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "solvers.classical.scipy_rk45"
    assert "solver 'scipy-rk45' of clashing ignored" in out.stderr


@pytest.mark.slow
def test_a_plugin_runs_every_default_suite_through_the_cli_and_the_report_names_it(site, tmp_path):
    run = python(["-m", "harness", "run", "--solver", "tiny", "--case", "smib-inference", "--quick",
                  "--progress", "off", "--out", "out"], [site], tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    lines = [json.loads(line) for line in (tmp_path / "out" / "rows.jsonl").read_text().splitlines()]
    rows = [row for row in lines if "_complete" not in row]  # not the markers of finished units
    by_suite: dict[str, set] = {}
    for row in rows:
        assert row["solver"] == "tiny"
        by_suite.setdefault(row["suite"], set()).add(row["status"])
    assert set(by_suite) == {"fit", "accuracy", "latency", "work_precision", "identification", "cct"}
    # every row measured, but a latency query the suite itself skips as too slow, with a row, and the
    # cct suite on a step case (fault cases only)
    assert by_suite.pop("cct") == {"skipped: cct measures fault cases only, and smib-inference has no fault"}
    assert all(s == "ok" or s.startswith("skipped: estimated") for statuses in by_suite.values() for s in statuses)
    assert all(statuses == {"ok"} for suite, statuses in by_suite.items() if suite != "latency"), by_suite
    accuracy = [r for r in rows if r["suite"] == "accuracy" and r["against"] == "reference" and r["quantity"] == "delta"]
    assert accuracy and accuracy[0]["rel_l2"] < 1e-4  # the run measured a real integrator
    tables = (tmp_path / "out" / "tables.md").read_text()
    assert "tiny default" in tables  # the accuracy, latency and identification tables and the summary
    assert json.loads((tmp_path / "out" / "metadata.json").read_text())["version_tinyplugin"] == "0.1"
    assert "tiny" in python(["-m", "harness", "run", "--help"], [site], tmp_path).stdout


@pytest.mark.slow
def test_asv_benchmarks_take_a_plugin_as_a_parameter(site, tmp_path):
    probe = "import json, benchmarks._common as c; print(json.dumps(c.PARAMS[c.PARAM_NAMES.index('solver')]))"
    out = python(["-c", probe], [site], tmp_path, SWINGBENCH_ASV_QUICK="1")
    assert out.returncode == 0, out.stderr[-3000:]
    assert "tiny" in json.loads(out.stdout.strip().splitlines()[-1])


GRID = """
from pathlib import Path

from systems.case_file import case_from_file


def grid():
    return case_from_file(Path(__file__).with_name("grid.json"), name="plugged")
"""


@pytest.mark.slow
def test_a_package_brings_a_case_by_the_swingbench_cases_entry_points(tmp_path):
    import pandapower as pp
    import pandapower.networks as pn

    site = tmp_path / "site"
    install(site, "gridplugin", {"plugged": "gridplugin:grid", "wscc9": "gridplugin:grid"},
            {"gridplugin/__init__.py": GRID}, group="swingbench.cases")
    pp.to_json(pn.case9(), str(site / "gridplugin" / "grid.json"))
    probe = ("import json, sys; from systems.cases import CASES; listed = 'gridplugin' in sys.modules; "
             "print(json.dumps({'listed': 'plugged' in CASES, 'imported_by_listing': listed, "
             "'n': CASES['plugged'].n, 'wscc9': CASES['wscc9'].source[:8]}))")
    done = python(["-c", probe], [site], tmp_path)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == {"listed": True, "imported_by_listing": False, "n": 3, "wscc9": "network:"}
    assert "[swingbench] case 'wscc9' of gridplugin ignored: the name is taken" in done.stderr
