"""Classical multi-machine swing model from a solved pandapower power flow: the generic machinery.

Each machine is the classical model: an EMF E_k e^{j delta_k} of constant magnitude behind its
transient reactance x'd_k, tied to its terminal bus; loads are constant impedances fixed at the
solved voltages; the network, with the loads and the machine reactances, is Kron-reduced to the
internal machine nodes: Y_red = G + jB (p.u. on the system base `net.sn_mva`). Then

    P_e,k(delta) = sum_j E_k E_j (G_kj cos(delta_k - delta_j) + B_kj sin(delta_k - delta_j))  (p.u.)

and p_m = P_e(delta0) equals each machine's power-flow P (checked). Nothing here imports
pandapower: a solved net is read through its tables and the documented internal structures
(`net._ppc["internal"]["Ybus"]`, `["V"]`, `net._pd2ppc_lookups["bus"]`, pandapower's
internal_datastructure tutorial). Machine order is the caller's `machine_buses` order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from systems.cases import Case, check_array

__all__ = ["BOX_FACTOR", "DAMPING_PER_INERTIA", "P1_SPREAD", "ClassicalModel", "classical_model",
           "electrical_power", "kron_reduce", "network_case"]

# No source gives damping for these classical models. Ours: d_k = 0.5 m_k (1/s), so each
# electromechanical mode decays as exp(-t d/(2m)) = exp(-t/4 s): visible over a 10 s horizon.
DAMPING_PER_INERTIA = 0.5
# The identification search box of each machine: (m_k / 4, 4 m_k) and (d_k / 4, 4 d_k).
BOX_FACTOR = 4.0
# The scenario's P1 range: generator 1's operating P +- 30 %.
P1_SPREAD = 0.3


@dataclass(frozen=True)
class ClassicalModel:
    """A classical model at its pre-disturbance equilibrium; n machines in `buses` order.

    buses (n,) pandapower bus indices and elements (n,) ("gen" | "ext_grid", index) of the machines;
    m (n,) p.u. s^2/rad; d (n,) p.u. s/rad; E (n,) p.u.; delta0 (n,) rad (absolute, the power
    flow's reference); p_m (n,) p.u. = P_e(delta0); p_flow (n,) p.u., the power flow's machine P;
    G, B (n, n) symmetric p.u.; all powers and admittances on base_mva (MVA); f_hz the frequency.
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


def electrical_power(delta: np.ndarray, E: np.ndarray, G: np.ndarray, B: np.ndarray) -> np.ndarray:
    """P_e(delta) (..., n) p.u. for angles delta (..., n) rad, EMFs E (n,) p.u., G, B (n, n) p.u."""
    delta = np.asarray(delta, np.float64)
    diff = delta[..., :, None] - delta[..., None, :]
    return E * np.sum((G * np.cos(diff) + B * np.sin(diff)) * E, axis=-1)


def kron_reduce(Y: np.ndarray, keep) -> np.ndarray:
    """Kron reduction of a nodal admittance matrix Y (N, N) onto the nodes `keep` (k,), in that
    order, with zero injection at every other node: Y_kk - Y_ke Y_ee^-1 Y_ek, (k, k)."""
    Y = np.asarray(Y)
    if Y.ndim != 2 or Y.shape[0] != Y.shape[1]:
        raise ValueError(f"Y must be a square matrix, got shape {Y.shape}")
    keep = np.asarray(keep, np.int64)
    if keep.ndim != 1 or keep.size == 0 or len(set(keep.tolist())) != keep.size \
            or keep.min() < 0 or keep.max() >= Y.shape[0]:
        raise ValueError(f"keep must be distinct node indices in [0, {Y.shape[0]}), got {keep.tolist()}")
    elim = np.setdiff1d(np.arange(Y.shape[0]), keep)
    reduced = Y[np.ix_(keep, keep)]
    if elim.size:
        reduced = reduced - Y[np.ix_(keep, elim)] @ np.linalg.solve(Y[np.ix_(elim, elim)], Y[np.ix_(elim, keep)])
    return reduced
