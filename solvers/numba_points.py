"""numba kernel of `solvers.numba_rk`'s points queries: pairs (t_i s, P1_i p.u.) grouped by P1
(`solvers.classical.PointGroups`), one trajectory per group integrated to that group's last time
with dense output at each of its times, every group in one compiled call (over numba's threads
with `parallel`). A group of one pair integrates to its own t_i: the bits of a one-point `solve`;
a group of many, the bits of a `solve` at that group's times.

The integrators and the packed arguments (`system`, `options`) are `solvers.numba_kernels`'.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import prange

from solvers.numba_kernels import OK, P_M, RK4, _is_coupled, _jit_variant, _make_adaptive, _make_rk4

__all__ = ["points_kernel"]


def _make_points(method: int, parallel: bool, n: int):
    if method == RK4:
        rk4 = _make_rk4(False, n)
        adaptive = None
    else:
        adaptive = _make_adaptive(method, False, n)
        rk4 = None

    def points(t, order, starts, P1, system, options):
        n_g = P1.size
        rtol, atol, dt, max_steps = options[0], options[1], options[2], int(options[3])
        coupled = _is_coupled(system, n)
        out = np.empty((2, 1, t.size, n))  # the integrators' (block, trajectory, time, machine)
        status = np.zeros(n_g, np.int64)
        for g in prange(n_g):
            P = system[:, P_M].copy()  # Case.powers: generator 1 gets P1, the others p_m
            P[0] = P1[g]
            pairs = order[starts[g]:starts[g + 1]]
            if method == RK4:
                status[g] = rk4(t, pairs, P, system, coupled, dt, max_steps, out, 0)
            else:
                status[g] = adaptive(t, pairs, P, system, coupled, rtol, atol, max_steps, out, 0)
        for g in range(n_g):
            if status[g] != OK:
                return out[:, 0], g, status[g]
        return out[:, 0], -1, OK

    return _jit_variant(points, f"{method}_{int(parallel)}_{n}", parallel=parallel)


@functools.cache
def points_kernel(method: int, parallel: bool, n: int = 1):
    """The compiled points integrator `(t, order, starts, P1, system, options) -> (out, failed,
    status)` of an n-machine `system` (`numba_kernels.system_array`): t (n_s,) s >= 0, the pairs'
    times in input order; order (n_s,) and starts (n_g + 1,) int64 and P1 (n_g,) p.u., the groups
    of `PointGroups` (each group's pairs by ascending time); options as `numba_kernels.kernel`'s.
    out (2, n_s, n): out[0] delta (rad), out[1] omega (rad/s), pair i at row i; `failed` the
    index of the first failed group (-1: none) and `status` its code (`numba_kernels`'s).
    `parallel`: groups over numba's threads (prange)."""
    return _make_points(method, parallel, n)
