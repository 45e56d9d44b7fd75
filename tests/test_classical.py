"""Accuracy and identification of the ODE-solver adapters against the tight reference: the SMIB
(n = 1) and a lossy 3-machine system built here."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import THREE_MACHINES, check_points_as_solves, max_rel

from harness.measure import metrics
from solvers import make_solver
from solvers.base import SolveError
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, Observations, standard_grid
from systems.reference import SEED_DIR, load_seed_reference, reference

CLASSICAL = ("scipy-rk45", "scipy-odeint", "casadi-cvodes")


THREE = THREE_MACHINES
THREE_T, THREE_P1 = np.linspace(0.0, THREE.t_final, 51), np.linspace(THREE.p1_min, THREE.p1_max, 4)


@pytest.mark.parametrize("name", CLASSICAL)
@pytest.mark.parametrize("batch", [None, "stacked"])
def test_tight_tolerance_matches_reference(name, batch):
    if batch and name != "scipy-rk45":
        pytest.skip("only scipy-rk45 has batch modes")
    options = {"batch": batch} if batch else {}
    solver = make_solver(name, SMIB_INFERENCE, "tight", **options)
    solver.fit()
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    traj = solver.solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    assert traj.delta.shape == traj.omega.shape == (12, 201, 1)
    assert metrics.rel_l2(traj.delta, ref_delta) <= 1e-8
    assert metrics.rel_l2(traj.omega, ref_omega) <= 1e-8


@pytest.mark.parametrize("name", CLASSICAL)
def test_default_tolerance_is_ode45_like(name):
    solver = make_solver(name, SMIB_INFERENCE)
    assert (solver.options["rtol"], solver.options["atol"]) == (1e-3, 1e-6)
    solver.fit()
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=5)
    error = metrics.rel_l2(solver.solve(t, P1).delta, reference(SMIB_INFERENCE, t, P1)[0])
    assert 1e-6 < error < 1e-2  # loose tolerances give a loose, but not a wrong, answer


@pytest.mark.parametrize("name", CLASSICAL)
def test_time_zero_only_returns_initial_state(name):
    solver = make_solver(name, SMIB_INFERENCE)
    solver.fit()
    traj = solver.solve([0.0, 0.0], [0.1, 0.15])
    np.testing.assert_allclose(traj.delta, 0.1)
    np.testing.assert_allclose(traj.omega, 0.1)


@pytest.mark.parametrize("name", CLASSICAL)
def test_three_machine_lossy_matches_reference(name):
    """Every coupling term (G, B, unequal E) and the mechanical powers (generator 1 gets P1, the
    others p_m), against the reference at tight tolerances; unsorted times with a repeat."""
    solver = make_solver(name, THREE, "tight")
    solver.fit()
    t = np.concatenate([THREE_T[::-1], [2.0]])
    traj = solver.solve(t, THREE_P1)
    ref_delta, ref_omega = reference(THREE, t, THREE_P1)
    assert traj.delta.shape == traj.omega.shape == (4, t.size, 3)
    # measured max errors: casadi-cvodes 2.7e-9 rad, 8.8e-9 rad/s
    np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=5e-8)
    np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=5e-8)


@pytest.mark.parametrize("options", [{"graph": "mx"}, {"method": "adams", "newton": "functional"}],
                         ids=["mx-graph", "adams"])
def test_casadi_s_other_graph_and_method_match_the_reference(options):
    """The matrix-expression model (the default from `MX_FROM_MACHINES` machines) is the same
    function as the scalar one; Adams with fixed-point iterations (the `adams` config) integrates
    the same system, at tight tolerances as close to the reference as BDF."""
    solver = make_solver("casadi-cvodes", THREE, "tight", **options)
    solver.fit()
    traj = solver.solve(THREE_T, THREE_P1)
    ref_delta, ref_omega = reference(THREE, THREE_T, THREE_P1)
    np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=5e-8)
    np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=5e-8)
    if options.get("graph") == "mx":  # the same CVODES run on the same function: equal to rounding
        sx = make_solver("casadi-cvodes", THREE, "tight", graph="sx")
        sx.fit()
        np.testing.assert_allclose(traj.delta, sx.solve(THREE_T, THREE_P1).delta, rtol=0, atol=1e-11)


def test_casadi_graph_auto_picks_by_the_number_of_machines():
    from solvers.classical.casadi_cvodes import MX_FROM_MACHINES

    assert make_solver("casadi-cvodes", THREE).graph == "sx" and THREE.n < MX_FROM_MACHINES
    assert make_solver("casadi-cvodes", THREE, graph="mx").graph == "mx"
    assert make_solver("casadi-cvodes", THREE, "adams").options["method"] == "adams"
    with pytest.raises(ValueError, match="graph"):
        make_solver("casadi-cvodes", THREE, graph="dense")


def _scattered(case, n=100, seed=0):
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, case.t_final, n)
    p1 = rng.uniform(case.p1_min, case.p1_max, n)
    # a few trajectories, each sampled at many times, and one sample per P1 elsewhere: any layout works
    delta = np.array([reference(case, [ti], [pi])[0][0, 0] for ti, pi in zip(t, p1)])  # (n, machines)
    return Observations(t, p1, delta)


def _grid_samples(case, n: int, seed: int) -> Observations:
    """`n` distinct noise-free points of the reference on `case`'s standard grid (100 x 201)."""
    t, P1 = standard_grid(case)
    delta, _ = reference(case, t, P1)
    rng = np.random.default_rng(seed)
    i, j = np.unravel_index(rng.choice(P1.size * t.size, n, replace=False), (P1.size, t.size))
    return Observations(t[j], P1[i], delta[i, j])


# scipy-rk45 identifies through the same `identify_by_simulation` as scipy-odeint (6.6 s more here)
@pytest.mark.slow
@pytest.mark.parametrize("name", ["scipy-odeint", "casadi-cvodes"])
def test_identify_recovers_m_and_d_from_tight_data(name):
    case = SMIB_IDENTIFICATION.with_params(0.18, 0.09)
    obs = _scattered(case, n=25)  # 25 distinct P1: casadi integrates one trajectory per P1
    est = make_solver(name, SMIB_INFERENCE, "tight").identify(obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (1,)
    assert max_rel(est.m, 0.18) < 1e-4
    assert max_rel(est.d, 0.09) < 1e-4
    assert est.seconds > 0 and est.iterations > 0


def test_casadi_identifies_every_machine():
    """All six parameters of the lossy 3-machine case from 40 noise-free samples of the three
    angles at 2 P1 (CVODES forward sensitivities for the 2n columns; measured relative errors
    5e-9 in m, 3e-8 in d, ~3 s)."""
    P1 = THREE_P1[[0, -1]]
    delta, _ = reference(THREE, THREE_T, P1)
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, P1.size, 40), rng.integers(0, THREE_T.size, 40)
    obs = Observations(THREE_T[j], P1[i], delta[i, j])
    est = make_solver("casadi-cvodes", THREE, "tight").identify(obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (3,) and est.m_ci95.shape == (3, 2)
    assert max_rel(est.m, THREE.m) < 1e-6
    assert max_rel(est.d, THREE.d) < 1e-6


@pytest.mark.parametrize("graph", ["sx", "mx"])
def test_casadi_sensitivities_equal_finite_differences(graph):
    """The forward sensitivities identify uses, unpacked to (P1, time, state, parameter) for all
    2n parameters, against central differences of the integrator (measured 4e-8 relative: the
    differences' own error at rtol 1e-10), on either expression graph."""
    solver = make_solver("casadi-cvodes", THREE, "tight", graph=graph)
    solver.fit()
    t, P1, n = THREE_T[1:20], THREE_P1[:3], THREE.n
    G = solver._identifiers(tuple(t), P1.size)
    theta = np.array(THREE.m + THREE.d)
    _, jac = solver._run(G, P1, THREE.powers(P1).T, np.repeat(theta[:, None], P1.size, axis=1))
    jac = jac.reshape(t.size, 2 * n, P1.size, 2 * n).transpose(2, 0, 1, 3)  # as `_identify` reads it
    h, fd = 1e-6, []
    for col in range(2 * n):
        step = np.zeros(2 * n)
        step[col] = h
        plus, minus = (solver._states(t, P1, x[:n], x[n:]) for x in (theta + step, theta - step))
        fd.append((plus - minus) / (2 * h))
    fd = np.stack(fd, axis=-1)  # (P1, time, state, parameter)
    assert np.abs(jac - fd).max() <= 1e-6 * np.abs(fd).max()


@pytest.mark.parametrize("name", CLASSICAL)
def test_machine_count_mismatch_names_obs_delta(name):
    obs = Observations(THREE_T[:5], np.full(5, 0.15), np.zeros((5, 1)))  # one column, three machines
    with pytest.raises(ValueError, match=r"obs\.delta"):
        make_solver(name, THREE, "tight").identify(obs)


@pytest.mark.parametrize("name", ["scipy-rk45", "scipy-odeint"])
def test_identify_at_ode45_tolerances(name):
    """rtol 1e-3: the finite-difference Jacobian needs a step of sqrt(rtol), not scipy's 1.5e-8
    (with it scipy-odeint was off by 18 % on this pair)."""
    from harness.settings import DEFAULT
    from systems.cases import IDENTIFICATION_PAIRS

    m, d = IDENTIFICATION_PAIRS[4]
    # a noise-free draw of the pair as the identification suite draws its pair 1 (n_u = 100, seed 1000 + 1)
    obs = _grid_samples(SMIB_IDENTIFICATION.with_params(m, d), DEFAULT.n_u, seed=1001)
    est = make_solver(name, SMIB_IDENTIFICATION).identify(obs)
    assert max_rel(est.m, m) < 5e-3
    assert max_rel(est.d, d) < 5e-3


# casadi: recovers tight data above, ~8 s here; scipy-rk45: the same least squares as scipy-odeint
@pytest.mark.slow
@pytest.mark.parametrize("name", ["scipy-odeint"])
def test_identify_on_the_papers_identification_data(name):
    t, P1, delta = load_seed_reference(SEED_DIR / "swingEquation_identification.mat")
    rng = np.random.default_rng(1)
    i, j = rng.integers(0, P1.size, 100), rng.integers(0, t.size, 100)
    est = make_solver(name, SMIB_IDENTIFICATION, "tight").identify(Observations(t[j], P1[i], delta[i, j]))
    # the paper's ode45 data carry ~1e-3 rad of error: that, not the method, limits the estimate
    assert max_rel(est.m, 0.25) < 2e-3
    assert max_rel(est.d, 0.15) < 2e-3


@pytest.mark.parametrize("name", CLASSICAL)
def test_identify_uses_omega_when_observed(name):
    """One state (t = 1 s, P1 = 0.14) observed twice: delta alone is one equation for two unknowns
    (the fit ends somewhere on a curve of (m, d)); delta and omega together pin (m, d) down."""
    case = SMIB_IDENTIFICATION
    t, P1 = np.array([1.0, 1.0]), np.array([0.14, 0.14])
    ref_delta, ref_omega = reference(case, t[:1], P1[:1])
    delta, omega = np.repeat(ref_delta[0], 2, axis=0), np.repeat(ref_omega[0], 2, axis=0)  # (2, 1)
    solver = make_solver(name, case, "tight")
    est = solver.identify(Observations(t, P1, delta, omega))
    assert max_rel(est.m, case.m) < 1e-6
    assert max_rel(est.d, case.d) < 1e-6
    without = solver.identify(Observations(t, P1, delta))  # the premise: delta alone does not do it
    assert max(max_rel(without.m, case.m), max_rel(without.d, case.d)) > 1e-2


@pytest.mark.parametrize("name", CLASSICAL)
def test_failed_integration_names_solver_and_p1(name):
    solver = make_solver(name, SMIB_INFERENCE)
    solver.fit()
    # finite but absurd: the state overflows and the step size collapses
    with pytest.raises(SolveError, match=rf"{name}: .*failed at P1=1e\+308"), np.errstate(all="ignore"):
        solver.solve([1.0, 20.0], [0.1, 1e308])


@pytest.mark.parametrize("name", CLASSICAL)
def test_solve_points_integrates_once_per_distinct_p1(name):
    """Pairs of distinct P1 (a duplicate pair among them) answer as one-point solves; pairs sharing
    P1 as one solve of that P1 at its pairs' times; scrambled order and t = 0 kept."""
    solver = make_solver(name, SMIB_INFERENCE)
    solver.fit()
    check_points_as_solves(solver, atol=1e-10)


@pytest.mark.parametrize("name", CLASSICAL)
def test_failed_point_names_solver_and_p1(name):
    solver = make_solver(name, SMIB_INFERENCE)
    solver.fit()
    with pytest.raises(SolveError, match=rf"{name}: .*failed at P1=1e\+308"), np.errstate(all="ignore"):
        solver.solve_points(np.array([1.0, 20.0, 5.0]), np.array([0.1, 1e308, 0.1]))
