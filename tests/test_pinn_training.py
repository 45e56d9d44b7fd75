"""PINN training and identification: a short training run's loose accuracy, m and d recovered
with their intervals, omega observations used, and the paper configs in float32. Small
networks and budgets."""

from __future__ import annotations

import numpy as np
import pytest
from pinn_helpers import (
    BACKENDS,
    CASE,
    SMALL,
    TORCH_JIT_SCRIPT_DEPRECATED,
    need_backend,
    sampled_observations,
)

from harness.measure.metrics import rel_l2
from solvers import make_solver
from solvers.pinn.problems import identification_problem
from systems.cases import SMIB_IDENTIFICATION, Observations
from systems.reference import reference

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BACKENDS))
def test_short_training_reaches_a_loose_accuracy(name):
    need_backend(name)
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
    need_backend(name)
    case = SMIB_IDENTIFICATION
    solver = make_solver(name, case, **{**SMALL, "id_width": 10, "id_n_f": 300, "id_max_iterations": 60})
    result = solver.identify(sampled_observations(case, 100))
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
    obs = sampled_observations(CASE, 30, with_omega=True)
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
    need_backend(name)
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
    ident = solver.identify(sampled_observations(CASE, 20))
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
