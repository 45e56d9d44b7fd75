"""Fault networks (`systems.faults`): for each contingency of wscc9, kundur4 and ieee39, the pre-fault,
fault-on and post-fault reduced networks, each checked against an independent computation."""

from __future__ import annotations

import copy
import functools

import numpy as np
import pytest
from scipy.sparse.csgraph import connected_components, shortest_path

from systems.cases import CASES
from systems.faults import CONTINGENCIES, Contingency, contingencies, fault_networks
from systems.grids import GRIDS
from systems.network import bus_indices, electrical_power, kron_reduce, solve_power_flow

NAMES = ("wscc9", "kundur4", "ieee39")
PAIRS = [(name, c) for name in NAMES for c in CONTINGENCIES[name]]
IDS = [f"{name}-{c.name}" for name, c in PAIRS]


@functools.cache
def _built(name: str):
    """(net, model, case) of the case `name`, built by its own builders."""
    build_net, build_model = GRIDS[name]
    net = build_net()
    return net, build_model(net), CASES[name]


@functools.cache
def _networks(name: str, contingency: Contingency):
    net, model, _ = _built(name)
    return fault_networks(net, model, contingency)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def _ppc_bus(net, name: int) -> int:
    return int(net._pd2ppc_lookups["bus"][bus_indices(net, [name])[0]])


def _line_index(net, contingency: Contingency) -> int:
    """pandapower index of the contingency's line, found by its end buses and circuit."""
    a, b = bus_indices(net, contingency.line)
    ends = [{int(f), int(t)} for f, t in zip(net.line.from_bus, net.line.to_bus)]
    return [i for i, e in zip(net.line.index, ends) if e == {a, b}][contingency.circuit]


@pytest.mark.parametrize(("name", "contingency"), PAIRS, ids=IDS)
def test_the_three_networks_are_symmetric_and_the_pre_fault_one_is_the_cases(name, contingency):
    case = _built(name)[2]
    nets = _networks(name, contingency)
    for M in (nets.G_pre, nets.B_pre, nets.G_on, nets.B_on, nets.G_post, nets.B_post):
        assert M.shape == (case.n, case.n) and np.array_equal(M, M.T)
    assert np.abs(nets.G_pre - np.array(case.G)).max() <= 1e-12
    assert np.abs(nets.B_pre - np.array(case.B)).max() <= 1e-12


@pytest.mark.parametrize(("name", "contingency"), PAIRS, ids=IDS)
def test_the_fault_on_network_is_the_dense_reduction_without_the_faulted_bus(name, contingency):
    net, model, _ = _built(name)
    nets = _networks(name, contingency)
    Y = model.network.augmented().toarray()
    keep = np.delete(np.arange(Y.shape[0]), _ppc_bus(net, contingency.fault_bus))
    Y_on = Y[np.ix_(keep, keep)]
    expected = kron_reduce(Y_on, np.arange(Y_on.shape[0] - model.E.size, Y_on.shape[0]))
    assert _rel(nets.G_on + 1j * nets.B_on, expected) <= 1e-10
    assert _rel(nets.G_on + 1j * nets.B_on, nets.G_pre + 1j * nets.B_pre) > 1e-2


@pytest.mark.parametrize(("name", "contingency"), PAIRS, ids=IDS)
def test_the_post_fault_network_is_pandapowers_network_without_the_line(name, contingency):
    """pandapower's own Ybus of the net with the line out of service, with the same pre-fault loads
    and machines, reduced densely."""
    net, model, _ = _built(name)
    nets = _networks(name, contingency)
    out = copy.deepcopy(net)
    out.line.loc[_line_index(net, contingency), "in_service"] = False
    solve_power_flow(out)
    assert np.array_equal(out._pd2ppc_lookups["bus"], net._pd2ppc_lookups["bus"])
    Y = model.network.augmented().toarray()
    nb = net._ppc["internal"]["Ybus"].shape[0]
    Y[:nb, :nb] += (out._ppc["internal"]["Ybus"] - net._ppc["internal"]["Ybus"]).toarray()
    expected = kron_reduce(Y, np.arange(nb, nb + model.E.size))
    assert _rel(nets.G_post + 1j * nets.B_post, expected) <= 1e-10
    assert _rel(nets.G_post + 1j * nets.B_post, nets.G_pre + 1j * nets.B_pre) > 1e-3


@pytest.mark.parametrize(("name", "contingency"), PAIRS, ids=IDS)
def test_the_pre_fault_equilibrium_is_at_rest_and_the_machines_nearest_the_fault_accelerate(name, contingency):
    """P_e(delta0) = p_m on the pre-fault network; on the fault-on one the machines fewest branches
    away from the faulted bus deliver less than p_m (their rotors speed up)."""
    net, model, case = _built(name)
    nets = _networks(name, contingency)
    delta0, E, p_m = np.array(case.delta0), np.array(case.E), np.array(case.p_m)
    assert np.abs(electrical_power(delta0, E, nets.G_pre, nets.B_pre) - model.p_flow).max() <= 1e-9
    hops = shortest_path(abs(net._ppc["internal"]["Ybus"]), unweighted=True, directed=False,
                         indices=_ppc_bus(net, contingency.fault_bus))
    machine_hops = hops[net._pd2ppc_lookups["bus"][np.asarray(model.buses)]]
    nearest = machine_hops == machine_hops.min()
    p_on = electrical_power(delta0, E, nets.G_on, nets.B_on)
    assert (p_on[nearest] < p_m[nearest]).all() and p_on.sum() < p_m.sum()


def test_the_wscc9_contingency_is_the_textbooks():
    """Anderson & Fouad's bus 7 (generator 2's high-voltage bus) and line 5-7 (to the 125 MW load A)."""
    net = _built("wscc9")[0]
    (contingency,) = contingencies("wscc9")
    fault, other = contingency.fault_bus, contingency.line[1 - contingency.line.index(contingency.fault_bus)]
    gen2 = bus_indices(net, [2])[0]
    neighbours = {int(t) for f, t in zip(net.line.from_bus, net.line.to_bus) if f == gen2} | {
        int(f) for f, t in zip(net.line.from_bus, net.line.to_bus) if t == gen2}
    assert neighbours == set(bus_indices(net, [fault]))
    assert net.load.p_mw[net.load.bus == bus_indices(net, [other])[0]].tolist() == [125.0]


def test_kundur4s_parallel_tie_circuits_are_alike():
    """The two 7-8 circuits are identical: opening either gives the same post-fault network."""
    first = _networks("kundur4", Contingency("a", fault_bus=7, line=(7, 8), circuit=0))
    second = _networks("kundur4", Contingency("b", fault_bus=7, line=(7, 8), circuit=1))
    assert _rel(second.G_post + 1j * second.B_post, first.G_post + 1j * first.B_post) <= 1e-12


def test_ieee39s_set_follows_its_rule():
    """The 10 lines with the largest pre-fault flow (max |P| of both ends) whose opening leaves the
    network in one piece (lines and transformers as a graph), each faulted at its sending end."""
    net = _built("ieee39")[0]
    name = net.bus.name
    edges = np.array([[f, t] for f, t in zip(net.line.from_bus, net.line.to_bus)]
                     + [[h, lv] for h, lv in zip(net.trafo.hv_bus, net.trafo.lv_bus)])
    flow = np.maximum(net.res_line.p_from_mw.abs().values, net.res_line.p_to_mw.abs().values)

    def splits(i: int) -> bool:
        rest = np.delete(edges, i, axis=0)
        graph = np.zeros((len(net.bus), len(net.bus)))
        graph[rest[:, 0], rest[:, 1]] = 1
        return connected_components(graph, directed=False)[0] > 1

    chosen = [i for i in np.argsort(-flow) if not splits(i)][:10]
    expected = []
    for i in chosen:
        f, t = int(name[net.line.from_bus.iat[i]]), int(name[net.line.to_bus.iat[i]])
        expected.append((f if net.res_line.p_from_mw.iat[i] > 0 else t, {f, t}))
    assert [(c.fault_bus, set(c.line)) for c in contingencies("ieee39")] == expected


def test_bad_contingencies_name_the_bus_or_line():
    net, model, _ = _built("wscc9")
    with pytest.raises(ValueError, match="line 5-9 does not touch the faulted bus 8"):
        Contingency("x", fault_bus=8, line=(5, 9))
    with pytest.raises(ValueError, match="net has no bus 99"):
        fault_networks(net, model, Contingency("x", fault_bus=99, line=(99, 9)))
    with pytest.raises(ValueError, match="net has no line 8-99"):
        fault_networks(net, model, Contingency("x", fault_bus=8, line=(8, 99)))
    with pytest.raises(ValueError, match="net has 0 in-service line"):
        fault_networks(net, model, Contingency("x", fault_bus=8, line=(8, 5)))
    with pytest.raises(ValueError, match="net has 1 in-service line.* 8-9, no circuit 1"):
        fault_networks(net, model, Contingency("x", fault_bus=8, line=(8, 9), circuit=1))
    with pytest.raises(ValueError, match="opening line 2-8 splits the network"):
        fault_networks(net, model, Contingency("x", fault_bus=8, line=(2, 8)))
    with pytest.raises(ValueError, match="no contingencies for case 'smib-inference'"):
        contingencies("smib-inference")
