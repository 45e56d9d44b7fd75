"""Shared fixtures: every registered adapter, fitted once per session on a small budget."""

from __future__ import annotations

import os

# one thread per pytest-xdist worker (`make test` runs two on two cores): more oversubscribes the cores,
# and torch's many small kernels then wait on each other
os.environ.setdefault("OMP_NUM_THREADS", "1" if "PYTEST_XDIST_WORKER" in os.environ else "2")

import numpy as np
import pytest

from solvers import SOLVERS, UNAVAILABLE, make_solver
from systems.cases import SMIB_INFERENCE, Case

ALL_SOLVERS = tuple(SOLVERS)

# Small budgets for the adapters that train: the contract tests check behaviour, not accuracy.
SMALL_BUDGET = {"max_iterations": 30, "n_f": 300, "progress": False}


def small_options(name: str) -> dict:
    cls = SOLVERS[name]
    return {k: v for k, v in SMALL_BUDGET.items() if k in cls.OPTIONS}


def fit_for_tests(solver) -> None:
    """`fit()`, with diffrax compiling one small shape instead of the benchmark's (its JIT is slow)."""
    if hasattr(solver, "FIT_SHAPES"):
        solver.FIT_SHAPES = ((7, 3),)
    if hasattr(solver, "FIT_POINTS"):
        solver.FIT_POINTS = ()
    solver.fit()


def require(name: str, case: Case = SMIB_INFERENCE) -> None:
    """Skip unless adapter `name` is installed and one of its configs is made for `case`'s kind
    (the SMIB by default: the contract tests' case)."""
    if SOLVERS[name] is None:
        pytest.skip(UNAVAILABLE[name])
    cls = SOLVERS[name]
    if not any(cls.made_for(config, case.kind, case.scenario) for config in cls.CONFIGS):
        pytest.skip(f"{name} is made for no {case.kind} case ({case.name})")


@pytest.fixture(scope="session")
def fitted_solvers() -> dict:
    """name -> a fitted adapter on SMIB_INFERENCE (built lazily, once per session)."""
    cache: dict = {}

    class Lazy(dict):
        def __missing__(self, name):
            require(name)
            solver = make_solver(name, SMIB_INFERENCE, **small_options(name))
            fit_for_tests(solver)
            self[name] = solver
            return solver

    return Lazy(cache)


def max_rel(estimate: np.ndarray, truth) -> float:
    """Largest relative error over the machines."""
    return float(np.max(np.abs(np.asarray(estimate) / np.asarray(truth) - 1.0)))


def three_machine_lossy() -> Case:
    """Three machines on a lossy Kron-reduced network (G, B non-zero, no infinite bus), unequal
    voltages and mechanical powers: exercises every term of the electrical power."""
    G = np.array([[0.3, -0.1, -0.05], [-0.1, 0.25, -0.08], [-0.05, -0.08, 0.2]])
    B = np.array([[-1.6, 0.9, 0.5], [0.9, -1.7, 0.7], [0.5, 0.7, -1.4]])
    return Case(name="three-lossy", m=(0.3, 0.2, 0.25), d=(0.12, 0.08, 0.1), delta0=(0.1, 0.05, -0.02),
                omega0=(0.1, 0.0, -0.05), p_m=(0.15, 0.1, 0.05), E=(1.05, 1.0, 1.02), G=G, B=B,
                g_inf=(0.0,) * 3, b_inf=(0.0,) * 3, t_final=10.0, p1_min=0.1, p1_max=0.2,
                m_box=((0.05, 1.0),) * 3, d_box=((0.02, 0.5),) * 3)


THREE_MACHINES = three_machine_lossy()


def points_queries(case) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Two `solve_points` queries on `case`, pairs (t s, P1 p.u.) in scrambled order with t = 0 and
    a duplicate pair: "distinct" (10 pairs, 9 distinct P1: every pair its own P1 but the duplicate)
    and "shared" (12 pairs over 3 P1, 4 each)."""
    rng = np.random.default_rng(11)
    t = np.concatenate([[0.0], case.t_final * (1.0 - rng.random(11))])
    distinct_p1 = rng.uniform(case.p1_min, case.p1_max, 10)
    distinct_t = t[:10].copy()
    distinct_t[9], distinct_p1[9] = distinct_t[3], distinct_p1[3]
    shared_p1 = rng.permutation(np.repeat(np.linspace(case.p1_min, case.p1_max, 3), 4))
    shared_t = t.copy()
    shared_t[7], shared_p1[7] = shared_t[2], shared_p1[2]
    return {"distinct": (distinct_t, distinct_p1), "shared": (shared_t, shared_p1)}


def per_group(solver, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(delta, omega), (n_s, n), of the pairs (t[i], P1[i]) from one `solve` per distinct P1 at its
    pairs' times: what a points query grouped by P1 answers."""
    delta, omega = np.empty((t.size, solver.case.n)), np.empty((t.size, solver.case.n))
    for p1 in np.unique(P1):
        pairs = np.flatnonzero(P1 == p1)
        traj = solver.solve(t[pairs], np.array([p1]))
        delta[pairs], omega[pairs] = traj.delta[0], traj.omega[0]
    return delta, omega


def per_pair(solver, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(delta, omega), (n_s, n), of the pairs (t[i], P1[i]) from one `solve` each."""
    rows = [solver.solve(t[i:i + 1], P1[i:i + 1]) for i in range(t.size)]
    return np.array([r.delta[0, 0] for r in rows]), np.array([r.omega[0, 0] for r in rows])


def check_points_as_solves(solver, atol: float = 0.0) -> tuple[np.ndarray, np.ndarray, object]:
    """Assert that `solver.solve_points` answers both `points_queries` of its case as solves do: the
    "distinct" pairs as one-point solves (`per_pair`), the "shared" ones as one solve per P1 at its
    pairs' times (`per_group`), to `atol` (0: the same bits), shapes (n_s, n), the t = 0 pairs at
    the case's delta0. Returns the "shared" query's t, P1 and points."""
    case = solver.case
    for pattern, expect in (("distinct", per_pair), ("shared", per_group)):
        t, P1 = points_queries(case)[pattern]
        points = solver.solve_points(t, P1)
        delta, omega = expect(solver, t, P1)
        assert points.delta.shape == points.omega.shape == (t.size, case.n)
        np.testing.assert_allclose(points.delta, delta, rtol=0, atol=atol)
        np.testing.assert_allclose(points.omega, omega, rtol=0, atol=atol)
        np.testing.assert_array_equal(points.delta[t == 0.0], np.broadcast_to(case.delta0, (1, case.n)))
    return t, P1, points