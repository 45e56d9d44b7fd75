"""The network kept sparse (`systems.sparse_network`): the same P_e as the Kron-reduced form, in
numpy and in the compiled solves of `solvers.classical.kernels.sparse`; how a `Case` carries it."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
from scipy.sparse import csr_matrix

from systems.cases import CASES, SMIB_INFERENCE, case_record
from systems.model import coupling, electrical_power
from systems.sparse_network import (
    LUFactors,
    SparseNetwork,
    augmented_network,
    lu_factors,
    sparse_electrical_power,
)

SIZES = ["wscc9", "ieee39", "case1354pegase"]


def _angles(case, rows: int, seed: int) -> np.ndarray:
    """`rows` random angle vectors (rows, n) rad: the equilibrium plus up to +-1 rad per machine."""
    rng = np.random.default_rng(seed)
    return np.asarray(case.delta0) + rng.uniform(-1.0, 1.0, (rows, case.n))


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.mark.parametrize("name", SIZES)
def test_power_of_the_sparse_network_is_the_reduced_forms(name):
    case = CASES[name]
    delta = _angles(case, 3, seed=len(name))
    reduced = electrical_power(coupling(case), delta)
    assert _rel(sparse_electrical_power(case.network, case.E, delta), reduced) <= 1e-10
    assert _rel(sparse_electrical_power(case.network, case.E, case.delta0), np.asarray(case.p_m)) <= 1e-10


@pytest.mark.parametrize("name", ["wscc9", "case1354pegase"])
def test_compiled_solves_of_the_factors_give_the_same_power(name):
    pytest.importorskip("numba")
    from solvers.classical.kernels.sparse import sparse_power

    case = CASES[name]
    factors = lu_factors(case.network, case.E)
    assert factors.nnz < 20 * case.network.n_buses  # the ordering keeps the fill small
    n = case.n
    for delta in _angles(case, 2, seed=3):
        scratch = np.concatenate([np.cos(delta), np.sin(delta), np.full(n, np.nan)])
        sparse_power(scratch, factors, n, np.full(case.network.n_buses, np.nan, complex))
        assert _rel(scratch[2 * n:], electrical_power(coupling(case), delta)) <= 1e-10


def test_a_case_carries_its_network_as_derived_data():
    case = CASES["wscc9"]
    assert isinstance(case.network, SparseNetwork) and case.network.at.size == case.n
    bare = dataclasses.replace(case, network=None)
    assert bare == case and hash(bare) == hash(case) and repr(bare) == repr(case)
    assert "network" not in case_record(case) and list(case_record(case)) == [
        f.name for f in dataclasses.fields(case) if f.name not in ("network", "fault")]  # a step case: no fault
    heavier = case.with_params(m=2.0, d=0.5)
    assert heavier.network is case.network  # m, d are not the network's
    assert pickle.loads(pickle.dumps(case)).network.Y_bb.nnz == case.network.Y_bb.nnz
    G = np.array(case.G)
    G[0, 1] = G[1, 0] = G[0, 1] + 1e-3
    with pytest.raises(ValueError, match="Case.network is not the network"):
        dataclasses.replace(case, G=G)
    assert dataclasses.replace(case, G=G, network=None).network is None
    with pytest.raises(ValueError, match="Case.network must be a SparseNetwork of 1 machines"):
        dataclasses.replace(SMIB_INFERENCE, network=case.network)
    assert SMIB_INFERENCE.network is None


def test_the_augmented_network_and_its_machine_nodes():
    Ybus = (1.0 - 4j) * (3 * np.eye(3) - np.ones((3, 3)))  # three buses, three equal lines
    y = np.array([-5j, -3j])

    Y = augmented_network(csr_matrix(Ybus), np.array([0.5, 0.0, 0.2 - 0.1j]), np.array([2, 0]), y).toarray()
    assert Y.shape == (5, 5) and np.allclose(Y, Y.T)
    assert Y[3, 2] == Y[2, 3] == 5j and Y[4, 0] == 3j and Y[3, 3] == -5j
    assert Y[2, 2] == Ybus[2, 2] + 0.2 - 0.1j - 5j
    network = SparseNetwork.of(Y, 2, reduces_to=0)
    assert network.at.tolist() == [2, 0] and np.allclose(network.y, y) and network.n_buses == 3
    assert np.array_equal(network.augmented().toarray(), Y)  # the same entries, back
    with pytest.raises(ValueError, match="augmented: its last 3 nodes"):
        SparseNetwork.of(Y, 3, reduces_to=0)
    with pytest.raises(ValueError, match="E must be"):
        lu_factors(network, [1.0])
    assert LUFactors.empty().nnz == 0
