"""The PINNs on a fault case (`PinnConfig.phases`, the fault-marching config): a fault-on chain of
windows in t, a post-fault chain in (t - t_c, t_c) starting from the fault-on state at t_c; tiny
networks and a few LM iterations on wscc9's textbook contingency (shapes, the initial state, the
switch, save/load, the refusals). Accuracy is measured by a script, not here (minutes of training)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from solvers import make_solver
from solvers.pinn import network
from solvers.pinn.common import PinnSolver
from solvers.pinn.config import CONFIGS, PinnConfig
from solvers.pinn.evaluator import SwitchedEvaluator
from solvers.pinn.problems import PhaseEdges, phase_edges, phase_problem
from systems.cases import CASES, FAULT_SCENARIO, NETWORK, STEP_SCENARIO, case_record
from systems.model import coupling

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE_NAME = "wscc9-bus8-line8-9"
# 2 x 8 networks on 60 points a window, 2 LM iterations each: 1 fault-on window and 2 pieces of
# clearing times, each 2 post-fault windows of 1.5 s
TINY = {"hidden_layers": 2, "width": 8, "n_f": 60, "max_iterations": 2, "window": 1.5, "pieces": 2, "threads": 1,
        "progress": False}


@pytest.fixture(scope="module")
def case():
    return CASES[CASE_NAME]


@pytest.fixture(scope="module")
def switched(case):
    """jax-pinn fault-marching on wscc9's fault case, a few LM iterations, and its FitReport."""
    pytest.importorskip("jax")
    solver = make_solver("jax-pinn", case, config="fault-marching", **TINY)
    return solver, solver.fit()


def test_phase_edges_and_training_points(case):
    """The fault-on windows span [0, p1_max] in t, the post-fault ones [0, t_final - p1_min] in
    tau; fault-on points sit at the constant scenario input, post-fault ones over the clearing times."""
    edges = phase_edges(case, 1.5, pieces=2)
    np.testing.assert_allclose(edges.on, [0.0, case.p1_max])
    np.testing.assert_allclose(edges.post, [0.0, 1.5, case.t_final - case.p1_min])
    np.testing.assert_allclose(edges.pieces, [case.p1_min, (case.p1_min + case.p1_max) / 2, case.p1_max])
    assert edges.count == 5
    config = PinnConfig(window=1.5, phases=True, n_u=0, n_f=50)
    on = phase_problem(config, case, edges, "on", 0, 0.2)
    post = phase_problem(config, case, edges, "post", 1, 0.2)
    assert (on.p_f == 0.2).all() and on.t_f.max() <= case.p1_max and on.t_u.size == 0
    assert post.p_f.min() >= case.p1_min and post.p_f.max() <= case.p1_max and np.ptp(post.p_f) > 0.3
    assert post.t_f.max() <= edges.post[2] - edges.post[1] and post.t_f.size == 50


def test_phase_physics_is_the_phase_network_at_the_case_powers(case):
    """Each phase's residual uses that phase's reduced network and P = p_m whatever the scenario
    input (the clearing time: no column of it enters the powers); a fault case has no single
    network to build a step's physics of."""
    for which in ("on", "post"):
        physics = network.Physics.of_phase(case, which)
        for got, want in zip(physics.coupling, coupling(case.phase(which))):
            np.testing.assert_array_equal(got, want)
        assert physics.phase == which and not physics.first.any()
        np.testing.assert_array_equal(physics.rest, case.p_m)
    assert not np.array_equal(network.Physics.of_phase(case, "on").coupling[0],
                              network.Physics.of_phase(case, "post").coupling[0])
    with pytest.raises(ValueError, match="fault case"):
        network.Physics.of(case)


def test_fault_model_shapes_and_initial_state(switched, case):
    solver, report = switched
    assert isinstance(solver.windows, PhaseEdges) and isinstance(solver._evaluate, SwitchedEvaluator)
    assert solver.theta.shape == (5, solver.arch.n_params) and solver.arch.sizes[-1] == case.n
    assert report.iterations == 10 and np.isfinite(report.loss)
    assert "1 fault-on windows" in report.message and "4 post-fault windows" in report.message
    t, t_c = np.linspace(0.0, case.t_final, 13), np.array([0.05, 0.18, 0.4])
    traj = solver.solve(t, t_c)
    assert traj.delta.shape == traj.omega.shape == (3, 13, case.n)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.broadcast_to(case.delta0, (3, case.n)), rtol=0, atol=1e-15)
    np.testing.assert_allclose(traj.omega[:, 0], np.broadcast_to(case.omega0, (3, case.n)), rtol=0, atol=1e-15)
    points = solver.solve_points(np.repeat(t, 3), np.tile(t_c, t.size))
    np.testing.assert_allclose(points.delta, traj.delta.transpose(1, 0, 2).reshape(-1, case.n), rtol=0, atol=1e-12)
    np.testing.assert_allclose(points.omega, traj.omega.transpose(1, 0, 2).reshape(-1, case.n), rtol=0, atol=1e-12)


def test_fault_on_phase_does_not_depend_on_the_clearing_time(switched, case):
    """Before the switch every clearing time answers the same state; after it they differ."""
    solver, _ = switched
    t, t_c = np.array([0.02, 0.04]), np.array([0.05, 0.2, 0.4])
    before = solver.solve(t, t_c)
    np.testing.assert_array_equal(before.delta, np.broadcast_to(before.delta[:1], before.delta.shape))
    after = solver.solve(np.array([1.0]), t_c)
    assert np.abs(np.diff(after.delta[:, 0], axis=0)).min() > 1e-9


def test_state_is_continuous_at_the_clearing_time(switched, case):
    """delta and omega just before t_c (the fault-on network) equal the post-fault start at t_c
    to rounding, while the acceleration switches network: the post-fault one is the post-fault
    chain's own, not the fault-on one's."""
    solver, _ = switched
    t_c = np.array([0.07, 0.18, 0.33])
    left = solver.solve_points(np.nextafter(t_c, 0.0), t_c)
    right = solver.solve_points(t_c, t_c)
    np.testing.assert_allclose(left.delta, right.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(left.omega, right.omega, rtol=0, atol=1e-12)
    h = 1e-4
    before = (left.omega - solver.solve_points(t_c - h, t_c).omega) / h
    after = (solver.solve_points(t_c + h, t_c).omega - right.omega) / h
    assert np.abs(after - before).max() > 1e-3


def test_fault_model_save_load_round_trip(switched, case, tmp_path):
    """The model file records the fault and both phases' window edges; loaded, it answers the same
    (the load path is the backends' shared one)."""
    solver, _ = switched
    target = solver.name
    _, meta = solver.save(tmp_path / "model")
    info = json.loads(meta.read_text())
    assert info["case"]["fault"]["name"] == case.fault.name
    assert info["windows"] == {"on": solver.windows.on.tolist(), "post": solver.windows.post.tolist(),
                               "pieces": solver.windows.pieces.tolist()}
    loaded = make_solver(target, case, config="fault-marching", threads=1).load(tmp_path / "model")
    assert case_record(loaded.case) == case_record(case) and loaded.pinn_config.phases
    t, t_c = np.linspace(0.0, case.t_final, 7), np.array([0.06, 0.3])
    a, b = solver.solve(t, t_c), loaded.solve(t, t_c)
    np.testing.assert_allclose(b.delta, a.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.omega, a.omega, rtol=0, atol=1e-12)


def test_configs_declare_and_check_their_scenario(case):
    """fault-marching is made for fault cases alone and every other config for steps alone, as the
    planner reads it (`made_for`) and as building the adapter checks it."""
    for config, options in CONFIGS.items():
        assert PinnSolver.CASE_SCENARIOS[config] == {FAULT_SCENARIO if options.get("phases") else STEP_SCENARIO}
    assert PinnSolver.made_for("fault-marching", NETWORK, FAULT_SCENARIO)
    assert not PinnSolver.made_for("fault-marching", NETWORK, STEP_SCENARIO)
    assert not PinnSolver.made_for("marching", NETWORK, FAULT_SCENARIO)
    with pytest.raises(ValueError, match="phases must be True .* use config fault-marching"):
        make_solver("torch-pinn", case, config="marching", threads=1)
    with pytest.raises(ValueError, match=r"phases must be False for case 'wscc9' \(a step case\)"):
        make_solver("torch-pinn", CASES["wscc9"], config="fault-marching", threads=1)
    with pytest.raises(ValueError, match="phases .* needs window set and n_u=0"):
        make_solver("torch-pinn", case, config="fault-marching", n_u=10)
    with pytest.raises(ValueError, match="option pieces needs phases=True"):
        make_solver("torch-pinn", CASES["wscc9"], config="marching", pieces=2)


def test_identification_refuses_a_fault_case(switched):
    from systems.cases import Observations

    solver, _ = switched
    obs = Observations(np.array([0.5, 1.0]), np.array([0.1, 0.2]), np.zeros((2, solver.case.n)))
    with pytest.raises(ValueError, match="identification on a fault case"):
        solver.identify(obs)


def test_pieces_map_clearing_times_onto_the_input_range(switched, case):
    """Each clearing time is answered by its piece's chain at its position in the piece, mapped
    onto the network's input range (an edge belongs to the piece above it)."""
    evaluator = switched[0]._evaluate
    middle = evaluator.pieces[1]
    np.testing.assert_allclose(evaluator.pieces, [case.p1_min, 0.225, case.p1_max], rtol=1e-15)
    t_c = np.array([case.p1_min, 0.2, middle, 0.3, case.p1_max])
    np.testing.assert_array_equal(evaluator.piece_of(t_c), [0, 0, 1, 1, 1])
    arch = evaluator.arch
    np.testing.assert_allclose(evaluator.position(0, np.array([case.p1_min, middle])), [arch.p_lo, arch.p_hi])
    np.testing.assert_allclose(evaluator.clearing_time(1, evaluator.position(1, t_c[2:])), t_c[2:], rtol=1e-15)


def test_the_planner_runs_each_pinn_config_on_its_scenario(case):
    from harness.run.plan import not_on_case
    from harness.settings import DEFAULT, SolverSpec

    fault, step = SolverSpec("jax-pinn", "fault-marching", seed=0), SolverSpec("jax-pinn", "marching", seed=0)
    assert not_on_case(fault, case, DEFAULT) is None and not_on_case(step, CASES["wscc9"], DEFAULT) is None
    assert not_on_case(fault, CASES["wscc9"], DEFAULT) == \
        "skipped: config fault-marching of jax-pinn is not made for network cases"
    assert not_on_case(step, case, DEFAULT) == "skipped: config marching of jax-pinn is not made for fault (t_c) cases"
