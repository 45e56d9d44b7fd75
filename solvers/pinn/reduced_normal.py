"""The Gauss-Newton products J^T J and J^T r of the reduced-output PINN's window loss, assembled
from the structure of its Jacobian instead of by automatic differentiation of every row
(`solvers.pinn.reduced`).

Every row is linear in the output layer: with the last hidden layer h (w,) and its tau
derivatives, a coefficient or its tau derivatives at a point is (e^T [W; b])_j + const, e (w + 1,)
a combination of [h, 1], [h_t, 0] and [h_tt, 0] with weights in phi(tau) (`jets`). Its Jacobian is
W^T de on the hidden parameters (de (w, P_h) that of e's first w entries) and e on the output
column j. A data row (a - target) is one such row; a physics row mixes the k coefficients through
the (k, k) matrices of the projected swing equation. For the data rows, with the output parameters
ordered (i, j) row-major (W's rows, then b):

    J^T J = [[sum_n de_n^T W W^T de_n,   sum_n de_n^T W (x) e_n^T],
             [...transposed,             (sum_n e_n e_n^T) (x) I_k]],

whose largest product costs n_u w P_h^2 (W W^T = R^T R, w rows a point) against n_u k P^2 from J
(P = P_h + (w + 1) k): ~10x less at k = 36, w = 20. The physics rows (few) are formed densely.
"""

from __future__ import annotations

import numpy as np

__all__ = ["data_normal_equations", "jets", "physics_jacobian"]


def jets(order: int, tau: np.ndarray, features: np.ndarray, d_features: np.ndarray,
         ) -> tuple[np.ndarray, np.ndarray]:
    """(e (n, w + 1), de (n, w, P_h)) of a's tau derivative of `order` (0, 1 or 2) at n points:
    a = a_s + phi v_s + phi^2 (h W + b), phi = 1 - exp(-tau). features (n, >= order + 1, w): h,
    h_t, h_tt, as many as there are; d_features (n, same, w, P_h) their Jacobians of the hidden
    parameters."""
    phi, dphi = 1.0 - np.exp(-tau), np.exp(-tau)  # phi'' = -phi'
    weights = [[phi * phi], [2 * phi * dphi, phi * phi], [2 * (dphi * dphi - phi * dphi), 4 * phi * dphi, phi * phi]]
    c = np.stack(weights[order], axis=1)  # (n, order + 1): weights of h, h_t, h_tt
    e = np.column_stack([np.einsum("nl,nlw->nw", c, features[:, :order + 1]), c[:, 0]])
    de = np.einsum("nl,nlwq->nwq", c, d_features[:, :order + 1], optimize=True)
    return e, de


def data_normal_equations(e: np.ndarray, de: np.ndarray, W: np.ndarray, r: np.ndarray,
                          ) -> tuple[np.ndarray, np.ndarray]:
    """(J^T J (P, P), J^T r (P,)) of rows r[n, j] = (e_n^T [W; b])_j - target: e (n, w + 1),
    de (n, w, P_h) (`jets`), W (w, k) the output weights, r (n, k) the rows' residuals;
    P = P_h + (w + 1) k, the hidden parameters first (float64 numpy throughout)."""
    n, w, n_h = de.shape
    k = W.shape[1]
    lam, V = np.linalg.eigh(W @ W.T)
    R = np.sqrt(np.clip(lam, 0.0, None))[:, None] * V.T  # R^T R = W W^T
    C = np.einsum("lm,nmq->nlq", R, de, optimize=True).reshape(n * w, n_h)
    A_hh = C.T @ C
    T = de.reshape(n, w * n_h).T @ e  # (w P_h, w + 1): sum_n de_n (x) e_n
    A_ho = np.tensordot(T.reshape(w, n_h, w + 1), W, axes=([0], [0])).reshape(n_h, (w + 1) * k)
    A = np.block([[A_hh, A_ho], [A_ho.T, np.kron(e.T @ e, np.eye(k))]])
    g = np.concatenate([np.einsum("nl,nlq->q", r @ W.T, de, optimize=True), (e.T @ r).reshape(-1)])
    return A, g


def physics_jacobian(e: np.ndarray, de: np.ndarray, W: np.ndarray, mix: np.ndarray) -> np.ndarray:
    """The Jacobian (n k, P) of n physics rows sum_m mix[n, m] a^(m) + const (k each): e (n, 3,
    w + 1) and de (n, 3, w, P_h) those of a, a' and a'' (`jets`), mix (n, 3, k, k)."""
    n, _, w, n_h = de.shape
    k = W.shape[1]
    hidden = np.einsum("nmjl,nmlq->njq", mix, np.einsum("wl,nmwq->nmlq", W, de, optimize=True), optimize=True)
    output = np.einsum("nmjl,nmi->njil", mix, e, optimize=True).reshape(n, k, (w + 1) * k)
    return np.concatenate([hidden, output], axis=2).reshape(n * k, n_h + (w + 1) * k)
