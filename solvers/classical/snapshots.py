"""Solver snapshots of a step case and their proper orthogonal decomposition (POD): the training data
and the bases of the reduced-order surrogates (`solvers.classical.pod_spline`, `solvers.pinn.jax_reduced`).

Units: t in s, P1 in p.u., delta in rad, omega in rad/s. Shapes: n machines on the last axis.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

from solvers.classical.numba_rk import NumbaRK
from systems.cases import Case

__all__ = ["Basis", "chebyshev_nodes", "pod_basis", "pod_modes", "solver_snapshots"]


def chebyshev_nodes(lo: float, hi: float, count: int) -> np.ndarray:
    """`count` >= 2 Chebyshev-Lobatto nodes (the extrema of T_{count-1}) on [lo, hi], ascending,
    both ends included exactly (a query at lo or hi is a node): the points where an interpolant in
    P1 (and a POD basis built from them) errs least at the ends."""
    if count < 2:
        raise ValueError(f"chebyshev_nodes: count must be at least 2 (both ends of the range), got {count}")
    nodes = lo + (hi - lo) * 0.5 * (1.0 - np.cos(np.pi * np.arange(count) / (count - 1)))
    nodes[0], nodes[-1] = lo, hi
    return nodes


def solver_snapshots(case: Case, P1: np.ndarray, t: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """delta (rad) and omega (rad/s), (len(P1), len(t), n): numba-rk's DOP853 at `rtol`
    (atol = rtol / 100) with its network form chosen as for the scaling suite (`network="auto"`:
    sparse from 100 machines), compiled on first use."""
    solver = NumbaRK(case, rtol=rtol, atol=rtol * 1e-2)
    solver.fit()
    trajectory = solver.solve(t, P1)
    return trajectory.delta, trajectory.omega


class Basis(NamedTuple):
    """An orthonormal basis of machine-angle deviations: `vectors` (n, k), U^T U = I; `energy` the
    fraction of the snapshots' squared norm it keeps (1 - sum of the dropped squared singular
    values / the total; NaN for a basis not made from snapshots)."""

    vectors: np.ndarray
    energy: float

    @property
    def modes(self) -> int:
        return self.vectors.shape[1]


def pod_modes(rows: np.ndarray, k: int | None, energy: float, most: int | None = None) -> tuple[np.ndarray, float]:
    """The leading right singular vectors (n, k) of `rows` (N, n), the POD modes of its rows, and
    the fraction of the squared singular values they leave out. `k` None: the fewest modes that
    keep `energy` of them, at most `most` (None: no cap). Each mode's largest entry is positive (SVD leaves the sign free). The
    singular values are those of R from a QR of `rows` (n x n), not of the N x n matrix itself."""
    R = scipy.linalg.qr(rows, mode="r", check_finite=False)[0][:min(rows.shape)]
    s, vt = np.linalg.svd(R, full_matrices=False)[1:]
    squared = s * s
    tail = np.append(np.cumsum(squared[::-1])[::-1], 0.0) / max(squared.sum(), np.finfo(float).tiny)
    if k is None:  # tail[j]: the fraction modes j, j + 1, ... hold
        k = max(1, int(np.argmax(tail <= 1.0 - energy)))
        k = k if most is None else min(k, most)
    modes = vt[:k].T
    largest = modes[np.abs(modes).argmax(axis=0), np.arange(k)]
    return modes * np.where(largest < 0, -1.0, 1.0), float(tail[k])


def pod_basis(deviations: np.ndarray, modes: int | None, tolerance: float, most: int | None = None) -> Basis:
    """The POD basis (`pod_modes`) of `deviations` (..., n), uncentred (so that a zero deviation,
    the initial state, is represented exactly): `modes` of them, or where None the fewest that keep
    all but `tolerance` of the squared norm, at most `most`. A ValueError names `modes` when the snapshots span
    fewer directions."""
    n = deviations.shape[-1]
    rows = deviations.reshape(-1, n)
    if modes is not None and modes > min(rows.shape):
        raise ValueError(f"option modes={modes} is larger than the snapshots allow: {rows.shape[0]} snapshots "
                         f"of {n} machines span at most {min(rows.shape)} directions")
    vectors, left_out = pod_modes(rows, modes, 1.0 - tolerance, most)
    return Basis(np.ascontiguousarray(vectors), 1.0 - left_out)
