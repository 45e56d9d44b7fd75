"""The PINNs on N machines and with time-marching: a two-machine fit and identification, the
identification horizon, the windows and their training points, marching models' shapes,
continuity at the window boundaries, cached starts, save/load and iteration budgets."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pinn_helpers import (
    BACKENDS,
    CASE,
    TORCH_JIT_SCRIPT_DEPRECATED,
    TWO,
    TWO_SMALL,
    need_backend,
    sampled_observations,
)

from harness.measure.metrics import rel_l2
from solvers import make_solver
from solvers.pinn.architecture import Architecture, init_theta, start_guess
from solvers.pinn.config import PinnConfig
from solvers.pinn.evaluator import MarchingEvaluator
from solvers.pinn.model_file import CorruptModelError, load_model
from solvers.pinn.problems import identification_problem, observations_within, window_edges, window_problem
from systems.cases import Observations
from systems.reference import reference

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


MARCHING = {**TWO_SMALL, "window": 1.0}  # 4 windows on TWO's 4 s


@pytest.fixture(scope="module", params=list(BACKENDS))
def marched(request):
    """A tiny time-marching model of TWO per backend (4 windows of 1 s, 3 LM iterations each) and
    its FitReport."""
    need_backend(request.param)
    solver = make_solver(request.param, TWO, **MARCHING)
    return solver, solver.fit()


def test_two_machine_fit_and_identify_shapes():
    """A single network on two machines: two angle outputs, (n_p, n_t, 2) trajectories, (n_s, 2)
    points, and identification of both machines' m and d with a 4 x 4 covariance."""
    need_backend("torch-pinn")
    solver = make_solver("torch-pinn", TWO, **TWO_SMALL)
    report = solver.fit()
    assert solver.arch.sizes[-1] == 2 and solver.theta.shape == (solver.arch.n_params,) and solver.windows is None
    assert report.iterations > 0 and np.isfinite(report.loss)
    traj = solver.solve(np.linspace(0.0, 4.0, 7), np.array([0.25, 0.3, 0.35]))
    assert traj.delta.shape == traj.omega.shape == (3, 7, 2)
    np.testing.assert_allclose(traj.delta[:, 0], np.broadcast_to(TWO.delta0, (3, 2)), atol=1e-15)  # hard IC
    points = solver.solve_points(np.array([0.5, 3.0]), np.array([0.26, 0.34]))
    assert points.delta.shape == points.omega.shape == (2, 2)
    ident = solver.identify(sampled_observations(TWO, 25))
    assert ident.m.shape == ident.d.shape == ident.m_se.shape == (2,) and ident.m_ci95.shape == (2, 2)
    assert np.isfinite(np.concatenate([ident.m, ident.d])).all() and ident.iterations > 0
    assert solver.identification["arch"].n_extra == 4 and solver.identification["m"].shape == (2,)


def test_identification_starts_at_the_centre_of_each_box():
    """m_init / d_init None: the geometric centre of each machine's box; a number: every machine."""
    m, d = start_guess(PinnConfig(), TWO)
    np.testing.assert_allclose(m, [0.1, 0.2], rtol=1e-15)
    np.testing.assert_allclose(d, [0.05, 0.1], rtol=1e-15)
    m, d = start_guess(PinnConfig(m_init=0.3), TWO)
    np.testing.assert_array_equal(m, [0.3, 0.3])
    arch = Architecture.of(PinnConfig(hidden_layers=1, width=3), TWO, identification=True)
    np.testing.assert_allclose(np.exp(init_theta(arch, 0, m, d)[-4:]), [0.3, 0.3, 0.05, 0.1], rtol=1e-15)
    # the SMIB boxes (0.02, 2) and (0.005, 1): m starts where the old default m_init did
    assert start_guess(PinnConfig(), CASE)[0][0] == pytest.approx(0.2, rel=1e-15)


def test_identification_horizon_keeps_the_early_observations_and_collocates_within_it():
    obs = Observations(np.array([0.5, 1.5, 3.0]), np.full(3, 0.3), np.zeros((3, 2)))
    config = PinnConfig(id_t_max=2.0, id_n_f=40)
    kept = observations_within(config, obs)
    assert kept.t.tolist() == [0.5, 1.5] and kept.delta.shape == (2, 2)
    assert observations_within(PinnConfig(), obs) is obs
    problem = identification_problem(config, TWO, obs)
    assert problem.targets.shape == (2, 2) and problem.t_f.max() <= 2.0 and problem.t_f.size == 42
    assert Architecture.of(config, TWO, identification=True).t_hi == 2.0
    assert Architecture.of(PinnConfig(), TWO, identification=True).t_hi == TWO.t_final
    with pytest.raises(ValueError, match="id_t_max=0.1 s: no observation"):
        observations_within(PinnConfig(id_t_max=0.1), obs)


def test_window_edges_and_training_points():
    np.testing.assert_array_equal(window_edges(4.2, 1.0), [0.0, 1.0, 2.0, 3.0, 4.0, 4.2])
    np.testing.assert_array_equal(window_edges(4.0 + 1e-12, 1.0), [0.0, 1.0, 2.0, 3.0, 4.0 + 1e-12])
    assert window_edges(10.0, 0.5).size == 21 and window_edges(1.0, 5.0).tolist() == [0.0, 1.0]
    config = PinnConfig(n_u=6, n_f=50, window=1.0)
    edges = window_edges(TWO.t_final, 1.0)
    problem = window_problem(config, TWO, edges, 2)
    assert problem.t_f.size == 56 and problem.targets.shape == (6, 2)
    assert (problem.t_f >= 0).all() and (problem.t_f <= 1.0).all()  # times since the window's start
    assert (problem.p_f >= TWO.p1_min).all() and (problem.p_f <= TWO.p1_max).all()
    assert set(problem.p_u) == {TWO.p1_min, TWO.p1_max}
    ref, _ = reference(TWO, 2.0 + problem.t_u, [TWO.p1_min, TWO.p1_max])
    np.testing.assert_allclose(problem.targets, np.where((problem.p_u == TWO.p1_max)[:, None], ref[1], ref[0]),
                               rtol=0, atol=1e-12)
    other = window_problem(config, TWO, edges, 3)
    assert not np.array_equal(other.t_f, problem.t_f)
    np.testing.assert_array_equal(window_problem(config, TWO, edges, 2).t_f, problem.t_f)


def test_marching_model_shapes(marched):
    solver, report = marched
    np.testing.assert_array_equal(solver.windows, [0.0, 1.0, 2.0, 3.0, 4.0])
    assert solver.theta.shape == (4, solver.arch.n_params) and solver.arch.t_hi == 1.0
    assert 4 <= report.iterations <= 12 and np.isfinite(report.loss) and "4 windows" in report.message
    assert not np.array_equal(solver.theta[0], solver.theta[1])
    traj = solver.solve(np.linspace(0.0, 4.0, 7), np.array([0.25, 0.3, 0.35]))
    assert traj.delta.shape == traj.omega.shape == (3, 7, 2)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.broadcast_to(TWO.delta0, (3, 2)), atol=1e-15)
    points = solver.solve_points(np.array([0.5, 3.0, 1.0]), np.array([0.26, 0.34, 0.3]))
    assert points.delta.shape == points.omega.shape == (3, 2)


def test_marching_is_continuous_at_the_window_boundaries(marched):
    """delta and omega just before a window's start (the previous window at its end) equal the
    window's own start state to 1e-12: each window's hard initial condition is the state the
    previous one reaches, for that P1."""
    solver, _ = marched
    P1 = np.array([0.25, 0.31, 0.35])
    inner = solver.windows[1:-1]
    left = solver.solve(np.nextafter(inner, 0.0), P1)  # the largest times of windows 0..2
    right = solver.solve(inner, P1)  # the starts of windows 1..3
    np.testing.assert_allclose(left.delta, right.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(left.omega, right.omega, rtol=0, atol=1e-12)
    # and the states do change across the windows (the check above is not of a constant)
    assert np.abs(np.diff(right.delta, axis=1)).min() > 1e-6


def test_marching_single_point_queries_use_the_cached_starts(marched, monkeypatch):
    """A repeated single-point query looks the window starts up instead of walking the windows, and
    gives what a grid query gives; the cache holds at most `cache_size` P1 values."""
    from solvers.pinn import evaluator as evaluators

    solver, _ = marched
    evaluator = solver._evaluate
    assert isinstance(evaluator, MarchingEvaluator)
    t, P1 = np.array([0.0, 0.7, 1.0, 2.5, 3.99, 4.0]), np.array([0.27, 0.33])
    grid = solver.solve(t, P1)
    walks = []
    real = evaluators.walk
    monkeypatch.setattr(evaluators, "walk", lambda *args: walks.append(args[3].size) or real(*args))
    for i in range(P1.size):
        for j in range(t.size):
            one = solver.solve(t[j:j + 1], P1[i:i + 1])
            np.testing.assert_allclose(one.delta[0, 0], grid.delta[i, j], rtol=0, atol=1e-12)
            np.testing.assert_allclose(one.omega[0, 0], grid.omega[i, j], rtol=0, atol=1e-12)
    assert walks == []  # the grid query cached both P1 values
    solver.solve(np.array([2.2]), 0.2987)
    solver.solve(np.array([3.2]), 0.2987)
    assert walks == [1]  # a new P1: one walk, then the cache
    points = solver.solve_points(np.repeat(t, 2), np.tile(P1, t.size))
    np.testing.assert_allclose(points.delta, grid.delta.transpose(1, 0, 2).reshape(-1, 2), rtol=0, atol=1e-12)
    evaluator.cache_size = 2
    solver.solve(t, np.array([0.28, 0.29, 0.3]))
    assert len(evaluator._cache) == 2


@pytest.mark.parametrize("target", list(BACKENDS))
def test_marching_save_load_round_trip(marched, target, tmp_path):
    """All windows in one model file (format version 3, the window edges in the .json): loaded by
    either backend they answer the same; the sha256 covers every window."""
    need_backend(target)
    solver, _ = marched
    npz, meta = solver.save(tmp_path / "model")
    info = json.loads(meta.read_text())
    assert info["version"] == 3 and info["windows"] == [0.0, 1.0, 2.0, 3.0, 4.0]
    loaded = make_solver(target, TWO, threads=1).load(tmp_path / "model")
    assert loaded.pinn_config.window == 1.0 and loaded.theta.shape == solver.theta.shape
    np.testing.assert_array_equal(loaded.windows, solver.windows)
    t, P1 = np.linspace(0.0, 4.0, 9), np.array([0.25, 0.3])
    a, b = solver.solve(t, P1), loaded.solve(t, P1)
    np.testing.assert_allclose(b.delta, a.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.omega, a.omega, rtol=0, atol=1e-12)
    with np.load(npz) as data:
        theta = data["theta"].copy()
    theta[3, 0] += 1e-9  # the last window only
    with open(npz, "wb") as fh:
        np.savez(fh, theta=theta)
    with pytest.raises(CorruptModelError, match="sha256"):
        load_model(tmp_path / "model")


def test_a_marching_model_budgeted_in_iterations_is_the_same_on_a_slower_machine(marched, monkeypatch):
    """`make bench` trains the network PINNs for iterations per window, not seconds: the same seed
    gives the same weights and the same error when every clock reading is 100 s later than the last
    (a machine far slower than this one), up to rounding."""
    import time as clock

    solver, report = marched
    name = solver.name
    t, P1 = np.linspace(0.0, TWO.t_final, 21), np.linspace(TWO.p1_min, TWO.p1_max, 3)
    ref = reference(TWO, t, P1)[0]
    now = [clock.perf_counter()]

    def slow() -> float:
        now[0] += 100.0
        return now[0]

    monkeypatch.setattr(clock, "perf_counter", slow)
    again = make_solver(name, TWO, **{**MARCHING, "max_seconds": None})
    again.fit()
    timed = make_solver(name, TWO, **{**MARCHING, "max_seconds": 1000.0})
    timed_report = timed.fit()
    monkeypatch.undo()
    assert timed_report.iterations < report.iterations  # what a budget in seconds does on that machine
    # equal up to the last bits of XLA's threaded sums
    assert rel_l2(again.solve(t, P1).delta, ref) == pytest.approx(rel_l2(solver.solve(t, P1).delta, ref), rel=1e-9)
