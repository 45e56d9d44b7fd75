"""The paper's multi-machine cases, built from published network and machine data.

Each builder solves a pandapower power flow and returns the classical model of `systems.network`
as a `Case` (system base 100 MVA, 60 Hz; no infinite bus). Machine k = 0 ("generator 1") is
named in each builder. pandapower is imported inside the builders (it takes seconds to import),
and each case is built once per process (functools.cache). A case is one builder registered in
`systems.cases.CASES` by `register_case`; its `<name>_net()` gives the solved net itself and
`<name>_model(net)` its classical model (`GRIDS`: the pair by case name).

Common choices (not from the sources): damping d_k = 0.5 m_k (`network.DAMPING_PER_INERTIA`),
search boxes (m/4, 4m), (d/4, 4d), P1 = generator 1's operating P +- 30 %, horizon T_FINAL
(`systems.network`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from systems.cases import Case, register_case
from systems.network import (
    T_FINAL,
    ClassicalModel,
    bus_indices,
    classical_model,
    network_case,
    solve_power_flow,
)

if TYPE_CHECKING:  # annotations only: importing pandapower costs seconds
    from pandapower.auxiliary import pandapowerNet

__all__ = ["GRIDS", "T_FINAL", "ieee39", "ieee39_model", "ieee39_net", "kundur4", "kundur4_model", "kundur4_net",
           "wscc9", "wscc9_model", "wscc9_net"]


def wscc9_net():
    """The solved pandapower net of the WSCC 9-bus system (bus names: MATPOWER numbers), built anew."""
    import pandapower.networks as pn

    net = pn.case9()  # MATPOWER case9: the WSCC network, loads and dispatch (Anderson & Fouad)
    # MATPOWER case9 sets every generator to 1.0 p.u.; Anderson & Fouad's flow has 1.04, 1.025, 1.025:
    net.ext_grid["vm_pu"] = 1.04  # bus 1
    net.gen.loc[net.gen.bus.isin(bus_indices(net, [2, 3])), "vm_pu"] = 1.025  # buses 2 and 3
    return solve_power_flow(net)


def wscc9_model(net: pandapowerNet) -> ClassicalModel:
    """The classical model of the solved `wscc9_net()`. Machines: generators at buses 1, 2, 3
    (MATPOWER case9 gen order; generator 1 = bus 1, the slack, pandapower's ext_grid)."""
    return classical_model(
        net, bus_indices(net, [1, 2, 3]),  # MATPOWER case9 gen table rows: buses 1, 2, 3
        # Anderson & Fouad, "Power System Control and Stability", Table 2.1 (stored energy 2364, 640,
        # 301 MW s over 100 MVA; also in Sauer & Pai, "Power System Dynamics and Stability"):
        H=[23.64, 6.40, 3.01],  # s on 100 MVA
        xd_prime=[0.0608, 0.1198, 0.1813],  # p.u. on 100 MVA
        f_hz=60.0,  # WSCC: 60 Hz
    )


@register_case("wscc9")
@functools.cache
def wscc9() -> Case:
    """WSCC 3-machine 9-bus system (`wscc9_model`)."""
    return network_case("wscc9", wscc9_model(wscc9_net()), t_final=T_FINAL, source=(
        "network: MATPOWER case9 via pandapower.networks.case9 with Anderson & Fouad's voltage set points; "
        "machines (H, x'd): Anderson & Fouad, Power System Control and Stability, Table 2.1; damping "
        "d = 0.5 m (ours)"))


def kundur4_net():
    """The solved pandapower net of Kundur's two-area system (bus names: the book's numbers 1..11),
    built anew."""
    import pandapower as pp

    # All data: P. Kundur, "Power System Stability and Control" (1994), Example 12.6.
    net = pp.create_empty_network(name="kundur4", f_hz=60.0, sn_mva=100.0)  # 60 Hz; 100 MVA base
    bus = {k: pp.create_bus(net, vn_kv=20.0 if k <= 4 else 230.0, name=k) for k in range(1, 12)}  # 20 kV gens
    for lv, hv in ((1, 5), (2, 6), (3, 11), (4, 10)):  # step-up 0 + j0.15 p.u. on 900 MVA, 20/230 kV
        pp.create_transformer_from_parameters(net, bus[hv], bus[lv], sn_mva=900.0, vn_hv_kv=230.0,
                                              vn_lv_kv=20.0, vkr_percent=0.0, vk_percent=15.0, pfe_kw=0.0,
                                              i0_percent=0.0)
    z_base = 230.0**2 / 100.0  # ohm: lines are given per km in p.u. on 100 MVA, 230 kV
    r, x, b = 0.0001 * z_base, 0.001 * z_base, 0.00175 / z_base  # ohm/km, ohm/km, S/km
    c_nf = b / (2 * math.pi * 60.0) * 1e9  # nF/km at 60 Hz
    for f, t, km in ((5, 6, 25), (6, 7, 10), (7, 8, 110), (7, 8, 110), (8, 9, 110), (8, 9, 110),
                     (9, 10, 10), (10, 11, 25)):  # two circuits 7-8 and 8-9, 110 km each
        pp.create_line_from_parameters(net, bus[f], bus[t], length_km=km, r_ohm_per_km=r, x_ohm_per_km=x,
                                       c_nf_per_km=c_nf, max_i_ka=10.0)
    for k, p, q, qc in ((7, 967.0, 100.0, 200.0), (9, 1767.0, 100.0, 350.0)):  # MW, Mvar, capacitor Mvar
        pp.create_load(net, bus[k], p_mw=p, q_mvar=q)
        pp.create_shunt(net, bus[k], q_mvar=-qc, vn_kv=230.0)  # q < 0: capacitive, qc at 1 p.u.
    for k, p, v in ((1, 700.0, 1.03), (2, 700.0, 1.01), (4, 700.0, 1.01)):  # P (MW), |Vt| (p.u.)
        pp.create_gen(net, bus[k], p_mw=p, vm_pu=v)
    pp.create_ext_grid(net, bus[3], vm_pu=1.03, va_degree=-6.8)  # G3 slack, 1.03 at -6.8 deg
    return solve_power_flow(net)


def kundur4_model(net: pandapowerNet) -> ClassicalModel:
    """The classical model of the solved `kundur4_net()`. Machines: G1, G2, G3, G4 at buses 1, 2,
    3, 4 (the book's numbering; generator 1 = G1; G3 is the slack, pandapower's ext_grid)."""
    return classical_model(
        net, bus_indices(net, [1, 2, 3, 4]),
        H=[6.5, 6.5, 6.175, 6.175],  # s on 900 MVA
        xd_prime=0.3,  # p.u. on 900 MVA (every machine)
        machine_mva=900.0,  # ratings 900 MVA, 20 kV
        f_hz=60.0,
    )


@register_case("kundur4")
@functools.cache
def kundur4() -> Case:
    """Kundur's two-area 4-machine system (`kundur4_model`)."""
    return network_case("kundur4", kundur4_model(kundur4_net()), t_final=T_FINAL, source=(
        "Kundur, Power System Stability and Control, Example 12.6 (network, loads, dispatch, H, x'd); "
        "power flow by pandapower; damping d = 0.5 m (ours)"))


def ieee39_net():
    """The solved pandapower net of the IEEE 39-bus system (bus names: MATPOWER numbers), built anew."""
    import pandapower.networks as pn

    return solve_power_flow(pn.case39())  # MATPOWER case39 (Athay, Podmore & Virmani 1979; Pai 1989)


def ieee39_model(net: pandapowerNet) -> ClassicalModel:
    """The classical model of the solved `ieee39_net()`. Machines: generators at buses 30, 31, ...,
    39 (MATPOWER case39 gen order; generator 1 = bus 30; bus 31 is the slack, pandapower's ext_grid)."""
    # Machine data by bus, s and p.u. on 100 MVA: M. A. Pai, "Energy Function Analysis for Power
    # System Stability" (1989), 10-machine New England data (after Athay et al. 1979); the same as
    # the IEEE PES TR-18 (2015) benchmark's New England machines, there on 100-2000 MVA machine bases
    # (as in OpenIPSL, OpenIPSL/Data/PowerPlant/PESTR18/MachineData/NewEngland39/Machine1..10.mo,
    # Machine1 = bus 39, Machine2..9 = buses 31..38, Machine10 = bus 30).
    machines = {  # bus: (H s, x'd p.u.)
        30: (42.0, 0.031), 31: (30.3, 0.0697), 32: (35.8, 0.0531), 33: (28.6, 0.0436), 34: (26.0, 0.132),
        35: (34.8, 0.05), 36: (26.4, 0.049), 37: (24.3, 0.057), 38: (34.5, 0.057), 39: (500.0, 0.006),
    }
    order = list(range(30, 40))  # MATPOWER case39 gen table rows: buses 30, 31, ..., 39
    return classical_model(
        net, bus_indices(net, order),
        H=[machines[k][0] for k in order], xd_prime=[machines[k][1] for k in order],
        f_hz=60.0,  # New England: 60 Hz
    )


@register_case("ieee39")
@functools.cache
def ieee39() -> Case:
    """IEEE 39-bus New England system (`ieee39_model`)."""
    return network_case("ieee39", ieee39_model(ieee39_net()), t_final=T_FINAL, source=(
        "network: MATPOWER case39 via pandapower.networks.case39; machines (H, x'd): Pai, Energy Function "
        "Analysis for Power System Stability (1989) = IEEE PES TR-18 (2015); damping d = 0.5 m (ours)"))


# Case name: (the solved net's builder, the classical model of that net), for the code that needs
# the network itself (`systems.faults`).
GRIDS: dict[str, tuple[Callable[[], pandapowerNet], Callable[[pandapowerNet], ClassicalModel]]] = {
    "wscc9": (wscc9_net, wscc9_model), "kundur4": (kundur4_net, kundur4_model), "ieee39": (ieee39_net, ieee39_model),
}
