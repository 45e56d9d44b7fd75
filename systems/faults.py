"""Fault networks: a bolted three-phase fault at a bus, cleared by opening a line (issue 23's study).

A contingency (`Contingency`) grounds bus b at t = 0 and, at the clearing time, opens a line (b, k).
Three Kron-reduced networks of the same classical model (`systems.network.classical_model`: each
machine's EMF behind x'd, loads the constant admittances of the pre-fault power flow) describe it,
each (G, B) (n, n) p.u. on the system base, exactly symmetric as `systems.cases.Case` needs:

- pre-fault: the case's own network (its G, B);
- fault-on: V_b = 0, so node b is removed from the augmented network (`ClassicalModel.network`)
  before the reduction onto the machines;
- post-fault: the augmented network less the opened line's branch admittance; the loads stay the
  pre-fault constant admittances and the machines' E and the pre-fault equilibrium are unchanged.

The line is removed with pandapower's own branch stamp, the rows of its internal `Yf`, `Yt`
(`net._ppc["internal"]`; `net._pd2ppc_lookups["branch"]["line"]` gives the line's branch row), not a
pi model rebuilt here: those rows are what pandapower summed into Ybus (series impedance, line
charging, any tap), so taking them out again is exactly the network without the line.

Buses are named by the source's bus numbers (pandapower's `bus.name`, as the case builders do).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from systems.cases import Case, Fault, register_case
from systems.network import ClassicalModel, bus_indices, reduce_to_machines
from systems.sparse_network import SparseNetwork

if TYPE_CHECKING:  # annotations only: importing pandapower costs seconds
    from pandapower.auxiliary import pandapowerNet
    from scipy.sparse import csc_matrix

__all__ = ["CLEARING_TIMES", "CONTINGENCIES", "FAULT_CASES", "FAULT_T_FINAL", "Contingency", "FaultNetworks",
           "case_fault_networks", "contingencies", "fault_case", "fault_networks"]

# Every fault case's scenario: the clearing time t_c in this range (s), on this horizon (s), a
# first-swing study window (the reference CCTs of the contingencies below lie inside the range:
# tests/test_fault_cases.py).
CLEARING_TIMES = (0.05, 0.40)
FAULT_T_FINAL = 3.0


@dataclass(frozen=True)
class Contingency:
    """A bolted three-phase fault at bus `fault_bus`, cleared by opening the line between the buses
    `line` (its two ends; one of them is `fault_bus`); `circuit` picks one of parallel lines between
    the same buses: 0 the first in pandapower's line order, 1 the second, ... Bus numbers are the
    source's (pandapower `bus.name`)."""

    name: str
    fault_bus: int
    line: tuple[int, int]
    circuit: int = 0

    def __post_init__(self) -> None:
        if len(self.line) != 2 or self.line[0] == self.line[1]:
            raise ValueError(f"Contingency {self.name!r}: line must be two distinct buses, got {self.line!r}")
        if self.fault_bus not in self.line:
            raise ValueError(f"Contingency {self.name!r}: line {self.line[0]}-{self.line[1]} does not touch the "
                             f"faulted bus {self.fault_bus}")
        if self.circuit < 0:
            raise ValueError(f"Contingency {self.name!r}: circuit must be >= 0, got {self.circuit!r}")


@dataclass(frozen=True, eq=False)
class FaultNetworks:
    """The reduced networks of one `Contingency` on an n-machine classical model: (G, B) (n, n)
    p.u., each exactly symmetric, of the pre-fault network (the case's), the fault-on network (the
    faulted bus grounded) and the post-fault network (the line open)."""

    contingency: Contingency
    G_pre: np.ndarray
    B_pre: np.ndarray
    G_on: np.ndarray
    B_on: np.ndarray
    G_post: np.ndarray
    B_post: np.ndarray


def _line_branch(net: pandapowerNet, contingency: Contingency) -> int:
    """The row in pandapower's internal branch data of `contingency`'s line, or a ValueError."""
    ends = bus_indices(net, contingency.line)
    lines = net.line
    joins = ((lines.from_bus.values == ends[0]) & (lines.to_bus.values == ends[1])) | (
        (lines.from_bus.values == ends[1]) & (lines.to_bus.values == ends[0]))
    found = np.flatnonzero(joins & lines.in_service.values)
    a, b = contingency.line
    if contingency.circuit >= found.size:
        raise ValueError(f"Contingency {contingency.name!r}: net has {found.size} in-service line(s) {a}-{b}, "
                         f"no circuit {contingency.circuit}")
    row = net._pd2ppc_lookups["branch"]["line"][0] + int(found[contingency.circuit])
    branch = net._ppc["internal"]["branch"]
    buses = net._pd2ppc_lookups["bus"][np.asarray(ends)]
    if row >= branch.shape[0] or sorted(branch[row, :2].real.astype(int).tolist()) != sorted(buses.tolist()):
        raise ValueError(f"Contingency {contingency.name!r}: net's internal branch data does not line up with "
                         "its line table (an out-of-service branch?); solve the net with every line in service")
    return row


def _without_line(Y: csc_matrix, net: pandapowerNet, row: int) -> csc_matrix:
    """The augmented network Y (nb + n, nb + n) less branch `row`'s stamp: its Yf row subtracted
    from its from-bus row of Y and its Yt row from its to-bus row."""
    from scipy.sparse import coo_matrix, csc_matrix

    internal = net._ppc["internal"]
    f, t = (int(x) for x in internal["branch"][row, :2].real)
    stamp = (coo_matrix(internal["Yf"][row]), coo_matrix(internal["Yt"][row]))
    rows = np.concatenate([np.full(stamp[0].nnz, f), np.full(stamp[1].nnz, t)])
    cols = np.concatenate([stamp[0].col, stamp[1].col])
    vals = np.concatenate([stamp[0].data, stamp[1].data])
    out = csc_matrix(Y - coo_matrix((vals, (rows, cols)), shape=Y.shape))
    out.eliminate_zeros()  # a single line's off-diagonal entries cancel exactly
    return out


def _islands(Y: csc_matrix) -> int:
    """The number of connected parts of the network Y (its nonzero off-diagonal pattern)."""
    from scipy.sparse.csgraph import connected_components

    return int(connected_components(abs(Y), directed=False)[0])


def fault_networks(net: pandapowerNet, model: ClassicalModel, contingency: Contingency) -> FaultNetworks:
    """The `FaultNetworks` of `contingency` on `model`, the classical model of the solved `net`
    (`systems.grids.GRIDS` pairs them). ValueError naming the bus or line if the faulted bus or the
    line does not exist, or if opening the line splits the network."""
    try:
        (bus,) = net._pd2ppc_lookups["bus"][np.asarray(bus_indices(net, [contingency.fault_bus]))]
    except ValueError:
        raise ValueError(f"Contingency {contingency.name!r}: net has no bus {contingency.fault_bus}") from None
    try:
        row = _line_branch(net, contingency)
    except ValueError as err:
        if "no bus named" not in str(err):
            raise
        raise ValueError(f"Contingency {contingency.name!r}: net has no line {contingency.line[0]}-"
                         f"{contingency.line[1]} (no such bus)") from None
    n = model.E.size
    Y = model.network.augmented()
    G_pre, B_pre = reduce_to_machines(Y, n)
    keep = np.setdiff1d(np.arange(Y.shape[0]), [bus])
    G_on, B_on = reduce_to_machines(Y[keep][:, keep], n)  # V_b = 0: node b leaves the network
    Y_post = _without_line(Y, net, row)
    if _islands(Y_post) != _islands(Y):
        a, b = contingency.line
        raise ValueError(f"Contingency {contingency.name!r}: opening line {a}-{b} splits the network")
    G_post, B_post = reduce_to_machines(Y_post, n)
    return FaultNetworks(contingency=contingency, G_pre=G_pre, B_pre=B_pre, G_on=G_on, B_on=B_on,
                         G_post=G_post, B_post=B_post)


# Each case's contingencies, bus numbers as in its builder (`systems.grids`).
CONTINGENCIES: dict[str, tuple[Contingency, ...]] = {
    # The textbook case: a fault at the high-voltage bus of generator 2, cleared by opening the line
    # from it to the 125 MW load A (Anderson & Fouad, Power System Control and Stability, ch. 2, the
    # 9-bus example: the fault near bus 7 at the end of line 5-7). MATPOWER case9 numbers the same
    # network otherwise (A&F bus: MATPOWER bus, from the two tables' generators, loads and branch
    # data): 4: 4, 7: 8, 9: 6, 5: 9 (load A 125 MW), 6: 5 (load B 90 MW), 8: 7 (load C 100 MW); A&F
    # line 5-7 (r 0.032, x 0.161, B 0.306 p.u.) is MATPOWER branch 8-9.
    "wscc9": (Contingency("bus8-line8-9", fault_bus=8, line=(8, 9)),),
    # Ours: the fault at bus 7, area 1's end of the tie between the areas (next to its 967 MW load),
    # cleared by opening the first of the two 7-8 circuits (Kundur, Example 12.6 numbering).
    "kundur4": (Contingency("bus7-line7-8a", fault_bus=7, line=(7, 8), circuit=0),),
    # An N-1 set, by a stated rule (computed from the solved case, `tests/test_faults_network.py`
    # checks it): the 10 lines of MATPOWER case39 (its lines, not its transformers) that carry the
    # most active power in the pre-fault flow (max of |P| at either end), among those whose opening
    # leaves the network in one piece (23-36 and 16-19, the two above the tenth, each feed generators
    # alone); each faulted at its sending end (where the power enters the line). In flow order.
    "ieee39": (
        Contingency("bus22-line21-22", fault_bus=22, line=(21, 22)),
        Contingency("bus6-line5-6", fault_bus=6, line=(5, 6)),
        Contingency("bus6-line6-7", fault_bus=6, line=(6, 7)),
        Contingency("bus23-line23-24", fault_bus=23, line=(23, 24)),
        Contingency("bus29-line28-29", fault_bus=29, line=(28, 29)),
        Contingency("bus5-line5-8", fault_bus=5, line=(5, 8)),
        Contingency("bus21-line16-21", fault_bus=21, line=(16, 21)),
        Contingency("bus10-line10-11", fault_bus=10, line=(10, 11)),
        Contingency("bus11-line6-11", fault_bus=11, line=(6, 11)),
        Contingency("bus10-line10-13", fault_bus=10, line=(10, 13)),
    ),
}


def contingencies(case_name: str) -> tuple[Contingency, ...]:
    """The contingencies of the case `case_name` (`CONTINGENCIES`), or a ValueError listing the cases."""
    if case_name not in CONTINGENCIES:
        raise ValueError(f"no contingencies for case {case_name!r}; cases with faults: {sorted(CONTINGENCIES)}")
    return CONTINGENCIES[case_name]


def case_fault_networks(case_name: str) -> dict[str, FaultNetworks]:
    """`FaultNetworks` of each of the case's contingencies, by contingency name (the net solved and
    its model built anew, by the case's own builders)."""
    from systems.grids import GRIDS

    found = contingencies(case_name)
    build_net, build_model = GRIDS[case_name]
    net = build_net()
    model = build_model(net)
    return {c.name: fault_networks(net, model, c) for c in found}


def _matrix(x: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(row) for row in np.asarray(x, np.float64).tolist())


def fault_case(case: Case, networks: FaultNetworks, *, t_final: float = FAULT_T_FINAL,
               clearing_times: tuple[float, float] = CLEARING_TIMES) -> Case:
    """The fault case of `networks`' contingency on the step case `case` (whose G, B must be the
    pre-fault network of `networks`): named '<case>-<contingency>', from the same equilibrium at
    rest, the scenario parameter the clearing time t_c in `clearing_times` (s) on [0, t_final] s,
    no carried sparse network (the phases are reduced ones), the machines' tie admittances of the
    step case's carried network, when it has one, kept on the fault (`Fault.y`)."""
    if not (np.array_equal(case.G, networks.G_pre) and np.array_equal(case.B, networks.B_pre)):
        raise ValueError(f"case {case.name!r}: its network is not the pre-fault network of "
                         f"{networks.contingency.name!r}")
    name = networks.contingency.name
    network = case.network
    ties = tuple(complex(x) for x in np.asarray(network.y)) if isinstance(network, SparseNetwork) else None
    fault = Fault(name=name, G_on=_matrix(networks.G_on), B_on=_matrix(networks.B_on),
                  G_post=_matrix(networks.G_post), B_post=_matrix(networks.B_post), y=ties)
    return dataclasses.replace(
        case, name=f"{case.name}-{name}", t_final=t_final, p1_min=clearing_times[0], p1_max=clearing_times[1],
        fault=fault, network=None, source=f"{case.source}; fault: {name} (systems.faults.CONTINGENCIES)")


@functools.cache
def _fault_cases(case_name: str) -> dict[str, Case]:
    from systems.cases import CASES

    case = CASES[case_name]
    return {c: fault_case(case, nets) for c, nets in case_fault_networks(case_name).items()}


def _builder(case_name: str, contingency: str) -> Callable[[], Case]:
    return lambda: _fault_cases(case_name)[contingency]


# The fault cases, '<case>-<contingency>', by the step case they fault: registered in
# `systems.cases.CASES` (each case's net is solved once for all of its contingencies).
FAULT_CASES: dict[str, tuple[str, ...]] = {
    case_name: tuple(f"{case_name}-{c.name}" for c in found) for case_name, found in CONTINGENCIES.items()}
for _case_name, _found in CONTINGENCIES.items():
    for _c in _found:
        register_case(f"{_case_name}-{_c.name}")(_builder(_case_name, _c.name))
