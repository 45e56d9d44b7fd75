"""pinnsim on fault cases: the terminals' impedance from a reduced network, the steps aligned with 0
and t_c, and a tiny network (config "faults", the contract tests' budget) that answers a fault case
in the contract's shapes, continuous at the switch; structure, not accuracy."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("pandapower")

from conftest import small_options
from scipy.sparse.linalg import splu

from solvers import make_solver
from solvers.base import PartialSolveError, SolveError
from solvers.pinn.component import INPUTS
from solvers.pinn.pinnsim import FAULT_DOMAIN
from solvers.pinn.simulator import impedance
from solvers.pinn.simulator_faults import FAULT_ON, POST_FAULT, fault_schedule, impedances, reduced_impedance
from systems.cases import CASES, case_record
from systems.faults import FAULT_CASES
from systems.network import reduce_to_machines

SMALL = small_options("pinnsim")
FAULT = FAULT_CASES["wscc9"][0]  # wscc9-bus8-line8-9


@pytest.mark.parametrize("name", ["wscc9", "kundur4"])
def test_the_impedance_from_the_reduced_network_is_the_sparse_one(name):
    """Z = D^-1 - D^-1 Y_red D^-1 (D = diag(y)) is (Y_bb^-1) at the terminals, from the case's own
    G, B; and so for the network with a bus grounded (a fault's, reduced as `systems.faults` does)."""
    case = CASES[name]
    network, y = case.network, np.asarray(case.network.y)
    Z = impedance(network)
    np.testing.assert_allclose(reduced_impedance(case.G, case.B, y), Z, rtol=0, atol=1e-10 * np.abs(Z).max())
    Y, n, at = network.augmented(), case.n, np.asarray(network.at)
    bus = int(np.setdiff1d(np.arange(network.n_buses), at)[0])  # a bus without a machine
    keep = np.setdiff1d(np.arange(Y.shape[0]), [bus])
    G_on, B_on = reduce_to_machines(Y[keep][:, keep], n)
    rest = np.setdiff1d(np.arange(network.n_buses), [bus])  # the bus grounded: gone from Y_bb
    rhs = np.zeros((rest.size, n), complex)
    rhs[np.searchsorted(rest, at), np.arange(n)] = 1.0
    sparse_on = splu(network.Y_bb[rest][:, rest].tocsc()).solve(rhs)[np.searchsorted(rest, at)]
    np.testing.assert_allclose(reduced_impedance(G_on, B_on, y), sparse_on, rtol=0, atol=1e-10 * np.abs(Z).max())


def test_a_machine_whose_terminal_is_faulted_sees_zero_voltage():
    case = CASES["wscc9"]
    network = case.network
    Y, n = network.augmented(), case.n
    keep = np.setdiff1d(np.arange(Y.shape[0]), [int(network.at[0])])  # generator 1's own bus grounded
    Z_on = reduced_impedance(*reduce_to_machines(Y[keep][:, keep], n), np.asarray(network.y))
    # its terminal voltage is 0 whatever the EMFs, and its EMF reaches no other terminal
    assert max(np.abs(Z_on[0]).max(), np.abs(Z_on[:, 0]).max()) < 1e-12 * np.abs(Z_on).max()
    assert np.abs(Z_on[1:, 1:]).min() > 0.0  # the others still see each other


def test_a_fault_at_a_machines_terminal_is_refused_when_built():
    """Its terminal voltage is 0, so its angle's coefficients drop out of the Gauss-Newton step
    (a singular matrix: the first fault-on step's update is NaN): refused in one line, not solved."""
    network, fault = CASES["wscc9"].network, CASES[FAULT]
    Y = network.augmented()
    keep = np.setdiff1d(np.arange(Y.shape[0]), [int(network.at[0])])  # generator 1's own bus grounded
    G_on, B_on = reduce_to_machines(Y[keep][:, keep], fault.n)
    case = dataclasses.replace(fault, name="wscc9-gen1-terminal", fault=dataclasses.replace(
        fault.fault, name="gen1-terminal", G_on=tuple(map(tuple, G_on)), B_on=tuple(map(tuple, B_on))))
    with pytest.raises(ValueError, match=r"^pinnsim: case 'wscc9-gen1-terminal' faults machine 0's terminal bus "
                                         r"\(its voltage 0, its angle undetermined in the Gauss-Newton step\): "
                                         r"not supported$"):
        make_solver("pinnsim", case, "faults")


def test_a_fault_case_keeps_its_tie_admittances_out_of_its_record():
    case, step = CASES[FAULT], CASES["wscc9"]
    assert case.network is None and np.array_equal(np.asarray(case.fault.y), np.asarray(step.network.y))
    assert "y" not in case_record(case)["fault"]
    assert dataclasses.replace(case, fault=dataclasses.replace(case.fault, y=None)) == case
    np.testing.assert_array_equal(impedances(case)[FAULT_ON], reduced_impedance(case.fault.G_on, case.fault.B_on,
                                                                                 np.asarray(step.network.y)))


def test_the_steps_end_on_each_clearing_time_and_none_is_longer_than_h():
    t_c, h = np.array([0.05, 0.4, 0.17, 0.0]), 0.25
    schedule = fault_schedule(t_c, h, 3.0, 0.4, 0.0)
    k_on = 2  # ceil(0.4 / 0.25) fault-on steps for every t_c, ceil(3 / 0.25) = 12 post-fault ones
    assert schedule.lengths.shape == (4, k_on + 12) and schedule.phase.shape == (k_on + 12,)
    np.testing.assert_array_equal(schedule.edges[:, k_on], t_c)  # exactly on t_c
    np.testing.assert_array_equal(schedule.edges[:, 0], 0.0)
    np.testing.assert_allclose(schedule.edges[:, -1], 3.0, rtol=0, atol=1e-15)
    assert (schedule.lengths <= h).all() and (schedule.lengths >= 0).all()
    assert (schedule.phase[:k_on] == FAULT_ON).all() and (schedule.phase[k_on:] == POST_FAULT).all()
    # to reach 0.17 s: t_c = 0.05 needs its first post-fault step (t_c = 0.4 its first fault-on one)
    assert schedule.steps_to(0.17, h) == k_on + 1
    assert schedule.steps_to(3.0, h) == k_on + 12
    with pytest.raises(ValueError, match="clearing times"):
        fault_schedule(np.array([0.5]), h, 3.0, 0.4, 0.05)


def test_the_default_domain_refuses_a_fault_case_naming_the_config_that_holds_it():
    with pytest.raises(ValueError, match=r"^pinnsim: case 'wscc9-bus8-line8-9' has fault-on terminal voltages in "
                                         r"\[.*\] p\.u\. at t = 0, outside the trained domain's v0 \[0\.85, 1\.2\] "
                                         r"p\.u\.; config 'faults' trains a domain for fault cases$"):
        make_solver("pinnsim", FAULT)


@pytest.mark.parametrize("h", [0.3, 1.0])
def test_a_step_outside_the_trained_range_is_one_line_on_a_fault_case(h):
    with pytest.raises(ValueError, match=r"^pinnsim: option h=.* s is outside \(0, h_max = 0.25\] s$"):
        make_solver("pinnsim", FAULT, "faults", h=h)


def test_the_faults_config_is_planned_on_fault_cases_only():
    cls = type(make_solver("pinnsim", FAULT, "faults"))
    case = CASES[FAULT]
    assert cls.handles_faults and cls.made_for("faults", case.kind, case.scenario)
    assert not cls.made_for("faults", case.kind) and not cls.made_for("default", case.kind, case.scenario)
    assert make_solver("pinnsim", FAULT, "faults").domain.v0 == (FAULT_DOMAIN["v0_min"], FAULT_DOMAIN["v0_max"])


@pytest.fixture(scope="module")
def fitted():
    """pinnsim, config "faults", on the contract tests' budget (its network trained once, ~30 s,
    then loaded from the default component_dir), fitted on wscc9's fault case; at h = 0.25 s, the
    config's retry step, so that no step is retried (the config's 0.1 s takes 2.5 times the steps;
    the retry's tests are below)."""
    solver = make_solver("pinnsim", FAULT, "faults", **{**SMALL, "h": 0.25})
    solver.fit()
    return solver


def test_a_fault_case_answers_in_the_contracts_shapes(fitted):
    case = fitted.case
    t, T_c = np.array([0.0, 0.1, 1.0, 2.5]), np.array([0.15, 0.1])
    traj = fitted.solve(t, T_c)
    assert traj.delta.shape == traj.omega.shape == (2, 4, 3)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.tile(case.delta0, (2, 1)), atol=1e-12)
    points = fitted.solve_points(np.array([1.0, 0.1]), T_c)
    assert points.delta.shape == points.omega.shape == (2, 3)
    np.testing.assert_allclose(points.delta, [traj.delta[0, 2], traj.delta[1, 1]], atol=1e-10)


def test_the_state_is_continuous_at_the_clearing_time_on_a_step_edge(fitted):
    """The machines' angle and speed carry over t_c (the voltage jumps there: the next step starts
    from the post-fault network's), and t_c is the edge of a step of each clearing time's query."""
    for t_c in (0.1, 0.15):
        _, _, _, _, edges, _ = fitted._simulate(fitted.options["h"], t_c + 0.5, np.array([t_c]))
        assert t_c in edges[0]
        near = fitted.solve(np.array([t_c - 1e-7, t_c, t_c + 1e-7]), t_c)
        np.testing.assert_allclose(near.delta[0, 1:], near.delta[0, :2], rtol=0, atol=1e-5)  # |omega| < 100 rad/s
        np.testing.assert_allclose(near.omega[0, 1:], near.omega[0, :2], rtol=0, atol=1e-3)


def test_a_newton_failure_names_the_phase_the_step_and_t_c():
    solver = make_solver("pinnsim", FAULT, "faults", **{**SMALL, "max_newton": 1})
    solver.fit()
    with pytest.raises(SolveError, match=r"^pinnsim: Gauss-Newton did not converge at fault-on step 1 \(t = 0 s\) "
                                         r"for t_c = 0\.1 after 1 iterations: last update .*$"):
        solver.solve(np.array([0.0, 1.0]), 0.1)


def test_a_machine_that_slips_out_of_the_domain_names_the_step_t_c_and_the_input(fitted):
    """Past the reference CCT (`systems.stability.reference_cct`, inside the range) a machine slips
    poles: its inputs leave any trained box, and the query is refused in one line naming the step,
    its phase, t_c and the input (or the Newton that fails first there), never answered from outside
    the domain."""
    inputs = "|".join(INPUTS[1:])
    with pytest.raises(SolveError, match=rf"^pinnsim: (Gauss-Newton did not converge )?at (fault-on|post-fault) step "
                                         rf"\d+ \(t = [0-9.]+ s\) for t_c = 0\.35( a machine's ({inputs}) leaves the "
                                         r"component's trained domain| after .*)"
                                         r"( \(at h = 0\.(25|1) s; steps tried \[0\.1, 0\.25\]\))?$"):
        fitted.solve(np.linspace(0.0, 3.0, 31), 0.35)


def test_a_refused_call_carries_each_trajectory_up_to_its_first_failed_step(fitted):
    """The refusal (`PartialSolveError`) holds each clearing time's angles before its first failed
    step, the same as a query that stops before it, and NaN from that step's start on; a clearing
    time that failed nowhere is whole."""
    t, T_c = np.linspace(0.0, 3.0, 301), np.array([0.1, 0.35])
    with pytest.raises(PartialSolveError) as caught:
        fitted.solve(t, T_c)
    error = caught.value
    assert error.delta.shape == (2, t.size, fitted.case.n) and np.isinf(error.held[0]) and error.held[1] < 3.0
    np.testing.assert_allclose(error.delta[0], fitted.solve(t, T_c[0]).delta[0], atol=1e-12)
    before = t < error.held[1]
    assert np.isnan(error.delta[1, ~before]).all() and np.isfinite(error.delta[1, before]).all()
    if before.sum() > 1:  # the part that held is what a query of those times alone answers
        np.testing.assert_allclose(error.delta[1, before], fitted.solve(t[before], T_c[1]).delta[0], atol=1e-12)


def test_a_retry_step_outside_the_trained_range_is_one_line():
    with pytest.raises(ValueError, match=r"^pinnsim: option retry_h has a step 0\.5 s outside \(0, h_max = 0.25\] s$"):
        make_solver("pinnsim", FAULT, "faults", retry_h=[0.1, 0.5])


def _failing(solver, fail: dict[float, dict[float, float]]):
    """`solver._simulate` in which, at each step h named, each P1 value named fails at its time (s)
    (a made failure, as a machine leaving the domain there); everything else as simulated."""
    real = solver._simulate

    def simulate(h, t_max, P1, check=True):
        out = real(h, t_max, P1, check)
        if not check or not any(value in P1 for value in fail.get(h, {})):
            return out
        held = np.full(P1.size, np.inf) if out[5] is None else out[5][1].copy()
        why = [None] * P1.size if out[5] is None else list(out[5][0])
        for value, at in fail[h].items():
            for i in np.flatnonzero(P1 == value):
                held[i], why[i] = min(held[i], at), f"made to fail at h = {h} for {value}"
        return (*out[:5], (why, held))
    return simulate


def _fitted(**options):
    """The faults config at h = 0.25 s unless `options` say otherwise (its retry step, 0.1 s, differs)."""
    solver = make_solver("pinnsim", FAULT, "faults", **{**SMALL, "h": 0.25, **options})
    solver.fit()
    return solver


def test_a_refused_clearing_time_is_answered_at_the_first_retry_step_that_holds(monkeypatch):
    """retry_h: a P1 that fails at h is simulated again at each retry step in turn and answered from
    the first one that holds throughout; every other P1 keeps its answer at h; points too. The
    failing P1 is the second, so that its row in a retry (the first) is not its row in the call."""
    solver = _fitted(retry_h=[0.2, 0.1])
    h = solver.options["h"]
    monkeypatch.setattr(solver, "_simulate", _failing(solver, {h: {0.15: 0.5}, 0.2: {0.15: 0.3}}))
    t, T_c = np.linspace(0.0, 2.0, 21), np.array([0.1, 0.15])
    traj = solver.solve(t, T_c)
    at = {step: _fitted(h=step, retry_h=[]) for step in (h, 0.1)}
    np.testing.assert_allclose(traj.delta[1], at[0.1].solve(t, T_c[1]).delta[0], atol=1e-12)
    np.testing.assert_allclose(traj.delta[0], at[h].solve(t, T_c[0]).delta[0], atol=1e-12)
    assert np.abs(traj.delta[1] - at[h].solve(t, T_c[1]).delta[0]).max() > 1e-6  # the steps differ
    points = solver.solve_points(np.array([1.0, 0.7, 1.5]), np.array([0.15, 0.1, 0.15]))
    np.testing.assert_allclose(points.delta, [traj.delta[1, 10], at[h].solve(np.array([0.7]), 0.1).delta[0, 0],
                                              traj.delta[1, 15]], atol=1e-10)


@pytest.mark.parametrize(("retry_at", "longest"), [(0.3, 0.5), (0.8, 0.8)], ids=["h-longer", "retry-longer"])
def test_where_every_step_fails_the_refusal_carries_the_attempt_that_held_longest(monkeypatch, retry_at, longest):
    solver = _fitted(retry_h=[0.1])
    h = solver.options["h"]
    monkeypatch.setattr(solver, "_simulate", _failing(solver, {h: {0.15: 0.5}, 0.1: {0.15: retry_at}}))
    t = np.linspace(0.0, 2.0, 21)
    step = h if longest == 0.5 else 0.1
    with pytest.raises(PartialSolveError, match=rf"^made to fail at h = {step} for 0\.15 \(at h = {step:g} s; steps "
                                                rf"tried \[{h}, 0\.1\]\)$") as caught:
        solver.solve(t, np.array([0.1, 0.15]))
    error = caught.value
    assert error.held[1] == longest and np.isinf(error.held[0])
    before = t < longest
    alone = _fitted(h=step, retry_h=[]).solve(t, 0.15).delta[0]
    np.testing.assert_allclose(error.delta[1, before], alone[before], atol=1e-12)
    assert np.isnan(error.delta[1, ~before]).all()
    with pytest.raises(SolveError, match=rf"^made to fail at h = {step} for 0\.15 "):
        solver.solve_points(np.array([1.0]), np.array([0.15]))


def test_without_retry_steps_a_refusal_is_the_steps_own_and_a_repeated_step_is_not_tried_again(monkeypatch):
    solver = _fitted(retry_h=[])
    h = solver.options["h"]
    monkeypatch.setattr(solver, "_simulate", _failing(solver, {h: {0.15: 0.5}}))
    with pytest.raises(PartialSolveError, match=rf"^made to fail at h = {h} for 0\.15$"):
        solver.solve(np.linspace(0.0, 2.0, 21), np.array([0.15]))
    again = _fitted(retry_h=[h, 0.1, 0.1])
    monkeypatch.setattr(again, "_simulate", _failing(again, {h: {0.15: 0.5}, 0.1: {0.15: 0.5}}))
    with pytest.raises(PartialSolveError, match=rf"steps tried \[{h}, 0\.1\]\)$"):
        again.solve(np.linspace(0.0, 2.0, 21), np.array([0.15]))
