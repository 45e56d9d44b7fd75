"""The network part of P_e from the unreduced network, compiled: the right-hand side of
`solvers.classical.kernels.rk` in its sparse mode (`systems.sparse_network`).

With the factors P_r Y_bb P_c = L U of `systems.sparse_network.LUFactors` (`net`), the bus voltages
of angles delta are two triangular solves of the machines' injections, and

    P_e,k = g_k - Re(conj(w_k) e^{j delta_k} conj(V_at[k])),

O(nnz(L + U)) a call instead of the reduced coupling's O(n^2).
"""

from __future__ import annotations

from solvers.classical.kernels.jit import jit_function

__all__ = ["sparse_power"]


@jit_function
def sparse_power(scratch, net, n, work):
    """scratch (3n,): cos delta_k at [k], sin delta_k at [n + k] (read); P_e,k of the network
    (p.u., no infinite bus) written at [2n + k]. net: `LUFactors`; work (nb,) complex128 scratch."""
    nb = work.size
    for i in range(nb):
        work[i] = 0.0
    for k in range(n):
        work[net.source[k]] = net.w[k] * complex(scratch[k], scratch[n + k])
    l_ptr, l_idx, l_val, l_inv = net.l_ptr, net.l_idx, net.l_val, net.l_inv
    for i in range(nb):  # L z = P_r b, rows in order
        acc = work[i]
        for p in range(l_ptr[i], l_ptr[i + 1]):
            acc -= l_val[p] * work[l_idx[p]]
        work[i] = acc * l_inv[i]
    u_ptr, u_idx, u_val, u_inv = net.u_ptr, net.u_idx, net.u_val, net.u_inv
    for i in range(nb - 1, -1, -1):  # U x' = z, rows in reverse
        acc = work[i]
        for p in range(u_ptr[i], u_ptr[i + 1]):
            acc -= u_val[p] * work[u_idx[p]]
        work[i] = acc * u_inv[i]
    for k in range(n):
        v = work[net.sink[k]]
        e = complex(scratch[k], scratch[n + k])
        scratch[2 * n + k] = net.g[k] - (net.w[k].conjugate() * e * v.conjugate()).real
