"""Saving and loading PINN models: the round trip across backends, and the refusal of a model
recorded as another case or as a case of other data. Small networks and budgets."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from pinn_helpers import (
    BACKENDS,
    CASE,
    SMALL,
    TORCH_JIT_SCRIPT_DEPRECATED,
    fit_tiny,
    need_backend,
    sampled_observations,
)

from solvers import make_solver
from systems.cases import SMIB_IDENTIFICATION, SMIB_INFERENCE, case_record

pytestmark = TORCH_JIT_SCRIPT_DEPRECATED


@pytest.fixture(scope="module", params=list(BACKENDS))
def fitted(request):
    """A tiny model of each backend, fitted for 3 iterations."""
    return fit_tiny(request.param)


@pytest.mark.slow
@pytest.mark.parametrize("source, target", [("torch-pinn", "jax-pinn"), ("jax-pinn", "torch-pinn")])
def test_save_load_round_trip_across_backends(tmp_path, source, target):
    need_backend(source)
    need_backend(target)
    trained = make_solver(source, CASE, **SMALL)
    trained.fit()
    ident = trained.identify(sampled_observations(SMIB_INFERENCE, 20))
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
