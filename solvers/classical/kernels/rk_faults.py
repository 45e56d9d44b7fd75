"""numba kernel of `solvers.classical.numba_rk` on a fault case (`systems.cases.Fault`): the fault-on
network from the equilibrium to the clearing time t_c, the post-fault network from the state at
t_c, no step across the switch.

The fault-on phase does not depend on t_c, so one trajectory of it serves every clearing time of a
call: integrated from t = 0 to the call's largest t_c (its last step ends there), its dense output
gives the states at each query time before a group's t_c and the state at every t_c. Each
post-fault trajectory then starts from its own state at its t_c: the system is autonomous, so it is
integrated in the time since t_c, from the packed post-fault system with that state as its initial
one (`layout.DELTA0`, `OMEGA0`). A query at t = t_c answers the state at t_c.

Arguments are `solvers.classical.kernels.layout`'s (`system_array` of each phase, `net`),
`options` as `solvers.classical.kernels.rk`'s, and the groups of
`solvers.classical.common.PointGroups`, with the clearing time in place of P1.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import prange

from solvers.classical.kernels.jit import jit_variant
from solvers.classical.kernels.layout import DELTA0, OK, OMEGA0, P_M, rhs_mode
from solvers.classical.kernels.rk import trajectory_kernel

__all__ = ["fault_kernel"]


def _make_fault(method: int, parallel: bool, n: int):
    trajectory = trajectory_kernel(method, False, n)

    def switched(t, order, starts, T_c, on, post, net, options, shared):
        n_g, n_t = T_c.size, t.size
        out = np.empty((2, 1 if shared else n_g, n_t, n))
        status = np.zeros(n_g, np.int64)
        # the fault-on trajectory's outputs: each group's times before its t_c (ascending within a
        # group), then every t_c, at index n_t + g of `ts`
        before = np.zeros(n_t, np.bool_)
        latest = 0
        for g in range(n_g):
            if T_c[g] > T_c[latest]:
                latest = g
            for i in range(starts[g], starts[g + 1]):
                if t[order[i]] >= T_c[g]:
                    break
                before[order[i]] = True
        ts = np.concatenate((t, T_c))
        picked = np.concatenate((np.flatnonzero(before), n_t + np.arange(n_g)))
        on_order = picked[np.argsort(ts[picked], kind="mergesort")]
        states = np.empty((2, 1, n_t + n_g, n))
        p1 = on[0, P_M]
        code = trajectory(ts, on_order, p1, on, net, rhs_mode(on, net, n), options, states, 0)
        if code != OK:
            return out, latest, code
        mode = rhs_mode(post, net, n)
        for g in prange(n_g):
            col = 0 if shared else np.int64(g)  # prange's index may be unsigned: 0 or g would unify to float
            split, end = starts[g], starts[g + 1]
            while split < end and t[order[split]] < T_c[g]:
                for b in range(2):
                    for k in range(n):
                        out[b, col, order[split], k] = states[b, 0, order[split], k]
                split += 1
            if split == end:
                continue
            system = post.copy()
            for k in range(n):
                system[k, DELTA0] = states[0, 0, n_t + g, k]
                system[k, OMEGA0] = states[1, 0, n_t + g, k]
            since = t[order[split:end]] - T_c[g]
            part = np.empty((2, 1, since.size, n))
            status[g] = trajectory(since, np.arange(since.size), p1, system, net, mode, options, part, 0)
            for i in range(since.size):
                for b in range(2):
                    for k in range(n):
                        out[b, col, order[split + i], k] = part[b, 0, i, k]
        for g in range(n_g):
            if status[g] != OK:
                return out, g, status[g]
        return out, -1, OK

    return jit_variant(switched, f"{method}_{int(parallel)}_{n}", parallel=parallel)


@functools.cache
def fault_kernel(method: int, parallel: bool, n: int):
    """The compiled integrator of a fault case `(t, order, starts, T_c, on, post, net, options,
    shared) -> (out, failed, status)`: t (n_t,) s >= 0; group g the times t[order[starts[g]:
    starts[g + 1]]] in ascending order (int64 order, starts (n_g + 1,)), cleared at T_c[g] (n_g,)
    s >= 0; `on`, `post` the packed fault-on and post-fault systems (`layout.system_array`
    of `Case.phase`), one `net` for both (`layout.NO_NETWORK`: a fault case's networks are
    reduced); `options` as `rk.kernel`'s. out (2, n_g, n_t, n), out[0] delta (rad) and out[1]
    omega (rad/s) of group g at column g (a `solve`: every group the same order of all t); with
    `shared`, out (2, 1, n_t, n), every group writing its own entries (`solve_points`). `failed`
    the first failed group (-1: none; a failed fault-on phase: the group of the largest t_c) and
    `status` its code (`layout.STATUS`). `parallel`: post-fault trajectories over numba's
    threads (prange)."""
    return _make_fault(method, parallel, n)
