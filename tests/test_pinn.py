"""Tests of the PINN adapters (torch-pinn, jax-pinn): physics, backend equivalence, persistence,
training, identification and the solver contract. Small networks and budgets throughout."""

from __future__ import annotations

import numpy as np
import pytest

from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, Observations
from harness.metrics import rel_l2
from systems.model import smib_system
from systems.reference import reference
from solvers import SOLVERS, make_solver
from solvers.base import NotFittedError
from solvers.pinn import network, spec
from solvers.pinn.common import _progress_enabled

# torch.func's first jvp registers decompositions through torch.jit.script, deprecated in torch 2.13
pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE = SMIB_INFERENCE
BACKENDS = {"torch-pinn": "torch", "jax-pinn": "jax"}
# for tests whose JAX run is slow (JIT compilation, > 2 s) and whose torch run is not
BACKENDS_SLOW_JAX = ["torch-pinn", pytest.param("jax-pinn", marks=pytest.mark.slow)]
# tiny networks and budgets; threads=1 because 2-thread ops stall on a busy 2-core machine
SMALL = {"hidden_layers": 2, "width": 8, "n_u": 20, "n_f": 150, "max_iterations": 3, "threads": 1,
         "id_hidden_layers": 2, "id_width": 8, "id_n_f": 100, "id_max_iterations": 3}


def _need(name: str) -> None:
    pytest.importorskip(BACKENDS[name])


def _ops(name: str):
    """The backend's Ops, a float64 array constructor and a to-numpy function; "torch-autograd"
    is torch with reverse-mode t-derivatives (the loss-gradient path)."""
    _need("torch-pinn" if name == "torch-autograd" else name)
    if name in ("torch-pinn", "torch-autograd"):
        import torch

        from solvers.pinn.torch_pinn import OPS, OPS_AUTOGRAD
        return ((OPS if name == "torch-pinn" else OPS_AUTOGRAD),
                (lambda x: torch.as_tensor(np.asarray(x), dtype=torch.float64)),
                (lambda x: x.detach().numpy()))
    import jax
    import jax.numpy as jnp

    from solvers.pinn.jax_pinn import OPS

    def array(x):
        with jax.enable_x64(True):
            return jnp.asarray(np.asarray(x), dtype=np.float64)
    return OPS, array, np.asarray


def _x64(name: str):
    if name == "jax-pinn":
        import jax
        return jax.enable_x64(True)
    import contextlib
    return contextlib.nullcontext()


@pytest.fixture(scope="module", params=list(BACKENDS))
def fitted(request):
    """A tiny model of each backend, fitted for 3 iterations."""
    _need(request.param)
    solver = make_solver(request.param, CASE, **SMALL)
    solver.fit()
    return solver


# ---- physics ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", [*BACKENDS, "torch-autograd"])
def test_swing_residual_of_a_known_function(name):
    """The residual by nested forward-mode autodiff equals the analytic one for a known delta(t)."""
    ops, array, to_np = _ops(name)
    system = smib_system(CASE)
    t_np = np.linspace(0.0, 20.0, 41)
    p_np = np.linspace(0.08, 0.18, 41)
    m, d, b = CASE.m, CASE.d, CASE.b
    delta = 0.1 + 0.3 * np.sin(0.7 * t_np) + 0.01 * t_np ** 2
    delta_t = 0.21 * np.cos(0.7 * t_np) + 0.02 * t_np
    delta_tt = -0.147 * np.sin(0.7 * t_np) + 0.02
    omega = 0.2 * np.cos(0.5 * t_np)
    omega_t = -0.1 * np.sin(0.5 * t_np)
    with _x64(name):
        t, p = array(t_np), array(p_np)

        def one(s):
            return (0.1 + 0.3 * ops.sin(0.7 * s) + 0.01 * s * s,)

        def two(s):
            return one(s)[0], 0.2 * ops.sin(0.5 * s + np.pi / 2)

        f1 = to_np(network.swing_residuals(one, 1, t, p, ops, system, m, d))
        f2 = to_np(network.swing_residuals(two, 2, t, p, ops, system, m, d))
    assert f1.shape == (41, 1) and f2.shape == (41, 2)
    np.testing.assert_allclose(f1[:, 0], m * delta_tt + d * delta_t + b * np.sin(delta) - p_np, atol=1e-13)
    np.testing.assert_allclose(f2[:, 0], delta_t - omega, atol=1e-13)
    np.testing.assert_allclose(f2[:, 1], m * omega_t + d * omega + b * np.sin(delta) - p_np, atol=1e-13)


@pytest.mark.parametrize("name", list(BACKENDS))
def test_hard_initial_condition_holds_for_any_weights(name):
    ops, array, to_np = _ops(name)
    arch = spec.Architecture.of(spec.PinnConfig(hidden_layers=2, width=8), CASE)
    theta = spec.init_theta(arch, seed=3)
    with _x64(name):
        delta, omega = network.delta_omega(arch, array(theta), array([[0.0]]), array([[0.08], [0.18]]), ops)
    np.testing.assert_allclose(to_np(delta), CASE.delta0, atol=1e-15)
    np.testing.assert_allclose(to_np(omega), CASE.omega0, atol=1e-15)


def test_forward_problem_is_the_papers_data_and_seeded():
    config = spec.PinnConfig(n_u=40, n_f=500, seed=7)
    problem = spec.forward_problem(config, CASE)
    on_edge = (problem.t_u == 0) | np.isin(problem.p_u, [CASE.p1_min, CASE.p1_max])
    assert problem.t_u.size == 40 and on_edge.all()
    for t, p, target in zip(problem.t_u[:5], problem.p_u[:5], problem.targets[:5, 0]):
        assert target == pytest.approx(reference(CASE, [t], [p])[0][0, 0], abs=1e-12)
    assert problem.t_f.size == 540  # LHS points plus the data points, as in the paper's code
    assert (problem.t_f >= 0).all() and (problem.t_f <= CASE.t_final).all()
    assert (problem.p_f >= CASE.p1_min).all() and (problem.p_f <= CASE.p1_max).all()
    again = spec.forward_problem(config, CASE)
    np.testing.assert_array_equal(again.t_f, problem.t_f)
    other = spec.forward_problem(spec.PinnConfig(n_u=40, n_f=500, seed=8), CASE)
    assert not np.array_equal(other.t_f, problem.t_f)
    np.testing.assert_array_equal(spec.init_theta(spec.Architecture.of(config, CASE), 7),
                                  spec.init_theta(spec.Architecture.of(config, CASE), 7))


# ---- the two backends are one specification -----------------------------------------------------

ARCH_VARIANTS = {
    "hard-ic": {"hidden_layers": 2, "width": 8},
    "paper": {"hidden_layers": 2, "width": 8, "hard_ic": False},
    "two-outputs": {"hidden_layers": 2, "width": 8, "outputs": 2},
}


# every architecture on the forward problem; the identification problem (m, d trained, omega data)
# on the single- and two-output networks (its soft-IC terms are the forward problem's, checked there)
@pytest.mark.slow
@pytest.mark.parametrize("variant, identification", [
    *((v, False) for v in ARCH_VARIANTS), ("hard-ic", True), ("two-outputs", True)],
    ids=["fit-hard-ic", "fit-paper", "fit-two-outputs", "identify-hard-ic", "identify-two-outputs"])
def test_backends_agree_on_loss_jacobian_and_outputs(variant, identification):
    """Same config and seed in float64: the same loss (1e-10 relative), gradient, Jacobian and
    network outputs in both backends, and torch's hand-rolled query path equals autodiff."""
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    from solvers.pinn.jax_pinn import JaxPinn
    from solvers.pinn.torch_pinn import TorchPinn

    config = spec.PinnConfig(n_u=10, n_f=60, seed=1, **ARCH_VARIANTS[variant])
    system = smib_system(CASE)
    if identification:
        rng = np.random.default_rng(0)
        t, p = rng.uniform(0, 20, 30), rng.uniform(CASE.p1_min, CASE.p1_max, 30)
        obs = Observations(t, p, np.sin(t) * p, np.cos(t))
        arch = spec.Architecture.of(config, CASE, True, spec.identification_p_range(CASE, obs))
        problem = spec.identification_problem(config, CASE, obs)
        theta = spec.init_theta(arch, config.seed, 0.3, 0.2)
    else:
        arch = spec.Architecture.of(config, CASE)
        problem = spec.forward_problem(config, CASE)
        theta = spec.init_theta(arch, config.seed)
    solvers = [cls(CASE, threads=1, **ARCH_VARIANTS[variant]) for cls in (TorchPinn, JaxPinn)]
    trainers = []
    for solver in solvers:
        solver._prepare_backend()
        trainers.append(solver._compile(arch, problem, system, "float64"))
    (r_torch, r_jax) = (tr.residuals(theta) for tr in trainers)
    loss_torch, loss_jax = r_torch @ r_torch, r_jax @ r_jax
    assert loss_torch == pytest.approx(loss_jax, rel=1e-10)
    (l_torch, g_torch), (l_jax, g_jax) = (tr.loss_and_grad(theta) for tr in trainers)
    assert l_torch == pytest.approx(loss_torch, rel=1e-12) and l_jax == pytest.approx(loss_jax, rel=1e-12)
    np.testing.assert_allclose(g_torch, g_jax, rtol=1e-9, atol=1e-12 * np.abs(g_jax).max())
    j_torch, j_jax = (tr.jacobian(theta) for tr in trainers)
    assert j_torch.shape == (r_torch.size, arch.n_params)
    np.testing.assert_allclose(j_torch, j_jax, rtol=1e-9, atol=1e-12 * np.abs(j_jax).max())
    np.testing.assert_allclose(2 * j_jax.T @ r_jax, g_jax, rtol=1e-8, atol=1e-12 * np.abs(g_jax).max())

    # outputs: both query paths and autodiff of the shared network
    t_q, p_q = np.array([0.0, 3.3, 20.0, 7.5, 3.3]), np.array([0.08, 0.131, 0.18])
    outs = []
    for solver in solvers:
        evaluator = solver._make_evaluator(arch, "float64")
        evaluator.load(theta)
        outs.append(evaluator(t_q, p_q))
    ops, array, to_np = _ops("torch-pinn")
    delta, omega = network.delta_omega(arch, array(theta), array(t_q)[None, :], array(p_q)[:, None], ops)
    for d_q, o_q in outs:
        assert d_q.shape == o_q.shape == (3, 5)
        np.testing.assert_allclose(d_q, to_np(delta), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(o_q, to_np(omega), rtol=1e-11, atol=1e-13)


def test_torch_query_on_the_full_grid_matches_autodiff():
    """The full 100 x 201 grid takes the query's large-tensor tanh (2 sigmoid(2 z) - 1)."""
    _need("torch-pinn")
    import torch

    from systems.cases import standard_grid
    from solvers.pinn.torch_pinn import _SIGMOID_TANH_MIN, _FastForward, _tanh_

    z = torch.linspace(-40.0, 40.0, 2 * _SIGMOID_TANH_MIN + 1, dtype=torch.float64)
    np.testing.assert_allclose(_tanh_(z.clone()).numpy(), torch.tanh(z).numpy(), rtol=0, atol=5e-16)
    arch = spec.Architecture.of(spec.PinnConfig(hidden_layers=2, width=16), CASE)
    theta = spec.init_theta(arch, seed=2)
    evaluator = _FastForward(arch, torch.float64)
    evaluator.load(theta)
    t, p = standard_grid(CASE)
    assert p.size * t.size * 16 >= _SIGMOID_TANH_MIN
    delta, omega = evaluator(t, p)
    ops, array, to_np = _ops("torch-pinn")
    ref_delta, ref_omega = network.delta_omega(arch, array(theta), array(t)[None, :], array(p)[:, None], ops)
    np.testing.assert_allclose(delta, to_np(ref_delta), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(omega, to_np(ref_omega), rtol=1e-11, atol=1e-13)


# ---- persistence -------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("source, target", [("torch-pinn", "jax-pinn"), ("jax-pinn", "torch-pinn")])
def test_save_load_round_trip_across_backends(tmp_path, source, target):
    _need(source)
    _need(target)
    trained = make_solver(source, CASE, **SMALL)
    trained.fit()
    ident = trained.identify(_observations(SMIB_INFERENCE, 20))
    npz, meta = trained.save(tmp_path / "model")
    assert npz.exists() and meta.exists()
    loaded = make_solver(target, CASE, threads=1).load(tmp_path / "model")
    assert loaded.fitted and loaded.pinn_config == trained.pinn_config
    t, p = np.linspace(0, 20, 21), np.linspace(CASE.p1_min, CASE.p1_max, 4)
    a, b = trained.solve(t, p), loaded.solve(t, p)
    np.testing.assert_allclose(b.delta, a.delta, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(b.omega, a.omega, rtol=1e-11, atol=1e-13)
    assert loaded.identification["m"] == ident.m and loaded.identification["d"] == ident.d
    with pytest.raises(ValueError, match="case"):
        make_solver(target, SMIB_IDENTIFICATION, threads=1).load(tmp_path / "model")


# ---- training and identification ------------------------------------------------------------------


def _observations(case, n, seed=0, with_omega=False):
    rng = np.random.default_rng(seed)
    t = np.round(rng.uniform(0.0, case.t_final, n), 1)
    p = rng.choice(np.linspace(case.p1_min, case.p1_max, 10), n)
    delta = np.array([reference(case, [ti], [pi])[0][0, 0] for ti, pi in zip(t, p)])
    omega = np.array([reference(case, [ti], [pi])[1][0, 0] for ti, pi in zip(t, p)]) if with_omega else None
    return Observations(t, p, delta, omega)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BACKENDS))
def test_short_training_reaches_a_loose_accuracy(name):
    _need(name)
    solver = make_solver(name, CASE, **{**SMALL, "width": 10, "n_f": 300, "max_iterations": 40})
    report = solver.fit()
    assert report.iterations > 0 and np.isfinite(report.loss) and report.seconds > 0
    t, p = np.linspace(0, 20, 41), np.linspace(CASE.p1_min, CASE.p1_max, 5)
    traj = solver.solve(t, p)
    ref_delta, ref_omega = reference(CASE, t, p)
    assert rel_l2(traj.delta, ref_delta) < 3e-2
    assert rel_l2(traj.omega, ref_omega) < 1e-1


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BACKENDS))
def test_identification_recovers_m_and_d(name):
    _need(name)
    case = SMIB_IDENTIFICATION
    solver = make_solver(name, case, **{**SMALL, "id_width": 10, "id_n_f": 300, "id_max_iterations": 60})
    result = solver.identify(_observations(case, 100))
    assert result.success and result.iterations > 0
    assert result.m == pytest.approx(case.m, rel=0.05)
    assert result.d == pytest.approx(case.d, rel=0.1)


def test_identification_uses_omega_observations():
    name = next((n for n in BACKENDS if _available(n)), None)
    if name is None:
        pytest.skip("neither torch nor jax installed")
    obs = _observations(CASE, 30, with_omega=True)
    solver = make_solver(name, CASE, **{**SMALL, "id_max_iterations": 10})  # at 3 no step is taken yet
    problem = spec.identification_problem(solver.pinn_config, CASE, obs)
    np.testing.assert_array_equal(problem.targets, np.stack([obs.delta, obs.omega], axis=1))
    # the loss sees the omega values: the same run on shifted omega data ends elsewhere
    result = solver.identify(obs)
    theta = solver.identification["theta"]
    shifted = solver.identify(Observations(obs.t, obs.P1, obs.delta, obs.omega + 0.05))
    assert np.isfinite([result.m, result.d]).all() and result.m > 0 and result.d > 0
    assert not np.array_equal(solver.identification["theta"], theta)
    assert (shifted.m, shifted.d) != (result.m, result.d)


def _available(name: str) -> bool:
    try:
        __import__(BACKENDS[name])
    except ImportError:
        return False
    return True


# JAX on the paper config only: its two-output variant shares every dtype path and costs ~6 s of JIT
@pytest.mark.parametrize("name, config", [("torch-pinn", "paper"), ("torch-pinn", "paper-two-outputs"),
                                          pytest.param("jax-pinn", "paper", marks=pytest.mark.slow)])
def test_paper_configs_run_in_float32(name, config, monkeypatch):
    """Training, identification and the query compute in float32: the training functions' values
    (float64 numpy by contract) are all float32 numbers, unlike the float64 build's, and the
    evaluator returns float32."""
    _need(name)
    solver = make_solver(name, CASE, config, max_iterations=2, id_max_iterations=2, threads=1,
                         n_f=200, id_n_f=0)
    assert solver.pinn_config.dtype == "float32" and solver.pinn_config.optimizer == "lbfgs"
    assert not solver.pinn_config.hard_ic
    compiled = []  # (dtype, the other arguments, the trainer) of each `_compile`
    real_compile = solver._compile

    def spy(arch, problem, system, dtype):
        compiled.append((dtype, (arch, problem, system), real_compile(arch, problem, system, dtype)))
        return compiled[-1][2]

    monkeypatch.setattr(solver, "_compile", spy)
    report = solver.fit()
    assert report.iterations <= 2 and np.isfinite(report.loss)
    assert float(np.float32(report.loss)) == report.loss  # (np.float32 == float compares in float32)
    traj = solver.solve(np.array([10.0, 0.0]), 0.13)
    assert traj.delta.dtype == traj.omega.dtype == np.float64 and traj.delta.shape == (1, 2)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    assert all(x.dtype == np.float32 for x in solver._evaluate(np.array([10.0, 0.0]), np.array([0.13])))
    ident = solver.identify(_observations(CASE, 20))
    assert np.isfinite([ident.m, ident.d]).all() and ident.m > 0 and ident.d > 0
    assert len(compiled) >= 2 and {dtype for dtype, *_ in compiled} == {"float32"}  # fit, identify
    # what L-BFGS trained on (fit, identify) gives float32 numbers ...
    for (*_, trainer), theta in [(compiled[0], solver.theta), (compiled[-1], solver.identification["theta"])]:
        loss, grad = trainer.loss_and_grad(theta)
        assert float(np.float32(loss)) == loss
        np.testing.assert_array_equal(grad, grad.astype(np.float32))
    if name != "torch-pinn":  # the float64 build costs JAX another compilation; torch shows the contrast
        return
    # ... where the float64 build of the same problem does not, and agrees to float32 accuracy
    loss64, grad64 = real_compile(*compiled[-1][1], "float64").loss_and_grad(solver.identification["theta"])
    assert not np.array_equal(grad64, grad64.astype(np.float32))
    assert loss == pytest.approx(loss64, rel=1e-4)
    np.testing.assert_allclose(grad, grad64, rtol=0, atol=1e-3 * np.abs(grad64).max())


# ---- the solver contract ----------------------------------------------------------------------------


@pytest.mark.parametrize("name, module, cls", [("torch-pinn", "torch_pinn", "TorchPinn"),
                                               ("jax-pinn", "jax_pinn", "JaxPinn")])
def test_registered(name, module, cls):
    """The registry maps each name to its backend's class, and that class carries the name."""
    _need(name)
    import importlib

    expected = getattr(importlib.import_module(f"solvers.pinn.{module}"), cls)
    assert SOLVERS[name] is expected and expected.name == name
    assert type(make_solver(name, CASE, threads=1)) is expected


@pytest.mark.parametrize("name", list(BACKENDS))
def test_solve_before_fit_raises(name):
    _need(name)
    solver = make_solver(name, CASE, **SMALL)
    with pytest.raises(NotFittedError):
        solver.solve([1.0], 0.1)
    with pytest.raises(NotFittedError):
        solver.save("never-written")


def test_domain_errors_and_extrapolation(fitted):
    with pytest.raises(ValueError, match="t_query"):
        fitted.solve([1.0, CASE.t_final + 0.5], 0.1)
    with pytest.raises(ValueError, match="P1"):
        fitted.solve([1.0], CASE.p1_max + 0.01)
    with pytest.raises(ValueError):
        fitted.solve([-1.0], 0.1)
    traj = fitted.solve([1.0, 25.0], [0.05, 0.2], extrapolate=True)
    assert traj.delta.shape == (2, 2) and np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()


def test_solve_order_repeats_and_scalar_p1(fitted):
    t = np.array([5.0, 0.0, 12.5, 5.0, 20.0])
    traj = fitted.solve(t, 0.13)
    assert traj.delta.shape == traj.omega.shape == (1, 5)
    assert traj.delta.dtype == np.float64 and traj.omega.dtype == np.float64
    order = np.argsort(t, kind="stable")
    sorted_traj = fitted.solve(t[order], [0.13])
    np.testing.assert_array_equal(sorted_traj.delta[0], traj.delta[0][order])
    np.testing.assert_array_equal(traj.delta[0, 0], traj.delta[0, 3])
    many = fitted.solve(t, np.array([0.09, 0.13, 0.17]))
    assert many.delta.shape == (3, 5)
    np.testing.assert_allclose(many.delta[1], traj.delta[0], rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("name", BACKENDS_SLOW_JAX)
def test_deterministic_for_a_seed(name):
    _need(name)
    thetas = []
    for seed in (4, 4, 5):
        solver = make_solver(name, CASE, **{**SMALL, "seed": seed})
        solver.fit()
        thetas.append(solver.theta)
    np.testing.assert_array_equal(thetas[0], thetas[1])
    assert not np.array_equal(thetas[0], thetas[2])


def test_training_runs_the_optimisers_blas_on_one_thread(monkeypatch):
    """The backend keeps `threads`; numpy/scipy BLAS inside the optimiser runs on one thread (two
    pools of 2 threads on 2 cores oversubscribe them; see PinnSolver._train)."""
    _need("torch-pinn")
    import torch
    from threadpoolctl import threadpool_info

    from solvers.pinn import common

    seen = []
    real = common.levenberg_marquardt

    def spy(*args, **kwargs):
        seen.append(({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"},
                     torch.get_num_threads()))
        return real(*args, **kwargs)

    monkeypatch.setattr(common, "levenberg_marquardt", spy)
    make_solver("torch-pinn", CASE, **{**SMALL, "threads": 2}).fit()
    assert seen == [({1}, 2)]


@pytest.mark.parametrize("name", list(BACKENDS))
@pytest.mark.parametrize("bad", [
    {"outputs": 3}, {"threads": 0}, {"dtype": "float16"}, {"n_u": 0, "n_f": 0}, {"max_seconds": -1.0},
    {"optimizer": "sgd"}, {"hidden_layers": 0}, {"progress": "yes"}, {"no_such_option": 1},
])
def test_bad_options_raise(name, bad):
    _need(name)
    with pytest.raises(ValueError):
        make_solver(name, CASE, **bad)


def test_progress_is_quiet_under_pytest():
    assert _progress_enabled(None) is False
    assert _progress_enabled(True) is True
