"""The reduced-output PINN (`reduced-pinn`) and its bases (`solvers.classical.snapshots`, `linear_basis`)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import require

from solvers import make_solver
from solvers.classical.snapshots import chebyshev_nodes, pod_basis
from systems.cases import CASES, SMIB_INFERENCE
from systems.model import relative_angles
from systems.reference import reference

NAME = "reduced-pinn"
# a tiny budget: 2 windows of 5 s, a few LM iterations, 3 snapshots (the test checks behaviour)
TINY = {"window": 5.0, "max_iterations": 3, "snapshots": 3, "n_f": 4, "threads": 1}


@pytest.fixture(scope="module")
def wscc9():
    pytest.importorskip("pandapower")
    require(NAME, CASES["wscc9"])
    return CASES["wscc9"]


def test_chebyshev_nodes_span_the_range_and_need_two():
    nodes = chebyshev_nodes(0.1, 0.3, 5)
    assert nodes[0] == pytest.approx(0.1) and nodes[-1] == pytest.approx(0.3) and np.all(np.diff(nodes) > 0)
    with pytest.raises(ValueError, match="count must be at least 2"):
        chebyshev_nodes(0.1, 0.3, 1)


def test_pod_basis_keeps_what_the_rule_asks_and_refuses_more_modes_than_the_snapshots_span():
    rng = np.random.default_rng(0)
    directions = np.linalg.qr(rng.normal(size=(6, 3)))[0]
    snapshots = rng.normal(size=(40, 3)) * [10.0, 1.0, 1e-4] @ directions.T  # (40, 6) of rank 3
    three = pod_basis(snapshots, None, 1e-12)
    assert three.modes == 3 and three.energy == pytest.approx(1.0)
    np.testing.assert_allclose(three.vectors.T @ three.vectors, np.eye(3), atol=1e-12)
    two = pod_basis(snapshots, None, 1e-6)  # the third direction holds ~1e-10 of the norm
    assert two.modes == 2 and 1 - 1e-6 < two.energy < 1
    with pytest.raises(ValueError, match="option modes=7 is larger than the snapshots allow"):
        pod_basis(snapshots, 7, 1e-12)


def test_linear_basis_is_orthonormal_and_holds_the_response(wscc9):
    """The static response and the slowest swing modes hold most of a step's trajectories: on ieee39
    (10 machines) 5 of them leave 2.7e-2 of the deviations from delta0 (measured)."""
    from solvers.pinn.jax_reduced import linear_basis

    case = CASES["ieee39"]
    basis = linear_basis(case, 5)
    np.testing.assert_allclose(basis.vectors.T @ basis.vectors, np.eye(5), atol=1e-12)
    assert np.isnan(basis.energy)
    ref, _ = reference(case, np.linspace(0.0, case.t_final, 51), np.linspace(case.p1_min, case.p1_max, 3))
    deviation = ref - np.asarray(case.delta0)
    left = deviation - deviation @ basis.vectors @ basis.vectors.T
    assert np.linalg.norm(left) / np.linalg.norm(deviation) < 5e-2


def test_the_normal_equations_from_the_structure_are_those_of_the_jacobian(wscc9):
    """J^T J and J^T r assembled from the network's structure (data and physics rows) equal the
    products of the Jacobian that automatic differentiation forms, at random weights and points."""
    from solvers.pinn.reduced import Layout, WindowData, init_weights, window_functions

    rng = np.random.default_rng(1)
    k, n_u, n_f = 3, 11, 5
    basis = np.linalg.qr(rng.normal(size=(wscc9.n, k)))[0]
    layout = Layout((2, 7, 6, k), 1.0, wscc9.p1_min, wscc9.p1_max)

    def p1(size):
        return rng.uniform(wscc9.p1_min, wscc9.p1_max, size)

    data = WindowData(rng.uniform(0, 1, n_u), p1(n_u), *rng.normal(size=(4, n_u, k)),
                      rng.uniform(0, 1, n_f), p1(n_f), *0.1 * rng.normal(size=(2, n_f, k)))
    theta = init_weights(layout, 0) + 0.3 * rng.normal(size=layout.n_params)
    for rate_weight, rows in ((0.0, k * n_u), (0.2, 2 * k * n_u)):  # with the rates' rows and without
        functions = window_functions(wscc9, layout, basis, np.asarray(wscc9.delta0), data, 0.3, rate_weight)
        r, J = functions[0](theta), functions[1](theta)
        A, g = functions[2](theta, r)
        assert r.size == rows + k * n_f
        np.testing.assert_allclose(A, J.T @ J, rtol=0, atol=1e-12 * np.abs(J.T @ J).max())
        np.testing.assert_allclose(g, J.T @ r, rtol=0, atol=1e-12 * np.abs(J.T @ r).max())


@pytest.mark.parametrize(("case_name", "options", "message"), [
    ("smib", {}, "reduced-pinn is made for multi-machine cases; case 'smib-inference' is a smib case"),
    ("wscc9", {"snapshots": 1}, "option snapshots must be at least 2"),
    ("wscc9", {"modes": 4}, "option modes=4 is larger than the case's 3 machines allow"),
    ("wscc9", {"basis": "linear"}, "option basis='linear' is the physics-only basis: set data=False"),
    ("wscc9-bus8-line8-9", {}, "reduced-pinn does not integrate fault cases"),
])
def test_bad_input_is_one_line_naming_what_is_wrong(case_name, options, message):
    require(NAME, CASES["wscc9"])
    case = SMIB_INFERENCE if case_name == "smib" else CASES[case_name]
    with pytest.raises(ValueError, match=message) as error:
        make_solver(NAME, case, **options)
    assert "\n" not in str(error.value)


def test_the_same_seed_gives_the_same_model(wscc9):
    t, P1 = np.linspace(0.0, wscc9.t_final, 9), np.linspace(wscc9.p1_min, wscc9.p1_max, 3)
    answers = []
    for _ in range(2):
        solver = make_solver(NAME, wscc9, **TINY)
        report = solver.fit()
        answers.append(solver.solve(t, P1))
    assert "snapshots 3 x 201 times" in report.message and "2 windows" in report.message
    np.testing.assert_array_equal(answers[0].delta, answers[1].delta)
    np.testing.assert_array_equal(answers[0].omega, answers[1].omega)
    other = make_solver(NAME, wscc9, **TINY, seed=1)
    other.fit()
    assert not np.array_equal(other.solve(t, P1).delta, answers[0].delta)


@pytest.mark.slow
def test_queries_keep_the_contract_and_learn_the_case(wscc9):
    """Shapes, the initial state, points that agree with the grid, the trained domain enforced,
    and a trained model near the reference (the default config at 60 iterations a window, on one
    thread, seed 0: COI rel. L2 2.3e-4 in 18 s, measured with the stopping rule off; the bound
    leaves room for another BLAS)."""
    solver = make_solver(NAME, wscc9, threads=1, max_iterations=60)
    solver.fit()
    t, P1 = np.linspace(0.0, wscc9.t_final, 41), np.linspace(wscc9.p1_min, wscc9.p1_max, 4)
    traj = solver.solve(t, P1)
    assert traj.delta.shape == traj.omega.shape == (4, 41, 3)
    np.testing.assert_allclose(traj.delta[:, 0], np.tile(wscc9.delta0, (4, 1)), atol=1e-12)
    points = solver.solve_points(t[[5, 30]], P1[[1, 3]])
    np.testing.assert_allclose(points.delta, traj.delta[[1, 3], [5, 30]], atol=1e-12)
    np.testing.assert_allclose(points.omega, traj.omega[[1, 3], [5, 30]], atol=1e-12)
    ref, _ = reference(wscc9, t, P1)
    pred, truth = relative_angles(wscc9, traj.delta), relative_angles(wscc9, ref)
    assert np.linalg.norm(pred - truth) / np.linalg.norm(truth) < 2e-2
    with pytest.raises(ValueError, match="P1"):
        solver.solve(t, wscc9.p1_max + 1.0)


def test_a_saved_model_loads_back_with_the_same_answers_and_refuses_another_case(wscc9, tmp_path):
    from types import SimpleNamespace

    from harness.model_cache import fit_or_load

    t, P1 = np.linspace(0.0, wscc9.t_final, 9), np.linspace(wscc9.p1_min, wscc9.p1_max, 3)
    settings = SimpleNamespace(cache_dir=tmp_path, retrain=False)
    trained = make_solver(NAME, wscc9, **TINY)
    report = fit_or_load(trained, settings)
    loaded = make_solver(NAME, wscc9, **TINY)
    again = fit_or_load(loaded, settings)
    assert "(cached model)" in again.message and again.seconds == report.seconds
    np.testing.assert_array_equal(loaded.solve(t, P1).delta, trained.solve(t, P1).delta)
    np.testing.assert_array_equal(loaded.solve_points(t[:2], P1[:2]).omega, trained.solve_points(t[:2], P1[:2]).omega)
    trained.save(tmp_path / "model")
    with pytest.raises(ValueError, match="saved for case 'wscc9'"):
        make_solver(NAME, CASES["kundur4"], **TINY).load(tmp_path / "model")
    with pytest.raises(ValueError, match="its record differs"):
        make_solver(NAME, wscc9.with_params(1.0, 0.5), **TINY).load(tmp_path / "model")
    with np.load(tmp_path / "model.npz") as saved:
        arrays = {key: saved[key] for key in saved.files}
    arrays["thetas"][0, 0] = np.nan
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ValueError, match="bad.npz: holds non-finite weights"):
        make_solver(NAME, wscc9, **TINY).load(tmp_path / "bad")
    arrays["thetas"][0, 0] = 0.0
    np.savez(tmp_path / "short.npz", **{**arrays, "thetas": arrays["thetas"][:1]})
    with pytest.raises(ValueError, match=r"short.npz: thetas has shape \(1, "):
        make_solver(NAME, wscc9, **TINY).load(tmp_path / "short")
    import json

    options = json.loads(str(arrays["options"]))
    np.savez(tmp_path / "opts.npz", **{**arrays, "options": np.array(json.dumps({**options, "width": -3}))})
    with pytest.raises(ValueError, match="opts.npz: its options are not reduced-pinn's: .*width"):
        make_solver(NAME, wscc9, **TINY).load(tmp_path / "opts")
    np.savez(tmp_path / "wide.npz", **{**arrays, "options": np.array(json.dumps({**options, "width": 7}))})
    with pytest.raises(ValueError, match="wide.npz: its layers .* are not those of its options"):
        make_solver(NAME, wscc9, **TINY).load(tmp_path / "wide")
