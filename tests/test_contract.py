"""The contract of every registered adapter: shapes, dtypes, order of t_query, errors."""

from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import ALL_SOLVERS, fit_for_tests, require, small_options

from solvers import SOLVERS, fault_adapters, make_solver
from solvers.base import NotFittedError, Trajectory
from systems.cases import CASES, SMIB_INFERENCE, Observations
from systems.reference import reference


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_grid_shapes_and_dtypes(fitted_solvers, name):
    solver = fitted_solvers[name]
    t = np.linspace(0.0, 20.0, 7)
    P1 = np.array([0.09, 0.12, 0.17])
    traj = solver.solve(t, P1)
    assert isinstance(traj, Trajectory)
    for arr in (traj.delta, traj.omega):
        assert arr.shape == (3, 7, 1)  # (n_P1, n_t, n machines): the one shape rule, N = 1 included
        assert arr.dtype == np.float64
        assert np.isfinite(arr).all()
    np.testing.assert_allclose(traj.delta[:, 0, 0], SMIB_INFERENCE.delta0[0], atol=0.05)


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_order_repeats_and_single_point(fitted_solvers, name):
    solver = fitted_solvers[name]
    t = np.array([12.0, 0.5, 7.25, 12.0, 3.0])
    P1 = 0.13
    shuffled = solver.solve(t, P1)
    order = np.argsort(t, kind="stable")
    ordered = solver.solve(t[order], P1)
    np.testing.assert_allclose(shuffled.delta[:, order], ordered.delta, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(shuffled.omega[:, order], ordered.omega, rtol=1e-9, atol=1e-12)
    assert shuffled.delta[0, 0] == shuffled.delta[0, 3]  # the repeated time
    single = solver.solve([7.25], [P1])
    assert single.delta.shape == (1, 1, 1)
    # another output grid may change an adaptive solver's steps: equal to within its tolerance
    np.testing.assert_allclose(single.delta[0, 0], ordered.delta[0, 2], rtol=1e-3, atol=1e-4)


BAD_QUERIES = [
    ("t_query", [0.0, np.nan], 0.1),
    ("t_query", [0.0, np.inf], 0.1),
    ("t_query", [-1.0, 1.0], 0.1),
    ("t_query", [[0.0, 1.0]], 0.1),
    ("t_query", [], 0.1),
    ("t_query", 1.0, 0.1),
    ("P1", [0.0, 1.0], [0.1, np.nan]),
    ("P1", [0.0, 1.0], [[0.1, 0.12]]),
    ("P1", [0.0, 1.0], []),
    ("P1", [0.0, 1.0], "abc"),
    ("t_query", [0.0, True, 5.0], 0.13),  # np.asarray would make True 1.0 s
    ("P1", [0.0, 1.0], [0.1, True]),
    ("P1", [0.0, 1.0], [0.1, "0.12"]),
]


@pytest.mark.parametrize("name", ALL_SOLVERS)
@pytest.mark.parametrize("argument,t,P1", BAD_QUERIES)
def test_bad_queries_raise_value_error_naming_the_argument(fitted_solvers, name, argument, t, P1):
    with pytest.raises(ValueError, match=argument):
        fitted_solvers[name].solve(t, P1)


@pytest.mark.parametrize("name", ALL_SOLVERS)
@pytest.mark.parametrize("argument,t,P1", [("t_query", [1.0, True], [0.1, 0.12]),
                                           ("P1", [1.0, 2.0], [0.1, np.True_])])
def test_solve_points_refuses_booleans_inside_lists(fitted_solvers, name, argument, t, P1):
    with pytest.raises(ValueError, match=f"^{argument} must be numeric.*booleans"):
        fitted_solvers[name].solve_points(t, P1)


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_solve_before_fit_raises(name):
    require(name)
    with pytest.raises(NotFittedError, match="fit"):
        make_solver(name, SMIB_INFERENCE).solve([1.0], 0.1)


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_unknown_option_and_config(name):
    require(name)
    with pytest.raises(ValueError, match="unknown option.*no_such_option"):
        make_solver(name, SMIB_INFERENCE, no_such_option=1)
    with pytest.raises(ValueError, match="unknown config 'nope'.*default"):
        make_solver(name, SMIB_INFERENCE, config="nope")


def test_unknown_solver_lists_known_ones():
    with pytest.raises(ValueError, match="unknown solver 'rk4'.*scipy-rk45.*casadi-cvodes"):
        make_solver("rk4", SMIB_INFERENCE)


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_a_case_is_given_as_a_case_or_by_its_name(name):
    require(name, CASES["wscc9"])
    assert make_solver(name, "wscc9", **small_options(name)).case is CASES["wscc9"]
    with pytest.raises(ValueError, match="^unknown case 'ieee300'; known: smib-inference, .*wscc9"):
        make_solver(name, "ieee300")


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_identify_rejects_bad_observations(name):
    require(name)
    solver = make_solver(name, SMIB_INFERENCE, **small_options(name))
    with pytest.raises(ValueError, match="Observations"):
        solver.identify("not observations")
    too_few = solver.identify(Observations([1.0], [0.1], [[0.2]]))  # an outcome, not an error
    assert not too_few.success and "distinct samples" in too_few.message
    assert too_few.m.shape == (1,) and too_few.m_ci95.shape == (1, 2)
    with pytest.raises(ValueError, match="obs.delta has 2 machine column"):
        solver.identify(Observations([1.0, 2.0], [0.1, 0.1], [[0.2, 0.1], [0.3, 0.1]]))


def test_registry_is_one_dict_of_adapter_classes():
    assert {"scipy-rk45", "casadi-cvodes"} <= set(SOLVERS)
    for name, cls in SOLVERS.items():
        if cls is not None:
            assert cls.name == name
            assert "default" in cls.CONFIGS


def test_registry_of_built_in_adapters_is_the_entry_point_table_of_pyproject():
    """One line of pyproject.toml each, read from the source tree (not an install's metadata)."""
    pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
    table = pyproject["project"]["entry-points"]["swingbench.solvers"]
    assert list(SOLVERS)[:len(table)] == list(table)
    for name, value in table.items():
        if SOLVERS[name] is not None:
            assert f"{SOLVERS[name].__module__}:{SOLVERS[name].__name__}" == value


def _linear_closed_form(case, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """delta, omega of m delta'' + d delta' = P1 (b = 0): with v = P1 / d and tau = m / d,
    delta = delta0 + v t + (omega0 - v) tau (1 - exp(-t / tau)), omega = v + (omega0 - v) exp(-t / tau)."""
    (m,), (d,), (delta0,), (omega0,) = case.m, case.d, case.delta0, case.omega0
    v, tau = P1[:, None] / d, m / d
    decay = np.exp(-t[None, :] / tau)
    return delta0 + v * t + (omega0 - v) * tau * (1 - decay), v + (omega0 - v) * decay


# A PINN trained briefly on the linear case: its error bound is loose, the check is that it learns
# the same solution (measured, 2 x 8 tanh, 200 collocation points, 200 LM iterations: rel. L2 of delta 4e-3).
LINEAR_PINN = {"hidden_layers": 2, "width": 8, "n_f": 200, "max_iterations": 200, "threads": 1, "progress": False}


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_every_adapter_matches_the_closed_form_of_the_linear_case(name):
    require(name)
    case = dataclasses.replace(SMIB_INFERENCE, b_inf=(0.0,), name="smib-linear")
    cls = SOLVERS[name]
    small = {key: value for key, value in LINEAR_PINN.items() if key in cls.OPTIONS}  # a trained adapter's own
    solver = make_solver(name, case, **small) if cls.trains else make_solver(name, case, "tight")
    fit_for_tests(solver)
    t, P1 = np.linspace(0.0, 20.0, 41), np.linspace(case.p1_min, case.p1_max, 5)
    traj = solver.solve(t, P1)
    delta, omega = _linear_closed_form(case, t, P1)
    tolerance = 1e-2 if cls.trains else 1e-8
    assert np.linalg.norm(traj.delta[..., 0] - delta) / np.linalg.norm(delta) < tolerance
    assert np.linalg.norm(traj.omega[..., 0] - omega) / np.linalg.norm(omega) < 10 * tolerance


@pytest.fixture(scope="module")
def wscc9():
    pytest.importorskip("pandapower")
    return CASES["wscc9"]


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_every_adapter_solves_a_multi_machine_case(wscc9, name):
    """The WSCC 9-bus system (3 machines, lossy Kron-reduced network, no infinite bus): every adapter
    answers with one angle and speed per machine; a classical one at its tight tolerances agrees
    with the reference, a PINN on a tiny budget is finite and starts at the initial state."""
    require(name)
    cls = SOLVERS[name]
    solver = make_solver(name, wscc9, **small_options(name)) if cls.trains else make_solver(name, wscc9, "tight")
    fit_for_tests(solver)
    t, P1 = np.array([0.0, 2.5, 1.0, 7.5]), np.array([wscc9.p1_min, wscc9.p1_max])
    traj = solver.solve(t, P1)
    points = solver.solve_points(t[:2], P1)
    assert traj.delta.shape == traj.omega.shape == (2, 4, 3)
    assert points.delta.shape == points.omega.shape == (2, 3)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.tile(wscc9.delta0, (2, 1)), atol=1e-6)
    if not cls.trains:
        ref_delta, ref_omega = reference(wscc9, t, P1)
        np.testing.assert_allclose(traj.delta, ref_delta, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(traj.omega, ref_omega, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(points.delta, [ref_delta[0, 0], ref_delta[1, 1]], rtol=1e-6, atol=1e-6)


# Fault adapters whose fault solve this test does not run: diffrax compiles it for ~10 s a shape on
# one core (measured), beyond the suite's budget; scripts/fault_grid.py checks it against the reference.
FAULTS_COMPILE_SLOWLY = frozenset({"diffrax"})


@pytest.fixture(scope="module")
def wscc9_fault():
    pytest.importorskip("pandapower")
    return CASES["wscc9-bus8-line8-9"]


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_every_adapter_solves_a_fault_case_or_refuses_it(wscc9_fault, name):
    """An adapter with `handles_faults` answers a fault case (the second argument the clearing time
    t_c, s): a classical one at its tight tolerances as the reference, a PINN on a tiny budget
    finite from the initial state; one without is refused by `make_solver`, naming the adapters
    that do (`fault_adapters`), and by its class (tests/test_fault_solvers.py has the details)."""
    require(name)
    cls, case = SOLVERS[name], wscc9_fault
    if not cls.handles_faults:
        with pytest.raises(ValueError, match=f"^{name} does not integrate fault cases.*adapters that do: "
                                             f"{re.escape(', '.join(fault_adapters()))}$"):
            make_solver(name, case)
        with pytest.raises(ValueError, match="handles_faults"):
            cls(case)
        return
    if name in FAULTS_COMPILE_SLOWLY:
        pytest.skip(f"{name}'s fault solve compiles too slowly for the suite (scripts/fault_grid.py checks it)")
    # a PINN: two pieces of clearing times, 1.5 s windows (the config's 8 and 0.5 s train 49 windows)
    # and 3 iterations a window: the contract is the answer's shape and start, not its accuracy
    solver = make_solver(name, case, "fault-marching", **{**small_options(name), "max_iterations": 3}, pieces=2,
                         window=1.5) \
        if cls.trains else make_solver(name, case, "tight")
    fit_for_tests(solver)
    t, T_c = np.array([0.0, 0.1, 1.0, 2.5]), np.array([0.15, 0.1])
    traj = solver.solve(t, T_c)
    assert traj.delta.shape == traj.omega.shape == (2, 4, 3)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.tile(case.delta0, (2, 1)), atol=1e-6)
    if not cls.trains:
        ref_delta, ref_omega = reference(case, t, T_c)
        np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=1e-5)
        np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=1e-4)
