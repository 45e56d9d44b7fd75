"""pinnsim's output forms: a "rest-exact" component holds a machine at rest exactly, whatever its
weights, and so does the simulator at a case's operating point; a "plain" one need not."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")
pytest.importorskip("pandapower")

import jax
import jax.numpy as jnp

from solvers import make_solver
from solvers.pinn.architecture import glorot_weights
from solvers.pinn.component import (
    FORMS,
    KAPPA,
    PHI0,
    SLIP,
    THETA2,
    V0,
    V1,
    V2,
    Component,
    Domain,
    P,
    phi_rate,
)
from systems.cases import CASES
from systems.model import center_of_inertia


def _untrained(form: str, domain: Domain | None = None, seed: int = 4, scale: float = 1.0) -> Component:
    """A component of random weights (biases too, so that nothing in it happens to be zero), all
    multiplied by `scale`."""
    domain = Domain() if domain is None else domain
    sizes = Component(24, 2, domain, np.empty(0), form=form).sizes
    rng = np.random.default_rng(seed)
    theta = np.concatenate(glorot_weights(sizes, rng))
    return Component(24, 2, domain, scale * (theta + 0.1 * rng.normal(size=theta.size)), form=form)


def _at_rest(domain: Domain, n: int, rng: np.random.Generator) -> np.ndarray:
    """n inputs of the box at rest: slip, theta2, v1, v2 zero and the power at balance, p = v0 sin(phi0)."""
    x = domain.sample(n, rng)
    x[:, [SLIP, THETA2, V1, V2]] = 0.0
    x[:, KAPPA] = domain.kappa[1] * rng.uniform(size=n)
    x[:, P] = x[:, V0] * np.sin(x[:, PHI0])
    return x


def _phi_rate(component: Component, x: np.ndarray, t: float) -> np.ndarray:
    with jax.enable_x64(True):
        run = jax.vmap(lambda xi: jnp.stack(phi_rate(component.sizes, component.domain, component.form,
                                                     jnp.asarray(component.theta), xi, jnp.asarray(t))))
        return np.asarray(run(jnp.asarray(x)))


@pytest.mark.parametrize("form", FORMS)
def test_a_rest_exact_component_holds_a_machine_at_rest_and_a_plain_one_need_not(form):
    domain = Domain()
    x = _at_rest(domain, 50, np.random.default_rng(2))
    out = _phi_rate(_untrained(form), x, domain.h)
    moved = np.abs(out[:, 0] - x[:, PHI0]).max(), np.abs(out[:, 1]).max()
    if form == "rest-exact":
        assert moved[0] <= 1e-15 and moved[1] <= 1e-13
    else:
        assert moved[0] > 1e-8 and moved[1] > 1e-6  # the same weights' single output moves it


def test_an_unknown_form_lists_the_known_ones():
    with pytest.raises(ValueError, match=r"^form must be one of \('plain', 'rest-exact'\), not 'exact'$"):
        Component(24, 2, Domain(), np.empty(0), form="exact").sizes  # noqa: B018


@pytest.mark.parametrize("form", [pytest.param("plain", marks=pytest.mark.slow), "rest-exact"])
def test_the_simulator_holds_the_operating_point_with_a_rest_exact_component(form, tmp_path):
    """wscc9 at P1 = generator 1's own power: the reference stays at its equilibrium. Random weights
    saved where the adapter looks for its trained network (so that nothing trains here), small
    enough that the plain one keeps the machines inside the domain."""
    case = CASES["wscc9"]
    solver = make_solver("pinnsim", case, form=form, component_dir=str(tmp_path))
    _untrained(form, solver.domain, scale=0.05).save(tmp_path / solver.component_key())
    assert "loaded from" in solver.fit().message
    traj = solver.solve(np.linspace(0.0, 1.0, 5), np.array([float(case.p_m[0])]))
    drift = np.abs(center_of_inertia(case, traj.omega)).max()  # rad/s
    if form == "rest-exact":
        assert drift <= 1e-9
    else:
        assert drift > 1e-6
