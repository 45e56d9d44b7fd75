"""numba kernels of `solvers.classical.pod_spline`: the tensor-product interpolant of a POD basis's modal
coefficients, evaluated at query points.

The interpolant of one quantity (the angles or the speeds), every array float64:
- `nodes` (S,) the P1 nodes (p.u.) and `weights` (S,) their barycentric weights: the polynomial
  interpolant of degree S - 1 in P1 (`solvers.classical.pod_spline.lobatto_nodes`);
- `values`, `slopes` (n_knots, S, k): the k modal coefficients at uniform time knots t_i = i h
  (i = 0 .. n_knots - 1, h s) of each node's trajectory, and their time derivatives (1/s): the
  piecewise cubic Hermite interpolant in t;
- `basis_t` (k, n) the modes as rows, `mean` (n,): the quantity is mean + coefficients @ basis_t.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["grid", "points"]


@njit(cache=True)
def _p1_weights(x: float, nodes: np.ndarray, weights: np.ndarray, out: np.ndarray) -> None:
    """The S interpolation weights of P1 = x into `out` (S,): 1 at a node it equals."""
    total = 0.0
    for s in range(nodes.size):
        dx = x - nodes[s]
        if dx == 0.0:
            out[:] = 0.0
            out[s] = 1.0
            return
        out[s] = weights[s] / dx
        total += out[s]
    out /= total


@njit(cache=True)
def _time_weights(t: float, h: float, n_knots: int) -> tuple[int, float, float, float, float]:
    """Knot i of the interval holding t (the last one from t_final on) and the cubic Hermite
    weights of values[i], slopes[i], values[i + 1], slopes[i + 1]."""
    u = t / h
    i = min(int(u), n_knots - 2)
    s = u - i
    r = 1.0 - s
    return i, (1.0 + 2.0 * s) * r * r, h * s * r * r, s * s * (3.0 - 2.0 * s), -h * s * s * r


@njit(cache=True)
def _coefficients(i: int, c0: float, c1: float, c2: float, c3: float, values: np.ndarray,
                  slopes: np.ndarray, out: np.ndarray) -> None:
    """The (S, k) modal coefficients at the time of weights (i, c0..c3) into `out`."""
    v0, d0, v1, d1 = values[i], slopes[i], values[i + 1], slopes[i + 1]
    for s in range(out.shape[0]):
        for q in range(out.shape[1]):
            out[s, q] = c0 * v0[s, q] + c1 * d0[s, q] + c2 * v1[s, q] + c3 * d1[s, q]


@njit(cache=True)
def _coefficients_at(t: np.ndarray, h: float, values: np.ndarray, slopes: np.ndarray) -> np.ndarray:
    """The modal coefficients (S, len(t), k) at the times t: the time weights first, then every
    node's coefficients in memory order."""
    n_s, k = values.shape[1], values.shape[2]
    knot = np.empty(t.size, np.int64)
    c = np.empty((t.size, 4))
    for j in range(t.size):
        knot[j], c[j, 0], c[j, 1], c[j, 2], c[j, 3] = _time_weights(t[j], h, values.shape[0])
    out = np.empty((n_s, t.size, k))
    for s in range(n_s):
        for j in range(t.size):
            i, c0, c1, c2, c3 = knot[j], c[j, 0], c[j, 1], c[j, 2], c[j, 3]
            for q in range(k):
                out[s, j, q] = (c0 * values[i, s, q] + c1 * slopes[i, s, q] + c2 * values[i + 1, s, q]
                                + c3 * slopes[i + 1, s, q])
    return out


@njit(cache=True)
def _combine(w: np.ndarray, C: np.ndarray, out: np.ndarray) -> None:
    """out (k,) = w (S,) @ C (S, k): the coefficients at one P1."""
    out[:] = 0.0
    for s in range(C.shape[0]):
        ws = w[s]
        for q in range(C.shape[1]):
            out[q] += ws * C[s, q]


@njit(cache=True)
def _add_modes(a: np.ndarray, basis_t: np.ndarray, out: np.ndarray) -> None:
    """out (n,) += a (k,) @ basis_t (k, n)."""
    for q in range(basis_t.shape[0]):
        mode, c = basis_t[q], a[q]
        for r in range(basis_t.shape[1]):
            out[r] += c * mode[r]


@njit(cache=True)
def grid(t: np.ndarray, P1: np.ndarray, h: float, nodes: np.ndarray, weights: np.ndarray, values: np.ndarray,
         slopes: np.ndarray, basis_t: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """The quantity at every (P1[p], t[j]): (len(P1), len(t), n). The coefficients at the query
    times (S, n_t, k) are contracted with the P1 weights then the basis, or with the basis first
    when that costs fewer multiply-adds (many P1 values, k close to n): two matrix products (BLAS)."""
    n_s, k = values.shape[1], values.shape[2]
    n, n_p, n_t = basis_t.shape[1], P1.size, t.size
    W = np.empty((n_p, n_s))
    for p in range(n_p):
        _p1_weights(P1[p], nodes, weights, W[p])
    C = _coefficients_at(t, h, values, slopes)
    if n_s * k * n + n_p * n_s * n < n_p * (n_s * k + k * n):  # per query time
        out = np.dot(W, np.dot(C.reshape(n_s * n_t, k), basis_t).reshape(n_s, n_t * n))
    else:
        out = np.dot(np.dot(W, C.reshape(n_s, n_t * k)).reshape(n_p * n_t, k), basis_t)
    out = out.reshape(n_p * n_t, n)
    for row in range(n_p * n_t):
        for r in range(n):
            out[row, r] += mean[r]
    return out.reshape(n_p, n_t, n)


@njit(cache=True)
def points(t: np.ndarray, P1: np.ndarray, h: float, nodes: np.ndarray, weights: np.ndarray, values: np.ndarray,
           slopes: np.ndarray, basis_t: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """The quantity at each pair (t[i], P1[i]): (len(t), n)."""
    n_s, k = values.shape[1], values.shape[2]
    w = np.empty(n_s)
    C = np.empty((n_s, k))
    a = np.empty(k)
    out = np.empty((t.size, basis_t.shape[1]))
    for m in range(t.size):
        _p1_weights(P1[m], nodes, weights, w)
        i, c0, c1, c2, c3 = _time_weights(t[m], h, values.shape[0])
        _coefficients(i, c0, c1, c2, c3, values, slopes, C)
        _combine(w, C, a)
        o = out[m]
        o[:] = mean
        _add_modes(a, basis_t, o)
    return out
