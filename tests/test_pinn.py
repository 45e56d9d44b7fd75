"""Tests of the PINN adapters (torch-pinn, jax-pinn): physics, backend equivalence, persistence,
training, identification, time-marching and the solver contract, on the SMIB and on a small
two-machine system. Small networks and budgets throughout."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from harness.measure.metrics import rel_l2
from solvers import SOLVERS, make_solver
from solvers.base import NotFittedError
from solvers.pinn import network
from solvers.pinn.architecture import Architecture, init_theta, start_guess
from solvers.pinn.config import PinnConfig
from solvers.pinn.evaluator import MarchingEvaluator
from solvers.pinn.model_file import CorruptModelError, load_model
from solvers.pinn.problems import (
    Problem,
    forward_problem,
    identification_p_range,
    identification_problem,
    observations_within,
    window_edges,
    window_problem,
)
from solvers.progress import progress_enabled
from systems import model
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, Case, Observations, case_record
from systems.reference import reference

# torch.func's first jvp registers decompositions through torch.jit.script, deprecated in torch 2.13
pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE = SMIB_INFERENCE
# Two machines, no infinite bus, lossy (G != 0), generator 1's P1 and the other's p_m unbalanced so
# that the angles drift as well as swing (~0.75 Hz): every term of the N-machine model is exercised.
TWO = Case(
    name="two-machines", m=(0.1, 0.2), d=(0.05, 0.1), delta0=(0.1, -0.05), omega0=(0.05, -0.02),
    p_m=(0.3, -0.25), E=(1.05, 1.0), G=((0.1, -0.05), (-0.05, 0.12)), B=((-3.0, 1.5), (1.5, -2.8)),
    g_inf=(0.0, 0.0), b_inf=(0.0, 0.0), t_final=4.0, p1_min=0.25, p1_max=0.35,
    m_box=((0.01, 1.0), (0.02, 2.0)), d_box=((0.005, 0.5), (0.01, 1.0)),
)
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


@pytest.mark.parametrize("case", [CASE, TWO], ids=["smib", "two-machines"])
@pytest.mark.parametrize("name", [*BACKENDS, "torch-autograd"])
def test_swing_residual_of_a_known_function(name, case):
    """The residual of every machine by nested forward-mode autodiff equals the model's
    (`systems.model.residual` in numpy, generator 1 at P1 and the others at p_m) for known
    delta_k(t), omega_k(t)."""
    ops, array, to_np = _ops(name)
    physics = network.Physics.of(case)
    n = case.n
    t_np = np.linspace(0.0, case.t_final, 41)
    p_np = np.linspace(case.p1_min, case.p1_max, 41)
    a, w = 0.3 + 0.1 * np.arange(n), 0.7 + 0.2 * np.arange(n)  # a different function per machine
    ts = t_np[:, None]
    delta = 0.1 + a * np.sin(w * ts) + 0.01 * ts ** 2
    delta_t = a * w * np.cos(w * ts) + 0.02 * ts
    delta_tt = -a * w * w * np.sin(w * ts) + 0.02
    omega = 0.2 * np.cos(0.5 * w * ts)
    omega_t = -0.1 * w * np.sin(0.5 * w * ts)
    k, m, d = model.coupling(case), np.asarray(case.m), np.asarray(case.d)
    P = case.powers(p_np)
    with _x64(name):
        t, p = array(t_np), array(p_np)

        def one(s):
            s = s[..., None]
            return (0.1 + array(a) * ops.sin(array(w) * s) + 0.01 * s * s,)

        def two(s):
            return one(s)[0], 0.2 * ops.sin(0.5 * array(w) * s[..., None] + np.pi / 2)

        f1 = to_np(network.swing_residuals(one, 1, t, p, ops, physics, array(m), array(d)))
        f2 = to_np(network.swing_residuals(two, 2, t, p, ops, physics, array(m), array(d)))
    assert f1.shape == (41, n) and f2.shape == (41, 2 * n)
    np.testing.assert_allclose(f1, model.residual(k, m, d, delta, delta_t, delta_tt, P), atol=1e-13)
    np.testing.assert_allclose(f2[:, :n], delta_t - omega, atol=1e-13)
    np.testing.assert_allclose(f2[:, n:], model.residual(k, m, d, delta, omega, omega_t, P), atol=1e-13)
    if case is CASE:  # the paper's SMIB equation, written out
        b = case.b_inf[0]
        np.testing.assert_allclose(f1[:, 0], m * delta_tt[:, 0] + d * delta_t[:, 0] + b * np.sin(delta[:, 0]) - p_np,
                                   atol=1e-13)


@pytest.mark.parametrize("case", [CASE, TWO], ids=["smib", "two-machines"])
@pytest.mark.parametrize("name", list(BACKENDS))
def test_hard_initial_condition_holds_for_any_weights(name, case):
    ops, array, to_np = _ops(name)
    for outputs in (1, 2):
        arch = Architecture.of(PinnConfig(hidden_layers=2, width=8, outputs=outputs), case)
        assert arch.sizes[-1] == outputs * case.n and arch.machines == case.n
        theta = init_theta(arch, seed=3)
        with _x64(name):
            delta, omega = network.delta_omega(arch, array(theta), array([[0.0]]),
                                               array([[case.p1_min], [case.p1_max]]), ops)
        assert to_np(delta).shape == (2, 1, case.n)
        np.testing.assert_allclose(to_np(delta), np.broadcast_to(case.delta0, (2, 1, case.n)), atol=1e-15)
        np.testing.assert_allclose(to_np(omega), np.broadcast_to(case.omega0, (2, 1, case.n)), atol=1e-15)


def test_forward_problem_is_the_papers_data_and_seeded():
    config = PinnConfig(n_u=40, n_f=500, seed=7)
    problem = forward_problem(config, CASE)
    on_edge = (problem.t_u == 0) | np.isin(problem.p_u, [CASE.p1_min, CASE.p1_max])
    assert problem.t_u.size == 40 and on_edge.all()
    assert problem.targets.shape == (40, 1)
    for t, p, target in zip(problem.t_u[:5], problem.p_u[:5], problem.targets[:5]):
        np.testing.assert_allclose(target, reference(CASE, [t], [p])[0][0, 0], rtol=0, atol=1e-12)
    assert problem.t_f.size == 540  # LHS points plus the data points, as in the paper's code
    assert (problem.t_f >= 0).all() and (problem.t_f <= CASE.t_final).all()
    assert (problem.p_f >= CASE.p1_min).all() and (problem.p_f <= CASE.p1_max).all()
    again = forward_problem(config, CASE)
    np.testing.assert_array_equal(again.t_f, problem.t_f)
    other = forward_problem(PinnConfig(n_u=40, n_f=500, seed=8), CASE)
    assert not np.array_equal(other.t_f, problem.t_f)
    np.testing.assert_array_equal(init_theta(Architecture.of(config, CASE), 7),
                                  init_theta(Architecture.of(config, CASE), 7))


# ---- the two backends are one specification -----------------------------------------------------

ARCH_VARIANTS = {
    "hard-ic": {"hidden_layers": 2, "width": 8},
    "paper": {"hidden_layers": 2, "width": 8, "hard_ic": False},
    "two-outputs": {"hidden_layers": 2, "width": 8, "outputs": 2},
}


# every architecture on the forward problem; the identification problem (m, d trained, omega data)
# on the single- and two-output networks (its soft-IC terms are the forward problem's, checked there);
# on two machines the forward problem of the hard-IC network and the identification of the
# two-output one (every machine's residual, 2n trained log m, log d)
@pytest.mark.slow
@pytest.mark.parametrize("variant, identification, case", [
    *((v, False, CASE) for v in ARCH_VARIANTS), ("hard-ic", True, CASE), ("two-outputs", True, CASE),
    ("hard-ic", False, TWO), ("two-outputs", True, TWO)],
    ids=["fit-hard-ic", "fit-paper", "fit-two-outputs", "identify-hard-ic", "identify-two-outputs",
         "two-machines-fit-hard-ic", "two-machines-identify-two-outputs"])
def test_backends_agree_on_loss_jacobian_and_outputs(variant, identification, case):
    """Same config and seed in float64: the same loss (1e-10 relative), gradient, Jacobian and
    network outputs in both backends, and torch's hand-rolled query path equals autodiff."""
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    from solvers.pinn.jax_pinn import JaxPinn
    from solvers.pinn.torch_pinn import TorchPinn

    config = PinnConfig(n_u=10, n_f=60, id_n_f=40, seed=1, **ARCH_VARIANTS[variant])
    n = case.n
    if identification:
        rng = np.random.default_rng(0)
        t, p = rng.uniform(0, case.t_final, 30), rng.uniform(case.p1_min, case.p1_max, 30)
        phase = np.arange(n)
        obs = Observations(t, p, np.sin(t[:, None] + phase) * p[:, None], np.cos(t[:, None] - phase))
        arch = Architecture.of(config, case, True, identification_p_range(case, obs))
        problem = identification_problem(config, case, obs)
        theta = init_theta(arch, config.seed, 0.3, 0.2)
        assert arch.n_extra == 2 * n and problem.targets.shape == (30, 2 * n)
    else:
        arch = Architecture.of(config, case)
        problem = forward_problem(config, case)
        theta = init_theta(arch, config.seed)
    solvers = [cls(case, threads=1, **ARCH_VARIANTS[variant]) for cls in (TorchPinn, JaxPinn)]
    trainers = []
    for solver in solvers:
        solver._prepare_backend()
        trainers.append(solver._compile(arch, problem, solver.physics, "float64"))
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

    physics_rows = problem.t_f.size * (n if arch.outputs == 1 else 2 * n)
    assert r_torch.size == problem.targets.size + physics_rows

    # outputs: both query paths and autodiff of the shared network
    t_q = np.array([0.0, 0.165, 1.0, 0.375, 0.165]) * case.t_final
    p_q = case.p1_min + np.array([0.0, 0.51, 1.0]) * (case.p1_max - case.p1_min)
    outs = []
    for solver in solvers:
        evaluator = solver._make_evaluator(arch, "float64")
        evaluator.load(theta)
        outs.append(evaluator(t_q, p_q))
    ops, array, to_np = _ops("torch-pinn")
    delta, omega = network.delta_omega(arch, array(theta), array(t_q)[None, :], array(p_q)[:, None], ops)
    for d_q, o_q in outs:
        assert d_q.shape == o_q.shape == (3, 5, n)
        np.testing.assert_allclose(d_q, to_np(delta), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(o_q, to_np(omega), rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("variant, identification, case, starts", [
    ("hard-ic", False, CASE, False), ("paper", False, CASE, False), ("two-outputs", True, CASE, False),
    ("hard-ic", True, CASE, False), ("hard-ic", False, TWO, True), ("two-outputs", False, TWO, True),
    ("hard-ic", True, TWO, False)],
    ids=["fit-hard-ic", "fit-paper", "identify-two-outputs", "identify-hard-ic", "two-machines-window",
         "two-machines-window-two-outputs", "two-machines-identify"])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_torch_taylor_mode_equals_the_shared_network(variant, identification, case, starts, dtype):
    """torch-pinn's training functions (t-derivatives propagated by hand,
    `solvers.pinn.torch_jacobian`) equal the shared network's `residual_vector` and per-point
    `jacobian_blocks` by torch.func (JAX's formulation, compared with JAX in
    test_backends_agree_on_loss_jacobian_and_outputs), and the loss and its gradient r^T r and
    2 J^T r of those, to rounding error: one and two outputs,
    no hard initial condition, identification (m and d trained, omega data), time-marching start
    states, two machines; in float32 to float32 rounding of the float64 reference."""
    _need("torch-pinn")
    import torch

    from solvers.pinn.torch_jacobian import taylor_jacobian, taylor_loss_and_grad, taylor_residuals
    from solvers.pinn.torch_pinn import OPS, OPS_AUTOGRAD

    config = PinnConfig(seed=1, **ARCH_VARIANTS[variant])
    n, n_u, n_f = case.n, 9, 13
    arch = Architecture.of(config, case, identification=identification)
    rng = np.random.default_rng(0)
    columns = 2 * n if identification else n
    arrays = {"t_u": rng.uniform(0.0, case.t_final, n_u), "p_u": rng.uniform(case.p1_min, case.p1_max, n_u),
              "targets": rng.normal(size=(n_u, columns)), "t_f": rng.uniform(0.0, case.t_final, n_f),
              "p_f": rng.uniform(case.p1_min, case.p1_max, n_f)}
    if starts:
        arrays |= {"start_u": rng.normal(size=(n_u, 2, n)), "start_f": rng.normal(size=(n_f, 2, n))}
    problem = Problem(loss_scale=1.0, **arrays)
    physics = network.Physics.of(case)
    theta = init_theta(arch, config.seed, 0.3, 0.2) + 0.1 * rng.normal(size=arch.n_params)  # nonzero biases
    as64 = {key: torch.as_tensor(value) for key, value in arrays.items()}
    r_ref = network.residual_vector(arch, torch.as_tensor(theta), as64, OPS_AUTOGRAD, physics, problem).detach()
    j_ref = network.jacobian_blocks(arch, torch.as_tensor(theta), as64, OPS, physics, problem)
    tdtype = getattr(torch, dtype)
    data = {key: value.to(tdtype) for key, value in as64.items()}
    r = taylor_residuals(arch, torch.as_tensor(theta, dtype=tdtype), data, OPS_AUTOGRAD, physics, problem)
    j = taylor_jacobian(arch, torch.as_tensor(theta, dtype=tdtype), data, OPS_AUTOGRAD, physics, problem)
    loss, grad = taylor_loss_and_grad(arch, torch.as_tensor(theta, dtype=tdtype), data, OPS_AUTOGRAD, physics,
                                      problem)
    assert r.dtype == j.dtype == loss.dtype == grad.dtype == tdtype
    assert r.shape == r_ref.shape == (problem.targets.size + n_f * arch.sizes[-1],)
    assert j.shape == j_ref.shape == (r_ref.shape[0], arch.n_params)
    tol = 1e-12 if dtype == "float64" else 1e-5
    np.testing.assert_allclose(r.double().numpy(), r_ref.numpy(), rtol=0, atol=tol * r_ref.abs().max().item())
    np.testing.assert_allclose(j.double().numpy(), j_ref.numpy(), rtol=0, atol=tol * j_ref.abs().max().item())
    assert loss.item() == pytest.approx((r_ref @ r_ref).item(), rel=10 * tol)
    g_ref = (2.0 * j_ref.T @ r_ref).numpy()
    np.testing.assert_allclose(grad.double().numpy(), g_ref, rtol=0, atol=10 * tol * np.abs(g_ref).max())


def test_torch_query_on_the_full_grid_matches_autodiff():
    """The full 100 x 201 grid takes the query's large-tensor tanh (2 sigmoid(2 z) - 1)."""
    _need("torch-pinn")
    import torch

    from solvers.pinn.torch_pinn import _SIGMOID_TANH_MIN, _FastForward, _tanh_
    from systems.cases import standard_grid

    z = torch.linspace(-40.0, 40.0, 2 * _SIGMOID_TANH_MIN + 1, dtype=torch.float64)
    np.testing.assert_allclose(_tanh_(z.clone()).numpy(), torch.tanh(z).numpy(), rtol=0, atol=5e-16)
    arch = Architecture.of(PinnConfig(hidden_layers=2, width=16), CASE)
    theta = init_theta(arch, seed=2)
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
    np.testing.assert_array_equal(loaded.identification["m"], ident.m)
    np.testing.assert_array_equal(loaded.identification["d"], ident.d)
    with pytest.raises(ValueError, match="case"):
        make_solver(target, SMIB_IDENTIFICATION, threads=1).load(tmp_path / "model")


def _record_case(meta, case) -> None:
    """Make the .json name `case`, as a reviewer did: the weights' hash covers the .npz only."""
    info = json.loads(meta.read_text())
    meta.write_text(json.dumps({**info, "case": case_record(case)}))


def test_a_model_recorded_as_another_case_does_not_load(fitted, tmp_path):
    """A SMIB model whose .json names wscc9 is refused by a wscc9 adapter (it would answer one
    machine's angles from the SMIB's start): the message names the file and the machine counts."""
    from systems.cases import CASES

    wscc9 = CASES["wscc9"]
    _, meta = fitted.save(tmp_path / "model")
    solver = make_solver(fitted.name, wscc9, threads=1)
    with pytest.raises(ValueError, match=r"saved for case 'smib-inference', this solver has case 'wscc9' "
                                         r"\(fields that differ: name, m, d, delta0, "):
        solver.load(tmp_path / "model")  # as saved: its case record is not wscc9
    _record_case(meta, wscc9)
    with pytest.raises(ValueError) as info:
        solver.load(tmp_path / "model")
    assert str(info.value) == f"{meta}: trained for 1 machine, case wscc9 has 3"
    assert not solver.fitted


@pytest.mark.parametrize("other, what", [
    (SMIB_IDENTIFICATION, "P1 range (p.u.) (0.08, 0.18), expected (0.1, 0.18)"),
    (dataclasses.replace(CASE, name="smib-other-start", delta0=(0.3,)),
     "initial angles delta0 (rad) (0.1,), expected (0.3,)"),
    (dataclasses.replace(CASE, name="smib-longer", t_final=30.0), "t range (s) (0.0, 20.0), expected (0.0, 30.0)"),
], ids=["p1-range", "initial-angle", "horizon"])
def test_a_model_recorded_as_a_case_of_other_data_does_not_load(fitted, tmp_path, other, what):
    """A model recorded as a case of as many machines but other data (what its network was
    normalised over or starts from) is refused, naming the file and what differs."""
    _, meta = fitted.save(tmp_path / "model")
    _record_case(meta, other)
    solver = make_solver(fitted.name, other, threads=1)
    with pytest.raises(ValueError) as info:
        solver.load(tmp_path / "model")
    message = str(info.value)
    assert message.startswith(f"{meta}: not the network of its config for case {other.name}: ")
    assert what in message and "\n" not in message
    assert not solver.fitted


def test_a_model_recorded_as_a_case_that_differs_in_what_no_network_records_does_not_load(fitted, tmp_path):
    """Inertia and damping shape no layer of the network: a .json edited to another m is caught by
    the record's hash stored among the weights."""
    other = dataclasses.replace(CASE, name="smib-heavier", m=(0.8,))
    _, meta = fitted.save(tmp_path / "model")
    _record_case(meta, other)
    with pytest.raises(ValueError) as info:
        make_solver(fitted.name, other, threads=1).load(tmp_path / "model")
    assert str(info.value) == (f"{meta}: its config, case or architecture is not what was saved with "
                               "model.npz (the .json was edited after saving)")


# ---- training and identification ------------------------------------------------------------------


def _observations(case, n, seed=0, with_omega=False):
    """n samples of every machine's delta (and omega) at random (t, P1), (n, case.n) each."""
    rng = np.random.default_rng(seed)
    t = np.round(rng.uniform(0.0, case.t_final, n), 1)
    p = rng.choice(np.linspace(case.p1_min, case.p1_max, 10), n)
    rows = [reference(case, [ti], [pi]) for ti, pi in zip(t, p)]
    delta = np.array([d[0, 0] for d, _ in rows])
    omega = np.array([o[0, 0] for _, o in rows]) if with_omega else None
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


def _within(interval, value) -> bool:
    return bool(interval[0] <= value <= interval[1])


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BACKENDS))
def test_identification_recovers_m_and_d(name):
    _need(name)
    case = SMIB_IDENTIFICATION
    solver = make_solver(name, case, **{**SMALL, "id_width": 10, "id_n_f": 300, "id_max_iterations": 60})
    result = solver.identify(_observations(case, 100))
    assert result.iterations > 0
    assert result.m.shape == result.d.shape == (1,)
    assert result.m[0] == pytest.approx(case.m[0], rel=0.05)
    assert result.d[0] == pytest.approx(case.d[0], rel=0.1)
    # 60 iterations leave the network's misfit far above the data's: the interval holds the truth
    # and says how little the misfit pins down (whether it is narrow enough to call a success)
    assert _within(result.m_ci95[0], case.m[0]) and _within(result.d_ci95[0], case.d[0])


def test_identification_uses_omega_observations():
    name = next((n for n in BACKENDS if _available(n)), None)
    if name is None:
        pytest.skip("neither torch nor jax installed")
    obs = _observations(CASE, 30, with_omega=True)
    solver = make_solver(name, CASE, **{**SMALL, "id_max_iterations": 10})  # at 3 no step is taken yet
    problem = identification_problem(solver.pinn_config, CASE, obs)
    np.testing.assert_array_equal(problem.targets, np.concatenate([obs.delta, obs.omega], axis=1))
    # the loss sees the omega values: the same run on shifted omega data ends elsewhere
    result = solver.identify(obs)
    theta = solver.identification["theta"]
    shifted = solver.identify(Observations(obs.t, obs.P1, obs.delta, obs.omega + 0.05))
    assert np.isfinite([result.m, result.d]).all() and (result.m > 0).all() and (result.d > 0).all()
    assert not np.array_equal(solver.identification["theta"], theta)
    assert not np.array_equal(np.concatenate([shifted.m, shifted.d]), np.concatenate([result.m, result.d]))


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
    assert traj.delta.dtype == traj.omega.dtype == np.float64 and traj.delta.shape == (1, 2, 1)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    assert all(x.dtype == np.float32 for x in solver._evaluate(np.array([10.0, 0.0]), np.array([0.13])))
    ident = solver.identify(_observations(CASE, 20))
    assert np.isfinite([ident.m, ident.d]).all() and ident.m[0] > 0 and ident.d[0] > 0
    # fit and identify train in float32; the identification's interval takes its Jacobian from a
    # float64 build of the same problem (the last compilation)
    assert len(compiled) >= 3 and {dtype for dtype, *_ in compiled[:-1]} == {"float32"}
    assert compiled[-1][0] == "float64" and compiled[-1][1] == compiled[-2][1]
    # what L-BFGS trained on (fit, identify) gives float32 numbers ...
    for (*_, trainer), theta in [(compiled[0], solver.theta), (compiled[-2], solver.identification["theta"])]:
        loss, grad = trainer.loss_and_grad(theta)
        assert float(np.float32(loss)) == loss
        np.testing.assert_array_equal(grad, grad.astype(np.float32))
    if name != "torch-pinn":  # the float64 build costs JAX another compilation; torch shows the contrast
        return
    # ... where the float64 build of the same problem does not, and agrees to float32 accuracy
    loss64, grad64 = compiled[-1][2].loss_and_grad(solver.identification["theta"])
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
    assert traj.delta.shape == (2, 2, 1) and np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()


def test_solve_order_repeats_and_scalar_p1(fitted):
    t = np.array([5.0, 0.0, 12.5, 5.0, 20.0])
    traj = fitted.solve(t, 0.13)
    assert traj.delta.shape == traj.omega.shape == (1, 5, 1)
    assert traj.delta.dtype == np.float64 and traj.omega.dtype == np.float64
    order = np.argsort(t, kind="stable")
    sorted_traj = fitted.solve(t[order], [0.13])
    np.testing.assert_array_equal(sorted_traj.delta[0], traj.delta[0][order])
    np.testing.assert_array_equal(traj.delta[0, 0], traj.delta[0, 3])
    many = fitted.solve(t, np.array([0.09, 0.13, 0.17]))
    assert many.delta.shape == (3, 5, 1)
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
    {"window": 0.0}, {"window": 0.5, "hard_ic": False}, {"m_init": -0.1},
])
def test_bad_options_raise(name, bad):
    _need(name)
    with pytest.raises(ValueError):
        make_solver(name, CASE, **bad)


def _trains_the_same_network_on(cpu_trained, device: str) -> None:
    """On a GPU machine: the adapter trained on `device` gives `cpu_trained`'s network to float64
    rounding, and its fit says where it trained."""
    gpu = make_solver(cpu_trained.name, CASE, **SMALL, device=device)
    assert "trained on" in gpu.fit().message
    np.testing.assert_allclose(gpu.theta, cpu_trained.theta, rtol=1e-6, atol=1e-9)


def test_jax_trains_on_the_device_it_is_given_and_answers_queries_on_the_cpu():
    _need("jax-pinn")
    import jax

    solver = make_solver("jax-pinn", CASE, **SMALL)
    assert solver.options["device"] == "cpu"
    assert "trained on" not in solver.fit().message
    delta = solver.solve(np.array([0.0, 1.0]), np.array([CASE.p1_min])).delta
    assert np.isfinite(delta).all()
    with pytest.raises(ValueError, match="device"):
        make_solver("jax-pinn", CASE, device="tpu")
    try:
        jax.devices("gpu")
    except RuntimeError:  # refused when the adapter is built, before a run measures
        with pytest.raises(ValueError, match="option device must be 'cpu' on this machine .* no GPU"):
            make_solver("jax-pinn", CASE, **SMALL, device="gpu")
        return
    _trains_the_same_network_on(solver, "gpu")


def test_torch_trains_on_the_device_it_is_given():
    _need("torch-pinn")
    import torch

    solver = make_solver("torch-pinn", CASE, **SMALL)
    assert solver.options["device"] == "cpu"
    cpu = solver.fit()
    assert "trained on" not in cpu.message
    with pytest.raises(ValueError, match="device"):
        make_solver("torch-pinn", CASE, device="tpu")
    with pytest.raises(ValueError, match="device"):
        make_solver("jax-pinn", CASE, device="cuda")  # the JAX backend trains where JAX computes
    if not torch.cuda.is_available():  # refused when the adapter is built, before a run measures
        with pytest.raises(ValueError, match="option device must be 'cpu' on this machine .* no CUDA device"):
            make_solver("torch-pinn", CASE, **SMALL, device="cuda")
        return
    _trains_the_same_network_on(solver, "cuda")


def test_progress_is_quiet_under_pytest():
    assert progress_enabled(None) is False
    assert progress_enabled(True) is True


# ---- N machines and time-marching ------------------------------------------------------------------

TWO_SMALL = {"hidden_layers": 1, "width": 6, "n_u": 4, "n_f": 30, "max_iterations": 3, "threads": 1,
             "progress": False, "id_hidden_layers": 1, "id_width": 6, "id_n_f": 30, "id_max_iterations": 5}
MARCHING = {**TWO_SMALL, "window": 1.0}  # 4 windows on TWO's 4 s


@pytest.fixture(scope="module", params=list(BACKENDS))
def marched(request):
    """A tiny time-marching model of TWO per backend (4 windows of 1 s, 3 LM iterations each) and
    its FitReport."""
    _need(request.param)
    solver = make_solver(request.param, TWO, **MARCHING)
    return solver, solver.fit()


def test_two_machine_fit_and_identify_shapes():
    """A single network on two machines: two angle outputs, (n_p, n_t, 2) trajectories, (n_s, 2)
    points, and identification of both machines' m and d with a 4 x 4 covariance."""
    _need("torch-pinn")
    solver = make_solver("torch-pinn", TWO, **TWO_SMALL)
    report = solver.fit()
    assert solver.arch.sizes[-1] == 2 and solver.theta.shape == (solver.arch.n_params,) and solver.windows is None
    assert report.iterations > 0 and np.isfinite(report.loss)
    traj = solver.solve(np.linspace(0.0, 4.0, 7), np.array([0.25, 0.3, 0.35]))
    assert traj.delta.shape == traj.omega.shape == (3, 7, 2)
    np.testing.assert_allclose(traj.delta[:, 0], np.broadcast_to(TWO.delta0, (3, 2)), atol=1e-15)  # hard IC
    points = solver.solve_points(np.array([0.5, 3.0]), np.array([0.26, 0.34]))
    assert points.delta.shape == points.omega.shape == (2, 2)
    ident = solver.identify(_observations(TWO, 25))
    assert ident.m.shape == ident.d.shape == ident.m_se.shape == (2,) and ident.m_ci95.shape == (2, 2)
    assert np.isfinite(np.concatenate([ident.m, ident.d])).all() and ident.iterations > 0
    assert solver.identification["arch"].n_extra == 4 and solver.identification["m"].shape == (2,)


def test_identification_starts_at_the_centre_of_each_box():
    """m_init / d_init None: the geometric centre of each machine's box; a number: every machine."""
    m, d = start_guess(PinnConfig(), TWO)
    np.testing.assert_allclose(m, [0.1, 0.2], rtol=1e-15)
    np.testing.assert_allclose(d, [0.05, 0.1], rtol=1e-15)
    m, d = start_guess(PinnConfig(m_init=0.3), TWO)
    np.testing.assert_array_equal(m, [0.3, 0.3])
    arch = Architecture.of(PinnConfig(hidden_layers=1, width=3), TWO, identification=True)
    np.testing.assert_allclose(np.exp(init_theta(arch, 0, m, d)[-4:]), [0.3, 0.3, 0.05, 0.1], rtol=1e-15)
    # the SMIB boxes (0.02, 2) and (0.005, 1): m starts where the old default m_init did
    assert start_guess(PinnConfig(), CASE)[0][0] == pytest.approx(0.2, rel=1e-15)


def test_identification_horizon_keeps_the_early_observations_and_collocates_within_it():
    obs = Observations(np.array([0.5, 1.5, 3.0]), np.full(3, 0.3), np.zeros((3, 2)))
    config = PinnConfig(id_t_max=2.0, id_n_f=40)
    kept = observations_within(config, obs)
    assert kept.t.tolist() == [0.5, 1.5] and kept.delta.shape == (2, 2)
    assert observations_within(PinnConfig(), obs) is obs
    problem = identification_problem(config, TWO, obs)
    assert problem.targets.shape == (2, 2) and problem.t_f.max() <= 2.0 and problem.t_f.size == 42
    assert Architecture.of(config, TWO, identification=True).t_hi == 2.0
    assert Architecture.of(PinnConfig(), TWO, identification=True).t_hi == TWO.t_final
    with pytest.raises(ValueError, match="id_t_max=0.1 s: no observation"):
        observations_within(PinnConfig(id_t_max=0.1), obs)


def test_window_edges_and_training_points():
    np.testing.assert_array_equal(window_edges(4.2, 1.0), [0.0, 1.0, 2.0, 3.0, 4.0, 4.2])
    np.testing.assert_array_equal(window_edges(4.0 + 1e-12, 1.0), [0.0, 1.0, 2.0, 3.0, 4.0 + 1e-12])
    assert window_edges(10.0, 0.5).size == 21 and window_edges(1.0, 5.0).tolist() == [0.0, 1.0]
    config = PinnConfig(n_u=6, n_f=50, window=1.0)
    edges = window_edges(TWO.t_final, 1.0)
    problem = window_problem(config, TWO, edges, 2)
    assert problem.t_f.size == 56 and problem.targets.shape == (6, 2)
    assert (problem.t_f >= 0).all() and (problem.t_f <= 1.0).all()  # times since the window's start
    assert (problem.p_f >= TWO.p1_min).all() and (problem.p_f <= TWO.p1_max).all()
    assert set(problem.p_u) == {TWO.p1_min, TWO.p1_max}
    ref, _ = reference(TWO, 2.0 + problem.t_u, [TWO.p1_min, TWO.p1_max])
    np.testing.assert_allclose(problem.targets, np.where((problem.p_u == TWO.p1_max)[:, None], ref[1], ref[0]),
                               rtol=0, atol=1e-12)
    other = window_problem(config, TWO, edges, 3)
    assert not np.array_equal(other.t_f, problem.t_f)
    np.testing.assert_array_equal(window_problem(config, TWO, edges, 2).t_f, problem.t_f)


def test_marching_model_shapes(marched):
    solver, report = marched
    np.testing.assert_array_equal(solver.windows, [0.0, 1.0, 2.0, 3.0, 4.0])
    assert solver.theta.shape == (4, solver.arch.n_params) and solver.arch.t_hi == 1.0
    assert 4 <= report.iterations <= 12 and np.isfinite(report.loss) and "4 windows" in report.message
    assert not np.array_equal(solver.theta[0], solver.theta[1])
    traj = solver.solve(np.linspace(0.0, 4.0, 7), np.array([0.25, 0.3, 0.35]))
    assert traj.delta.shape == traj.omega.shape == (3, 7, 2)
    assert np.isfinite(traj.delta).all() and np.isfinite(traj.omega).all()
    np.testing.assert_allclose(traj.delta[:, 0], np.broadcast_to(TWO.delta0, (3, 2)), atol=1e-15)
    points = solver.solve_points(np.array([0.5, 3.0, 1.0]), np.array([0.26, 0.34, 0.3]))
    assert points.delta.shape == points.omega.shape == (3, 2)


def test_marching_is_continuous_at_the_window_boundaries(marched):
    """delta and omega just before a window's start (the previous window at its end) equal the
    window's own start state to 1e-12: each window's hard initial condition is the state the
    previous one reaches, for that P1."""
    solver, _ = marched
    P1 = np.array([0.25, 0.31, 0.35])
    inner = solver.windows[1:-1]
    left = solver.solve(np.nextafter(inner, 0.0), P1)  # the largest times of windows 0..2
    right = solver.solve(inner, P1)  # the starts of windows 1..3
    np.testing.assert_allclose(left.delta, right.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(left.omega, right.omega, rtol=0, atol=1e-12)
    # and the states do change across the windows (the check above is not of a constant)
    assert np.abs(np.diff(right.delta, axis=1)).min() > 1e-6


def test_marching_single_point_queries_use_the_cached_starts(marched, monkeypatch):
    """A repeated single-point query looks the window starts up instead of walking the windows, and
    gives what a grid query gives; the cache holds at most `cache_size` P1 values."""
    from solvers.pinn import evaluator as evaluators

    solver, _ = marched
    evaluator = solver._evaluate
    assert isinstance(evaluator, MarchingEvaluator)
    t, P1 = np.array([0.0, 0.7, 1.0, 2.5, 3.99, 4.0]), np.array([0.27, 0.33])
    grid = solver.solve(t, P1)
    walks = []
    real = evaluators.walk
    monkeypatch.setattr(evaluators, "walk", lambda *args: walks.append(args[3].size) or real(*args))
    for i in range(P1.size):
        for j in range(t.size):
            one = solver.solve(t[j:j + 1], P1[i:i + 1])
            np.testing.assert_allclose(one.delta[0, 0], grid.delta[i, j], rtol=0, atol=1e-12)
            np.testing.assert_allclose(one.omega[0, 0], grid.omega[i, j], rtol=0, atol=1e-12)
    assert walks == []  # the grid query cached both P1 values
    solver.solve(np.array([2.2]), 0.2987)
    solver.solve(np.array([3.2]), 0.2987)
    assert walks == [1]  # a new P1: one walk, then the cache
    points = solver.solve_points(np.repeat(t, 2), np.tile(P1, t.size))
    np.testing.assert_allclose(points.delta, grid.delta.transpose(1, 0, 2).reshape(-1, 2), rtol=0, atol=1e-12)
    evaluator.cache_size = 2
    solver.solve(t, np.array([0.28, 0.29, 0.3]))
    assert len(evaluator._cache) == 2


@pytest.mark.parametrize("target", list(BACKENDS))
def test_marching_save_load_round_trip(marched, target, tmp_path):
    """All windows in one model file (format version 3, the window edges in the .json): loaded by
    either backend they answer the same; the sha256 covers every window."""
    _need(target)
    solver, _ = marched
    npz, meta = solver.save(tmp_path / "model")
    info = json.loads(meta.read_text())
    assert info["version"] == 3 and info["windows"] == [0.0, 1.0, 2.0, 3.0, 4.0]
    loaded = make_solver(target, TWO, threads=1).load(tmp_path / "model")
    assert loaded.pinn_config.window == 1.0 and loaded.theta.shape == solver.theta.shape
    np.testing.assert_array_equal(loaded.windows, solver.windows)
    t, P1 = np.linspace(0.0, 4.0, 9), np.array([0.25, 0.3])
    a, b = solver.solve(t, P1), loaded.solve(t, P1)
    np.testing.assert_allclose(b.delta, a.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.omega, a.omega, rtol=0, atol=1e-12)
    with np.load(npz) as data:
        theta = data["theta"].copy()
    theta[3, 0] += 1e-9  # the last window only
    with open(npz, "wb") as fh:
        np.savez(fh, theta=theta)
    with pytest.raises(CorruptModelError, match="sha256"):
        load_model(tmp_path / "model")


def test_a_marching_model_budgeted_in_iterations_is_the_same_on_a_slower_machine(marched, monkeypatch):
    """`make bench` trains the network PINNs for iterations per window, not seconds: the same seed
    gives the same weights and the same error when every clock reading is 100 s later than the last
    (a machine far slower than this one), up to rounding."""
    import time as clock

    solver, report = marched
    name = solver.name
    t, P1 = np.linspace(0.0, TWO.t_final, 21), np.linspace(TWO.p1_min, TWO.p1_max, 3)
    ref = reference(TWO, t, P1)[0]
    now = [clock.perf_counter()]

    def slow() -> float:
        now[0] += 100.0
        return now[0]

    monkeypatch.setattr(clock, "perf_counter", slow)
    again = make_solver(name, TWO, **{**MARCHING, "max_seconds": None})
    again.fit()
    timed = make_solver(name, TWO, **{**MARCHING, "max_seconds": 1000.0})
    timed_report = timed.fit()
    monkeypatch.undo()
    assert timed_report.iterations < report.iterations  # what a budget in seconds does on that machine
    # equal up to the last bits of XLA's threaded sums
    assert rel_l2(again.solve(t, P1).delta, ref) == pytest.approx(rel_l2(solver.solve(t, P1).delta, ref), rel=1e-9)
