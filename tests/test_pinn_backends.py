"""The two PINN backends are one specification: the same loss, gradient, Jacobian and outputs in
torch and JAX for the same config and seed, and torch's Taylor-mode query path against the
shared network and autodiff. Small networks throughout."""

from __future__ import annotations

import numpy as np
import pytest
from pinn_helpers import CASE, TORCH_JIT_SCRIPT_DEPRECATED, TWO, backend_ops, need_backend

from solvers.pinn import network
from solvers.pinn.architecture import Architecture, init_theta
from solvers.pinn.config import PinnConfig
from solvers.pinn.problems import Problem, forward_problem, identification_p_range, identification_problem
from systems.cases import Observations

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


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
    ops, array, to_np = backend_ops("torch-pinn")
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
    need_backend("torch-pinn")
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
    need_backend("torch-pinn")
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
    ops, array, to_np = backend_ops("torch-pinn")
    ref_delta, ref_omega = network.delta_omega(arch, array(theta), array(t)[None, :], array(p)[:, None], ops)
    np.testing.assert_allclose(delta, to_np(ref_delta), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(omega, to_np(ref_omega), rtol=1e-11, atol=1e-13)
