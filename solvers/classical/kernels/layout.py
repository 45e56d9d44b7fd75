"""The packed system every numba kernel integrates, the modes of its right-hand side, and the status
codes the kernels return (one table, with the message an adapter's SolveError gives).

Packed arguments (each array argument costs ~0.1 us of dispatch, so they are few):
- `system` (n, 7 + 2n), `system_array(case)`: per machine k the columns `M`, `D` (p.u.), `DELTA0`
  (rad), `OMEGA0` (rad/s), `P_M`, `C_INF`, `S_INF` (p.u.), then row k of C and row k of S
  (p.u., from `COUPLING`; `systems.model.coupling`); (n, 7) without C and S for the sparse form,
  (n, 8) in the trapezoid's sparse form, which adds `SELF`
  (`solvers.classical.kernels.trapezoid_sparse`);
- `net`: the network kept sparse, `systems.sparse_network.LUFactors` of the case (P_e from the bus
  voltages, `solvers.classical.kernels.sparse`), or `NO_NETWORK` for the reduced form (C and S in
  `system`).
"""

from __future__ import annotations

import numba
import numpy as np

from solvers.classical.kernels.jit import jit_function
from systems.cases import Case
from systems.model import coupling

__all__ = [
    "COUPLING",
    "C_INF",
    "DELTA0",
    "DENSE",
    "NEWTON_FAILED",
    "NOT_FINITE",
    "NO_NETWORK",
    "OK",
    "OMEGA0",
    "P_M",
    "SELF",
    "SINGULAR",
    "SPARSE",
    "STATUS",
    "STEP_TOO_SMALL",
    "S_INF",
    "TOO_MANY_STEPS",
    "UNCOUPLED",
    "D",
    "M",
    "check_threads",
    "rhs_mode",
    "start_trajectory",
    "system_array",
]

# Columns of the packed system (see the module docstring); COUPLING + j is C[k, j],
# COUPLING + n + j is S[k, j].
M, D, DELTA0, OMEGA0, P_M, C_INF, S_INF, COUPLING = range(8)
# The trapezoid's sparse form: the constant part of each machine's own slope, where the reduced
# form's coupling starts
SELF = 7

# The modes of the right-hand side: P_e,k = s_inf_k sin(delta_k) only; the reduced (dense)
# coupling; the network kept sparse (`net`).
UNCOUPLED, DENSE, SPARSE = 0, 1, 2
# The reduced form's `net`: None, so that the kernels compiled for it carry no factors (a tuple of
# 12 arrays passed down to every right-hand side costs their reference counts on each call: numba-rk
# was 1.7-13x slower with `LUFactors.empty()` here, docs/notebook.md), and the sparse branches are
# pruned at compile time (`net is None`).
NO_NETWORK = None

# The status codes of every kernel: a trajectory's, or of the first one that failed.
OK, TOO_MANY_STEPS, STEP_TOO_SMALL, NOT_FINITE, NEWTON_FAILED, SINGULAR = range(6)
STATUS = {
    OK: "ok",
    TOO_MANY_STEPS: "more than max_steps steps",
    STEP_TOO_SMALL: "step size fell below 10 ulp of t",
    NOT_FINITE: "the state became NaN or inf",
    NEWTON_FAILED: "Newton did not converge to newton_tol in max_newton iterations",
    SINGULAR: "the Newton matrix is singular",
}


def check_threads(owner: str, threads: int) -> None:
    """The rule of a numba adapter's `threads` option: at most numba's NUMBA_NUM_THREADS, or a
    ValueError starting with `owner`."""
    if threads > numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"{owner}: option threads must be <= {numba.config.NUMBA_NUM_THREADS} "
                         f"(numba's NUMBA_NUM_THREADS), got {threads!r}")


def system_array(case: Case, sparse: bool = False) -> np.ndarray:
    """The packed system of `case` (n, 7 + 2n) float64, the layout of the module docstring; (n, 7)
    with `sparse` (the coupling is then `net`'s)."""
    k = coupling(case)
    columns = np.array([case.m, case.d, case.delta0, case.omega0, case.p_m, k.c_inf, k.s_inf], np.float64).T
    return np.ascontiguousarray(columns) if sparse else np.column_stack([columns, k.C, k.S])


@jit_function
def start_trajectory(y, ts, order, system, n, out, col):
    """y = the initial state (delta0, omega0 of each machine; zeros after the first 2n entries, the
    sensitivities of `solvers.classical.kernels.rk`); writes it to trajectory `col` of `out`
    (blocks of n entries of y, as `rk.kernel`'s) at every output time ts[order[i]] <= 0 and returns
    how many output times that was."""
    for k in range(n):
        y[k], y[n + k] = system[k, DELTA0], system[k, OMEGA0]
    for i in range(2 * n, y.size):
        y[i] = 0.0
    i_out = 0
    while i_out < order.size and ts[order[i_out]] <= 0.0:
        for i in range(y.size):
            out[i // n, col, order[i_out], i % n] = y[i]
        i_out += 1
    return i_out


@jit_function
def rhs_mode(system, net, n):
    """SPARSE when `net` holds factors (not None); else DENSE when P_e needs more than
    s_inf_k sin(delta_k) (some C, S or c_inf entry is non-zero), else UNCOUPLED."""
    if net is not None:
        return SPARSE
    for k in range(n):
        if system[k, C_INF] != 0.0:
            return DENSE
        for j in range(2 * n):
            if system[k, COUPLING + j] != 0.0:
                return DENSE
    return UNCOUPLED
