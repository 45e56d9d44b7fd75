"""numba kernel of `solvers.classical.numba_rk`'s points queries: pairs (t_i s, P1_i p.u.) grouped
by P1 (`solvers.classical.common.PointGroups`), one trajectory per group integrated to that group's
last time with dense output at each of its times, every group in one compiled call (over numba's
threads with `parallel`). A group of one pair integrates to its own t_i: the bits of a one-point `solve`;
a group of many, the bits of a `solve` at that group's times.

The integrators and `options` are `solvers.classical.kernels.rk`'s, `system` and `net`
`solvers.classical.kernels.layout`'s.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import prange

from solvers.classical.kernels.jit import jit_variant
from solvers.classical.kernels.layout import OK, rhs_mode
from solvers.classical.kernels.rk import trajectory_kernel

__all__ = ["points_kernel"]


def _make_points(method: int, parallel: bool, n: int):
    trajectory = trajectory_kernel(method, False, n)

    def points(t, order, starts, P1, system, net, options):
        n_g = P1.size
        mode = rhs_mode(system, net, n)
        out = np.empty((2, 1, t.size, n))  # the integrators' (block, trajectory, time, machine)
        status = np.zeros(n_g, np.int64)
        for g in prange(n_g):
            status[g] = trajectory(t, order[starts[g]:starts[g + 1]], P1[g], system, net, mode, options, out, 0)
        for g in range(n_g):
            if status[g] != OK:
                return out[:, 0], g, status[g]
        return out[:, 0], -1, OK

    return jit_variant(points, f"{method}_{int(parallel)}_{n}", parallel=parallel)


@functools.cache
def points_kernel(method: int, parallel: bool, n: int = 1):
    """The compiled points integrator `(t, order, starts, P1, system, net, options) -> (out, failed,
    status)` of an n-machine `system` and `net` (`layout`'s): t (n_s,) s >= 0, the pairs' times in
    input order; order (n_s,) and starts (n_g + 1,) int64 and P1 (n_g,) p.u., the groups of
    `PointGroups` (each group's pairs by ascending time); options as `rk.kernel`'s. out (2, n_s, n):
    out[0] delta (rad), out[1] omega (rad/s), pair i at row i; `failed` the index of the first
    failed group (-1: none) and `status` its code (`layout.STATUS`).
    `parallel`: groups over numba's threads (prange)."""
    return _make_points(method, parallel, n)
