"""numba-rk: accuracy of each method against the reference and a closed form (the SMIB and a lossy
three-machine system, with and without an infinite bus), RK4's order, the sensitivities,
identification of every machine, option checks and failures."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from conftest import check_points_as_solves, per_pair

from harness.measure import metrics
from harness.suites.identification import observations
from solvers import make_solver
from solvers.base import SolveError
from solvers.classical.common import keeps_network_sparse
from solvers.classical.kernels import layout
from solvers.classical.kernels import rk as kernels
from solvers.classical.numba_rk import SPARSE_FROM_MACHINES
from systems.cases import CASES, SMIB_IDENTIFICATION, SMIB_INFERENCE, Case, Observations, standard_grid
from systems.reference import reference

pytest.importorskip("numba")

TIGHT = {"dop853": {}, "dopri5": {"method": "dopri5"}, "rk4": {"method": "rk4", "dt": 0.002}}

# A lossy three-machine system (Kron-reduced G and B with the usual signs: off-diagonal G < 0 and
# B > 0), started away from equilibrium. NET has no infinite bus: its mechanical powers do not
# balance the losses, so the angles also drift together. BUS ties machines 1 and 3 to an infinite
# bus through a lossy branch (g_inf, b_inf), the c_inf and s_inf terms of P_e.
NET = Case(
    name="three-machine lossy", m=(0.3, 0.2, 0.25), d=(0.1, 0.08, 0.12), delta0=(0.1, -0.05, 0.2),
    omega0=(0.1, 0.0, -0.1), p_m=(0.1, 0.05, -0.12), E=(1.05, 1.0, 0.98),
    G=((0.12, -0.05, -0.04), (-0.05, 0.10, -0.03), (-0.04, -0.03, 0.09)),
    B=((-2.1, 0.9, 0.7), (0.9, -1.8, 0.6), (0.7, 0.6, -1.6)),
    g_inf=(0.0, 0.0, 0.0), b_inf=(0.0, 0.0, 0.0), t_final=5.0, p1_min=0.08, p1_max=0.18,
    m_box=((0.05, 1.0),) * 3, d_box=((0.02, 0.5),) * 3,
)
BUS = dataclasses.replace(NET, name="three-machine lossy, infinite bus", g_inf=(0.05, 0.0, 0.02),
                          b_inf=(1.0, 0.0, 0.5))


def _fitted(config: str = "default", case=SMIB_INFERENCE, **options):
    solver = make_solver("numba-rk", case, config, **options)
    solver.fit()
    return solver


@pytest.mark.parametrize("method", TIGHT)
def test_tight_matches_reference(method):
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    traj = _fitted("tight", **TIGHT[method]).solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    assert metrics.rel_l2(traj.delta, ref_delta) <= 1e-9
    assert metrics.rel_l2(traj.omega, ref_omega) <= 1e-9


@pytest.mark.parametrize("method", TIGHT)
def test_linear_case_matches_closed_form(method):
    case = dataclasses.replace(SMIB_INFERENCE, b_inf=(0.0,))
    (m,), (d,), (delta0,), (omega0,) = case.m, case.d, case.delta0, case.omega0
    t, P1 = np.array([7.3, 0.0, 20.0, 2.5]), np.array([0.08, 0.18])
    traj = _fitted("tight", case=case, **TIGHT[method]).solve(t, P1)
    assert traj.delta.shape == traj.omega.shape == (2, 4, 1)
    v = P1[:, None] / d
    decay = np.exp(-d * t / m)
    np.testing.assert_allclose(traj.delta[..., 0],
                               delta0 + v * t + (omega0 - v) * (m / d) * (1 - decay), rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(traj.omega[..., 0], v + (omega0 - v) * decay, rtol=1e-9, atol=1e-11)


# (config, options, rel_l2 bound): tight at each method, and the ode45 tolerances and RK4's 0.1 s
ACCURACY = [pytest.param("tight", options, 1e-9, id=f"tight-{method}") for method, options in TIGHT.items()] + [
    pytest.param("default", {}, 1e-3, id="default"), pytest.param("rk4", {}, 1e-3, id="rk4-0.1s")]


@pytest.mark.parametrize("case", [NET, BUS], ids=["no-bus", "bus"])
@pytest.mark.parametrize("config,options,bound", ACCURACY)
def test_network_matches_reference(case, config, options, bound):
    """Every machine of a lossy three-machine system, generator 1 at P1 and the others at p_m."""
    t, P1 = np.array([5.0, 0.0, 1.3, 2.5, 4.0, 2.5]), np.array([0.08, 0.13, 0.18])
    traj = _fitted(config, case=case, **options).solve(t, P1)
    ref_delta, ref_omega = reference(case, t, P1)
    assert traj.delta.shape == traj.omega.shape == (3, 6, 3)
    assert metrics.rel_l2(traj.delta, ref_delta) <= bound
    assert metrics.rel_l2(traj.omega, ref_omega) <= bound


def test_network_points_and_parallel_batch():
    """solve_points gives (n_s, n) rows, each machine's state at its (t, P1) (to the tolerance: a
    P1 integrates to its own pairs' last time, with other steps than the grid's); the parallel
    kernel gives the serial one's bits."""
    solver = _fitted("tight", case=BUS)
    t, P1 = np.array([4.5, 0.7, 2.0]), np.array([0.09, 0.17, 0.09])
    points = solver.solve_points(t, P1)
    assert points.delta.shape == points.omega.shape == (3, 3)
    grid = solver.solve(np.unique(t), np.unique(P1))
    for i in range(3):
        row, col = np.searchsorted(np.unique(P1), P1[i]), np.searchsorted(np.unique(t), t[i])
        np.testing.assert_allclose(points.delta[i], grid.delta[row, col], rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(points.omega[i], grid.omega[row, col], rtol=1e-8, atol=1e-9)
    parallel = kernels.kernel(kernels.DOP853, False, True, BUS.n)
    states, failed, _ = parallel(grid.t, grid.P1, solver._system, solver._net, solver._options)
    assert failed == -1
    np.testing.assert_array_equal(states[0], grid.delta)
    np.testing.assert_array_equal(states[1], grid.omega)


@pytest.mark.parametrize("name", ["wscc9", "ieee39"])
def test_the_network_kept_sparse_gives_the_reduced_trajectories(name):
    """rk4 takes the same steps in both forms, so they differ by the rounding of P_e only; so do
    the points queries."""
    case = CASES[name]
    t, P1 = np.linspace(0.0, case.t_final, 21), np.array([case.p1_min, case.p1_max])
    reduced, sparse = (_fitted("rk4", case=case, network=form) for form in ("reduced", "sparse"))
    assert reduced._net is layout.NO_NETWORK and sparse._system.shape == (case.n, layout.COUPLING)
    assert reduced.fit().message == "network: reduced" and sparse.fit().message.startswith("network: sparse")
    for query in ("solve", "solve_points"):
        args = (t, P1) if query == "solve" else (t[::2], np.resize(P1, t[::2].size))
        a, b = getattr(reduced, query)(*args), getattr(sparse, query)(*args)
        for x, y in ((a.delta, b.delta), (a.omega, b.omega)):
            assert np.abs(x - y).max() <= 1e-10 * np.abs(x).max()
    assert not keeps_network_sparse("numba-rk", "auto", case, SPARSE_FROM_MACHINES)
    assert keeps_network_sparse("numba-rk", "auto", case, case.n)
    assert not keeps_network_sparse("numba-rk", "auto", SMIB_INFERENCE, 1)


def test_rk4_is_fourth_order():
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=3, n_t=41)
    ref = reference(SMIB_INFERENCE, t, P1)[0]
    errors = [metrics.max_abs(_fitted("rk4", dt=dt).solve(t, P1).delta, ref) for dt in (0.2, 0.1, 0.05)]
    for coarse, fine in itertools.pairwise(errors):
        assert 12.0 < coarse / fine < 20.0


def test_precision_sweep():
    steps = (0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001)
    assert _fitted("rk4").precision_sweep([1e-3] * 8) == [{"dt": dt} for dt in steps]
    assert _fitted("rk4").precision_sweep([1e-3, 1e-6, 1e-9]) == [{"dt": dt} for dt in steps[:3]]  # coarsest
    assert make_solver("numba-rk", SMIB_INFERENCE).precision_sweep([1e-4]) == [{"rtol": 1e-4, "atol": 1e-4 * 1e-3}]


@pytest.mark.parametrize("case", [SMIB_INFERENCE, NET, BUS], ids=["smib", "no-bus", "bus"])
@pytest.mark.parametrize("method", TIGHT)
def test_sensitivities_equal_finite_differences(method, case):
    """d(delta, omega)/d(m_1..n, d_1..n), every column, against central differences (step 1e-6)."""
    solver = _fitted("tight", case=case, **TIGHT[method])
    solver._prepare(sensitivities=True)  # fit leaves the sensitivity kernel to identify
    t, P1 = np.linspace(0.0, case.t_final, 9), np.array([0.1, 0.17])
    n = case.n

    def states(params):
        system = solver._system.copy()
        system[:, layout.M], system[:, layout.D] = params[:n], params[n:]
        out, failed, _ = solver._sensitivities(t, P1, system, layout.NO_NETWORK, solver._options)
        assert failed == -1
        # blocks: delta, omega, then d delta / d p_j, d omega / d p_j for each j -> p_j last
        return out[0], out[1], np.moveaxis(out[2::2], 0, -1), np.moveaxis(out[3::2], 0, -1)

    params = np.array([0.3, 0.12]) if n == 1 else np.concatenate([NET.m, NET.d]) * 1.1
    _, _, jd, jo = states(params)
    assert jd.shape == jo.shape == (2, 9, n, 2 * n)
    for col in range(2 * n):
        step = np.zeros(2 * n)
        step[col] = 1e-6
        (d_plus, o_plus, _, _), (d_minus, o_minus, _, _) = states(params + step), states(params - step)
        np.testing.assert_allclose(jd[..., col], (d_plus - d_minus) / 2e-6, rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(jo[..., col], (o_plus - o_minus) / 2e-6, rtol=1e-5, atol=1e-5)


def test_identify_recovers_m_and_d():
    obs = observations(SMIB_IDENTIFICATION.with_params(0.25, 0.15), 100, 0.0, seed=1000)
    est = make_solver("numba-rk", SMIB_INFERENCE, "tight").identify(obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (1,)
    assert metrics.rel_error(est.m[0], 0.25) < 1e-4
    assert metrics.rel_error(est.d[0], 0.15) < 1e-4


@pytest.mark.parametrize("case", [NET, BUS], ids=["no-bus", "bus"])
def test_identify_recovers_every_machine(case):
    """Every machine's m and d from noise-free reference angles on a small grid (60 samples)."""
    t, P1 = np.meshgrid(np.linspace(0.25, 5.0, 20), [0.08, 0.13, 0.18])
    delta, _ = reference(case, t[0], P1[:, 0])
    obs = Observations(t.ravel(), P1.ravel(), delta.reshape(-1, case.n))
    est = make_solver("numba-rk", case, "tight").identify(obs)
    assert est.success, est.message
    assert est.m.shape == est.d.shape == (3,) and est.m_ci95.shape == (3, 2)
    np.testing.assert_allclose(est.m, case.m, rtol=1e-6)
    np.testing.assert_allclose(est.d, case.d, rtol=1e-6)


def test_repeated_and_shuffled_times_and_parallel():
    t = np.array([12.0, 0.5, 7.25, 12.0, 0.0, 3.0])
    P1 = np.linspace(0.08, 0.18, 5)
    solver = _fitted("tight")
    serial = solver.solve(t, P1)
    parallel = kernels.kernel(kernels.DOP853, False, True)  # the kernel of parallel=True (compiles ~5 s)
    states, failed, _ = parallel(t, P1, solver._system, solver._net, solver._options)
    assert failed == -1
    assert serial.delta.shape == (5, 6, 1)
    np.testing.assert_array_equal(serial.delta, states[0])
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    np.testing.assert_allclose(serial.delta, ref_delta, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(serial.omega, ref_omega, rtol=1e-9, atol=1e-11)


BAD_OPTIONS = [
    ("rtol", 0.0), ("rtol", -1e-3), ("rtol", float("nan")), ("rtol", True), ("rtol", "1e-3"),
    ("atol", float("inf")), ("atol", None), ("dt", 0.0), ("dt", 25.0), ("dt", False),
    ("method", "euler"), ("max_steps", 0), ("max_steps", 1.5), ("threads", 0), ("threads", 10_000),
    ("parallel", 1), ("m_bounds", (0.5, 0.1)), ("m_bounds", (0.0, 1.0)), ("d_bounds", (0.1,)),
    ("d_bounds", (0.1, float("inf"))), ("d_bounds", "ab"), ("network", "dense"), ("network", "sparse"),
]


@pytest.mark.parametrize("option,value", BAD_OPTIONS)
def test_bad_options_raise_value_error_naming_the_option(option, value):
    with pytest.raises(ValueError, match=f"option {option}"):
        make_solver("numba-rk", SMIB_INFERENCE, **{option: value})


@pytest.mark.parametrize("method", TIGHT)
def test_too_few_steps_raises_solve_error_naming_p1(method):
    solver = _fitted(method=method, max_steps=5)
    with pytest.raises(SolveError, match=r"numba-rk: integration failed at P1=0\.13: more than max_steps"):
        solver.solve([1.0, 20.0], [0.13])
    with pytest.raises(SolveError, match=r"at P1=0\.15"):
        solver.solve([20.0], [0.15, 0.1])


def test_overflow_raises_solve_error():
    with pytest.raises(SolveError, match=r"failed at P1=1e\+308"), np.errstate(all="ignore"):
        _fitted().solve([1.0, 20.0], [0.1, 1e308])


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize(("method", "case"), [*((m, SMIB_INFERENCE) for m in TIGHT), ("dop853", BUS)])
def test_solve_points_in_one_call_has_the_bits_of_solve(method, case, parallel):
    """Pairs of distinct P1 (a duplicate among them) have the bits of one-point solves; pairs
    sharing P1 those of one solve of that P1 at its pairs' times, and so the per-pair solves' values
    to the tolerance; scrambled order and t = 0 kept."""
    solver = _fitted("tight", case, parallel=parallel, **TIGHT[method])
    t, P1, points = check_points_as_solves(solver)
    delta, omega = per_pair(solver, t, P1)
    np.testing.assert_allclose(points.delta, delta, rtol=0, atol=1e-8)
    np.testing.assert_allclose(points.omega, omega, rtol=0, atol=1e-8)


def test_failed_point_names_p1():
    with pytest.raises(SolveError, match=r"numba-rk: integration failed at P1=0\.15: more than max_steps"):
        _fitted(max_steps=5).solve_points(np.array([0.5, 20.0, 0.0]), np.array([0.1, 0.15, 0.15]))
    with pytest.raises(SolveError, match=r"failed at P1=1e\+308"), np.errstate(all="ignore"):
        _fitted(parallel=True).solve_points(np.array([1.0, 20.0]), np.array([0.1, 1e308]))
