"""Solver snapshots of a step case and their proper orthogonal decomposition (POD): the training data
and the basis of the reduced-order surrogates (`solvers.pinn.jax_reduced`).

Units: t in s, P1 in p.u., delta in rad, omega in rad/s. Shapes: n machines on the last axis.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from systems.cases import Case

__all__ = ["Basis", "chebyshev_nodes", "pod_basis", "solver_snapshots"]


def chebyshev_nodes(lo: float, hi: float, count: int) -> np.ndarray:
    """`count` >= 2 Chebyshev-Lobatto nodes on [lo, hi], ascending, both ends included: the
    points where an interpolant in P1 (and a POD basis built from them) errs least at the ends."""
    if count < 2:
        raise ValueError(f"chebyshev_nodes: count must be at least 2 (both ends of the range), got {count}")
    return 0.5 * (lo + hi) - 0.5 * (hi - lo) * np.cos(np.pi * np.arange(count) / (count - 1))


def solver_snapshots(case: Case, P1: np.ndarray, t: np.ndarray, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """delta (rad) and omega (rad/s), (len(P1), len(t), n): numba-rk's DOP853 at `rtol`
    (atol = rtol / 100) with its network form chosen as for the scaling suite (`network="auto"`:
    sparse from 100 machines), compiled on first use."""
    from solvers import make_solver  # the registry imports adapters on first use

    solver = make_solver("numba-rk", case=case, rtol=rtol, atol=rtol * 1e-2)
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


def pod_basis(deviations: np.ndarray, modes: int | None, tolerance: float) -> Basis:
    """The POD basis of `deviations` (..., n): the leading left singular vectors of the
    (n, snapshots) matrix of its rows, uncentred (so that a zero deviation, the initial state, is
    represented exactly). `modes` of them, or where None the fewest that keep all but `tolerance`
    of the squared norm. A ValueError names `modes` when the snapshots span fewer directions."""
    n = deviations.shape[-1]
    snapshots = deviations.reshape(-1, n).T
    if modes is not None and modes > min(snapshots.shape):
        raise ValueError(f"option modes={modes} is larger than the snapshots allow: {snapshots.shape[1]} snapshots "
                         f"of {n} machines span at most {min(snapshots.shape)} directions")
    U, s, _ = np.linalg.svd(snapshots, full_matrices=False)
    tail = 1.0 - np.cumsum(s ** 2) / np.sum(s ** 2)  # tail[j]: the fraction lost keeping j + 1 modes
    k = modes if modes is not None else int(np.searchsorted(-tail, -tolerance) + 1)
    k = min(k, s.size)
    return Basis(np.ascontiguousarray(U[:, :k]), float(1.0 - tail[k - 1]) if k < s.size else 1.0)
