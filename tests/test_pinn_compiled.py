"""Tests of the compiled (numba) PINN query: equal to the JAX and torch evaluators in float64, on
saved models and through the adapter's `query` option, for one machine, two machines and
time-marching models. Random weights, no long training."""

from __future__ import annotations

import numpy as np
import pytest
from pinn_helpers import TWO  # two machines, lossy, no infinite bus

from solvers import make_solver
from solvers.pinn.architecture import Architecture, init_theta
from solvers.pinn.config import PinnConfig
from solvers.pinn.evaluator import MarchingEvaluator
from systems.cases import SMIB_INFERENCE

pytest.importorskip("numba")
from solvers.pinn.compiled import NumbaEvaluator, compiled_model

# torch.func's first jvp registers decompositions through torch.jit.script, deprecated in torch 2.13
pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE = SMIB_INFERENCE
T_GRID = np.linspace(0.0, CASE.t_final, 201)
P_GRID = np.linspace(CASE.p1_min, CASE.p1_max, 100)
POINTS = [(np.array([10.0]), np.array([0.13])), (np.array([0.0]), np.array([CASE.p1_min])),
          (np.array([CASE.t_final, 0.37, 3.0]), np.array([0.1]))]
# (hidden_layers, width, outputs, hard_ic)
VARIANTS = [(2, 16, 1, True), (2, 16, 1, False), (2, 16, 2, True), (2, 16, 2, False),
            (5, 10, 1, False), (1, 3, 1, True), (3, 40, 2, True), (4, 7, 1, True)]
SMALL = {"hidden_layers": 2, "width": 8, "n_u": 20, "n_f": 150, "max_iterations": 3, "threads": 1,
         "progress": False}


def _network(hidden_layers, width, outputs, hard_ic, seed=1):
    """An architecture of the case and random weights (Glorot plus noise in the zero biases)."""
    config = PinnConfig(hidden_layers=hidden_layers, width=width, outputs=outputs, hard_ic=hard_ic)
    arch = Architecture.of(config, CASE)
    theta = init_theta(arch, seed) + 0.2 * np.random.default_rng(seed).normal(size=arch.n_params)
    return arch, theta


def _framework(backend, arch, theta):
    pytest.importorskip("torch" if backend == "torch-pinn" else "jax")
    evaluator = make_solver(backend, CASE, threads=1)._make_evaluator(arch, "float64")
    evaluator.load(theta)
    return evaluator


@pytest.fixture(scope="module")
def numba_evaluators():
    """One compiled evaluator per variant (the kernels compile once per process)."""
    return {variant: NumbaEvaluator(_network(*variant)[0]) for variant in VARIANTS}


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("backend", [pytest.param("jax-pinn", marks=pytest.mark.slow), "torch-pinn"])  # JAX: JIT
@pytest.mark.parametrize("variant", VARIANTS)
def test_numba_equals_the_frameworks(numba_evaluators, backend, variant):
    """delta and omega on the 100 x 201 grid and on single points equal the backend's float64
    evaluator to 1e-12."""
    arch, theta = _network(*variant)
    ours = numba_evaluators[variant]
    ours.load(theta)
    reference = _framework(backend, arch, theta)
    for t, p in [(T_GRID, P_GRID), *POINTS]:
        delta, omega = ours(t, p)
        ref_delta, ref_omega = reference(t, p)
        assert delta.shape == omega.shape == (p.size, t.size, 1)
        assert delta.dtype == omega.dtype == np.float64
        _close(delta, ref_delta)
        _close(omega, ref_omega)


def test_a_point_gives_the_same_bits_in_any_query(numba_evaluators):
    """The one-point path and the blocked grid path run the same operations in the same order."""
    ours = numba_evaluators[VARIANTS[0]]
    ours.load(_network(*VARIANTS[0])[1])
    delta, omega = ours(T_GRID, P_GRID)
    for i, j in [(0, 0), (37, 101), (99, 200)]:
        d1, o1 = ours(T_GRID[j:j + 1], P_GRID[i:i + 1])
        np.testing.assert_array_equal(d1[0, 0], delta[i, j])
        np.testing.assert_array_equal(o1[0, 0], omega[i, j])


def test_threads_give_the_same_bits():
    arch, theta = _network(*VARIANTS[0])
    one, two = NumbaEvaluator(arch, threads=1), NumbaEvaluator(arch, threads=2)
    one.load(theta)
    two.load(theta)
    for a, b in zip(one(T_GRID, P_GRID), two(T_GRID, P_GRID)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("variant", [VARIANTS[0], VARIANTS[1], VARIANTS[4]])
def test_omega_is_the_time_derivative_of_delta(numba_evaluators, variant):
    """For one-output networks omega is d delta/dt: a central difference of delta agrees to ~1e-6."""
    ours = numba_evaluators[variant]
    ours.load(_network(*variant)[1])
    t, h = np.linspace(0.5, CASE.t_final - 0.5, 40), 1e-5
    _, omega = ours(t, P_GRID[::10])
    fd = (ours(t + h, P_GRID[::10])[0] - ours(t - h, P_GRID[::10])[0]) / (2 * h)
    np.testing.assert_allclose(omega, fd, rtol=0, atol=1e-6 * max(1.0, np.abs(omega).max()))


@pytest.mark.slow
def test_a_torch_saved_model_loads_without_the_framework(tmp_path):
    """A model fitted and saved by torch-pinn answers the same through `compiled_model`."""
    pytest.importorskip("torch")
    solver = make_solver("torch-pinn", CASE, **SMALL)
    solver.fit()
    solver.save(tmp_path / "model")
    ours = compiled_model(tmp_path / "model")
    for t, p in [(T_GRID, P_GRID), *POINTS]:
        traj = solver.solve(t, p)
        delta, omega = ours(t, p)
        _close(delta, traj.delta)
        _close(omega, traj.omega)


@pytest.mark.slow
def test_query_numba_through_the_adapter_equals_the_framework(tmp_path):
    """query="numba" trains the same model and answers the same queries as query="framework",
    after fit and after load (either backend's file)."""
    pytest.importorskip("jax")
    options = {**SMALL, "threads": 2}
    framework = make_solver("jax-pinn", CASE, query="framework", **options)
    compiled = make_solver("jax-pinn", CASE, query="numba", **options)
    framework.fit()
    compiled.fit()
    np.testing.assert_array_equal(compiled.theta, framework.theta)  # training ignores the option
    assert isinstance(compiled._evaluate, NumbaEvaluator)
    framework.save(tmp_path / "model")
    loaded = make_solver("jax-pinn", CASE, query="numba", threads=1).load(tmp_path / "model")
    assert isinstance(loaded._evaluate, NumbaEvaluator)
    for t, p in [(T_GRID, P_GRID), *POINTS]:
        a = framework.solve(t, p)
        for b in (compiled.solve(t, p), loaded.solve(t, p)):
            _close(b.delta, a.delta)
            _close(b.omega, a.omega)


@pytest.mark.parametrize("bad", ["jit", None, "Numba", 1])
def test_bad_query_raises(bad):
    pytest.importorskip("jax")
    with pytest.raises(ValueError, match="query"):
        make_solver("jax-pinn", CASE, query=bad)


def test_identification_networks_are_refused():
    arch = Architecture.of(PinnConfig(), CASE, identification=True)
    with pytest.raises(ValueError, match="identification"):
        NumbaEvaluator(arch)
    with pytest.raises(ValueError, match="theta"):
        NumbaEvaluator(_network(*VARIANTS[0])[0]).load(np.zeros(3))


@pytest.mark.parametrize("name", [pytest.param("jax-pinn", marks=pytest.mark.slow), "torch-pinn"])  # JAX: JIT
@pytest.mark.parametrize("query", ["framework", "numba"])
def test_solve_points_equals_one_point_queries(name, query):
    """A batch of scattered single points gives what one-point grid queries give, on every path."""
    pytest.importorskip(name.split("-")[0])
    solver = make_solver(name, SMIB_INFERENCE, query=query, max_iterations=3, progress=False, threads=1,
                         hidden_layers=2, width=8, n_f=100)
    solver.fit()
    rng = np.random.default_rng(5)
    t, p1 = rng.uniform(0, 20, 7), rng.uniform(0.08, 0.18, 7)
    points = solver.solve_points(t, p1)
    for i in range(7):
        one = solver.solve(t[i:i + 1], p1[i:i + 1])
        np.testing.assert_allclose(points.delta[i], one.delta[0, 0], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(points.omega[i], one.omega[0, 0], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("outputs, hard_ic", [(1, True), (2, True), (1, False), (2, False)])
def test_two_machines_and_start_states_equal_the_framework(outputs, hard_ic):
    """Two machines (n or 2n outputs): the grid, the points, and the time-marching calls with each
    P1's or point's own start state equal torch's float64 evaluator to 1e-12."""
    pytest.importorskip("torch")
    config = PinnConfig(hidden_layers=2, width=7, outputs=outputs, hard_ic=hard_ic)
    arch = Architecture.of(config, TWO)
    theta = init_theta(arch, 4) + 0.2 * np.random.default_rng(4).normal(size=arch.n_params)
    ours = NumbaEvaluator(arch)
    ours.load(theta)
    reference = make_solver("torch-pinn", TWO, threads=1)._make_evaluator(arch, "float64")
    reference.load(theta)
    t, p = np.linspace(0.0, 4.0, 37), np.linspace(0.25, 0.35, 5)
    for a, b in zip(ours(t, p), reference(t, p)):
        assert a.shape == (5, 37, 2)
        _close(a, b)
    rng = np.random.default_rng(0)
    t_s, p_s = rng.uniform(0, 4, 20), rng.uniform(0.25, 0.35, 20)
    for a, b in zip(ours.points(t_s, p_s), reference.points(t_s, p_s)):
        assert a.shape == (20, 2)
        _close(a, b)
    start_grid, start_points = rng.normal(size=(5, 2, 2)), rng.normal(size=(20, 2, 2))
    mine, theirs = ours.prepare(theta), reference.prepare(theta)
    for a, b in zip(ours.grid(mine, t, p, start_grid), reference.grid(theirs, t, p, start_grid)):
        _close(a, b)
    for a, b in zip(ours.pairs(mine, t_s, p_s, start_points), reference.pairs(theirs, t_s, p_s, start_points)):
        _close(a, b)
    if hard_ic:  # the start state is the state at the window's start
        delta, omega = ours.grid(mine, np.zeros(1), p, start_grid)
        np.testing.assert_array_equal(delta[:, 0], start_grid[:, 0])
        np.testing.assert_array_equal(omega[:, 0], start_grid[:, 1])


def test_a_marching_model_through_the_adapter_and_from_its_file(tmp_path):
    """query="numba" on a time-marching model: the windows of the same training, evaluated by numba,
    answer as the framework does (grid, single points, scattered points), after fit and from the
    saved file (`compiled_model`)."""
    pytest.importorskip("torch")
    options = {**SMALL, "hidden_layers": 1, "width": 6, "n_u": 2, "n_f": 30, "window": 1.5}
    framework = make_solver("torch-pinn", TWO, query="framework", **options)
    compiled = make_solver("torch-pinn", TWO, query="numba", **options)
    framework.fit()
    compiled.fit()
    np.testing.assert_array_equal(compiled.theta, framework.theta)  # training ignores the option
    assert compiled.theta.shape[0] == 3 and isinstance(compiled._evaluate, MarchingEvaluator)
    assert isinstance(compiled._evaluate.inner, NumbaEvaluator)
    framework.save(tmp_path / "model")
    from_file = compiled_model(tmp_path / "model")
    assert isinstance(from_file, MarchingEvaluator)
    t, p = np.linspace(0.0, 4.0, 41), np.array([0.25, 0.3, 0.35])
    a = framework.solve(t, p)
    for delta, omega in [tuple(compiled.solve(t, p)[2:]), from_file(t, p)]:
        _close(delta, a.delta)
        _close(omega, a.omega)
    one = compiled.solve(np.array([2.9]), 0.3)
    _close(one.delta[0, 0], framework.solve(np.array([2.9]), 0.3).delta[0, 0])
    points = compiled.solve_points(np.array([0.1, 1.5, 3.7]), np.array([0.26, 0.3, 0.34]))
    _close(points.delta, framework.solve_points(np.array([0.1, 1.5, 3.7]), np.array([0.26, 0.3, 0.34])).delta)
