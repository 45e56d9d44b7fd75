"""The network kept sparse: the classical model without the Kron reduction.

The augmented network (`augmented_network`: the buses, their loads as constant admittances, and
each machine's internal node tied to its bus at[k] through y_k = 1 / (j x'd_k)) is what the Kron
reduction eliminates down to the machines (`systems.network.classical_model`). Kept as it is, with
the machine EMFs E_k e^{j delta_k} as sources, the bus voltages V (nb,) solve

    Y_bb V = sum_k y_k E_k e^{j delta_k} e_at[k],

Y_bb (nb, nb) the augmented network's bus block (Ybus + diag(loads) + diag(y_k at the machine
buses)), and each machine delivers I_k = y_k (E_k e^{j delta_k} - V_at[k]) and

    P_e,k = Re(E_k e^{j delta_k} conj(I_k)) = g_k - Re(conj(w_k) e^{j delta_k} conj(V_at[k])),

with w_k = y_k E_k and g_k = Re(y_k) E_k^2: the reduced form's P_e (`systems.model`) to rounding.
Y_bb is factorised once per topology (`lu_factors`: SuperLU with a fill-reducing ordering); each
evaluation is then n complex exponentials and two sparse triangular solves, O(nnz(L + U)) instead
of the reduced form's O(n^2). All admittances p.u. on the system base.

Nothing here imports the rest of the project (`systems.cases` imports `SparseNetwork`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, NamedTuple

import numpy as np

if TYPE_CHECKING:  # annotations only
    from scipy.sparse import csc_matrix

__all__ = ["ORDERING", "LUFactors", "Ordering", "SparseNetwork", "augmented_network", "lu_factors", "sparse_electrical_power"]

# SuperLU's column ordering for Y_bb: the minimum degree ordering of Y + Y^T, kept symmetric
# (SymmetricMode, no pivoting off the diagonal: Y_bb is diagonally heavy), the least fill of
# SuperLU's orderings on a symmetric network (`lu_factors` reports nnz).
Ordering = Literal["NATURAL", "COLAMD", "MMD_ATA", "MMD_AT_PLUS_A"]
ORDERING: Ordering = "MMD_AT_PLUS_A"


def augmented_network(Ybus, y_load: np.ndarray, at: np.ndarray, y: np.ndarray) -> csc_matrix:
    """The network with its machines, (nb + n, nb + n) complex csc p.u.: the bus admittance
    matrix Ybus (nb, nb) (scipy.sparse) plus diag(y_load) (nb,) (constant-admittance loads), and
    machine k's internal node nb + k tied to bus at[k] (n,) through y[k] (n,). The machine nodes
    carry no other branch; the Kron reduction onto them is the classical model's Y_red."""
    from scipy.sparse import block_diag, coo_matrix, diags

    nb, n = Ybus.shape[0], len(at)
    at, y = np.asarray(at, np.int64), np.asarray(y, complex)
    k = np.arange(nb, nb + n)
    ties = coo_matrix((np.concatenate([y, y, -y, -y]), (np.concatenate([at, k, at, k]),
                                                        np.concatenate([at, k, k, at]))), shape=(nb + n, nb + n))
    return (block_diag([Ybus + diags(np.asarray(y_load, complex)), coo_matrix((n, n))]) + ties).tocsc()


@dataclass(frozen=True, eq=False)
class SparseNetwork:
    """The unreduced network of n machines: Y_bb (nb, nb) complex csc p.u. (buses, loads, and each
    machine's tie admittance on its bus's diagonal), at (n,) int64 the bus of each machine, y (n,)
    complex p.u. each machine's tie admittance 1 / (j x'd). `reduces_to`: `hash((G, B))` of the
    reduced form (the `Case`'s tuples) that this network was reduced to, so that a `Case` can
    refuse a network that is not its own. Compares by identity (a `Case` leaves it out of its
    equality and hash: it is the same system in another form)."""

    Y_bb: csc_matrix
    at: np.ndarray
    y: np.ndarray
    reduces_to: int

    @classmethod
    def of(cls, augmented, n: int, reduces_to: int) -> SparseNetwork:
        """From an `augmented_network` (nb + n, nb + n) whose last n nodes are the machines'."""
        from scipy.sparse import csc_matrix

        Y = csc_matrix(augmented)
        nb = Y.shape[0] - n
        ties = Y[:nb, nb:].tocsc()  # column k: -y_k at row at[k], nothing else
        if n <= 0 or nb <= 0 or np.diff(ties.indptr).tolist() != [1] * n:
            raise ValueError(f"augmented: its last {n} nodes must be machine nodes, each tied to one bus")
        return cls(Y_bb=Y[:nb, :nb].tocsc(), at=ties.indices.astype(np.int64), y=-ties.data.astype(complex),
                   reduces_to=reduces_to)

    @property
    def n_buses(self) -> int:
        return self.Y_bb.shape[0]

    def augmented(self) -> csc_matrix:
        """The `augmented_network` (nb + n, nb + n) complex csc p.u. this network was made `of`: Y_bb,
        and machine k's node nb + k tied to bus at[k] by y[k] (the same entries, not recomputed)."""
        from scipy.sparse import bmat, coo_matrix, csc_matrix

        nb, n = self.n_buses, self.at.size
        k = np.arange(n)
        ties = coo_matrix((-self.y, (self.at, k)), shape=(nb, n))
        machines = coo_matrix((self.y, (k, k)), shape=(n, n))
        return csc_matrix(bmat([[coo_matrix(self.Y_bb), ties], [ties.T, machines]]))


class LUFactors(NamedTuple):
    """The factors of Y_bb and the machines' coefficients, as plain arrays (nb buses, n machines),
    for triangular solves written out (numba, JAX): P_r Y_bb P_c = L U (SuperLU), stored as

    l_ptr, l_idx, l_val: the strictly lower part of L in CSR ((nb + 1,), int64, complex128);
    l_inv (nb,): 1 / diag(L); u_ptr, u_idx, u_val, u_inv: the strictly upper part of U and
    1 / diag(U), alike; source (n,) int64: the row of L U z = P_r b where machine k's injection
    lands (perm_r[at[k]]); sink (n,) int64: the entry of z that is V_at[k] (perm_c[at[k]]);
    w (n,) complex = y_k E_k and g (n,) = Re(y_k) E_k^2 p.u. (`sparse_electrical_power`).
    """

    l_ptr: np.ndarray
    l_idx: np.ndarray
    l_val: np.ndarray
    l_inv: np.ndarray
    u_ptr: np.ndarray
    u_idx: np.ndarray
    u_val: np.ndarray
    u_inv: np.ndarray
    source: np.ndarray
    sink: np.ndarray
    w: np.ndarray
    g: np.ndarray

    @property
    def nnz(self) -> int:
        """Entries of L + U (diagonals included): the multiply-adds of one pair of solves."""
        return self.l_val.size + self.u_val.size + 2 * self.l_inv.size

    @classmethod
    def empty(cls) -> LUFactors:
        """No network: zero-length arrays of the factors' types."""
        ints, cplx = np.zeros(0, np.int64), np.zeros(0, complex)
        return cls(np.zeros(1, np.int64), ints, cplx, cplx, np.zeros(1, np.int64), ints, cplx, cplx, ints, ints,
                   cplx, np.zeros(0))


def _strict(M, lower: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(indptr, indices, data, 1 / diagonal) of the strictly lower (upper) part of a triangular M, CSR."""
    from scipy.sparse import csr_matrix, tril, triu

    M = csr_matrix(M)
    part = csr_matrix(tril(M, -1) if lower else triu(M, 1))
    part.sort_indices()
    return (part.indptr.astype(np.int64), part.indices.astype(np.int64), part.data.astype(complex),
            1.0 / M.diagonal().astype(complex))


def lu_factors(network: SparseNetwork, E, ordering: Ordering = ORDERING) -> LUFactors:
    """`LUFactors` of `network` with the machines' EMFs E (n,) p.u.: one SuperLU factorisation
    (scipy.sparse.linalg.splu) with the column ordering `ordering` (SuperLU's permc_spec)."""
    from scipy.sparse.linalg import splu

    E = np.asarray(E, np.float64)
    if E.shape != network.at.shape:
        raise ValueError(f"E must be ({network.at.size},), one EMF per machine, got shape {E.shape}")
    lu = splu(network.Y_bb, permc_spec=ordering, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return LUFactors(*_strict(lu.L, lower=True), *_strict(lu.U, lower=False),
                     source=lu.perm_r[network.at].astype(np.int64), sink=lu.perm_c[network.at].astype(np.int64),
                     w=network.y * E, g=network.y.real * E ** 2)


def sparse_electrical_power(network: SparseNetwork, E, delta) -> np.ndarray:
    """P_e (..., n) p.u. of the machines for angles delta (..., n) rad and EMFs E (n,) p.u., from
    the bus voltages (one SuperLU solve of Y_bb for all the angles): the reference evaluation of
    the module docstring's formula, in numpy."""
    from scipy.sparse.linalg import splu

    E, delta = np.asarray(E, np.float64), np.asarray(delta, np.float64)
    emf = E * np.exp(1j * delta)  # (..., n)
    flat = emf.reshape(-1, emf.shape[-1])
    b = np.zeros((network.n_buses, flat.shape[0]), complex)
    np.add.at(b, network.at, (network.y * flat).T)
    V = splu(network.Y_bb).solve(b).T.reshape(emf.shape[:-1] + (network.n_buses,))
    current = network.y * (emf - V[..., network.at])
    return (emf * np.conj(current)).real
