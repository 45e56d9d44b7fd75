"""The scaling family: real networks of growing size as classical N-machine swing systems.

The small end is the paper's wscc9 (3 machines) and ieee39 (10), with published machine data
(`systems.grids`). The rest are the MATPOWER cases that pandapower ships (`pandapower.networks`):
case118 and case300 (the IEEE 118- and 300-bus systems, US, 60 Hz) and case1354pegase,
case2869pegase, case9241pegase (parts of the European high-voltage grid from the PEGASE project,
50 Hz: Josz, Fliscounakis, Maeght & Panciatici, "AC power flow data in MATPOWER and QCQP format:
iTesla, RTE snapshots, and PEGASE", arXiv:1603.01533, 2016). They carry no dynamic data, so every
machine gets the same typical data on its own rating (below), and each net becomes a `Case` by the
code that builds wscc9 and ieee39: `network.classical_model`, `network.network_case` (horizon
T_FINAL = 10 s, P1 = generator 1's operating P +- 30 %, damping d = 0.5 m).

Machine data rule (for the cases without dynamic data):
  * H = 4 s and x'd = 0.3 p.u., both on the machine's own MVA rating: mid-range typical values,
    P. Kundur, "Power System Stability and Control" (1994), Table 3.2 (H: 2.5-6 s for 2-pole and
    4-10 s for 4-pole thermal units, 2-4 s for hydro units) and Table 4.2 (x'd: 0.15-0.4 p.u. round
    rotor, 0.2-0.5 p.u. salient pole). Kundur's two-area system (`grids.kundur4`) uses the same
    x'd = 0.3 on rating.
  * Rating S_k (MVA) = max(S_plate, |P + jQ| of the solved flow, RATING_FLOOR_MVA = 10 MVA), where
    S_plate is the gen's sn_mva if pandapower has a positive one, else its |max_p_mw| (0 if none);
    summed over the machines merged at one bus. None of the family's nets has an sn_mva (MATPOWER's
    mBase is not a rating), and P_max, the unit's capability, is its size (it understates the MVA
    rating by the power factor, ~0.85-0.95). The flow's |S| keeps every machine within its rating
    (synchronous condensers have P_max = 0 and Q != 0); the floor keeps m_k > 0 for a unit with
    neither. With H and x'd fixed on the rating, m_k ~ S_k and the machine's tie admittance ~ S_k:
    a machine's local mode (~ sqrt(omega_s / (2 H x'd))) does not depend on S_k.
  * Frequency: 60 Hz for the US cases (case118, case300), 50 Hz for the European PEGASE cases.
  * Machines: every in-service gen and ext_grid (the slack), P <= 0 included (condensers, pumps);
    several at one bus are merged into one (`merge_machines`). Generator 1 (machine 0, whose
    mechanical power steps to P1) = the machine with the largest operating P; the others follow in
    pandapower bus order.
  * Transformer phase shifts are set to 0 (the PEGASE cases have a few, of < 1 deg): a phase
    shifter makes Ybus, and so G and B, unsymmetric, which `Case` does not allow. The power flow is
    solved after that, so the equilibrium is exact for the network modelled.
Power flow: `network.solve_power_flow` (as `grids`): Newton-Raphson at 1e-10 MVA, numba off (no faster
at 9241 buses, 0.4 s, and it compiles for seconds). The reduction is sparse, as for every net
(`network.kron_reduce_sparse`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from systems.cases import CASES, Case, register_case
from systems.network import T_FINAL, ClassicalModel, classical_model, network_case, solve_power_flow

if TYPE_CHECKING:  # annotations only: importing pandapower costs seconds
    from pandapower.auxiliary import pandapowerNet

__all__ = ["FAMILY", "FAMILY_CASES", "F_HZ", "H_S", "RATING_FLOOR_MVA", "XD_PRIME", "MachineData", "family_case",
           "family_model", "family_size", "machine_buses", "merge_machines"]

# The family's larger networks, each a MATPOWER case of `pandapower.networks` of that name, in order
# of size (machines: 54, 69, 260, 510, 1445): system frequency (Hz: US 60, European PEGASE 50) and
# origin. Each is registered in `systems.cases.CASES` (bottom of this module); the family's small
# end, wscc9 and ieee39, is `systems.grids`'.
_PEGASE = "PEGASE, Josz et al. arXiv:1603.01533"
_MEMBERS = {
    "case118": (60.0, "IEEE 118-bus system"),
    "case300": (60.0, "IEEE 300-bus system"),
    "case1354pegase": (50.0, _PEGASE),
    "case2869pegase": (50.0, _PEGASE),
    "case9241pegase": (50.0, _PEGASE),
}
FAMILY_CASES = tuple(_MEMBERS)
# The family, in order of size (machines: 3, 10, 54, 69, 260, 510, 1445).
FAMILY: tuple[str, ...] = ("wscc9", "ieee39", *FAMILY_CASES)
# The machine data rule (module docstring): s and p.u. on the machine's rating; the rating floor, MVA.
H_S = 4.0
XD_PRIME = 0.3
RATING_FLOOR_MVA = 10.0
# System frequency (Hz) of each case without dynamic data.
F_HZ = {name: f_hz for name, (f_hz, _) in _MEMBERS.items()}
# pandapower.networks loader of each family member (wscc9 and ieee39 are MATPOWER case9 and case39).
_LOADER = {"wscc9": "case9", "ieee39": "case39", **{name: name for name in FAMILY_CASES}}
# Elements that classical_model has no model for: an in-service one is refused.
_UNSUPPORTED = ("ward", "xward", "storage", "dcline", "svc", "tcsc", "ssc", "vsc", "motor",
                "asymmetric_load", "asymmetric_sgen")


def _check_name(name) -> str:
    if name not in FAMILY:
        raise ValueError(f"name must be one of {', '.join(FAMILY)}; got {name!r}")
    return name


def _load(name: str) -> pandapowerNet:
    import pandapower.networks as pn

    return getattr(pn, _LOADER[name])()


def _machines(net: pandapowerNet) -> dict[int, list[tuple[str, int]]]:
    """bus -> its in-service ("ext_grid" | "gen", index) elements, ext_grids first."""
    found: dict[int, list[tuple[str, int]]] = {}
    for table in ("ext_grid", "gen"):
        frame = net[table]
        on = frame.in_service.values.astype(bool)
        for idx, bus in zip(frame.index[on], frame.bus.values[on]):
            found.setdefault(int(bus), []).append((table, int(idx)))
    return found


def machine_buses(net: pandapowerNet) -> list[int]:
    """The pandapower bus indices that hold an in-service gen or ext_grid (one machine each once
    merged, `merge_machines`), sorted."""
    return sorted(_machines(net))


def family_size(name: str) -> tuple[int, int]:
    """(buses, machines) of family case `name`, read from its net without a power flow (~1 s):
    in-service buses, and buses with an in-service gen or ext_grid."""
    net = _load(_check_name(name))
    return int(net.bus.in_service.sum()), len(_machines(net))


def _nameplate(net: pandapowerNet, table: str, idx: int) -> float:
    """sn_mva (MVA) of element `idx` of `table` if positive, else |max_p_mw| (MW), else 0."""
    for column in ("sn_mva", "max_p_mw"):
        value = float(net[table].at[idx, column]) if column in net[table] else math.nan
        if math.isfinite(value) and (value > 0 or column == "max_p_mw"):
            return abs(value)
    return 0.0


def merge_machines(net: pandapowerNet) -> dict[int, float]:
    """One machine per bus, in place, before the power flow. At a bus with several in-service gen
    and ext_grid elements the first ext_grid (else the first gen) stays; a kept gen takes the
    others' P set points (a kept ext_grid, the slack, takes them up in the flow), and the others go
    out of service: the flow then gives the kept element the bus's summed P and Q, as the merged
    elements had together.
    Returns {bus: S_plate}, MVA: the sum of `_nameplate` over each machine bus's elements."""
    plate = {}
    for bus, elements in _machines(net).items():
        plate[bus] = sum(_nameplate(net, table, idx) for table, idx in elements)
        (kept_table, kept), others = elements[0], elements[1:]
        for table, idx in others:
            if kept_table == "gen":
                net.gen.at[kept, "p_mw"] += net.gen.at[idx, "p_mw"]
            net[table].at[idx, "in_service"] = False
    return plate


class MachineData(NamedTuple):
    """One machine's data on its own rating: H (s), xd_prime (p.u.) and D (p.u. power per p.u.
    speed deviation, so d_k = D S_k / (omega_s S_base) p.u. s/rad on the system base; the family's
    d = 0.5 m is D = H)."""

    H: float
    xd_prime: float
    D: float


def _check_elements(net: pandapowerNet) -> None:
    """ValueError naming the in-service elements of `net` that the classical model does not model,
    and each asymmetric impedance (rft_pu != rtf_pu or xft_pu != xtf_pu: an unsymmetric Ybus). A
    symmetric impedance is a series branch of pandapower's Ybus, r + jx = rft_pu + j xft_pu on its
    sn_mva (its shunts gf/bf, gt/bt sit on the diagonal), and is modelled as such."""
    present = [t for t in _UNSUPPORTED if t in net and len(net[t]) and net[t].in_service.astype(bool).any()]
    if present:
        raise ValueError(f"net has in-service {', '.join(present)} element(s), which the classical "
                         "model does not model")
    imp = net.impedance if "impedance" in net else None
    if imp is not None and len(imp):
        on = imp[imp.in_service.astype(bool)]
        asym = on.index[(on.rft_pu.values != on.rtf_pu.values) | (on.xft_pu.values != on.xtf_pu.values)]
        if len(asym):
            i = int(asym[0])
            raise ValueError(f"net: impedance {i} ({on.at[i, 'name']!r}) is asymmetric (rft_pu, xft_pu = "
                             f"{on.at[i, 'rft_pu']:g}, {on.at[i, 'xft_pu']:g}; rtf_pu, xtf_pu = {on.at[i, 'rtf_pu']:g}, "
                             f"{on.at[i, 'xtf_pu']:g}), which the classical model's symmetric network does not model")


def family_model(net: pandapowerNet, f_hz: float, data: Mapping[int, MachineData] | None = None) -> ClassicalModel:
    """The classical model of an unsolved pandapower `net` by the module's machine data rule.

    Changes `net` in place: transformer phase shifts set to 0, machines merged per bus
    (`merge_machines`), the power flow solved. Machine 0 = the largest operating P, then bus order.
    f_hz: the system frequency (Hz). data: pandapower bus index -> `MachineData` of the merged
    machine there, every machine bus (`machine_buses`) given, on the rating the rule gives; None:
    the rule's H_S, XD_PRIME and d = DAMPING_PER_INERTIA m. Raises ValueError naming `net` if it
    has an in-service element classical_model does not model (ward, storage, dcline, an
    asymmetric impedance, ...).
    """
    _check_elements(net)
    if len(net.trafo):
        net.trafo["shift_degree"] = 0.0
    plate = merge_machines(net)
    solve_power_flow(net)
    rows = [(bus, *elements[0]) for bus, elements in sorted(_machines(net).items())]
    p = [float(net[f"res_{t}"].at[i, "p_mw"]) for _, t, i in rows]
    s = [abs(complex(net[f"res_{t}"].at[i, "p_mw"], net[f"res_{t}"].at[i, "q_mvar"])) for _, t, i in rows]
    first = max(range(len(rows)), key=p.__getitem__)  # the first of equals in bus order
    order = [first] + [k for k in range(len(rows)) if k != first]
    rating = [max(plate[rows[k][0]], s[k], RATING_FLOOR_MVA) for k in order]
    buses = [rows[k][0] for k in order]
    if data is None:
        return classical_model(net, buses, H=H_S, xd_prime=XD_PRIME, machine_mva=rating, f_hz=f_hz)
    missing = sorted(set(buses) - set(data))
    if missing:
        raise ValueError(f"data gives no machine data for the machine bus(es) {missing}")
    H, xd, D = (np.array([getattr(data[b], key) for b in buses]) for key in MachineData._fields)
    model = classical_model(net, buses, H=H, xd_prime=xd, machine_mva=rating, f_hz=f_hz)
    d = D * np.asarray(rating) / (2.0 * np.pi * model.f_hz * model.base_mva)
    if not (d > 0).all():
        raise ValueError(f"data: D must be > 0, got {D.tolist()}")
    return dataclasses.replace(model, d=d)


@functools.cache
def family_case(name: str) -> Case:
    """The `Case` of family member `name` (FAMILY), built once per process: wscc9 and ieee39 are
    `CASES["wscc9"]` and `CASES["ieee39"]` (`systems.grids`); the others follow the module's machine
    data rule."""
    _check_name(name)
    if name not in FAMILY_CASES:
        return CASES[name]
    net = _load(name)
    shifts = net.trafo.shift_degree.values[net.trafo.shift_degree.values != 0] if len(net.trafo) else []
    model = family_model(net, F_HZ[name])
    shifted = (f"; phase shifts of {len(shifts)} transformers (|shift| <= {max(abs(s) for s in shifts):.2g} "
               "deg) set to 0" if len(shifts) else "")
    return network_case(name, model, t_final=T_FINAL, source=(
        f"network: MATPOWER {name} ({_MEMBERS[name][1]}) via pandapower.networks.{name}{shifted}; machines: "
        f"every gen and ext_grid, one per bus, H = {H_S:g} s, x'd = {XD_PRIME:g} p.u. on rating max(sn_mva "
        f"or P_max, |S_flow|, {RATING_FLOOR_MVA:g} MVA) (typical values: Kundur, Power System Stability "
        f"and Control, Tables 3.2, 4.2); {F_HZ[name]:g} Hz; generator 1 = the largest P; damping "
        "d = 0.5 m (ours)"))


for _name in FAMILY_CASES:
    register_case(_name)(functools.partial(family_case, _name))
