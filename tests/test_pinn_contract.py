"""The PINN adapters under the solver contract: registration, errors before fit, domain and
extrapolation, query order and repeats, determinism, BLAS threads, option errors, devices and
progress output. Small networks and budgets."""

from __future__ import annotations

import numpy as np
import pytest
from pinn_helpers import (
    BACKENDS,
    BACKENDS_SLOW_JAX,
    CASE,
    SMALL,
    TORCH_JIT_SCRIPT_DEPRECATED,
    fit_tiny,
    need_backend,
)

from solvers import SOLVERS, make_solver
from solvers.base import NotFittedError
from solvers.progress import progress_enabled

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


@pytest.fixture(scope="module", params=list(BACKENDS))
def fitted(request):
    """A tiny model of each backend, fitted for 3 iterations."""
    return fit_tiny(request.param)


@pytest.mark.parametrize("name, module, cls", [("torch-pinn", "torch_pinn", "TorchPinn"),
                                               ("jax-pinn", "jax_pinn", "JaxPinn")])
def test_registered(name, module, cls):
    """The registry maps each name to its backend's class, and that class carries the name."""
    need_backend(name)
    import importlib

    expected = getattr(importlib.import_module(f"solvers.pinn.{module}"), cls)
    assert SOLVERS[name] is expected and expected.name == name
    assert type(make_solver(name, CASE, threads=1)) is expected


@pytest.mark.parametrize("name", list(BACKENDS))
def test_solve_before_fit_raises(name):
    need_backend(name)
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
    need_backend(name)
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
    need_backend("torch-pinn")
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
    need_backend(name)
    with pytest.raises(ValueError):
        make_solver(name, CASE, **bad)


def _trains_the_same_network_on(cpu_trained, device: str) -> None:
    """On a GPU machine: the adapter trained on `device` gives `cpu_trained`'s network to float64
    rounding, and its fit says where it trained."""
    gpu = make_solver(cpu_trained.name, CASE, **SMALL, device=device)
    assert "trained on" in gpu.fit().message
    np.testing.assert_allclose(gpu.theta, cpu_trained.theta, rtol=1e-6, atol=1e-9)


def test_jax_trains_on_the_device_it_is_given_and_answers_queries_on_the_cpu():
    need_backend("jax-pinn")
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
    need_backend("torch-pinn")
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
