"""The diffrax adapter: accuracy against the reference and a closed form, batch modes, constant step,
identification with the Jacobian through the solver, option checks, failures."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import require

from harness import metrics
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, standard_grid
from systems.reference import reference
from solvers import make_solver
from solvers.base import SolveError

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")

SMALL_SHAPES = ((201, 12),)  # what the secondary solvers compile in fit: JIT is the slow part here


def _fitted(case=SMIB_INFERENCE, config="default", shapes=SMALL_SHAPES, **options):
    require("diffrax")
    solver = make_solver("diffrax", case, config, **options)
    solver.FIT_SHAPES = shapes
    solver.fit()
    return solver


@pytest.fixture(scope="module")
def tight():
    """The tight config, fitted on the grid's shapes (the default config shares its compiled code:
    the tolerances are arguments)."""
    return _fitted(config="tight", shapes=((201, 100), (201, 12), (1, 1)))


def test_tight_matches_reference_on_the_grid(tight):
    t, P1 = standard_grid(SMIB_INFERENCE)
    traj = tight.solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    assert metrics.rel_l2(traj.delta, ref_delta) <= 1e-9
    assert metrics.rel_l2(traj.omega, ref_omega) <= 1e-8  # measured 1.6e-9


def test_default_is_ode45_like():
    solver = _fitted()
    assert (solver.options["rtol"], solver.options["atol"]) == (1e-3, 1e-6)
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    error = metrics.rel_l2(solver.solve(t, P1).delta, reference(SMIB_INFERENCE, t, P1)[0])
    assert 1e-9 < error < 1e-2


def test_arbitrary_sizes_padded_order_and_time_zero(tight):
    t = np.array([3.0, 0.0, 19.5, 3.0, 7.0, 0.0, 0.2])  # 7 times, 5 P1: padded to 8 and 8
    P1 = np.array([0.08, 0.1, 0.13, 0.15, 0.18])
    traj = tight.solve(t, P1)
    ref_delta, ref_omega = reference(SMIB_INFERENCE, t, P1)
    np.testing.assert_allclose(traj.delta, ref_delta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.omega, ref_omega, rtol=0, atol=1e-9)
    assert (traj.delta[:, 1] == SMIB_INFERENCE.delta0).all() and (traj.omega[:, 5] == SMIB_INFERENCE.omega0).all()


def test_linear_case_matches_closed_form():
    case = dataclasses.replace(SMIB_INFERENCE, b=0.0)
    solver = _fitted(case, "tight")
    t, P1 = standard_grid(case, n_p1=12)
    traj = solver.solve(t, P1)
    m, d = case.m, case.d
    v = P1[:, None] / d
    decay = np.exp(-d * t / m)
    delta = case.delta0 + v * t + (case.omega0 - v) * (m / d) * (1.0 - decay)
    omega = v + (case.omega0 - v) * decay
    assert metrics.rel_l2(traj.delta, delta) <= 1e-9
    assert metrics.rel_l2(traj.omega, omega) <= 1e-9


def test_vmap_and_stacked_agree(tight):
    vmap = _fitted(config="tight", batch="vmap")
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    a, b = tight.solve(t, P1), vmap.solve(t, P1)
    # their steps differ: the difference is the solvers' error at rtol 1e-10 (~4e-9 measured)
    np.testing.assert_allclose(a.delta, b.delta, rtol=0, atol=2e-8)
    np.testing.assert_allclose(a.omega, b.omega, rtol=0, atol=2e-8)


def test_constant_step_converges():
    t, P1 = standard_grid(SMIB_INFERENCE, n_p1=12)
    ref_delta = reference(SMIB_INFERENCE, t, P1)[0]
    solver = _fitted(dt=1.0)
    assert [p["dt"] for p in solver.precision_sweep([1e-3])] == [1.0, 0.5, 0.2, 0.1, 0.05, 0.02]
    errors = []
    for dt in (1.0, 0.5, 0.25):  # dt is an argument of the compiled code: no recompilation
        solver.options["dt"] = dt
        solver.fit()
        errors.append(metrics.rel_l2(solver.solve(t, P1).delta, ref_delta))
    assert errors[0] > 20 * errors[1] > 400 * errors[2]  # measured ~60x a halving (3e-8, 5e-10, 8e-12)
    assert errors[2] < 1e-10


def test_adaptive_precision_sweep_is_the_tolerance_sweep(tight):
    assert tight.precision_sweep([1e-4]) == [{"rtol": 1e-4, "atol": pytest.approx(1e-7)}]


@pytest.fixture(scope="module")
def identification_obs():
    from harness.suites.identification import observations

    return observations(SMIB_IDENTIFICATION.with_params(0.18, 0.09), 100, 0.0, seed=1000)


def test_identify_recovers_m_and_d(identification_obs):
    est = make_solver("diffrax", SMIB_IDENTIFICATION, "tight").identify(identification_obs)
    assert est.success, est.message
    assert metrics.rel_error(est.m, 0.18) < 1e-4
    assert metrics.rel_error(est.d, 0.09) < 1e-4


def test_jacobian_equals_finite_differences(identification_obs):
    """The sensitivities identify uses (same padded layout, so the same compiled code)."""
    import jax

    from systems.model import smib_system
    from solvers.classical import ObservationLayout
    from solvers.diffrax_ode import _compiled, _pad, bucket

    solver = make_solver("diffrax", SMIB_IDENTIFICATION, "tight")
    layout = ObservationLayout.of(identification_obs)
    t, p1 = _pad(layout.t, bucket(layout.t.size)), _pad(layout.P1, bucket(layout.P1.size))
    values, sensitivities = solver._functions(smib_system(SMIB_IDENTIFICATION))
    assert (values, sensitivities) == _compiled(smib_system(SMIB_IDENTIFICATION), "dopri8", "stacked", True, 16384)
    m, d, h = 0.18, 0.09, 1e-6
    with jax.enable_x64(True):
        _, ok, jac = sensitivities(m, d, 1e-12, 1e-14, 0.0, t, p1)
        sim = [np.asarray(values(np.array([mm]), np.array([dd]), 1e-12, 1e-14, 0.0, t, p1)[0])
               for mm, dd in ((m + h, d), (m - h, d), (m, d + h), (m, d - h))]
    assert np.asarray(ok).all()
    fd = np.stack([(sim[0] - sim[1]) / (2 * h), (sim[2] - sim[3]) / (2 * h)], axis=-1)
    jac = np.asarray(jac)
    assert np.abs(jac - fd).max() <= 1e-5 * np.abs(fd).max()


BAD_OPTIONS = [
    ("rtol", 0.0), ("rtol", -1e-3), ("rtol", float("nan")), ("rtol", "1e-3"), ("rtol", True),
    ("atol", float("inf")), ("atol", None),
    ("dt", 0.0), ("dt", -0.1), ("dt", "0.1"), ("dt", float("inf")),
    ("method", "rk4"), ("batch", "loop"),
    ("max_steps", 0), ("max_steps", 10.5), ("max_steps", True),
    ("m_bounds", (2.0, 0.02)), ("m_bounds", (0.0, 1.0)), ("m_bounds", 0.5), ("d_bounds", (0.1,)),
    ("d_bounds", (0.1, float("inf"))), ("threads", 0), ("threads", 2.0),
]


@pytest.mark.parametrize("option,value", BAD_OPTIONS)
def test_bad_options_raise_value_error_naming_the_option(option, value):
    require("diffrax")
    with pytest.raises(ValueError, match=f"option {option}"):
        make_solver("diffrax", SMIB_INFERENCE, **{option: value})


def test_too_few_steps_raise_solve_error():
    """Stacked: the failing P1 is found by solving each alone (vmap names it directly)."""
    solver = _fitted(max_steps=5)
    with pytest.raises(SolveError, match=r"diffrax: .*failed at P1=0\.08.*max_steps=5"):
        solver.solve(np.linspace(0.0, 20.0, 201), np.linspace(0.08, 0.18, 12))


def test_failed_integration_names_p1(tight):
    with pytest.raises(SolveError, match=r"diffrax: .*failed at P1=1e\+308"):
        tight.solve([1.0, 20.0], [0.1, 1e308])
