"""`step_count`: the steps (and, where counted, the right-hand side evaluations) of one trajectory,
which the scaling suite reports beside its times."""

from __future__ import annotations

import math

import numpy as np
import pytest

from solvers import SOLVERS, make_solver
from solvers.base import AbstractSolver, SolveError
from systems.cases import CASES, SMIB_INFERENCE
from systems.faults import FAULT_CASES
from tests.conftest import require

MID = 0.5 * (SMIB_INFERENCE.p1_min + SMIB_INFERENCE.p1_max)
COUNTING = [name for name in SOLVERS if SOLVERS[name] is None or SOLVERS[name].counts_steps]
ADAPTIVE = ["numba-rk", "scipy-rk45", "scipy-odeint", "casadi-cvodes"]


@pytest.mark.parametrize("name", COUNTING)
def test_a_counting_adapter_reports_the_steps_of_one_trajectory(fitted_solvers, name):
    require(name)
    count = fitted_solvers[name].step_count(MID)
    assert count.steps > 0
    assert count.rhs_evals is None or count.rhs_evals >= count.steps
    with pytest.raises(ValueError, match="outside the case's range"):
        fitted_solvers[name].step_count(SMIB_INFERENCE.p1_max + 1.0)


@pytest.mark.parametrize("name", ADAPTIVE)
def test_a_tighter_tolerance_takes_more_steps(name):
    require(name)
    loose, tight = (make_solver(name, SMIB_INFERENCE, rtol=r, atol=r * 1e-3) for r in (1e-3, 1e-8))
    for solver in (loose, tight):
        solver.fit()
    assert tight.step_count(MID).steps > 2 * loose.step_count(MID).steps


def test_numba_rk_counts_exactly_the_steps_its_kernel_takes():
    """The least max_steps with which the trajectory succeeds: one fewer fails."""
    require("numba-rk")
    steps = make_solver("numba-rk", SMIB_INFERENCE)
    steps.fit()
    n = steps.step_count(MID).steps
    t = np.array([SMIB_INFERENCE.t_final])
    enough, short = (make_solver("numba-rk", SMIB_INFERENCE, max_steps=k) for k in (n, n - 1))
    enough.fit()
    short.fit()
    enough.solve(t, MID)
    with pytest.raises(SolveError, match="max_steps"):
        short.solve(t, MID)


@pytest.mark.parametrize(("name", "config"), [("trapezoid", "default"), ("numba-rk", "rk4")])
def test_a_fixed_step_takes_ceil_horizon_over_dt_steps(name, config):
    require(name)
    solver = make_solver(name, SMIB_INFERENCE, config)
    solver.fit()
    count = solver.step_count(MID)
    assert count.steps == math.ceil(SMIB_INFERENCE.t_final / solver.options["dt"])
    assert count.rhs_evals >= count.steps  # the trapezoid: one Newton iteration at least a step; rk4: 4 a step


def test_step_count_is_refused_where_it_means_nothing():
    require("numba-rk")
    with pytest.raises(ValueError, match="fault case"):
        make_solver("numba-rk", CASES[FAULT_CASES["wscc9"][0]]).step_count(0.1)
    require("jax-pinn")
    with pytest.raises(ValueError, match="does not count its steps"):
        make_solver("jax-pinn", SMIB_INFERENCE).step_count(MID)


@pytest.mark.parametrize("name", list(SOLVERS))
def test_counts_steps_is_declared_by_exactly_the_adapters_that_count(name):
    require(name)
    cls = SOLVERS[name]
    assert cls.counts_steps == (cls._step_count is not AbstractSolver._step_count)
