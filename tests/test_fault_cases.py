"""Fault cases (`systems.cases.Fault`, `Case.scenario`, `Case.phase`, `systems.faults.fault_case`),
their reference trajectories across the switch, and the stability criterion and reference CCT
(`systems.stability`). The reduced networks themselves are tested in tests/test_faults_network.py."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from conftest import THREE_MACHINES

from systems.cases import CASES, FAULT_SCENARIO, STEP_SCENARIO, Case, Fault, case_record
from systems.faults import CLEARING_TIMES, FAULT_CASES, Contingency, FaultNetworks, fault_case
from systems.model import rhs
from systems.reference import reference
from systems.stability import ANGLE_LIMIT, is_unstable, max_coi_angle, reference_cct, reference_unstable

# Every fault case of wscc9 and kundur4, and ieee39's first (the one of its largest pre-fault flow).
CHECKED = ("wscc9-bus8-line8-9", "kundur4-bus7-line7-8a", "ieee39-bus22-line21-22")
EVERY = [name for names in FAULT_CASES.values() for name in names]


def _base(case: Case) -> Case:
    """The step case that `case` faults."""
    return next(CASES[base] for base, names in FAULT_CASES.items() if case.name in names)


def _state(case: Case, t: np.ndarray, t_c: float) -> np.ndarray:
    """The reference state [delta, omega] (len(t), 2n) of `case` cleared at t_c s."""
    delta, omega = reference(case, t, [t_c])
    return np.concatenate([delta[0], omega[0]], axis=1)


@pytest.mark.parametrize("name", CHECKED)
def test_a_fault_case_starts_at_rest_at_its_step_cases_equilibrium(name):
    """The pre-fault network, machines and equilibrium are the step case's, and there dy/dt = 0."""
    case = CASES[name]
    base = _base(case)
    assert (case.G, case.B, case.delta0, case.omega0, case.p_m) == (base.G, base.B, base.delta0, base.omega0, base.p_m)
    y0 = np.array(base.delta0 + base.omega0)
    assert np.abs(rhs(base)(0.0, y0, base.powers(np.array([base.p_m[0]]))[0])).max() <= 1e-10
    assert not any(base.omega0)


@pytest.mark.parametrize("name", CHECKED)
def test_the_reference_is_continuous_at_the_clearing_time_and_its_derivative_switches_network(name):
    """Around t_c the state is continuous; the one-sided derivatives (second-order differences, step
    1e-4 s) are the fault-on rhs on the left and the post-fault rhs on the right, at the state at
    t_c, and the two differ (the accelerations jump)."""
    case = CASES[name]
    t_c, h = 0.1, 1e-4
    y = _state(case, t_c + h * np.arange(-2.0, 3.0), t_c)
    P = np.array(case.p_m)
    on, post = rhs(case.phase("on"))(t_c, y[2], P), rhs(case.phase("post"))(t_c, y[2], P)
    left = (3 * y[2] - 4 * y[1] + y[0]) / (2 * h)
    right = (-3 * y[2] + 4 * y[3] - y[4]) / (2 * h)
    assert np.abs(y[3] - y[1]).max() <= 2 * h * np.abs(on).max()
    assert np.abs(left - on).max() <= 1e-4
    assert np.abs(right - post).max() <= 1e-4
    assert np.abs(on - post).max() >= 1.0
    assert np.array_equal(on[:case.n], post[:case.n])  # the angles' derivative, omega, does not jump


def test_the_reference_at_the_clearing_time_alone_is_the_state_there():
    """Queries at t_c only (a post-fault phase of zero length) give the fault-on phase's end state,
    the same as within a longer query."""
    case = CASES[CHECKED[0]]
    alone = _state(case, np.array([0.1, 0.1]), 0.1)
    within = _state(case, np.array([0.0, 0.1, 0.5]), 0.1)
    assert np.array_equal(alone[0], alone[1]) and np.abs(alone[0] - within[1]).max() <= 1e-10


@pytest.mark.parametrize("name", CHECKED)
def test_clearing_well_before_the_cct_is_stable_and_well_after_it_unstable(name):
    """20 ms either side of the reference CCT (to 10 ms), judged on the reference every 10 ms (not
    by the bisection's terminal event): the early clearing keeps every machine well within pi of
    the centre of inertia, the late one passes it and runs away."""
    case = CASES[name]
    cct = reference_cct(case, tol=1e-2)
    delta = reference(case, np.linspace(0.0, case.t_final, 301), [cct - 0.02, cct + 0.02])[0]
    angles = max_coi_angle(case, delta)
    assert is_unstable(case, delta).tolist() == [False, True]
    assert angles[0] < 0.75 * ANGLE_LIMIT and angles[1] > 2 * ANGLE_LIMIT


@pytest.mark.parametrize("name", EVERY)
def test_every_registered_fault_cases_cct_lies_inside_its_clearing_times(name):
    case = CASES[name]
    assert (case.p1_min, case.p1_max) == CLEARING_TIMES and case.scenario == FAULT_SCENARIO
    assert not reference_unstable(case, case.p1_min)
    assert reference_unstable(case, case.p1_max)


def test_the_reference_cct_brackets_the_switch_from_stable_to_unstable():
    case = CASES[CHECKED[1]]
    cct = reference_cct(case)
    assert not reference_unstable(case, cct - 1e-6) and reference_unstable(case, cct + 1e-6)
    assert abs(reference_cct(case, tol=1e-2) - cct) <= 1e-2


def test_the_criterion_on_a_hand_made_trajectory():
    """Machines of inertia 1, 1, 2 at angles x, -x, 0: their centre of inertia is 0, so the largest
    angle from it is x; shifting every angle alike changes nothing."""
    case = dataclasses.replace(THREE_MACHINES, m=(1.0, 1.0, 2.0))
    x = np.array([0.5, 3.0, 3.2])
    swing = np.stack([x, -x, np.zeros(3)], axis=1)  # (3 trajectories, 3 machines)
    delta = np.stack([np.zeros((3, 3)), swing, swing + 7.0], axis=1)  # (3 trajectories, 3 times, 3)
    assert np.allclose(max_coi_angle(case, delta), x)
    assert is_unstable(case, delta).tolist() == [False, False, True]
    with pytest.raises(ValueError, match=r"delta must be \(\.\.\., n_t, 3\)"):
        max_coi_angle(case, np.zeros((4, 2)))


def test_case_fault_scenario_and_phases():
    case = CASES[CHECKED[0]]
    base = _base(case)
    assert base.fault is None and base.scenario == STEP_SCENARIO and case.scenario.symbol == "t_c"
    assert np.array_equal(case.powers(np.array([0.1, 0.2])), np.tile(case.p_m, (2, 1)))
    for which in ("on", "post"):
        phase = case.phase(which)
        assert phase.fault is None and phase.network is None
        assert (phase.G, phase.B) == (getattr(case.fault, f"G_{which}"), getattr(case.fault, f"B_{which}"))
        assert np.array_equal(phase.powers(np.array([phase.p1_min])), np.array([case.p_m]))
    with pytest.raises(ValueError, match="phase must be 'on' or 'post', got 'pre'"):
        case.phase("pre")
    with pytest.raises(ValueError, match="'wscc9' is no fault case"):
        base.phase("on")


def test_case_records_round_trip_through_json():
    """A fault case's record is plain data: through JSON and back it rebuilds the same case; a step
    case's record has no 'fault' entry."""
    case = CASES[CHECKED[0]]
    record = json.loads(json.dumps(case_record(case)))
    assert record["fault"]["name"] == case.fault.name
    assert Case(**{**record, "fault": Fault(**record["fault"])}) == case
    assert "fault" not in case_record(_base(case))


def test_bad_fault_cases_name_what_is_wrong():
    case = CASES[CHECKED[0]]
    fault = case.fault
    with pytest.raises(ValueError, match=r"Case.fault.G_on must be \(3, 3\) for 3 machines"):
        dataclasses.replace(case, fault=dataclasses.replace(fault, G_on=fault.G_on[:2]))
    with pytest.raises(ValueError, match="Case.fault.B_post must be symmetric"):
        dataclasses.replace(case, fault=dataclasses.replace(fault, B_post=((0.0, 1.0, 0.0),) * 3))
    with pytest.raises(ValueError, match="Case.fault must be a systems.cases.Fault or None, got dict"):
        dataclasses.replace(case, fault=dataclasses.asdict(fault))
    smib = CASES["smib-inference"]
    one = Fault("x", ((0.0,),), ((0.0,),), ((0.0,),), ((0.0,),))
    with pytest.raises(ValueError, match="a fault case has no infinite bus"):
        dataclasses.replace(smib, fault=one)
    with pytest.raises(ValueError, match=r"clearing times \[p1_min, p1_max\] = \[0.05, 3.5\] s must lie in"):
        dataclasses.replace(case, p1_max=3.5)
    on, post = np.array(fault.B_on), np.array(fault.B_post)
    other = FaultNetworks(Contingency("other", 8, (8, 9)), np.array(case.G), 2 * np.array(case.B), 0 * on, on,
                          0 * post, post)
    with pytest.raises(ValueError, match="'wscc9': its network is not the pre-fault network of 'other'"):
        fault_case(_base(case), other)


def test_reference_cct_refuses_what_has_no_cct_inside_the_range():
    case = CASES[CHECKED[0]]  # its CCT: ~0.18 s
    with pytest.raises(ValueError, match="unstable at the shortest clearing time p1_min = 0.3 s"):
        reference_cct(dataclasses.replace(case, p1_min=0.3))
    with pytest.raises(ValueError, match="stable at the longest clearing time p1_max = 0.1 s"):
        reference_cct(dataclasses.replace(case, p1_max=0.1))
    with pytest.raises(ValueError, match="'wscc9' is no fault case"):
        reference_cct(CASES["wscc9"])
    with pytest.raises(ValueError, match="tol must be > 0 s, got 0.0"):
        reference_cct(case, tol=0.0)
    with pytest.raises(ValueError, match=r"t_c must lie in \(0, t_final = 3.0\) s, got 3.0"):
        reference_unstable(case, 3.0)
