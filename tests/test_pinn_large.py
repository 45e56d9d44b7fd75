"""The PINN's training for large systems: the residuals in acceleration units, the JAX trainer's
Jacobian products and Gauss-Newton diagonal, the matrix-free optimiser through the adapter, and
the named config for large systems. Tiny networks on a two-machine system; no long training."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pinn_helpers import BACKENDS, TWO, TWO_SMALL, need_backend

from solvers import make_solver
from solvers.base import LARGE_SYSTEMS
from solvers.pinn.architecture import Architecture, init_theta
from solvers.pinn.config import CONFIGS, PinnConfig
from solvers.pinn.problems import Problem, residual_weights, window_edges, window_problem

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

LARGE = "marching-large"


def _window(config: PinnConfig) -> tuple[Architecture, Problem, np.ndarray]:
    """TWO's window 1 problem of `config` (start states drawn at random; its data points are the
    last collocation points, with theirs), its network and weights."""
    arch = Architecture.of(config, TWO)
    problem = window_problem(config, TWO, window_edges(TWO.t_final, config.window), 1)
    rng = np.random.default_rng(3)
    start = np.stack([rng.uniform(-0.2, 0.2, (problem.t_f.size, 2)), rng.uniform(-0.5, 0.5, (problem.t_f.size, 2))],
                     axis=1)
    problem = dataclasses.replace(problem, start_f=start, start_u=start[problem.t_f.size - problem.t_u.size:])
    return arch, problem, init_theta(arch, config.seed, window=1)


def test_acceleration_units_divide_each_machines_residual_by_its_inertia():
    assert residual_weights(PinnConfig(), TWO) is None
    np.testing.assert_allclose(residual_weights(PinnConfig(residual_units="acceleration"), TWO), [10.0, 5.0])
    # two outputs: the f_omega columns (rad/s already) keep 1
    np.testing.assert_allclose(residual_weights(PinnConfig(residual_units="acceleration", outputs=2), TWO),
                               [1.0, 1.0, 10.0, 5.0])


# the adapter's options and the same config: the products test and the fit share one compilation
OPTIONS = {**TWO_SMALL, "window": 1.0, "residual_units": "acceleration"}
CONFIG = PinnConfig(**{k: v for k, v in OPTIONS.items() if k not in ("threads", "progress")})


def test_torch_trains_on_the_residuals_in_acceleration_units():
    """The same network's residuals: in acceleration units, machine k's column is its power
    residual / m_k, and so are the Jacobian's rows (torch's Taylor-mode path; JAX's shares
    `network.residual_vector`, checked below)."""
    need_backend("torch-pinn")
    solver = make_solver("torch-pinn", TWO, **OPTIONS)
    solver._prepare_backend()
    (arch, a_problem, theta), (_, p_problem, _) = _window(CONFIG), _window(dataclasses.replace(
        CONFIG, residual_units="power"))
    a_trainer, p_trainer = (solver._compile(arch, pr, solver.physics, "float64") for pr in (a_problem, p_problem))
    scale = np.concatenate([np.ones(a_problem.targets.size), np.tile(1.0 / np.asarray(TWO.m), a_problem.t_f.size)])
    r_power = p_trainer.residuals(theta)
    assert np.abs(r_power).max() > 1e-3  # the premise: residuals that are not zero
    np.testing.assert_allclose(a_trainer.residuals(theta), scale * r_power, rtol=1e-12)
    np.testing.assert_allclose(a_trainer.jacobian(theta), scale[:, None] * p_trainer.jacobian(theta), rtol=1e-11,
                               atol=1e-14)


def test_jax_jacobian_products_and_diagonal_equal_the_jacobians():
    """The matrix-free trainer's J v, J^T u and diag(J^T J) (in batches of points) against the
    explicit Jacobian, on a window problem with start states and data points, in acceleration
    units (the residuals: the power residuals / m_k)."""
    need_backend("jax-pinn")
    solver = make_solver("jax-pinn", TWO, **OPTIONS)
    solver._prepare_backend()
    arch, problem, theta = _window(CONFIG)
    trainer = solver._compile(arch, problem, solver.physics, "float64")
    r = trainer.residuals(theta)
    # jax.jit compiles on the first call: only the residuals of the problem in p.u.
    r_power = solver._compile(arch, dataclasses.replace(problem, residual_weights=None), solver.physics,
                              "float64").residuals(theta)
    scale = np.concatenate([np.ones(problem.targets.size), np.tile(1.0 / np.asarray(TWO.m), problem.t_f.size)])
    np.testing.assert_allclose(r, scale * r_power, rtol=1e-12)
    J = trainer.jacobian(theta)
    rng = np.random.default_rng(4)
    v, u = rng.normal(size=J.shape[1]), rng.normal(size=J.shape[0])
    np.testing.assert_allclose(trainer.jvp(theta, v), J @ v, rtol=1e-10, atol=1e-12 * np.abs(J @ v).max())
    np.testing.assert_allclose(trainer.vjp(theta, u), J.T @ u, rtol=1e-10, atol=1e-12 * np.abs(J.T @ u).max())
    np.testing.assert_allclose(trainer.diagonal(theta), np.sum(J ** 2, axis=0), rtol=1e-10)


def test_the_matrix_free_optimiser_trains_through_the_adapter_and_torch_refuses_it():
    need_backend("jax-pinn")
    solver = make_solver("jax-pinn", TWO, **OPTIONS, optimizer="gn-cg", cg_iterations=5, warm_start=True)
    report = solver.fit()
    assert report.iterations == 4 * 3 and np.isfinite(report.loss)
    assert "Gauss-Newton-CG" in report.message and solver.theta.shape[0] == 4
    if "torch-pinn" in BACKENDS:
        pytest.importorskip("torch")
        with pytest.raises(ValueError, match="optimizer"):
            make_solver("torch-pinn", TWO, **OPTIONS, optimizer="gn-cg")


def test_the_config_for_large_systems_is_marked_and_valid():
    from solvers.pinn.jax_pinn import JaxPinn

    config = PinnConfig(**CONFIGS[LARGE])
    assert config.window is not None and config.residual_units == "acceleration"
    assert LARGE_SYSTEMS in JaxPinn.marks(LARGE)
    with pytest.raises(ValueError):
        PinnConfig(optimizer="gn-cg", cg_iterations=0)
    with pytest.raises(ValueError):
        PinnConfig(residual_units="watts")
