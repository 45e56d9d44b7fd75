"""The interface's own promises: the fast path of `solve` validates like the slow one, batches of
single points, the do-nothing adapter, declared capabilities."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from solvers import INTERFACE, SOLVERS, make_solver, solver_class
from solvers.base import Points, Trajectory
from solvers.null import NullSolver
from systems.cases import SMIB_INFERENCE, check_array


@pytest.fixture(scope="module")
def null() -> NullSolver:
    solver = make_solver(INTERFACE, SMIB_INFERENCE)
    solver.fit()
    return solver


def _slow_path_accepts(name: str, value, nonnegative: bool) -> bool:
    try:
        check_array(name, np.atleast_1d(value) if name == "P1" else value, nonnegative=nonnegative)
    except ValueError:
        return False
    return True


floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=300, deadline=None)
@given(t=st.one_of(arrays(np.float64, st.integers(0, 20), elements=floats), floats, st.lists(floats, max_size=3)),
       p1=st.one_of(floats, arrays(np.float64, st.integers(0, 20), elements=floats)))
def test_fast_path_accepts_and_rejects_exactly_what_check_array_does(null, t, p1):
    """Whatever the input, `solve` succeeds iff `check_array` accepts both arguments, and returns
    the same arrays then; a rejection is a ValueError naming the argument."""
    t_ok = _slow_path_accepts("t_query", t, nonnegative=True)
    p_ok = _slow_path_accepts("P1", p1, nonnegative=False)
    if t_ok and p_ok:
        traj = null.solve(t, p1)
        np.testing.assert_array_equal(traj.t, check_array("t_query", t, nonnegative=True))
        np.testing.assert_array_equal(traj.P1, check_array("P1", np.atleast_1d(p1)))
        assert traj.delta.shape == (traj.P1.size, traj.t.size, 1)
    else:
        with pytest.raises(ValueError, match="t_query" if not t_ok else "P1"):
            null.solve(t, p1)


def test_fast_path_returns_a_trajectory_of_float64(null):
    traj = null.solve(np.array([10.0, 2.0]), 0.13)
    assert type(traj) is Trajectory
    assert traj.delta.dtype == np.float64 and traj.delta.shape == (1, 2, 1)
    assert traj.P1.tolist() == [0.13]


def test_solve_points_pairs_times_with_p1():
    solver = make_solver("scipy-odeint", SMIB_INFERENCE, "tight")
    solver.fit()
    t, p1 = np.array([3.0, 10.0, 0.0]), np.array([0.1, 0.15, 0.12])
    points = solver.solve_points(t, p1)
    assert type(points) is Points and points.delta.shape == (3, 1)
    for i in range(3):
        single = solver.solve(t[i:i + 1], p1[i:i + 1])
        assert points.delta[i, 0] == pytest.approx(single.delta[0, 0, 0], abs=1e-9)
        assert points.omega[i, 0] == pytest.approx(single.omega[0, 0, 0], abs=1e-9)
    with pytest.raises(ValueError, match="pairs"):
        solver.solve_points([1.0, 2.0], [0.1])
    with pytest.raises(ValueError, match="P1"):
        solver.solve_points([1.0], [np.nan])


def test_the_interface_adapter_is_not_a_registered_solver(null):
    assert INTERFACE not in SOLVERS and solver_class(INTERFACE) is NullSolver
    assert not NullSolver.does_work and all(cls.does_work for cls in SOLVERS.values() if cls is not None)
    assert null.solve_points([1.0, 2.0], [0.1, 0.1]).delta.shape == (2, 1)
    with pytest.raises(NotImplementedError, match="interface only"):
        null._identify(None)


def test_capabilities_are_declared():
    declared = {name: (cls.trains, cls.compiled) for name, cls in SOLVERS.items() if cls is not None}
    for name in ("torch-pinn", "jax-pinn"):
        if name in declared:
            assert declared[name] == (True, False)
    for name in ("scipy-rk45", "scipy-odeint", "casadi-cvodes"):
        assert declared[name] == (False, False)
    for name in ("numba-rk", "diffrax"):
        if name in declared:
            assert declared[name] == (False, True)
    assert SOLVERS["scipy-odeint"].blas_threads == 1


def test_precision_sweep_follows_the_declared_tolerance():
    rk = make_solver("scipy-rk45", SMIB_INFERENCE)
    assert rk.precision_sweep((1e-3, 1e-6)) == [{"rtol": 1e-3, "atol": 1e-6}, {"rtol": 1e-6, "atol": 1e-9}]
    assert NullSolver(SMIB_INFERENCE).precision_sweep((1e-3,)) == []
