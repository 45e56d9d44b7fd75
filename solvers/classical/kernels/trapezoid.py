"""numba kernels of `solvers.classical.trapezoid`: the implicit trapezoidal rule at a fixed step on
the n-machine swing equation (`systems.model`), Newton's method on the angle increments with a
reused LU factorisation, every trajectory of a query in one compiled call.

Packed arguments: `system` (n, 7 + 2n), `solvers.classical.kernels.layout.system_array` (its
columns M, D, P_M, ...); `options` (3,): dt (s), newton_tol (rad), max_newton.

The step. With y = [delta, omega], a = (P - d omega - P_e(delta)) / m per machine, the rule
y1 = y0 + h/2 (f(y0) + f(y1)) reads, in the angle increment x = delta1 - delta0 (n,),

    omega1 = 2 x / h - omega0                                   (the angle equation)
    m (omega1 - omega0) = h/2 (F0 + P - d omega1 - P_e(delta0 + x)),  F0 = m a0,

so omega1 is eliminated and each step solves the n equations (products elementwise)

    R(x) = (4 m / h^2 + 2 d / h) x + P_e(delta0 + x) - b = 0,  b = 4 m omega0 / h + 2 P - P_e(delta0),

with Jacobian J(x) = diag(4 m / h^2 + 2 d / h) + dP_e/d delta (delta0 + x) (n x n, unsymmetric
when the network is lossy). Newton starts from the explicit Taylor predictor x = h omega0 +
h^2/2 a0 and iterates x <- x - J^-1 R(x) until the largest |update| is <= newton_tol (rad), at most
max_newton iterations a step. J is a "very dishonest" Newton's, as in production simulators: LU
factorised (partial pivoting) at the first iterate of the first step, then reused across
iterations and steps, and factorised again at the current iterate only when an update fails to
contract (|update| > `CONTRACTION` x the previous one in the same step). The step's end state
then costs one more evaluation of P_e, for a1 (the next step's F0 and the cubic Hermite output:
delta with derivatives omega, omega with derivatives a, at both ends of each step).

The network enters only through `network` (P_e and, when asked, dP_e/d delta): a sparse form of
the network replaces that one function.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import prange

from solvers.classical.kernels.jit import jit_function, jit_variant
from solvers.classical.kernels.layout import (
    C_INF,
    COUPLING,
    NEWTON_FAILED,
    NO_NETWORK,
    NOT_FINITE,
    OK,
    P_M,
    S_INF,
    SINGULAR,
    UNCOUPLED,
    D,
    M,
    rhs_mode,
    start_trajectory,
)

__all__ = ["CONTRACTION", "STATS", "hermite_output", "network", "run_kernel", "trajectory"]

CONTRACTION = 0.5  # an update larger than this fraction of the previous one refactorises J
# Columns of the per-trajectory statistics the kernel returns: steps, Newton iterations, LU
# factorisations, and the time (s) of the step that failed (NaN when none did).
STATS = ("steps", "iterations", "factorisations", "t_failed")


@jit_function
def network(delta, pe, jac, with_jac, system, n, coupled, scratch):
    """pe (n,) = P_e(delta) (p.u.) of every machine for angles delta (n,) rad (`systems.model`'s
    expansion: n sin and n cos, two products with C and S); with `with_jac`, jac (n, n) =
    dP_e/d delta (p.u./rad). `coupled`: `layout.rhs_mode` is not UNCOUPLED (False: P_e,k =
    s_inf_k sin(delta_k), diagonal jac). scratch (2n,): cos and sin of each angle."""
    if not coupled:
        for k in range(n):
            pe[k] = system[k, S_INF] * math.sin(delta[k])
            if with_jac:
                for j in range(n):
                    jac[k, j] = 0.0
                jac[k, k] = system[k, S_INF] * math.cos(delta[k])
        return
    for k in range(n):
        scratch[k] = math.cos(delta[k])
        scratch[n + k] = math.sin(delta[k])
    for k in range(n):
        ck, sk = scratch[k], scratch[n + k]
        cc = cs = sc = ss = 0.0
        for j in range(n):
            ckj, skj = system[k, COUPLING + j], system[k, COUPLING + n + j]
            cj, sj = scratch[j], scratch[n + j]
            cc += ckj * cj
            cs += ckj * sj
            sc += skj * cj
            ss += skj * sj
        pe[k] = ck * (cc - ss) + sk * (cs + sc) + (system[k, C_INF] * ck + system[k, S_INF] * sk)
        if with_jac:
            # d P_e,k / d delta_j = C_kj sin(d_k - d_j) - S_kj cos(d_k - d_j), j != k; P_e,k depends
            # on the differences, so d / d delta_k is minus their sum, plus the infinite bus's term
            diagonal = system[k, S_INF] * ck - system[k, C_INF] * sk
            for j in range(n):
                if j != k:
                    cj, sj = scratch[j], scratch[n + j]
                    g = system[k, COUPLING + j] * (sk * cj - ck * sj) - system[k, COUPLING + n + j] * (ck * cj + sk * sj)
                    jac[k, j] = g
                    diagonal -= g
            jac[k, k] = diagonal


@jit_function
def _lu_factor(A, piv, n):
    """A (n, n) <- its LU factors in place (unit lower L below the diagonal, U on and above),
    rows exchanged by partial pivoting (piv[k]: the row swapped with row k at column k);
    False when a pivot is zero or not finite (J singular)."""
    for k in range(n):
        p, big = k, abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                p, big = i, abs(A[i, k])
        if not (big > 0.0 and math.isfinite(big)):
            return False
        piv[k] = p
        if p != k:
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            lik = A[i, k] * inv
            A[i, k] = lik
            if lik != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= lik * A[k, j]
    return True


@jit_function
def _lu_solve(LU, piv, b, n):
    """b (n,) <- J^-1 b from `_lu_factor`'s factors of J."""
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= LU[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= LU[i, j] * b[j]
        b[i] = acc / LU[i, i]


@jit_function
def hermite_output(ts, order, i_out, t0, t1, h, delta0, omega0, a0, delta1, omega1, a1, out, col):
    """The states of one step [t0, t1] (s, length h) at the query times ts[order[i_out:]] up to t1,
    by cubic Hermite interpolation (delta with derivatives omega, omega with derivatives a, each
    (n,) at both ends) into out[:, col, order[i]]; returns the index of the next time left."""
    n = delta0.size
    while i_out < order.size and ts[order[i_out]] <= t1:
        s = (ts[order[i_out]] - t0) / h
        h00, h10 = (1 + 2 * s) * (1 - s) ** 2, h * s * (1 - s) ** 2
        h01, h11 = s * s * (3 - 2 * s), h * s * s * (s - 1)
        o = order[i_out]
        for k in range(n):
            out[0, col, o, k] = h00 * delta0[k] + h10 * omega0[k] + h01 * delta1[k] + h11 * omega1[k]
            out[1, col, o, k] = h00 * omega0[k] + h10 * a0[k] + h01 * omega1[k] + h11 * a1[k]
        i_out += 1
    return i_out


@jit_function
def trajectory(ts, order, p1, system, coupled, options, out, col, stats):
    """One trajectory for generator-1 power p1 (p.u.; the others at their p_m): ceil(t_end / dt)
    equal steps from 0 to t_end = ts[order[-1]] (s), the states at ts[order] written to
    out[:, col, order] (out (2, n_col, n_t, n): delta rad, omega rad/s), `stats` (4,) the
    trajectory's `STATS`; returns a status code."""
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
    diag = 4.0 * m / (h * h) + 2.0 * d / h
    delta0, omega0 = y[:n].copy(), y[n:].copy()
    delta1, omega1 = np.empty(n), np.empty(n)
    a0, a1, pe, b, x, r = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    scratch = np.empty(2 * n)
    A = np.empty((n, n))
    piv = np.empty(n, np.int64)
    network(delta0, pe, A, False, system, n, coupled, scratch)
    for k in range(n):
        a0[k] = (P[k] - d[k] * omega0[k] - pe[k]) / m[k]
    factored = False
    iterations = factorisations = 0
    for step in range(n_steps):
        t0 = step * h
        t1 = t_end if step == n_steps - 1 else (step + 1) * h
        for k in range(n):
            b[k] = 4.0 * m[k] * omega0[k] / h + 2.0 * P[k] - pe[k]
            x[k] = h * omega0[k] + 0.5 * h * h * a0[k]
        previous = math.inf
        converged = False
        for _ in range(max_newton):
            for k in range(n):
                delta1[k] = delta0[k] + x[k]
            network(delta1, pe, A, not factored, system, n, coupled, scratch)
            for k in range(n):
                r[k] = -(diag[k] * x[k] + pe[k] - b[k])
            if not factored:
                for k in range(n):
                    A[k, k] += diag[k]
                if not _lu_factor(A, piv, n):
                    stats[0], stats[1], stats[2], stats[3] = step, iterations, factorisations, t0
                    return SINGULAR
                factored = True
                factorisations += 1
            _lu_solve(A, piv, r, n)
            iterations += 1
            size = 0.0
            for k in range(n):
                x[k] += r[k]
                if not abs(r[k]) <= size:  # NaN too
                    size = abs(r[k])
            if not math.isfinite(size):
                stats[0], stats[1], stats[2], stats[3] = step, iterations, factorisations, t0
                return NOT_FINITE
            if size <= tol:
                converged = True
                break
            if size > CONTRACTION * previous:
                factored = False
            previous = size
        if not converged:
            stats[0], stats[1], stats[2], stats[3] = step, iterations, factorisations, t0
            return NEWTON_FAILED
        for k in range(n):
            delta1[k] = delta0[k] + x[k]
            omega1[k] = 2.0 * x[k] / h - omega0[k]
        network(delta1, pe, A, False, system, n, coupled, scratch)
        for k in range(n):
            a1[k] = (P[k] - d[k] * omega1[k] - pe[k]) / m[k]
        i_out = hermite_output(ts, order, i_out, t0, t1, h, delta0, omega0, a0, delta1, omega1, a1, out, col)
        for k in range(n):
            delta0[k], omega0[k], a0[k] = delta1[k], omega1[k], a1[k]
    stats[0], stats[1], stats[2] = n_steps, iterations, factorisations
    for k in range(n):
        if not (math.isfinite(delta0[k]) and math.isfinite(omega0[k])):
            return NOT_FINITE
    return OK



def _make_run(parallel: bool):
    def run(t, order, starts, P1, system, options, shared):
        n_g, n = P1.size, system.shape[0]
        coupled = rhs_mode(system, NO_NETWORK, n) != UNCOUPLED
        out = np.empty((2, 1 if shared else n_g, t.size, n))
        stats = np.zeros((n_g, 4))
        status = np.zeros(n_g, np.int64)
        for g in prange(n_g):
            col = 0 if shared else np.int64(g)  # prange's index may be unsigned: 0 or g would unify to float
            status[g] = trajectory(t, order[starts[g]:starts[g + 1]], P1[g], system, coupled, options, out, col,
                                    stats[g])
        for g in range(n_g):
            if status[g] != OK:
                return out, stats, g, status[g]
        return out, stats, -1, OK

    return jit_variant(run, f"trapezoid_{int(parallel)}", parallel=parallel)


@functools.cache
def run_kernel(parallel: bool):
    """The compiled integrator `(t, order, starts, P1, system, options, shared) -> (out, stats,
    failed, status)`, one trajectory per group g of times: t (n_t,) s >= 0, group g the times
    t[order[starts[g]:starts[g + 1]]] in ascending order (int64 order, starts (n_g + 1,)), at
    generator-1 power P1[g] (n_g,) p.u.; `system` and `options` as the module docstring's.
    out (2, n_g, n_t, n), out[0] delta (rad) and out[1] omega (rad/s) of group g at column g
    (a `solve`: every group the same order of all t); with `shared`, out (2, 1, n_t, n), every group
    writing its own entries of the one column (`solve_points`). stats (n_g, 4): `STATS` of each
    trajectory; `failed` the first failed group (-1: none) and `status` its code. Compiled once
    for every n; `parallel`: groups over numba's threads (prange)."""
    return _make_run(parallel)
