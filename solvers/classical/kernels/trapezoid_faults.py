"""numba kernel of `solvers.classical.trapezoid` on a fault case (`systems.cases.Fault`): for each
clearing time t_c, the fault-on network from the equilibrium to t_c, then the post-fault network
from the state at t_c; t_c is a step boundary.

At a fixed step the switch can only be exact if a step ends at t_c, so each clearing time takes its
own fault-on phase: ceil(t_c / dt) equal steps ending at t_c (the trapezoid's step rule,
`kernels.trapezoid`), then the post-fault phase in the time since t_c (the system is autonomous)
from the packed post-fault system with the state at t_c as its initial one. A query at t = t_c
answers the state at t_c. Sharing one fault-on phase across the clearing times would need a step
to end at every t_c; the phase is at most p1_max / t_final of a trajectory (0.4 of 3 s).

Arguments are `kernels.trapezoid.run_kernel`'s, with the clearing time in place of P1 and the
packed systems of both phases (`layout.system_array` of `Case.phase`).
"""

from __future__ import annotations

import functools

import numpy as np
from numba import prange

from solvers.classical.kernels.jit import jit_variant
from solvers.classical.kernels.layout import DELTA0, NO_NETWORK, OK, OMEGA0, P_M, UNCOUPLED, rhs_mode
from solvers.classical.kernels.trapezoid import trajectory

__all__ = ["fault_kernel"]


def _make_fault(parallel: bool):
    def switched(t, order, starts, T_c, on, post, options, shared):
        n_g, n = T_c.size, on.shape[0]
        coupled_on = rhs_mode(on, NO_NETWORK, n) != UNCOUPLED
        coupled_post = rhs_mode(post, NO_NETWORK, n) != UNCOUPLED
        p1 = on[0, P_M]
        out = np.empty((2, 1 if shared else n_g, t.size, n))
        stats = np.zeros((n_g, 4))
        status = np.zeros(n_g, np.int64)
        for g in prange(n_g):
            col = 0 if shared else np.int64(g)  # prange's index may be unsigned: 0 or g would unify to float
            first, end = starts[g], starts[g + 1]
            split = first
            while split < end and t[order[split]] < T_c[g]:
                split += 1
            # the fault-on phase: this group's times before t_c, then t_c, where its last step ends
            ts = np.empty(split - first + 1)
            for i in range(split - first):
                ts[i] = t[order[first + i]]
            ts[-1] = T_c[g]
            part = np.empty((2, 1, ts.size, n))
            phase = np.zeros(4)
            status[g] = trajectory(ts, np.arange(ts.size), p1, on, coupled_on, options, part, 0, stats[g])
            if status[g] != OK:
                continue
            for i in range(split - first):
                for b in range(2):
                    for k in range(n):
                        out[b, col, order[first + i], k] = part[b, 0, i, k]
            if split == end:
                continue
            system = post.copy()
            for k in range(n):
                system[k, DELTA0] = part[0, 0, ts.size - 1, k]
                system[k, OMEGA0] = part[1, 0, ts.size - 1, k]
            since = t[order[split:end]] - T_c[g]
            part = np.empty((2, 1, since.size, n))
            status[g] = trajectory(since, np.arange(since.size), p1, system, coupled_post, options, part, 0, phase)
            for j in range(3):
                stats[g, j] += phase[j]
            stats[g, 3] = phase[3] + T_c[g]
            for i in range(since.size):
                for b in range(2):
                    for k in range(n):
                        out[b, col, order[split + i], k] = part[b, 0, i, k]
        for g in range(n_g):
            if status[g] != OK:
                return out, stats, g, status[g]
        return out, stats, -1, OK

    return jit_variant(switched, f"trapezoid_fault_{int(parallel)}", parallel=parallel)


@functools.cache
def fault_kernel(parallel: bool):
    """The compiled integrator of a fault case `(t, order, starts, T_c, on, post, options, shared)
    -> (out, stats, failed, status)`: `kernels.trapezoid.run_kernel`'s, group g cleared at T_c[g]
    (n_g,) s >= 0 in place of its P1, `on` and `post` the packed fault-on and post-fault systems.
    stats (n_g, 4): `kernels.trapezoid.STATS` of both phases together (t_failed in the time of
    the trajectory). Compiled once for every n; `parallel`: groups over numba's threads (prange)."""
    return _make_fault(parallel)

