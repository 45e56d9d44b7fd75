"""The PINNs' physics (torch-pinn, jax-pinn): every machine's swing residual by nested forward-mode
autodiff against the model's, the hard initial condition for any weights, and the forward
problem (the paper's data, seeded), on the SMIB and on a small two-machine system."""

from __future__ import annotations

import numpy as np
import pytest
from pinn_helpers import BACKENDS, CASE, TORCH_JIT_SCRIPT_DEPRECATED, TWO, backend_ops, x64_scope

from solvers.pinn import network
from solvers.pinn.architecture import Architecture, init_theta
from solvers.pinn.config import PinnConfig
from solvers.pinn.problems import forward_problem
from systems import model
from systems.reference import reference

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


@pytest.mark.parametrize("case", [CASE, TWO], ids=["smib", "two-machines"])
@pytest.mark.parametrize("name", [*BACKENDS, "torch-autograd"])
def test_swing_residual_of_a_known_function(name, case):
    """The residual of every machine by nested forward-mode autodiff equals the model's
    (`systems.model.residual` in numpy, generator 1 at P1 and the others at p_m) for known
    delta_k(t), omega_k(t)."""
    ops, array, to_np = backend_ops(name)
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
    with x64_scope(name):
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
    ops, array, to_np = backend_ops(name)
    for outputs in (1, 2):
        arch = Architecture.of(PinnConfig(hidden_layers=2, width=8, outputs=outputs), case)
        assert arch.sizes[-1] == outputs * case.n and arch.machines == case.n
        theta = init_theta(arch, seed=3)
        with x64_scope(name):
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
