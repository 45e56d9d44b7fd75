"""The contract of every registered adapter: shapes, dtypes, order of t_query, errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import ALL_SOLVERS, require, small_options

from harness.cases import SMIB_INFERENCE, Observations
from solvers import SOLVERS, make_solver
from solvers.base import NotFittedError, Trajectory


@pytest.mark.parametrize("name", ALL_SOLVERS)
def test_grid_shapes_and_dtypes(fitted_solvers, name):
    solver = fitted_solvers[name]
    t = np.linspace(0.0, 20.0, 7)
    P1 = np.array([0.09, 0.12, 0.17])
    traj = solver.solve(t, P1)
    assert isinstance(traj, Trajectory)
    for arr in (traj.delta, traj.omega):
        assert arr.shape == (3, 7)
        assert arr.dtype == np.float64
        assert np.isfinite(arr).all()
    np.testing.assert_allclose(traj.delta[:, 0], SMIB_INFERENCE.delta0, atol=0.05)


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
    assert single.delta.shape == (1, 1)
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
]


@pytest.mark.parametrize("name", ALL_SOLVERS)
@pytest.mark.parametrize("argument,t,P1", BAD_QUERIES)
def test_bad_queries_raise_value_error_naming_the_argument(fitted_solvers, name, argument, t, P1):
    with pytest.raises(ValueError, match=argument):
        fitted_solvers[name].solve(t, P1)


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
def test_identify_rejects_bad_observations(name):
    require(name)
    solver = make_solver(name, SMIB_INFERENCE, **small_options(name))
    with pytest.raises(ValueError, match="Observations"):
        solver.identify("not observations")
    with pytest.raises(ValueError, match="at least 2 samples"):
        solver.identify(Observations([1.0], [0.1], [0.2]))


def test_registry_is_one_dict_of_adapter_classes():
    assert {"scipy-rk45", "casadi-cvodes"} <= set(SOLVERS)
    for name, cls in SOLVERS.items():
        if cls is not None:
            assert cls.name == name
            assert "default" in cls.CONFIGS
