"""trapezoid with the network kept sparse (`solvers.classical.kernels.trapezoid_sparse`): the reduced form's
trajectories to Newton's tolerance, P_e and each machine's own slope against the dense network's,
points and the parallel kernel against solves, Newton's failure, and the option `network`."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import check_points_as_solves

from solvers import make_solver
from solvers.base import SolveError
from solvers.classical import trapezoid
from solvers.classical.kernels import trapezoid as trapezoid_kernels
from solvers.classical.kernels import trapezoid_sparse
from solvers.classical.kernels.layout import system_array
from systems.cases import CASES, SMIB_INFERENCE, standard_grid

pytest.importorskip("numba")


def _fitted(case, **options):
    solver = make_solver("trapezoid", case, threads=1, **options)
    solver.fit()
    return solver


@pytest.mark.parametrize("name", ["wscc9", "ieee39"])
def test_sparse_gives_the_reduced_trajectories(name):
    """Both forms solve the same step equations, so they differ by Newton's tolerance: within 1e-10
    rad and rad/s at newton_tol 1e-12, and ~30-60x further apart at the default 1e-10 (the
    speeds, 2 x / h - omega0, carry the increments' error times 2 / h)."""
    case = CASES[name]
    t, P1 = standard_grid(case, n_p1=3, n_t=41)
    gaps = {}
    for tol in (1e-10, 1e-12):
        reduced, sparse = (_fitted(case, network=form, newton_tol=tol) for form in ("reduced", "sparse"))
        a, b = reduced.solve(t, P1), sparse.solve(t, P1)
        gaps[tol] = [np.abs(a.delta - b.delta).max(), np.abs(a.omega - b.omega).max()]
        assert sparse.stats[:, 2].sum() == 0 and (sparse.stats[:, 1] >= sparse.stats[:, 0]).all()
    assert max(gaps[1e-12]) < 1e-10, gaps
    assert max(gaps[1e-10]) < 1e-8 and gaps[1e-10][0] > 10 * gaps[1e-12][0], gaps


def test_power_and_own_slope_are_the_dense_networks():
    """At angles away from equilibrium, `trapezoid_sparse`'s P_e and each machine's own slope equal
    P_e and the diagonal of dP_e/d delta of the Kron-reduced network (ieee39)."""
    case = CASES["ieee39"]
    n = case.n
    system, _, net = trapezoid_sparse.prepare(case, False)
    delta = np.asarray(case.delta0) + np.random.default_rng(0).uniform(-0.5, 0.5, n)
    pe, slope = np.empty(n), np.empty(n)
    trapezoid_sparse._power(delta, pe, slope, system, net, n, np.empty(3 * n), np.empty(net.l_inv.size, complex))
    dense_pe, jac = np.empty(n), np.empty((n, n))
    trapezoid_kernels.network(delta, dense_pe, jac, True, system_array(case), n, True, np.empty(2 * n))
    np.testing.assert_allclose(pe, dense_pe, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(slope, np.diag(jac), rtol=1e-10, atol=1e-10)
    assert np.abs(jac - np.diag(np.diag(jac))).max() > 1.0  # the coupling left out is not nothing


def test_points_and_parallel_have_the_bits_of_solve_and_newton_failure_raises():
    solver = _fitted(CASES["wscc9"], network="sparse")
    check_points_as_solves(solver)
    t, P1 = np.array([7.5, 0.0, 2.0]), np.linspace(CASES["wscc9"].p1_min, CASES["wscc9"].p1_max, 3)
    serial, parallel = solver.solve(t, P1), _fitted(CASES["wscc9"], network="sparse", parallel=True).solve(t, P1)
    np.testing.assert_array_equal(parallel.delta, serial.delta)
    np.testing.assert_array_equal(parallel.omega, serial.omega)
    failing = _fitted(CASES["wscc9"], network="sparse", max_newton=1)
    with pytest.raises(SolveError, match=r"trapezoid: integration failed at P1=[^:]+: Newton did not converge "
                                         r".*\(step from t=0 s\)"):
        failing.solve([1.0], [CASES["wscc9"].p1_min])


def test_the_option_network(monkeypatch):
    """'auto' keeps the network sparse from `SPARSE_FROM_MACHINES` machines (100) on a case that
    carries it; 'sparse' needs one; other values are a one-line ValueError."""
    ieee39 = CASES["ieee39"]
    assert trapezoid.SPARSE_FROM_MACHINES == 100 > ieee39.n
    assert _fitted(ieee39).fit().message == "network: reduced"
    monkeypatch.setattr(trapezoid, "SPARSE_FROM_MACHINES", ieee39.n)
    assert _fitted(ieee39).fit().message.startswith("network: sparse (39 buses")
    assert _fitted(SMIB_INFERENCE).fit().message == ""
    with pytest.raises(ValueError, match="^trapezoid: option network='sparse' needs a case that carries its network"):
        make_solver("trapezoid", SMIB_INFERENCE, network="sparse", threads=1)
    with pytest.raises(ValueError, match="^trapezoid: option network must be [^\n]*$"):
        make_solver("trapezoid", ieee39, network="dense", threads=1)
