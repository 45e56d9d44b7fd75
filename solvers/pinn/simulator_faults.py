"""What the PINNSim simulator (`solvers.pinn.simulator`) needs of a fault case: the impedance seen
from the machine terminals in each phase, and the steps that put the switch on a step's edge.

A fault case (`systems.cases.Fault`) carries its networks Kron-reduced onto the machines' internal
nodes, Y_red = G + j B (n, n), and the machines' tie admittances y_k = 1 / (j x'd_k) (`Fault.y`).
With D = diag(y) and Y_T the network seen from the terminals (the buses, the other buses
eliminated), the reduction is Y_red = D - D (Y_T + D)^-1 D, and (Y_T + D)^-1 is the simulator's Z
(the impedance with the machines' ties on the diagonal, `simulator.impedance` of a sparse step
network), so

    Z = D^-1 (D - Y_red) D^-1 = D^-1 - D^-1 Y_red D^-1,

no inversion: the fault-on and post-fault Z from the case's own reduced networks. A machine whose
terminal bus is the faulted one gets a zero row of the fault-on Z (its terminal voltage is 0, its
terminal angle undetermined: the adapter refuses such a case).

The steps (`fault_schedule`): each clearing time t_c of a query splits [0, t_end] into K_on equal
fault-on steps on [0, t_c] and K_post equal post-fault steps on [t_c, t_end], K_on and K_post fixed
for the query (from the longest and the shortest t_c) so that every t_c is one row of one compiled
call; no step is longer than h. At t_c the machines' state carries over and the next step starts
from the post-fault network's voltage.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from solvers.pinn.simulator import impedance
from systems.cases import Case
from systems.sparse_network import SparseNetwork

__all__ = ["FAULT_ON", "POST_FAULT", "Schedule", "fault_schedule", "impedances", "reduced_impedance",
           "tie_admittances", "uniform_schedule"]

FAULT_ON, POST_FAULT = 0, 1  # the phases' rows of the adapter's stack of Z


class Schedule(NamedTuple):
    """Every P1's steps: lengths (n_P, K) s, phase (K,) int (the row of the stack of Z step k is on,
    the same for every P1: the simulator's products by Z then serve every P1 at once), edges (n_P,
    K + 1) s (step k on [edges[k], edges[k + 1]], edges[0] = 0)."""

    lengths: np.ndarray
    phase: np.ndarray
    edges: np.ndarray

    def steps_to(self, t_max: float, h: float) -> int:
        """The steps (>= 1) that reach t_max (s) for every P1: those starting more than 1e-9 h
        before it (a time on an edge belongs to the later step, whose start state is known)."""
        return max(1, int((self.edges[:, :-1] < t_max - 1e-9 * h).sum(axis=1).max()))


def reduced_impedance(G: np.ndarray, B: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Z = D^-1 - D^-1 (G + j B) D^-1 (n, n) complex p.u., D = diag(y): the impedance seen from the
    machine terminals, ties on the diagonal, of the network reduced onto the internal nodes."""
    inv = 1.0 / np.asarray(y, complex)
    return np.diag(inv) - inv[:, None] * (np.asarray(G) + 1j * np.asarray(B)) * inv[None, :]


def tie_admittances(case: Case) -> np.ndarray | None:
    """Each machine's tie admittance y = 1 / (j x'd) (n,) complex p.u.: a step case's from its carried
    network, a fault case's from its fault (`Fault.y`); None when the case has neither."""
    if case.fault is not None:
        return None if case.fault.y is None else np.asarray(case.fault.y, np.complex128)
    return np.asarray(case.network.y, np.complex128) if isinstance(case.network, SparseNetwork) else None


def impedances(case: Case) -> np.ndarray:
    """The networks' impedances seen from the machine terminals (`simulator.impedance`), stacked
    (phases, n, n) complex p.u.: a step case's one (from its sparse network), a fault case's fault-on
    and post-fault ones (`simulator_faults.reduced_impedance`, rows `FAULT_ON`, `POST_FAULT`)."""
    if case.fault is None:
        return impedance(case.network)[None]
    y, f = tie_admittances(case), case.fault
    return np.stack([reduced_impedance(f.G_on, f.B_on, y), reduced_impedance(f.G_post, f.B_post, y)])


def uniform_schedule(n_p: int, h: float, steps: int) -> Schedule:
    """A step case's: `steps` steps of h (s) for each of n_p P1, all on the one network (phase 0)."""
    edges = np.tile(h * np.arange(steps + 1, dtype=np.float64), (n_p, 1))
    return Schedule(np.full((n_p, steps), h), np.zeros(steps, np.int64), edges)


def fault_schedule(t_c: np.ndarray, h: float, t_end: float, longest: float, shortest: float) -> Schedule:
    """The steps of clearing times t_c (n_P,) s, each in [shortest, longest] (s, the range a compile
    serves), over [0, t_end] s: K_on = ceil(longest / h) fault-on steps of t_c / K_on and K_post =
    ceil((t_end - shortest) / h) post-fault steps of (t_end - t_c) / K_post (each <= h; a t_c of 0:
    fault-on steps of length 0). ValueError if some t_c is outside [0, t_end) or the range."""
    t_c = np.asarray(t_c, np.float64)
    if not (0.0 <= shortest <= t_c.min() and t_c.max() <= longest < t_end):
        raise ValueError(f"clearing times [{t_c.min():g}, {t_c.max():g}] s must lie in [{shortest:g}, {longest:g}] "
                         f"s, within [0, {t_end:g}) s")
    k_on = max(1, int(np.ceil(longest / h - 1e-9)))
    k_post = max(1, int(np.ceil((t_end - shortest) / h - 1e-9)))
    on = t_c[:, None] * (np.arange(k_on + 1) / k_on)  # ends exactly on t_c
    post = t_c[:, None] + (t_end - t_c)[:, None] * (np.arange(1, k_post + 1) / k_post)
    edges = np.concatenate([on, post], axis=1)
    phase = np.r_[np.full(k_on, FAULT_ON), np.full(k_post, POST_FAULT)]
    return Schedule(np.diff(edges, axis=1), phase, edges)
