"""Classical multi-machine swing model from a solved pandapower power flow: the generic machinery.

Each machine is the classical model: an EMF E_k e^{j delta_k} of constant magnitude behind its
transient reactance x'd_k, tied to its terminal bus; loads are constant impedances fixed at the
solved voltages; the network, with the loads and the machine reactances, is Kron-reduced to the
internal machine nodes: Y_red = G + jB (p.u. on the system base `net.sn_mva`). Then

    P_e,k(delta) = sum_j E_k E_j (G_kj cos(delta_k - delta_j) + B_kj sin(delta_k - delta_j))  (p.u.)

and p_m = P_e(delta0) equals each machine's power-flow P (checked). Only `solve_power_flow`
imports pandapower (when called): a solved net is read through its tables and the documented
internal structures (`net._ppc["internal"]["Ybus"]`, `["V"]`, `net._pd2ppc_lookups["bus"]`,
pandapower's internal_datastructure tutorial). Machine order is the caller's `machine_buses` order.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from systems.cases import Case, check_array, per_machine
from systems.sparse_network import SparseNetwork, augmented_network

if TYPE_CHECKING:  # annotations only: importing pandapower costs seconds
    from pandapower.auxiliary import pandapowerNet

__all__ = ["BOX_FACTOR", "BOX_OFFSET", "DAMPING_PER_INERTIA", "P1_SPREAD", "PF_TOL_MVA", "T_FINAL", "ClassicalModel",
           "bus_indices", "classical_model", "electrical_power", "kron_reduce", "kron_reduce_sparse", "network_case",
           "reduce_to_machines", "solve_power_flow"]

# No source gives damping for these classical models. Ours: d_k = 0.5 m_k (1/s), so each
# electromechanical mode decays as exp(-t d/(2m)) = exp(-t/4 s): visible over a 10 s horizon.
DAMPING_PER_INERTIA = 0.5
# The identification search box of each machine spans a factor BOX_FACTOR**2 = 16 around
# BOX_OFFSET x the truth: (m_k / 2, 8 m_k) and (d_k / 2, 8 d_k). Off-centre on purpose: a method that
# starts at the box's (log) centre starts at twice the truth, not at it.
BOX_FACTOR = 4.0
BOX_OFFSET = 2.0
# The scenario's P1 range: generator 1's operating P +- 30 %.
P1_SPREAD = 0.3
# Horizon (s) of the network cases: the first swings (periods ~0.5-2 s) and their damping (time
# constant 4 s) show.
T_FINAL = 10.0
# Power-flow tolerance (MVA) for pandapower.runpp: tight, so p_m matches the flow to ~1e-10 p.u.
PF_TOL_MVA = 1e-10


def solve_power_flow(net: pandapowerNet) -> pandapowerNet:
    """Run pandapower's AC power flow on `net` in place (tolerance `PF_TOL_MVA`; numba off: on small
    nets its compilation costs seconds and saves nothing, on 9241 buses it is no faster) and
    return it."""
    import pandapower as pp

    with warnings.catch_warnings():  # pandapower 3 on its own stored case39: a notice, not a fault
        warnings.filterwarnings("ignore", "tap_dependency_table is missing", DeprecationWarning)
        pp.runpp(net, tolerance_mva=PF_TOL_MVA, numba=False)
    return net


@dataclass(frozen=True)
class ClassicalModel:
    """A classical model at its pre-disturbance equilibrium; n machines in `buses` order.

    buses (n,) pandapower bus indices and elements (n,) ("gen" | "ext_grid", index) of the machines;
    m (n,) p.u. s^2/rad; d (n,) p.u. s/rad; E (n,) p.u.; delta0 (n,) rad (absolute, the power
    flow's reference); p_m (n,) p.u. = P_e(delta0); p_flow (n,) p.u., the power flow's machine P;
    G, B (n, n) symmetric p.u.; all powers and admittances on base_mva (MVA); f_hz the frequency;
    network: the same network unreduced (`systems.sparse_network`), reduced to G, B.
    """

    buses: tuple[int, ...]
    elements: tuple[tuple[str, int], ...]
    m: np.ndarray
    d: np.ndarray
    E: np.ndarray
    delta0: np.ndarray
    p_m: np.ndarray
    p_flow: np.ndarray
    G: np.ndarray
    B: np.ndarray
    base_mva: float
    f_hz: float
    network: SparseNetwork


def electrical_power(delta: np.ndarray, E: np.ndarray, G: np.ndarray, B: np.ndarray) -> np.ndarray:
    """P_e(delta) (..., n) p.u. for angles delta (..., n) rad, EMFs E (n,) p.u., G, B (n, n) p.u."""
    delta = np.asarray(delta, np.float64)
    diff = delta[..., :, None] - delta[..., None, :]
    return E * np.sum((G * np.cos(diff) + B * np.sin(diff)) * E, axis=-1)


def kron_reduce(Y: np.ndarray, keep) -> np.ndarray:
    """Kron reduction of a nodal admittance matrix Y (N, N) onto the nodes `keep` (k,), in that
    order, with zero injection at every other node: Y_kk - Y_ke Y_ee^-1 Y_ek, (k, k)."""
    Y = np.asarray(Y)
    keep, elim = _split_nodes(Y.shape, keep)
    reduced = Y[np.ix_(keep, keep)]
    if elim.size:
        solved = np.linalg.solve(Y[np.ix_(elim, elim)], Y[np.ix_(elim, keep)])
        reduced = reduced - Y[np.ix_(keep, elim)] @ solved
    return reduced


def kron_reduce_sparse(Y, keep, *, block: int = 256) -> np.ndarray:
    """`kron_reduce` of a scipy.sparse Y (N, N): one sparse LU factorisation of Y_ee
    (scipy.sparse.linalg.splu), solved for the kept columns `block` at a time (memory
    O(N block)). Returns the dense (k, k) Y_kk - Y_ke Y_ee^-1 Y_ek."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    Y = sparse.csc_matrix(Y)
    keep, elim = _split_nodes(Y.shape, keep)
    reduced = Y[keep][:, keep].toarray()
    if elim.size:
        lu = splu(Y[elim][:, elim].tocsc())
        Y_ek, Y_ke = Y[elim][:, keep].tocsc(), Y[keep][:, elim].tocsr()
        for start in range(0, keep.size, block):
            cols = slice(start, start + block)
            reduced[:, cols] -= Y_ke @ lu.solve(Y_ek[:, cols].toarray())
    return reduced


def reduce_to_machines(Y, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(G, B) (n, n) p.u., exactly symmetric: an augmented network Y (N, N) (scipy.sparse, its last
    n nodes the machines') Kron-reduced onto its machine nodes (`kron_reduce_sparse`). ValueError if
    the reduction is not symmetric to 1e-10 relative (a phase shifter)."""
    N = Y.shape[0]
    Y_red = kron_reduce_sparse(Y, np.arange(N - n, N))
    asym = np.abs(Y_red - Y_red.T).max() / np.abs(Y_red).max()
    if asym > 1e-10:
        raise ValueError(f"net: the reduced admittance is not symmetric (relative {asym:.3g}): phase "
                         "shifters are not supported")
    Y_red = (Y_red + Y_red.T) / 2  # exactly symmetric, as Case requires
    return Y_red.real.copy(), Y_red.imag.copy()


def _split_nodes(shape: tuple[int, ...], keep) -> tuple[np.ndarray, np.ndarray]:
    """(keep, eliminated) node indices of a square (N, N) matrix, or a ValueError."""
    if len(shape) != 2 or shape[0] != shape[1]:
        raise ValueError(f"Y must be a square matrix, got shape {shape}")
    keep = np.asarray(keep, np.int64)
    if keep.ndim != 1 or keep.size == 0 or len(set(keep.tolist())) != keep.size \
            or keep.min() < 0 or keep.max() >= shape[0]:
        raise ValueError(f"keep must be distinct node indices in [0, {shape[0]}), got {keep.tolist()}")
    return keep, np.setdiff1d(np.arange(shape[0]), keep)


def bus_indices(net: pandapowerNet, names) -> list[int]:
    """pandapower bus indices of the buses whose `name` is each of `names` (the source's bus numbers)."""
    index = {int(name): int(idx) for idx, name in zip(net.bus.index, net.bus.name) if name is not None}
    missing = [name for name in names if int(name) not in index]
    if missing:
        raise ValueError(f"names: net has no bus named {missing}")
    return [index[int(name)] for name in names]


def _positive(name: str, value) -> float:
    """`value` as a positive float or a ValueError naming `name`."""
    arr = check_array(name, value, ndim=0)
    if arr <= 0:
        raise ValueError(f"{name} must be > 0, got {float(arr)!r}")
    return float(arr)


def _machine_elements(net: pandapowerNet, buses: list[int]) -> list[tuple[str, int]]:
    """The one in-service gen or ext_grid at each bus; every in-service one must be listed."""
    found: dict[int, list[tuple[str, int]]] = {}
    for table in ("ext_grid", "gen"):
        frame = net[table]
        for idx, bus in zip(frame.index[frame.in_service.values], frame.bus.values[frame.in_service.values]):
            found.setdefault(int(bus), []).append((table, int(idx)))
    missing = sorted(set(found) - set(buses))
    if missing:
        raise ValueError(f"machine_buses leaves out the generator bus(es) {missing}: every in-service "
                         "gen and ext_grid is a machine")
    elements = []
    for bus in buses:
        at_bus = found.get(bus, [])
        if len(at_bus) != 1:
            raise ValueError(f"machine_buses: bus {bus} has {len(at_bus)} in-service gen/ext_grid elements, "
                             "a machine bus needs exactly one")
        elements.append(at_bus[0])
    return elements


def classical_model(net: pandapowerNet, machine_buses, H, xd_prime, f_hz: float, *, machine_mva=None,
                    damping_per_inertia: float = DAMPING_PER_INERTIA, tol: float = 1e-9,
                    balance_tol: float = 1e-6) -> ClassicalModel:
    """The classical model of a solved pandapower `net` (run `pandapower.runpp` first).

    machine_buses (n,): pandapower bus indices, one per machine, in the machine order wanted (each bus
    holds exactly one in-service gen or ext_grid, and every one is listed: the slack is a machine).
    H (n,) s and xd_prime (n,) p.u. on machine_mva (n,) MVA (None: the system base net.sn_mva); a
    number sets every machine's. f_hz: the system frequency (Hz), omega_s = 2 pi f_hz.
    M_k = 2 H_k S_k / (omega_s S_base); d_k = damping_per_inertia m_k. Loads and static generators
    become constant admittances conj(S)/|V|^2 at their solved voltages; shunts and branches are in Ybus.
    E_k e^{j delta_k} = V_k + j x'd_k conj(S_k / V_k) with S_k the machine's solved P + jQ.
    Raises ValueError if the power flow does not balance to `balance_tol` p.u. with these elements
    (an unsolved net, or an element this model lacks: ward, storage, ...), or if p_m = P_e(delta0)
    differs from the power flow's machine P by more than `tol` p.u.
    The network (`sparse_network.augmented_network`) is reduced with sparse matrices
    (`kron_reduce_sparse`: 9241 buses in ~2 s) and also kept unreduced (`ClassicalModel.network`).
    """
    ppc = getattr(net, "_ppc", None) or {}
    if not getattr(net, "converged", False) or "Ybus" not in ppc.get("internal", {}):
        raise ValueError("net must hold a converged AC power flow (run pandapower.runpp(net) first)")
    buses = [int(b) for b in np.atleast_1d(np.asarray(machine_buses)).tolist()]
    if not buses or len(set(buses)) != len(buses):
        raise ValueError(f"machine_buses must be distinct bus indices, got {buses}")
    unknown = sorted(set(buses) - {int(b) for b in net.bus.index})
    if unknown:
        raise ValueError(f"machine_buses names bus(es) {unknown} that net does not have")
    n = len(buses)
    H = per_machine("H", H, n)
    xd_prime = per_machine("xd_prime", xd_prime, n)
    base = float(net.sn_mva)
    rating = per_machine("machine_mva", base if machine_mva is None else machine_mva, n)
    f_hz = _positive("f_hz", f_hz)
    damping_per_inertia = _positive("damping_per_inertia", damping_per_inertia)
    elements = _machine_elements(net, buses)

    # Network in pandapower's internal (ppci) bus order, p.u. on `base`.
    Ybus = ppc["internal"]["Ybus"]  # scipy.sparse
    nb = Ybus.shape[0]
    V = np.asarray(ppc["internal"]["V"])
    lookup = net._pd2ppc_lookups["bus"]
    s_flow = np.array([complex(net[f"res_{t}"].at[i, "p_mw"], net[f"res_{t}"].at[i, "q_mvar"])
                       for t, i in elements]) / base
    at = lookup[np.asarray(buses)]
    if (at >= nb).any():
        raise ValueError(f"machine_buses: bus(es) {np.asarray(buses)[at >= nb].tolist()} are out of service")
    s_load = np.zeros(nb, complex)
    for table, sign in (("load", 1.0), ("sgen", -1.0)):
        on = net[table].in_service.values
        node = lookup[net[table].bus.values[on]]
        res = net[f"res_{table}"].loc[net[table].index[on]]
        s_elem = sign * (res.p_mw.values + 1j * res.q_mvar.values) / base
        np.add.at(s_load, node[node < nb], s_elem[node < nb])  # none on out-of-service buses
    # Machine power = its bus's injection V conj(Ybus V) plus the bus's load: exact for the solved V
    # (pandapower's reported gen Q can be off by ~1e-9 p.u.); checked against the reported P + jQ.
    s_free = V * np.conj(Ybus @ V) + s_load
    s_gen = s_free[at]
    s_free[at] -= s_flow
    mismatch = np.abs(s_free).max()
    if mismatch > balance_tol:
        raise ValueError(f"net: the power flow does not balance with its machines and loads (mismatch "
                         f"{mismatch:.3g} p.u. > {balance_tol:g}): unsolved, or an element this model lacks")

    # Augmented network: internal machine nodes nb..nb+n-1 behind j x'd (system base), sparse.
    y = 1.0 / (1j * xd_prime * base / rating)
    Y = augmented_network(Ybus, np.conj(s_load) / np.abs(V) ** 2, at, y)
    G, B = reduce_to_machines(Y, n)

    emf = V[at] + 1j * xd_prime * base / rating * np.conj(s_gen / V[at])
    E, delta0 = np.abs(emf), np.angle(emf)
    p_m = electrical_power(delta0, E, G, B)
    err = np.abs(p_m - s_flow.real).max()
    if err > tol:
        raise ValueError(f"net: P_e(delta0) differs from the power-flow P by {err:.3g} p.u. > tol {tol:g}")
    m = 2.0 * H * rating / (2.0 * np.pi * f_hz * base)
    network = SparseNetwork.of(Y, n, reduces_to=hash((_rows(G), _rows(B))))
    return ClassicalModel(buses=tuple(buses), elements=tuple(elements), m=m, d=damping_per_inertia * m,
                          E=E, delta0=delta0, p_m=p_m, p_flow=s_flow.real.copy(), G=G, B=B,
                          base_mva=base, f_hz=f_hz, network=network)


def network_case(name: str, model: ClassicalModel, *, t_final: float, p1_spread: float = P1_SPREAD,
                 box_factor: float = BOX_FACTOR, box_offset: float = BOX_OFFSET, source: str = "") -> Case:
    """The `Case` of `model`: at rest at its equilibrium (delta0, omega0 = 0), no infinite bus,
    P1 in generator 1's p_m[0] (1 -+ p1_spread), boxes (c / box_factor, c box_factor) for m and d
    with c = box_offset x the truth (the truth must lie inside: box_offset < box_factor)."""
    if not (0 <= p1_spread < 1):
        raise ValueError(f"p1_spread must be in [0, 1), got {p1_spread!r}")
    if not box_factor > 1:
        raise ValueError(f"box_factor must be > 1, got {box_factor!r}")
    if not 1 / box_factor < box_offset < box_factor:
        raise ValueError(f"box_offset must be in (1 / box_factor, box_factor) = ({1 / box_factor:g}, "
                         f"{box_factor:g}) so that the truth is inside its box, got {box_offset!r}")
    p1 = sorted((model.p_m[0] * (1 - p1_spread), model.p_m[0] * (1 + p1_spread)))
    zeros = (0.0,) * model.m.size
    m_box = box_offset * np.column_stack([model.m / box_factor, model.m * box_factor])
    d_box = box_offset * np.column_stack([model.d / box_factor, model.d * box_factor])
    return Case(name=name, m=_floats(model.m), d=_floats(model.d), delta0=_floats(model.delta0), omega0=zeros,
                p_m=_floats(model.p_m), E=_floats(model.E), G=_rows(model.G), B=_rows(model.B), g_inf=zeros,
                b_inf=zeros, t_final=t_final, p1_min=p1[0], p1_max=p1[1], m_box=_pairs(m_box),
                d_box=_pairs(d_box), source=source, network=model.network)


# A Case holds tuples of floats (hashable, compared by value): the model's arrays as such
def _floats(x: np.ndarray) -> tuple[float, ...]:
    return tuple(np.asarray(x, np.float64).tolist())


def _rows(x: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(row) for row in np.asarray(x, np.float64).tolist())


def _pairs(x: np.ndarray) -> tuple[tuple[float, float], ...]:
    return tuple((lo, hi) for lo, hi in np.asarray(x, np.float64).tolist())
