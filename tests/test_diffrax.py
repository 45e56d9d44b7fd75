"""The diffrax adapter: accuracy against the reference and a closed form (SMIB and a lossy
3-machine system), batch modes, constant step, identification of every machine's m and d with the
Jacobian through the solver, option checks, failures.

JIT compilation dominates the runtime: the shapes are chosen so that tests share compiled code
(queries of len(P1) = 16 and 4 are compiled sizes of `bucket`; the 3-machine tests share one
case, one observation layout and so one compilation of values and of sensitivities)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import THREE_MACHINES, max_rel, per_pair, points_queries, require

from harness.measure import metrics
from solvers import make_solver
from solvers.base import SolveError
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, Observations, standard_grid
from systems.reference import reference

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")

N_P1 = 16  # a compiled size of `bucket`: fit compiles what the queries use
SMALL_SHAPES = ((201, N_P1),)


def _fitted(case=SMIB_INFERENCE, config="default", shapes=SMALL_SHAPES, **options):
    require("diffrax")
    solver = make_solver("diffrax", case, config, **options)
    solver.FIT_SHAPES = shapes
    solver.FIT_POINTS = ()
    solver.fit()
    return solver


THREE = THREE_MACHINES
THREE_T, THREE_P1 = np.linspace(0.0, THREE.t_final, 64), np.linspace(THREE.p1_min, THREE.p1_max, 4)


@pytest.fixture(scope="module")
def tight():
    """The tight config, fitted on the grid's shapes (the default config shares its compiled code:
    the tolerances are arguments)."""
    return _fitted(config="tight", shapes=((201, 100), (201, N_P1), (1, 1)))


@pytest.fixture(scope="module")
def three_tight():
    """The tight config on the 3-machine case, compiled for the (64 t, 4 P1) grid."""
    return _fitted(THREE, "tight", shapes=((THREE_T.size, THREE_P1.size),))


@pytest.fixture(scope="module")
def three_obs() -> Observations:
    """80 noise-free samples of every machine's angle from the reference on the 3-machine grid:
    their layout pads to the grid's compiled size (64 t, 4 P1)."""
    delta, _ = reference(THREE, THREE_T, THREE_P1)
    rng = np.random.default_rng(7)
    i, j = np.unravel_index(rng.choice(THREE_P1.size * THREE_T.size, 80, replace=False),
                            (THREE_P1.size, THREE_T.size))
    return Observations(THREE_T[j], THREE_P1[i], delta[i, j])


@pytest.mark.slow
def test_tight_matches_reference_on_the_grid(tight):
    t, P1 = standard_grid(SMIB_INFERENCE)
    traj = tight.solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    assert traj.delta.shape == traj.omega.shape == (100, 201, 1)
    assert metrics.rel_l2(traj.delta, ref_delta) <= 1e-9
    assert metrics.rel_l2(traj.omega, ref_omega) <= 1e-8  # measured 1.6e-9


def test_default_is_ode45_like():
    solver = _fitted()
    assert (solver.options["rtol"], solver.options["atol"]) == (1e-3, 1e-6)
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=N_P1)
    error = metrics.rel_l2(solver.solve(t, P1).delta, reference(SMIB_INFERENCE, t, P1)[0])
    assert 1e-9 < error < 1e-2


def test_arbitrary_sizes_padded_order_and_time_zero(tight):
    t = np.array([3.0, 0.0, 19.5, 3.0, 7.0, 0.0, 0.2])  # 7 times, 5 P1: padded to 8 and 8
    P1 = np.array([0.08, 0.1, 0.13, 0.15, 0.18])
    traj = tight.solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=1e-9)
    assert (traj.delta[:, 1] == SMIB_INFERENCE.delta0).all()
    assert (traj.omega[:, 5] == SMIB_INFERENCE.omega0).all()


def test_linear_case_matches_closed_form():
    case = dataclasses.replace(SMIB_INFERENCE, b_inf=(0.0,))
    solver = _fitted(case, "tight")
    t, P1 = standard_grid(case, n_p1=N_P1)
    traj = solver.solve(t, P1)
    (m,), (d,), (delta0,), (omega0,) = case.m, case.d, case.delta0, case.omega0
    v = P1[:, None] / d
    decay = np.exp(-d * t / m)
    delta = delta0 + v * t + (omega0 - v) * (m / d) * (1.0 - decay)
    omega = v + (omega0 - v) * decay
    assert metrics.rel_l2(traj.delta[..., 0], delta) <= 1e-9
    assert metrics.rel_l2(traj.omega[..., 0], omega) <= 1e-9


@pytest.mark.slow
def test_three_machine_lossy_matches_reference(three_tight):
    """Every coupling term (G, B, unequal E) and the mechanical powers (generator 1 gets P1, the
    others p_m): measured max errors 3e-10 rad, 1.1e-9 rad/s."""
    traj = three_tight.solve(THREE_T, THREE_P1)
    ref_delta, ref_omega = reference(THREE, THREE_T, THREE_P1)
    assert traj.delta.shape == traj.omega.shape == (4, 64, 3)
    np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=1e-8)
    np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=1e-8)


def test_vmap_and_stacked_agree(three_tight):
    """On the 3-machine case: vmap batches the (n, n_p) powers one column per trajectory."""
    vmap = _fitted(THREE, "tight", shapes=((THREE_T.size, THREE_P1.size),), batch="vmap")
    a, b = three_tight.solve(THREE_T, THREE_P1), vmap.solve(THREE_T, THREE_P1)
    # their steps differ: the difference is the solvers' error at rtol 1e-10 (~1e-9 measured)
    np.testing.assert_allclose(a.delta, b.delta, rtol=0, atol=2e-8)
    np.testing.assert_allclose(a.omega, b.omega, rtol=0, atol=2e-8)


def test_constant_step_converges():
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=N_P1)
    ref_delta = reference(SMIB_INFERENCE, t, P1)[0]
    solver = _fitted(dt=1.0)
    assert [p["dt"] for p in solver.precision_sweep([1e-3] * 8)] == [1.0, 0.5, 0.2, 0.1, 0.05, 0.02]
    assert [p["dt"] for p in solver.precision_sweep([1e-3, 1e-6])] == [1.0, 0.5]  # as many as the tolerances
    errors = []
    for dt in (1.0, 0.5, 0.25):  # dt is an argument of the compiled code: no recompilation
        solver.options["dt"] = dt
        solver.fit()
        errors.append(metrics.rel_l2(solver.solve(t, P1).delta, ref_delta))
    assert errors[0] > 20 * errors[1] > 400 * errors[2]  # measured ~60x a halving (3e-8, 5e-10, 8e-12)
    assert errors[2] < 1e-10


def test_adaptive_precision_sweep_is_the_tolerance_sweep(tight):
    assert tight.precision_sweep([1e-4]) == [{"rtol": 1e-4, "atol": pytest.approx(1e-7)}]


@pytest.mark.slow
def test_identify_recovers_m_and_d(tight):
    """SMIB, noise-free: every time of the grid once, each at one of 16 P1. The layout is the
    (201, 16) grid `tight` compiled values for (SMIB_IDENTIFICATION has the inference case's
    coupling and initial state), so only the sensitivities compile here."""
    case = SMIB_IDENTIFICATION.with_params(0.18, 0.09)
    t, P1 = standard_grid(case, n_p1=N_P1)
    delta, _ = reference(case, t, P1)
    i = np.random.default_rng(1000).permutation(np.arange(t.size) % N_P1)  # every P1 used
    obs = Observations(t, P1[i], delta[i, np.arange(t.size)])
    est = make_solver("diffrax", SMIB_IDENTIFICATION, "tight").identify(obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (1,) and est.m_ci95.shape == (1, 2)
    assert max_rel(est.m, 0.18) < 1e-6  # measured 1e-9
    assert max_rel(est.d, 0.09) < 1e-6  # measured 9e-10


@pytest.mark.slow
def test_identify_recovers_every_machine(three_obs):
    """All six parameters of the lossy 3-machine case from noise-free angles (measured relative
    errors 4e-10 in m, 2e-9 in d; 20 s cold, most of it compiling the sensitivities, 0.9 s warm)."""
    require("diffrax")
    est = make_solver("diffrax", THREE, "tight").identify(three_obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (3,)
    assert max_rel(est.m, THREE.m) < 1e-6
    assert max_rel(est.d, THREE.d) < 1e-6


def test_machine_count_mismatch_names_obs_delta():
    require("diffrax")
    obs = Observations(THREE_T[:5], np.full(5, 0.15), np.zeros((5, 1)))
    with pytest.raises(ValueError, match=r"obs\.delta"):
        make_solver("diffrax", THREE, "tight").identify(obs)


def test_jacobian_equals_finite_differences(three_obs):
    """The sensitivities identify uses, w.r.t. all 2n parameters (same padded layout as the
    identification above, so the same compiled code)."""
    import jax

    from solvers.classical.common import ObservationLayout
    from solvers.classical.diffrax_ode import Structure, _compiled, _pad, bucket

    require("diffrax")
    solver = make_solver("diffrax", THREE, "tight")
    layout = ObservationLayout.of(three_obs)
    t, p1 = _pad(layout.t, bucket(layout.t.size)), _pad(layout.P1, bucket(layout.P1.size))
    values, sensitivities, points = solver._functions(Structure.of(THREE))
    assert (values, sensitivities, points) == _compiled(Structure.of(THREE), "dopri8", "stacked", True, 16384)
    # identification's trial cases share the compilation: only m, d (and p_m) differ
    assert Structure.of(THREE.with_params(0.5, 0.2)) == Structure.of(THREE)
    n, h = THREE.n, 1e-6
    theta = np.array(THREE.m + THREE.d)
    p_m = np.array(THREE.p_m)
    with jax.enable_x64(True):
        y, ok, jac = sensitivities(theta[:n], theta[n:], p_m, 1e-12, 1e-14, 0.0, t, p1)
        fd = []
        for col in range(2 * n):
            step = np.zeros(2 * n)
            step[col] = h
            plus, minus = (np.asarray(values(x[:n], x[n:], p_m, 1e-12, 1e-14, 0.0, t, p1)[0])
                           for x in (theta + step, theta - step))
            fd.append((plus - minus) / (2 * h))
    assert np.asarray(ok).all()
    jac, fd = np.asarray(jac), np.stack(fd, axis=-1)
    assert jac.shape == (p1.size, t.size, 2 * n, 2 * n)
    assert np.abs(jac - fd).max() <= 1e-5 * np.abs(fd).max()
    np.testing.assert_allclose(np.asarray(y)[..., :n], reference(THREE, t, p1)[0], rtol=0, atol=1e-9)


BAD_OPTIONS = [
    ("rtol", 0.0), ("rtol", -1e-3), ("rtol", float("nan")), ("rtol", "1e-3"), ("rtol", True),
    ("atol", float("inf")), ("atol", None),
    ("dt", 0.0), ("dt", -0.1), ("dt", "0.1"), ("dt", float("inf")),
    ("method", "rk4"), ("batch", "loop"),
    ("max_steps", 0), ("max_steps", 10.5), ("max_steps", True),
    ("m_bounds", (2.0, 0.02)), ("m_bounds", (0.0, 1.0)), ("m_bounds", 0.5), ("d_bounds", (0.1,)),
    ("d_bounds", (0.1, float("inf"))), ("threads", 0), ("threads", 2.0),
]


@pytest.mark.parametrize("option,value", BAD_OPTIONS)
def test_bad_options_raise_value_error_naming_the_option(option, value):
    require("diffrax")
    with pytest.raises(ValueError, match=f"option {option}"):
        make_solver("diffrax", SMIB_INFERENCE, **{option: value})


@pytest.mark.slow
def test_too_few_steps_raise_solve_error():
    """Stacked: the failing P1 is found by solving each alone (vmap names it directly)."""
    solver = _fitted(max_steps=5)
    with pytest.raises(SolveError, match=r"diffrax: .*failed at P1=0\.08.*max_steps=5"):
        solver.solve(np.linspace(0.0, 20.0, 201), np.linspace(0.08, 0.18, N_P1))


def test_failed_integration_names_p1(tight):
    with pytest.raises(SolveError, match=r"diffrax: .*failed at P1=1e\+308"):
        tight.solve([1.0, 20.0], [0.1, 1e308])


def test_fit_leaves_shapes_over_its_memory_cap_to_their_first_query(monkeypatch):
    """A cap of 0 bytes compiles nothing in fit; the first query then compiles and answers the same."""
    solver = make_solver("diffrax", THREE, "tight")
    monkeypatch.setattr(type(solver), "FIT_MAX_BYTES", 0)
    solver.fit()
    t, P1 = np.linspace(0.0, THREE.t_final, 11), np.array([THREE.p1_min, THREE.p1_max])
    ref_delta, _ = reference(THREE, t, P1)
    np.testing.assert_allclose(solver.solve(t, P1).delta, ref_delta, rtol=0, atol=1e-8)


@pytest.mark.slow
def test_solve_points_in_one_call_equals_one_point_solves(tight):
    """Pairs of distinct P1 (a duplicate among them) equal one-point solves; pairs sharing P1, one
    trajectory per P1 to its pairs' last time, equal them to the tolerance; scrambled order and
    t = 0 kept. Both queries pad to one compiled shape (10 P1 x 10 times)."""
    for pattern, atol in (("distinct", 1e-10), ("shared", 1e-8)):
        t, P1 = points_queries(SMIB_INFERENCE)[pattern]
        points = tight.solve_points(t, P1)
        delta, omega = per_pair(tight, t, P1)
        assert points.delta.shape == points.omega.shape == (t.size, 1)
        np.testing.assert_allclose(points.delta, delta, rtol=0, atol=atol)
        np.testing.assert_allclose(points.omega, omega, rtol=0, atol=atol)
        np.testing.assert_array_equal(points.delta[t == 0.0], 0.1)


def test_solve_points_over_its_memory_cap_integrates_per_p1(tight, monkeypatch):
    t, P1 = points_queries(SMIB_INFERENCE)["distinct"]
    monkeypatch.setattr(tight, "POINTS_MAX_BYTES", 0)
    points = tight.solve_points(t, P1)
    delta, omega = per_pair(tight, t, P1)
    np.testing.assert_array_equal(points.delta, delta)
    np.testing.assert_array_equal(points.omega, omega)


def test_failed_point_names_p1(tight):
    with pytest.raises(SolveError, match=r"diffrax: .*failed at P1=1e\+308"):
        tight.solve_points(np.array([1.0, 20.0, 5.0]), np.array([0.1, 1e308, 0.1]))
