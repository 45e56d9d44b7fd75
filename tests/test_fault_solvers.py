"""The classical adapters on a fault case (wscc9-bus8-line8-9: 3 machines, cleared in [0.05, 0.40] s
on 3 s, critical clearing time ~0.18 s): the switch integrated exactly, against the reference."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import check_points_as_solves, fit_for_tests, require

from solvers import make_solver
from solvers.base import SolveError
from systems.cases import CASES, Observations
from systems.model import relative_angles, rhs
from systems.reference import reference

CASE = "wscc9-bus8-line8-9"
STABLE, UNSTABLE = 0.1, 0.3  # s, clearing times either side of the case's critical one
# name -> (options of its tight run, bound on the max abs error of the angles against the centre of
# inertia (rad) and of the speeds (rad/s) over t in [0, 3] s at STABLE and UNSTABLE, a few times
# what each measured: docs/fault-solvers.md)
TIGHT = {
    "numba-rk": ({}, 1e-7),
    "trapezoid": ({}, 1e-4),
    "scipy-rk45": ({}, 1e-7),
    "scipy-odeint": ({}, 1e-7),
    "casadi-cvodes": ({"threads": 1}, 1e-6),
}


@pytest.fixture(scope="module")
def case():
    pytest.importorskip("pandapower")
    return CASES[CASE]


@pytest.fixture(scope="module")
def fitted(case):
    """(name, config) -> the adapter at that config on the fault case (TIGHT's options), fitted
    (built once)."""
    solvers: dict = {}

    def get(name: str, config: str):
        if (name, config) not in solvers:
            require(name)
            solvers[name, config] = make_solver(name, case, config, **TIGHT[name][0])
            fit_for_tests(solvers[name, config])
        return solvers[name, config]

    return get


@pytest.fixture(scope="module")
def tight(fitted):
    """name -> the adapter at its "tight" config on the fault case, fitted (built once)."""
    return lambda name: fitted(name, "tight")


def _errors(case, delta, omega, ref_delta, ref_omega) -> tuple[float, float]:
    """Max abs error of the angles against the centre of inertia (rad) and of the speeds (rad/s)."""
    angles = np.abs(relative_angles(case, delta) - relative_angles(case, ref_delta)).max()
    return float(angles), float(np.abs(omega - ref_omega).max())


@pytest.mark.parametrize("name", TIGHT)
def test_matches_the_reference_with_clearing_times_in_any_order(case, tight, name):
    """A grid over [0, 3] s that holds both clearing times, t_c unsorted and repeated: every row as
    the reference's, a repeated t_c the same bits."""
    solver, bound = tight(name), TIGHT[name][1]
    t = np.concatenate([np.linspace(0.0, 3.0, 31), [UNSTABLE, STABLE, 0.15]])
    T_c = np.array([UNSTABLE, STABLE, UNSTABLE])
    traj = solver.solve(t, T_c)
    ref_delta, ref_omega = reference(case, t, T_c)
    assert traj.delta.shape == traj.omega.shape == (3, t.size, 3)
    angles, speeds = _errors(case, traj.delta, traj.omega, ref_delta, ref_omega)
    assert angles < bound and speeds < 10 * bound
    np.testing.assert_array_equal(traj.delta[0], traj.delta[2])
    np.testing.assert_array_equal(traj.delta[:, 0], np.broadcast_to(case.delta0, (3, 3)))
    assert np.abs(relative_angles(case, traj.delta[1])).max() < np.pi  # stable
    assert np.abs(relative_angles(case, traj.delta[0])).max() > np.pi  # unstable


@pytest.mark.parametrize("name", TIGHT)
def test_the_state_is_continuous_at_the_clearing_time_and_the_network_switches_there(case, tight, name):
    """Queries at t_c - 1e-9, t_c and t_c + 1e-9 s: one state (to its speed times 2e-9 s), the
    state at t_c the reference's; the slope of omega before t_c is the fault-on network's
    acceleration at that state, after it the post-fault network's (one-sided differences of 1e-3 s),
    which differ by far more than either difference's error."""
    solver, bound = tight(name), TIGHT[name][1]
    h = 1e-3
    t = STABLE + np.array([-1e-9, 0.0, 1e-9, -h, h])
    traj = solver.solve(t, STABLE)
    delta, omega = traj.delta[0], traj.omega[0]
    ref_delta, ref_omega = reference(case, [STABLE, 1.0], [STABLE])  # (a lone t_c trips the reference)
    assert _errors(case, delta[1:2], omega[1:2], ref_delta[0, :1], ref_omega[0, :1])[0] < bound
    np.testing.assert_allclose(delta[[0, 2]], delta[[1, 1]], rtol=0, atol=1e-8)
    np.testing.assert_allclose(omega[[0, 2]], omega[[1, 1]], rtol=0, atol=1e-6)
    y_c, P = np.concatenate([delta[1], omega[1]]), np.asarray(case.p_m)
    n = case.n
    on, post = rhs(case.phase("on"))(0.0, y_c, P)[n:], rhs(case.phase("post"))(0.0, y_c, P)[n:]
    slope_before, slope_after = (omega[1] - omega[3]) / h, (omega[4] - omega[1]) / h
    jump = np.abs(post - on).max()
    assert np.abs(slope_before - on).max() < 0.05 * jump
    assert np.abs(slope_after - post).max() < 0.05 * jump


@pytest.mark.parametrize("name", TIGHT)
def test_points_answer_as_solves_and_a_single_query_at_the_clearing_time(case, fitted, tight, name):
    """Pairs (t_i, t_c,i) as one-point solves and as one solve per t_c (`check_points_as_solves`):
    the same bits at the default config, but numba-rk's to a tenth of its tight bound, since it
    shares its fault-on phase across the call's t_c; one query at t = t_c, as a pair and as a
    solve, is the state at t_c of a longer solve."""
    if name == "numba-rk":
        check_points_as_solves(tight(name), atol=0.1 * TIGHT[name][1])
    else:
        check_points_as_solves(fitted(name, "default"))
    solver = tight(name)
    at_clearing = solver.solve_points([UNSTABLE, 2.0], [UNSTABLE, UNSTABLE])
    single = solver.solve([UNSTABLE], [UNSTABLE])
    longer = solver.solve([0.0, UNSTABLE, 2.0], [UNSTABLE])
    for delta in (at_clearing.delta[0], single.delta[0, 0]):
        np.testing.assert_allclose(delta, longer.delta[0, 1], rtol=0, atol=0.1 * TIGHT[name][1])


@pytest.mark.parametrize("name", TIGHT)
def test_a_negative_clearing_time_and_identification_are_refused(case, tight, name):
    solver = tight(name)
    with pytest.raises(ValueError, match="clearing time t_c must be >= 0"):
        solver.solve([0.0, 1.0], [0.1, -0.1])
    with pytest.raises(ValueError, match="clearing time t_c must be >= 0"):
        solver.solve_points([0.0, 1.0], [0.1, -0.1])
    obs = Observations([0.5, 1.0], [0.1, 0.1], [[0.2, 0.1, 0.0], [0.3, 0.1, 0.0]])
    with pytest.raises(ValueError, match="identification on a fault case is not supported"):
        solver.identify(obs)


@pytest.mark.parametrize(("name", "options"), [("numba-rk", {"max_steps": 20}), ("trapezoid", {"max_newton": 1})])
def test_a_failed_integration_names_the_clearing_time(case, name, options):
    require(name)
    solver = make_solver(name, case, threads=1, **options)
    solver.fit()
    with pytest.raises(SolveError, match=f"^{name}: integration failed at t_c=0.3: "):
        solver.solve([0.0, 3.0], [0.3])
    with pytest.raises(SolveError, match=f"^{name}: integration failed at t_c=0.3: "):
        solver.solve_points([3.0], [0.3])


def test_stacked_post_fault_calls_are_chunked_and_give_the_unchunked_states(case, monkeypatch):
    """`switched_states` stacks the post-fault phases of many clearing times in chunks whose output
    is bounded (STACKED_CELLS): the same states as one call per t_c, and no call larger than allowed."""
    from solvers.classical import fault_phases

    calls = []

    def integrate(phase, y0, times, T_c):  # a stand-in with the interface's shapes: y0 + t, exact
        calls.append(y0.shape[0] * times.size)
        return y0[:, None, :] + times[None, :, None] * (1.0 + np.arange(y0.shape[1]))

    t, T_c = np.linspace(0.0, 3.0, 41), np.linspace(0.05, 0.4, 37)[::-1]
    one_each = fault_phases.switched_states(integrate, case, t, T_c, stacked=False)
    monkeypatch.setattr(fault_phases, "STACKED_CELLS", 41 * 10 ** 2)  # chunks of 10 clearing times
    calls.clear()
    chunked = fault_phases.switched_states(integrate, case, t, T_c, stacked=True)
    np.testing.assert_allclose(chunked, one_each, rtol=0, atol=1e-12)
    assert len(calls) == 1 + 4 and max(calls[1:]) <= 10 * 10 * 41  # the fault-on call, then 4 chunks
