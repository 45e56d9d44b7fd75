"""The trapezoid's network kept sparse: `solvers.classical.kernels.trapezoid`'s step on the unreduced
network (`systems.sparse_network`), P_e from two sparse triangular solves
(`solvers.classical.kernels.sparse`) each Newton iteration, compiled with numba.

Each step solves the trapezoid kernels' n equations of the angle increments x,

    R(x) = c x + P_e(delta0 + x) - b = 0,  c = 4 m / h^2 + 2 d / h,

with the network solved exactly for every iterate (the bus voltages of the iterate's EMFs), and a
Newton matrix that keeps only what costs O(n): diag(c + dP_e,k / d delta_k), every machine's own
slope at the current iterate, updated each iteration (no factorisation). The coupling it leaves
out, dP_e,k / d delta_j for j != k, is of the order of a machine's synchronising power (~1-100
p.u./rad) against c ~ 4 m / h^2 (~10^3 at half a cycle), so the iteration contracts by about the
ratio of the two (the spectral radius of diag^-1 times the coupling at the initial angles: at most
2e-3 at h = 1/120 s, 1.1e-6 at 2e-4 s, 0.065 at 0.05 s on wscc9, ieee39, case300 and
case1354pegase). An iteration costs O(nnz(L + U) + n), a step one more P_e: linear in the buses
where the reduced form's iteration is ~5 n^2.

The machine's own slope, from P_e,k = g_k - Re(conj(w_k) e^{j delta_k} conj(V_at[k])) with V the
solution of Y_bb V = sum_j w_j e^{j delta_j} e_at[j]:

    dP_e,k / d delta_k = Im(conj(w_k) e^{j delta_k} conj(V_at[k])) - Im(conj(w_k)^2 conj(Z_kk))
                         + s_inf_k cos(delta_k) - c_inf_k sin(delta_k),

Z_kk = (Y_bb^-1)[at[k], at[k]] (p.u.): the constant second term (`self_coupling`) removes machine
k's own EMF from V_at[k], on which P_e,k does not depend through the angle.

Packed arguments: `system` (n, 8), `solvers.classical.kernels.layout.system_array(case,
sparse=True)`'s columns and, at `layout.SELF`, Im(conj(w_k)^2 conj(Z_kk)) (p.u.; `prepare`); `net`
the case's `systems.sparse_network.LUFactors`; `options` and the statistics as
`solvers.classical.kernels.trapezoid`'s (the factorisations column counts none: the diagonal needs
none).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numba import prange

from solvers.classical.kernels.jit import jit_function, jit_variant
from solvers.classical.kernels.layout import (
    C_INF,
    NEWTON_FAILED,
    NOT_FINITE,
    OK,
    P_M,
    S_INF,
    SELF,
    SINGULAR,
    D,
    M,
    start_trajectory,
    system_array,
)
from solvers.classical.kernels.sparse import sparse_power
from solvers.classical.kernels.trapezoid import hermite_output
from systems.cases import Case
from systems.sparse_network import LUFactors, lu_factors

__all__ = ["prepare", "run_kernel", "self_coupling"]


@jit_function
def _self_impedances(net, n):
    """Z_kk w_k (n,) complex p.u.: machine k's bus voltage with its EMF 1 at angle 0 and the
    others' EMFs zero (one `sparse_power` each)."""
    scratch = np.zeros(3 * n)
    work = np.empty(net.l_inv.size, np.complex128)
    out = np.empty(n, np.complex128)
    for k in range(n):
        scratch[k] = 1.0
        sparse_power(scratch, net, n, work)
        out[k] = work[net.sink[k]]
        scratch[k] = 0.0
    return out


def self_coupling(net: LUFactors) -> np.ndarray:
    """Im(conj(w_k)^2 conj(Z_kk)) (n,) p.u. of every machine k (module docstring)."""
    n = net.w.size
    Z_kk = _self_impedances(net, n) / net.w
    return np.imag(np.conj(net.w) ** 2 * np.conj(Z_kk))


def prepare(case: Case, parallel: bool) -> tuple[np.ndarray, Callable, LUFactors]:
    """(system, kernel, net) of `case`'s carried network (`Case.network`): the packed system (n, 8)
    (module docstring), `run_kernel(parallel)` with `net` bound, so that it is called as
    `kernels.trapezoid.run_kernel`'s kernel is, and the factors `net` (one SuperLU factorisation)."""
    if case.network is None:
        raise ValueError(f"case {case.name} carries no network to keep sparse")
    net = lu_factors(case.network, case.E)
    system = np.column_stack([system_array(case, sparse=True), self_coupling(net)])
    run = run_kernel(parallel)

    def kernel(t, order, starts, P1, system, options, shared):
        return run(t, order, starts, P1, system, net, options, shared)

    return system, kernel, net


@jit_function
def _power(delta, pe, slope, system, net, n, scratch, work):
    """pe (n,) = P_e(delta) (p.u.) for angles delta (n,) rad, and slope (n,) = each machine's own
    dP_e,k / d delta_k (p.u./rad); scratch (3n,) and work (nb,) complex as `sparse_power`'s."""
    for k in range(n):
        scratch[k] = math.cos(delta[k])
        scratch[n + k] = math.sin(delta[k])
    sparse_power(scratch, net, n, work)
    for k in range(n):
        ck, sk = scratch[k], scratch[n + k]
        pe[k] = scratch[2 * n + k] + (system[k, C_INF] * ck + system[k, S_INF] * sk)
        v = work[net.sink[k]]
        own = (net.w[k].conjugate() * complex(ck, sk) * v.conjugate()).imag
        slope[k] = own - system[k, SELF] + (system[k, S_INF] * ck - system[k, C_INF] * sk)


@jit_function
def _failed(stats, step, iterations, t0, status):
    stats[0], stats[1], stats[2], stats[3] = step, iterations, 0, t0
    return status


@jit_function
def _trajectory(ts, order, p1, system, net, options, out, col, stats):
    """`kernels.trapezoid.trajectory` with the network kept sparse (module docstring): one
    trajectory for generator-1 power p1 (p.u.), ceil(t_end / dt) equal steps to t_end =
    ts[order[-1]] (s), states at ts[order] into out[:, col, order] by cubic Hermite interpolation,
    `stats` (4,) its `STATS`; returns a status code."""
    n = system.shape[0]
    dt, tol, max_newton = options[0], options[1], int(options[2])
    n_t = order.size
    stats[3] = math.nan
    y = np.empty(2 * n)
    i_out = start_trajectory(y, ts, order, system, n, out, col)
    t_end = ts[order[n_t - 1]]
    if t_end <= 0.0:
        return OK
    n_steps = math.ceil(t_end / dt)
    h = t_end / n_steps
    m, d = system[:, M], system[:, D]
    P = system[:, P_M].copy()
    P[0] = p1
    c = 4.0 * m / (h * h) + 2.0 * d / h
    delta0, omega0 = y[:n].copy(), y[n:].copy()
    delta1, omega1 = np.empty(n), np.empty(n)
    a0, a1, pe, slope, b, x = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    scratch = np.empty(3 * n)
    work = np.empty(net.l_inv.size, np.complex128)
    _power(delta0, pe, slope, system, net, n, scratch, work)
    for k in range(n):
        a0[k] = (P[k] - d[k] * omega0[k] - pe[k]) / m[k]
    iterations = 0
    for step in range(n_steps):
        t0 = step * h
        t1 = t_end if step == n_steps - 1 else (step + 1) * h
        for k in range(n):
            b[k] = 4.0 * m[k] * omega0[k] / h + 2.0 * P[k] - pe[k]
            x[k] = h * omega0[k] + 0.5 * h * h * a0[k]
        converged = False
        for _ in range(max_newton):
            for k in range(n):
                delta1[k] = delta0[k] + x[k]
            _power(delta1, pe, slope, system, net, n, scratch, work)
            iterations += 1
            size = 0.0
            for k in range(n):
                pivot = c[k] + slope[k]
                if not (pivot != 0.0 and math.isfinite(pivot)):
                    return _failed(stats, step, iterations, t0, SINGULAR)
                update = -(c[k] * x[k] + pe[k] - b[k]) / pivot
                x[k] += update
                if not abs(update) <= size:  # NaN too
                    size = abs(update)
            if not math.isfinite(size):
                return _failed(stats, step, iterations, t0, NOT_FINITE)
            if size <= tol:
                converged = True
                break
        if not converged:
            return _failed(stats, step, iterations, t0, NEWTON_FAILED)
        for k in range(n):
            delta1[k] = delta0[k] + x[k]
            omega1[k] = 2.0 * x[k] / h - omega0[k]
        _power(delta1, pe, slope, system, net, n, scratch, work)
        for k in range(n):
            a1[k] = (P[k] - d[k] * omega1[k] - pe[k]) / m[k]
        i_out = hermite_output(ts, order, i_out, t0, t1, h, delta0, omega0, a0, delta1, omega1, a1, out, col)
        for k in range(n):
            delta0[k], omega0[k], a0[k] = delta1[k], omega1[k], a1[k]
    stats[0], stats[1], stats[2] = n_steps, iterations, 0
    for k in range(n):
        if not (math.isfinite(delta0[k]) and math.isfinite(omega0[k])):
            return NOT_FINITE
    return OK



def _make_run(parallel: bool):
    def run(t, order, starts, P1, system, net, options, shared):
        n_g, n = P1.size, system.shape[0]
        out = np.empty((2, 1 if shared else n_g, t.size, n))
        stats = np.zeros((n_g, 4))
        status = np.zeros(n_g, np.int64)
        for g in prange(n_g):
            col = 0 if shared else np.int64(g)  # prange's index may be unsigned: 0 or g would unify to float
            status[g] = _trajectory(t, order[starts[g]:starts[g + 1]], P1[g], system, net, options, out, col,
                                    stats[g])
        for g in range(n_g):
            if status[g] != OK:
                return out, stats, g, status[g]
        return out, stats, -1, OK

    return jit_variant(run, f"trapezoid_sparse_{int(parallel)}", parallel=parallel)


@functools.cache
def run_kernel(parallel: bool):
    """The compiled integrator `(t, order, starts, P1, system, net, options, shared) -> (out, stats,
    failed, status)`: `kernels.trapezoid.run_kernel`'s with `system` (n, 8) and `net` as the module
    docstring's. Compiled once for every n; `parallel`: groups over numba's threads (prange)."""
    return _make_run(parallel)

