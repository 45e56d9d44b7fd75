"""numba kernels of `solvers.classical.numba_rk`: explicit Runge-Kutta on the n-machine swing
equation (`systems.model`: lossy Kron-reduced coupling, optional infinite bus), the loop over the
batch of input powers inside compiled code.

Arguments: `system` and `net` as `solvers.classical.kernels.layout`'s, and
- `P1` (n_batch,): generator 1's mechanical power in each trajectory (p.u.); the other machines
  get their p_m from `system` (as `Case.powers`);
- `options` (4,): rtol, atol, dt (s, rk4 only), max_steps.
The state of one trajectory is y = [delta_1..n, omega_1..n] (2n,); with sensitivities it is
followed by the columns of S = dy/dp (2n, 2n), p = (m_1..n, d_1..n), column j at
y[2n + 2n j : 2n + 2n (j + 1)]. Step-size control sees only the first 2n entries, so a run with
sensitivities takes exactly the steps of a run without.

P_e takes n sin and n cos per evaluation (the expansion of `systems.model`: two mat-vecs, no
trigonometric call per pair of machines); a system whose machines see only their own susceptance
to the infinite bus (C = S = 0, c_inf = 0: the SMIB) takes one sin per machine instead, and the
same bits (the expansion's other terms are exact zeros). In the sparse form the network's part of
P_e is two sparse triangular solves (`solvers.classical.kernels.sparse`) instead of the two dense
mat-vecs; the sensitivities (identification) take the reduced form only.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import prange
from scipy.integrate._ivp import dop853_coefficients as _c853

from solvers.classical.kernels.jit import jit_function, jit_variant
from solvers.classical.kernels.layout import (
    C_INF,
    COUPLING,
    DENSE,
    NOT_FINITE,
    OK,
    P_M,
    S_INF,
    SPARSE,
    STEP_TOO_SMALL,
    TOO_MANY_STEPS,
    UNCOUPLED,
    D,
    M,
    rhs_mode,
    start_trajectory,
)
from solvers.classical.kernels.sparse import sparse_power

__all__ = ["DOP853", "DOPRI5", "METHODS", "RK4", "kernel", "trajectory_kernel"]

RK4, DOPRI5, DOP853 = 0, 1, 2
METHODS = {"rk4": RK4, "dopri5": DOPRI5, "dop853": DOP853}
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0  # scipy's step-size control

# Dormand-Prince 5(4) with Shampine's quartic dense output: scipy's RK45 tableau.
DP_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])
DP_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 5, 0.0, 0.0, 0.0, 0.0],
    [3 / 40, 9 / 40, 0.0, 0.0, 0.0],
    [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
])
DP_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
DP_E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
DP_P = np.array([
    [1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
])
# DOP853 (Hairer's, as scipy's DOP853): 12 stages, 3 more for the 7th-order dense output.
D8_A, D8_C, D8_B = _c853.A.copy(), _c853.C.copy(), _c853.B.copy()
D8_E3, D8_E5, D8_D = _c853.E3.copy(), _c853.E5.copy(), _c853.D.copy()


@jit_function
def _rhs(y, out, P, system, net, n, sens, mode, scratch, work):
    """out = dy/dt for state y (see the module docstring); P (n,) p.u.; `mode` from
    `layout.rhs_mode` (UNCOUPLED: P_e,k = s_inf_k sin(delta_k), one sin per machine); scratch (3n,)
    work space: cos of each angle, sin of each angle, one row of the Jacobian of P_e (DENSE) or the
    network's P_e (SPARSE); work (nb,) complex128, the sparse solves' (empty otherwise). (Indexes into scratch,
    not slices of it: a view costs reference counting on every call, measured 3x on the SMIB
    grid.) `sens` with SPARSE is not supported (`kernel` refuses it)."""
    two_n = 2 * n
    coupled = mode == DENSE
    if mode != UNCOUPLED:
        for k in range(n):
            scratch[k] = math.cos(y[k])
            scratch[n + k] = math.sin(y[k])
    if net is not None:
        sparse_power(scratch, net, n, work)
    for k in range(n):
        m, d, omega = system[k, M], system[k, D], y[n + k]
        ck = sk = 0.0
        if mode == SPARSE:
            ck, sk = scratch[k], scratch[n + k]
            pe = scratch[two_n + k] + (system[k, C_INF] * ck + system[k, S_INF] * sk)
        elif coupled:
            # P_e,k = c_k (C c - S s)_k + s_k (C s + S c)_k + c_inf_k c_k + s_inf_k s_k (systems.model)
            ck, sk = scratch[k], scratch[n + k]
            cc = cs = sc = ss = 0.0
            for j in range(n):
                ckj, skj = system[k, COUPLING + j], system[k, COUPLING + n + j]
                cj, sj = scratch[j], scratch[n + j]
                cc += ckj * cj
                cs += ckj * sj
                sc += skj * cj
                ss += skj * sj
            pe = ck * (cc - ss) + sk * (cs + sc) + (system[k, C_INF] * ck + system[k, S_INF] * sk)
        else:
            pe = system[k, S_INF] * math.sin(y[k])
        acc = (P[k] - d * omega - pe) / m
        out[k] = omega
        out[n + k] = acc
        if sens:
            if coupled:
                # scratch[2n + j] = d P_e,k / d delta_j = C_kj sin(d_k - d_j) - S_kj cos(d_k - d_j)
                # for j != k; P_e,k depends on the differences, so d / d delta_k is minus their sum,
                # plus the infinite bus's term
                dpe = system[k, S_INF] * ck - system[k, C_INF] * sk
                for j in range(n):
                    if j != k:
                        cj, sj = scratch[j], scratch[n + j]
                        g = (system[k, COUPLING + j] * (sk * cj - ck * sj)
                             - system[k, COUPLING + n + j] * (ck * cj + sk * sj))
                        scratch[two_n + j] = g
                        dpe -= g
            else:
                dpe = system[k, S_INF] * math.cos(y[k])  # d P_e,k / d delta_k
            for col in range(two_n):
                base = two_n + two_n * col
                s_acc = -(dpe * y[base + k] + d * y[base + n + k])
                if coupled:
                    for j in range(n):
                        if j != k:
                            s_acc -= scratch[two_n + j] * y[base + j]
                s_acc /= m
                if col == k:
                    s_acc -= acc / m  # d acc_k / d m_k
                elif col == n + k:
                    s_acc -= omega / m  # d acc_k / d d_k
                out[base + k] = y[base + n + k]
                out[base + n + k] = s_acc


@jit_function
def _rms(v, scale, n_ctrl):
    total = 0.0
    for i in range(n_ctrl):
        total += (v[i] / scale[i]) ** 2
    return math.sqrt(total / n_ctrl)


@jit_function
def _initial_step(y0, f0, P, system, net, n, sens, mode, scratch, cwork, t_end, order, rtol, atol, work):
    """scipy's `select_initial_step` (Hairer, Norsett & Wanner, II.4) on the controlled entries."""
    n_ctrl = 2 * n
    scale, y1, f1 = work[0], work[1], work[2]
    for i in range(n_ctrl):
        scale[i] = atol + abs(y0[i]) * rtol
    d0, d1 = _rms(y0, scale, n_ctrl), _rms(f0, scale, n_ctrl)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_end)
    for i in range(y0.size):
        y1[i] = y0[i] + h0 * f0[i]
    _rhs(y1, f1, P, system, net, n, sens, mode, scratch, cwork)
    for i in range(n_ctrl):
        y1[i] = f1[i] - f0[i]
    d2 = _rms(y1, scale, n_ctrl) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    return min(100 * h0, h1, t_end)


@jit_function
def _stages(K, y, h, A, first, last, tmp, P, system, net, n, sens, mode, scratch, cwork):
    """K[s] = f(y + h sum_j A[s, j] K[j]) for s in [first, last)."""
    for s in range(first, last):
        for i in range(y.size):
            acc = 0.0
            for j in range(s):
                acc += A[s, j] * K[j, i]
            tmp[i] = y[i] + h * acc
        _rhs(tmp, K[s], P, system, net, n, sens, mode, scratch, cwork)


@functools.cache
def _make_adaptive(method: int, sens: bool, n: int):
    """One trajectory by dopri5 or dop853 (scipy's step-size control), compiled for one method
    and one `sens` (closure constants, so the branches on them fold away)."""
    if method == DOPRI5:
        A, B, E, n_stages, err_order = DP_A, DP_B, DP_E, 6, 4
    else:
        A, B, E, n_stages, err_order = D8_A, D8_B, D8_E5, 12, 7
    exponent = -1.0 / (err_order + 1)
    n_ctrl, n_y = 2 * n, 2 * n + (4 * n * n if sens else 0)

    def adaptive(ts, order, P, system, net, mode, rtol, atol, max_steps, out, col):
        """From t = 0 to ts[order[-1]] (s), dense output at ts[order] into trajectory `col` of `out`
        (see `kernel`); `order` indexes ts in ascending time, all of it or a part (one trajectory's
        times of a points query); returns a status code."""
        n_t = order.size
        scratch = np.empty(3 * n)
        if net is None:
            cwork = np.empty(0, np.complex128)
        else:
            cwork = np.empty(net.l_inv.size, np.complex128)
        K = np.empty((16, n_y))
        work = np.empty((8, n_y))
        y, y_new, tmp = work[3], work[4], work[5]
        F = np.empty((7, n_y))
        t_end = ts[order[n_t - 1]]
        i_out = start_trajectory(y, ts, order, system, n, out, col)
        if t_end <= 0.0:
            return OK
        _rhs(y, K[0], P, system, net, n, sens, mode, scratch, cwork)
        h_abs = _initial_step(y, K[0], P, system, net, n, sens, mode, scratch, cwork, t_end, err_order, rtol,
                              atol, work)
        t = 0.0
        steps = 0
        while t < t_end:
            if steps >= max_steps:
                return TOO_MANY_STEPS
            steps += 1
            min_step = 10.0 * max(abs(t) * 2.220446049250313e-16, 5e-324)  # ~10 ulp of t, as scipy
            h_abs = max(h_abs, min_step)
            rejected = False
            while True:
                if not h_abs >= min_step:  # NaN too
                    return STEP_TOO_SMALL
                t_new = min(t + h_abs, t_end)
                h = t_new - t
                h_abs = h
                _stages(K, y, h, A, 1, n_stages, tmp, P, system, net, n, sens, mode, scratch, cwork)
                for i in range(n_y):
                    acc = 0.0
                    for j in range(n_stages):
                        acc += B[j] * K[j, i]
                    y_new[i] = y[i] + h * acc
                _rhs(y_new, K[n_stages], P, system, net, n, sens, mode, scratch, cwork)
                e5n, e3n = 0.0, 0.0
                for i in range(n_ctrl):
                    sc = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                    e5 = 0.0
                    for j in range(n_stages + 1):
                        e5 += E[j] * K[j, i]
                    e5n += (e5 / sc) ** 2
                    if method == DOP853:
                        e3 = 0.0
                        for j in range(n_stages + 1):
                            e3 += D8_E3[j] * K[j, i]
                        e3n += (e3 / sc) ** 2
                if method == DOPRI5:
                    err = h * math.sqrt(e5n / n_ctrl)
                elif e5n == 0.0 and e3n == 0.0:
                    err = 0.0
                else:
                    err = h * e5n / math.sqrt((e5n + 0.01 * e3n) * n_ctrl)
                if err < 1.0:
                    factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** exponent)
                    if rejected:
                        factor = min(1.0, factor)
                    h_abs *= factor
                    break
                factor = SAFETY * err ** exponent
                # a NaN error (state overflow) takes MIN_FACTOR: the step shrinks until it is too small
                h_abs *= factor if factor > MIN_FACTOR else MIN_FACTOR  # noqa: FURB136
                rejected = True
            if i_out < n_t and ts[order[i_out]] <= t_new:
                _dense_coefficients(method, K, y, y_new, h, F, tmp, P, system, net, n, sens, mode, scratch, cwork)
                while i_out < n_t and ts[order[i_out]] <= t_new:
                    x = (ts[order[i_out]] - t) / h
                    o = order[i_out]
                    for i in range(n_y):
                        out[i // n, col, o, i % n] = _dense_eval(method, F, y[i], i, x, h)
                    i_out += 1
            t = t_new
            for i in range(n_y):
                y[i] = y_new[i]
                K[0, i] = K[n_stages, i]
        for i in range(n_y):
            if not math.isfinite(y[i]):
                return NOT_FINITE
        return OK

    return jit_variant(adaptive, f"{method}_{int(sens)}_{n}")


@jit_function
def _dense_coefficients(method, K, y, y_new, h, F, tmp, P, system, net, n, sens, mode, scratch, cwork):
    """F: dopri5's Q^T = (K^T P)^T (4 rows), or DOP853's 7 rows (3 extra stages evaluated)."""
    n_y = y.size
    if method == DOPRI5:
        for r in range(4):
            for i in range(n_y):
                acc = 0.0
                for j in range(7):
                    acc += DP_P[j, r] * K[j, i]
                F[r, i] = acc
        return
    _stages(K, y, h, D8_A, 13, 16, tmp, P, system, net, n, sens, mode, scratch, cwork)
    for i in range(n_y):
        dy = y_new[i] - y[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (K[12, i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(16):
                acc += D8_D[r, j] * K[j, i]
            F[3 + r, i] = h * acc


@jit_function
def _dense_eval(method, F, y_i, i, x, h):
    """Entry i of the step's interpolant at x = (t - t_old) / h in [0, 1]."""
    if method == DOPRI5:
        return y_i + h * x * (F[0, i] + x * (F[1, i] + x * (F[2, i] + x * F[3, i])))
    v = 0.0
    for r in range(7):
        v += F[6 - r, i]
        v *= x if r % 2 == 0 else 1.0 - x
    return y_i + v


@functools.cache
def _make_rk4(sens: bool, n: int):
    """One trajectory by classic RK4, compiled for one `sens` and n machines."""
    n_y = 2 * n + (4 * n * n if sens else 0)

    def rk4(ts, order, P, system, net, mode, dt, max_steps, out, col):
        """ceil(t_end / dt) equal steps from t = 0 to t_end = ts[order[-1]] (s), output at ts[order]
        by cubic Hermite interpolation of each step's end states and derivatives (4th order, as
        RK4 itself); `order` as the adaptive methods'; returns a status code."""
        n_t = order.size
        scratch = np.empty(3 * n)
        if net is None:
            cwork = np.empty(0, np.complex128)
        else:
            cwork = np.empty(net.l_inv.size, np.complex128)
        K = np.empty((4, n_y))
        work = np.empty((4, n_y))
        y, y_old, f_new, tmp = work[0], work[1], work[2], work[3]
        t_end = ts[order[n_t - 1]]
        i_out = start_trajectory(y, ts, order, system, n, out, col)
        if t_end <= 0.0:
            return OK
        n_steps = math.ceil(t_end / dt)
        if n_steps > max_steps:
            return TOO_MANY_STEPS
        h = t_end / n_steps
        _rhs(y, K[0], P, system, net, n, sens, mode, scratch, cwork)
        for step in range(n_steps):
            t0 = step * h
            t1 = t_end if step == n_steps - 1 else (step + 1) * h
            for i in range(n_y):
                y_old[i] = y[i]
                tmp[i] = y[i] + 0.5 * h * K[0, i]
            _rhs(tmp, K[1], P, system, net, n, sens, mode, scratch, cwork)
            for i in range(n_y):
                tmp[i] = y_old[i] + 0.5 * h * K[1, i]
            _rhs(tmp, K[2], P, system, net, n, sens, mode, scratch, cwork)
            for i in range(n_y):
                tmp[i] = y_old[i] + h * K[2, i]
            _rhs(tmp, K[3], P, system, net, n, sens, mode, scratch, cwork)
            for i in range(n_y):
                y[i] = y_old[i] + h / 6.0 * (K[0, i] + 2.0 * (K[1, i] + K[2, i]) + K[3, i])
            _rhs(y, f_new, P, system, net, n, sens, mode, scratch, cwork)
            while i_out < n_t and ts[order[i_out]] <= t1:
                x = (ts[order[i_out]] - t0) / h
                h00, h10 = (1 + 2 * x) * (1 - x) ** 2, h * x * (1 - x) ** 2
                h01, h11 = x * x * (3 - 2 * x), h * x * x * (x - 1)
                o = order[i_out]
                for i in range(n_y):
                    out[i // n, col, o, i % n] = h00 * y_old[i] + h10 * K[0, i] + h01 * y[i] + h11 * f_new[i]
                i_out += 1
            for i in range(n_y):
                K[0, i] = f_new[i]
        for i in range(n_y):
            if not math.isfinite(y[i]):
                return NOT_FINITE
        return OK

    return jit_variant(rk4, f"{int(sens)}_{n}")


def trajectory_kernel(method: int, sens: bool, n: int):
    """One trajectory for generator-1 power p1 (p.u.; the other generators at their p_m, as
    `Case.powers`), compiled for one method, `sens` and n machines: `(t, order, p1, system, net,
    mode, options, out, index) -> status`, the states at t[order] written into out[:, index]
    (the integrators' layout), `options` packed as `kernel`'s, `mode` `layout.rhs_mode`'s."""
    if method == RK4:
        rk4 = _make_rk4(sens, n)

        def trajectory(t, order, p1, system, net, mode, options, out, index):
            P = system[:, P_M].copy()
            P[0] = p1
            return rk4(t, order, P, system, net, mode, options[2], int(options[3]), out, index)
    else:
        adaptive = _make_adaptive(method, sens, n)

        def trajectory(t, order, p1, system, net, mode, options, out, index):
            P = system[:, P_M].copy()
            P[0] = p1
            return adaptive(t, order, P, system, net, mode, options[0], options[1], int(options[3]), out, index)

    return jit_variant(trajectory, f"{method}_{int(sens)}_{n}")


def _make_batch(method: int, sens: bool, parallel: bool, n: int):
    trajectory = trajectory_kernel(method, sens, n)

    def batch(t, P1, system, net, options):
        n_b, n_t = P1.size, t.size
        ordered = True
        for i in range(1, n_t):
            if t[i] < t[i - 1]:
                ordered = False
                break
        order = np.arange(n_t) if ordered else np.argsort(t, kind="mergesort")
        mode = rhs_mode(system, net, n)
        if sens and mode == SPARSE:
            raise ValueError("the sensitivities take the reduced network only (net = NO_NETWORK)")
        out = np.empty((2 + (4 * n if sens else 0), n_b, n_t, n))
        status = np.zeros(n_b, np.int64)
        for b in prange(n_b):
            status[b] = trajectory(t, order, P1[b], system, net, mode, options, out, b)
        for b in range(n_b):
            if status[b] != OK:
                return out, b, status[b]
        return out, -1, OK

    return jit_variant(batch, f"{method}_{int(sens)}_{int(parallel)}_{n}", parallel=parallel)


@functools.cache
def kernel(method: int, sens: bool, parallel: bool, n: int = 1):
    """The compiled batch integrator `(t, P1, system, net, options) -> (out, failed, status)` of an
    n-machine `system` and `net` (`layout`'s; `layout.NO_NETWORK` with `sens`) at times t (s, 1-D,
    >= 0, any order, repeats allowed) for each generator-1 power P1 (n_batch,) p.u.: out (2 (+ 4n
    with `sens`), n_batch, n_t, n), the state y (module docstring) in blocks of n, so that out[0] is
    delta (rad) and out[1] omega (rad/s), each (n_batch, n_t, n) as the adapter returns them (no
    reshaping per query), and out[2 + 2j], out[3 + 2j] are d delta / d p_j, d omega / d p_j,
    p = (m_1..n, d_1..n) p.u.; `failed` the index of the first failed trajectory (-1: none) and
    `status` its code (`layout.STATUS`). `parallel`: trajectories over numba's threads (prange)."""
    return _make_batch(method, sens, parallel, n)
