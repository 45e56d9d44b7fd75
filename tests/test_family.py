"""The scaling family (systems.family): case118 at its equilibrium, machines merged per bus, the
sparse Kron reduction against the dense one, and the lazy registration in CASES."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse

from systems import family, grids
from systems.cases import CASES
from systems.family import FAMILY, FAMILY_CASES, family_case, family_model, family_size, merge_machines
from systems.network import kron_reduce, kron_reduce_sparse
from systems.reference import reference


def p_e(delta, E, G, B):
    """P_e,k = sum_j E_k E_j (G_kj cos(d_k - d_j) + B_kj sin(d_k - d_j)), written independently."""
    diff = delta[:, None] - delta[None, :]
    return E * ((G * np.cos(diff) + B * np.sin(diff)) @ E)


@pytest.fixture(scope="module")
def case118():
    """(case, model, net): the Case from CASES, and a second build's model and solved net."""
    import pandapower.networks as pn

    net = pn.case118()
    return CASES["case118"], family_model(net, 60.0), net


def test_case118_equilibrium(case118):
    case, model, net = case118
    assert case is family_case("case118") and case.n == 54 and case.t_final == 10.0
    E, G, B, delta0, p_m, m, d = (np.array(x) for x in (case.E, case.G, case.B, case.delta0, case.p_m,
                                                       case.m, case.d))
    np.testing.assert_allclose(p_e(delta0, E, G, B), p_m, rtol=0, atol=1e-10)
    assert np.array_equal(G, G.T) and np.array_equal(B, B.T)
    # p_m is the power flow's machine P, machine by machine (the slack, bus 69, included).
    np.testing.assert_allclose(model.p_m, model.p_flow, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(model.p_m, p_m)
    flow = {("gen", i): p for i, p in net.res_gen.p_mw.items()} | {("ext_grid", i): p for i, p in
                                                                 net.res_ext_grid.p_mw.items()}
    np.testing.assert_allclose(p_m, [flow[e] / 100.0 for e in model.elements], rtol=0, atol=1e-10)
    # Generator 1 = the largest P (607 MW at MATPOWER bus 89); the others in bus order.
    assert p_m[0] == p_m.max() == pytest.approx(6.07, abs=1e-10) and list(model.buses[1:]) == sorted(model.buses[1:])
    # The rule: H = 4 s on ratings >= max(P_max, |S|, 10 MVA), 60 Hz; d = 0.5 m; P1 = p_m[0] +- 30 %.
    rating = m * 2 * np.pi * 60.0 * 100.0 / (2 * 4.0)
    assert (rating >= 10.0 - 1e-9).all() and (rating >= 100 * np.abs(p_m) - 1e-9).all()
    np.testing.assert_allclose(d, 0.5 * m, rtol=1e-15)
    np.testing.assert_allclose((case.p1_min, case.p1_max), (0.7 * p_m[0], 1.3 * p_m[0]), rtol=1e-14)
    assert "Kundur" in case.source and "case118" in case.source


def test_case118_at_rest(case118):
    """With P1 = p_m[0] nothing moves: DOP853 at rtol = atol = 1e-12 over 2 s."""
    case = case118[0]
    delta, omega = reference(case, np.linspace(0.0, 2.0, 21), [case.p_m[0]])
    assert np.abs(delta[0] - np.array(case.delta0)).max() <= 1e-9
    assert np.abs(omega).max() <= 1e-9


def _tiny(split: bool, slack_pair: bool = False):
    """3 buses, 110 kV: ext_grid at bus 0, 80 MW of generation at bus 1, a 120 MW load at bus 2.
    split: the 80 MW as two gens (60 MW sn_mva 100, 20 MW P_max 50) instead of one (sn_mva 150);
    slack_pair: a 10 MW gen next to the ext_grid too."""
    import pandapower as pp

    net = pp.create_empty_network(sn_mva=100.0, f_hz=50.0)
    b = [pp.create_bus(net, vn_kv=110.0) for _ in range(3)]
    for f, t in ((0, 1), (1, 2), (0, 2)):
        pp.create_line_from_parameters(net, b[f], b[t], length_km=20.0, r_ohm_per_km=0.05, x_ohm_per_km=0.4,
                                       c_nf_per_km=10.0, max_i_ka=1.0)
    pp.create_ext_grid(net, b[0], vm_pu=1.02, max_p_mw=200.0)
    pp.create_load(net, b[2], p_mw=120.0, q_mvar=30.0)
    if split:
        pp.create_gen(net, b[1], p_mw=60.0, vm_pu=1.01, sn_mva=100.0)
        pp.create_gen(net, b[1], p_mw=20.0, vm_pu=1.01, max_p_mw=50.0)
    else:
        pp.create_gen(net, b[1], p_mw=80.0, vm_pu=1.01, sn_mva=150.0)
    if slack_pair:
        pp.create_gen(net, b[0], p_mw=10.0, vm_pu=1.02, max_p_mw=40.0)
    return net


def test_machines_merged_per_bus():
    """Two gens on one bus are one machine: summed P, Q and rating, the same model as one gen;
    a gen beside the slack merges into the ext_grid (rating: the ext_grid's 200 + the gen's 40 MW)."""
    split, one = _tiny(split=True), _tiny(split=False)
    assert merge_machines(_tiny(split=True)) == {0: 200.0, 1: 150.0}
    a, b = family_model(split, 50.0), family_model(one, 50.0)
    assert a.buses == b.buses == (1, 0) and a.elements == (("gen", 0), ("ext_grid", 0))  # 80 MW > the slack's
    for name in ("m", "E", "delta0", "p_m", "G", "B"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(a.m, 2 * 4.0 * np.array([150.0, 200.0]) / (2 * np.pi * 50.0 * 100.0), rtol=1e-15)
    pair = family_model(_tiny(split=False, slack_pair=True), 50.0)
    assert pair.elements == b.elements  # the same flow, the slack machine on a larger rating
    np.testing.assert_allclose(pair.p_m, b.p_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pair.m, 2 * 4.0 * np.array([150.0, 240.0]) / (2 * np.pi * 50.0 * 100.0), rtol=1e-15)


def test_sparse_kron_reduction_equals_dense():
    rng = np.random.default_rng(0)
    n = 40  # a random sparse network: a ring plus chords, lossy lines, shunts at every node
    edges = [(i, (i + 1) % n) for i in range(n)] + [tuple(rng.choice(n, 2, replace=False)) for _ in range(20)]
    Y = np.zeros((n, n), complex)
    for i, j in edges:
        y = 1.0 / complex(rng.uniform(0.001, 0.05), rng.uniform(0.01, 0.3))
        Y[[i, j], [i, j]] += y
        Y[i, j] -= y
        Y[j, i] -= y
    Y += np.diag(rng.uniform(0.0, 1.0, n) - 1j * rng.uniform(0.0, 0.5, n))
    keep = [7, 3, 31, 12]
    dense = kron_reduce(Y, keep)
    for block in (256, 3):
        np.testing.assert_allclose(kron_reduce_sparse(sparse.csr_matrix(Y), keep, block=block), dense,
                                   rtol=0, atol=1e-12 * np.abs(dense).max())
    with pytest.raises(ValueError, match="keep"):
        kron_reduce_sparse(sparse.csr_matrix(Y), [0, 0])


def test_registered_lazily_and_bad_names(monkeypatch):
    assert FAMILY == ("wscc9", "ieee39", *FAMILY_CASES) and family_case("wscc9") is grids.wscc9()
    monkeypatch.setattr(family, "family_case", lambda name: pytest.fail(f"built {name}"))
    assert set(FAMILY) <= set(CASES) and "case9241pegase" in CASES and len(CASES) == len(list(CASES))
    monkeypatch.undo()
    assert family_size("case118") == (118, 54)
    for bad in ("case9999", "CASE118", 118):
        with pytest.raises(ValueError, match="name"):
            family_case(bad)
        with pytest.raises(ValueError, match="name"):
            family_size(bad)
    import pandapower as pp

    net = _tiny(split=False)
    pp.create_ward(net, 2, ps_mw=5.0, qs_mvar=0.0, pz_mw=0.0, qz_mvar=0.0)
    with pytest.raises(ValueError, match="net has in-service ward"):
        family_model(net, 50.0)
