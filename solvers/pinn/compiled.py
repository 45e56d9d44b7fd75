"""A compiled (numba) query of a trained PINN: delta and omega without torch or JAX.

The forward pass of any `Architecture` network (any layer sizes, n machines, one or two
outputs per machine, with or without the hard initial condition, from the architecture's initial
state or each P1's own: the windows of a time-marching model), computed in float64 from the flat float64 parameter vector,
exactly as `network.delta_omega`: inputs normalised to [-1, 1], tanh hidden layers, a linear output
layer, omega = d delta/dt by forward-mode differentiation written out by hand (the t-tangent
enters the first layer as 2 / (t_hi - t_lo) times the t-column of W_0; through each hidden layer
z_t = h_t W, h = tanh(z), h_t = (1 - h^2) z_t; then the chain rule of the hard-IC head), or the
network's second output for two-output networks.

Points are taken in blocks of `_BLOCK` (the flattened (P1, t) grid), so that every loop over a
block is elementwise over contiguous memory and vectorises; tanh over a block is computed as
-expm1(-2|z|) / (2 + expm1(-2|z|)) with a Cody-Waite reduced Taylor expm1 (relative error a few
ulp; libm's tanh is a scalar call that does not vectorise). error_model="numpy" drops numba's
division-by-zero check, which kept these loops from vectorising. A query is one numba call; the
weights are copied once, at `load`, into one contiguous array. The kernels are cached on disk
(numba `cache=True`): a cold compile takes seconds, a cached one a fraction of a second.

A network trained in float32 (the `paper` configs) is evaluated here in float64 from its saved
float64 weights, so its answers differ from the framework's float32 evaluation by float32
rounding (see `NumbaEvaluator`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from solvers.pinn.architecture import Architecture
from solvers.pinn.evaluator import Evaluator, MarchingEvaluator, SwitchedEvaluator
from solvers.pinn.model_file import load_model
from solvers.pinn.problems import PhaseEdges

__all__ = ["NumbaEvaluator", "compiled_model"]

# Fused multiply-adds only: no reassociation, no NaN or infinity assumptions
_FASTMATH = {"contract"}
_BLOCK = 64  # points per block: the scratch (4 x width x 64 doubles) stays in L1
_N_HEAD = 4  # params[0:4] = t_lo, 2 / (t_hi - t_lo), p_lo, 2 / (p_hi - p_lo); then the flat weights
# expm1 on [-ln2 / 2, ln2 / 2]: Cody-Waite split of ln 2 and Taylor coefficients
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_INV_LN2 = 1.44269504088896338700e+00
_C = tuple(1.0 / math.factorial(k) for k in range(14, 1, -1))  # 1/14!, ..., 1/2!, for Horner


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _tanh_block(z, h, kbits, m):
    """h[:m] = tanh(z[:m]); kbits is int64 scratch of at least m entries."""
    for k in range(m):
        y = -2.0 * min(abs(z[k]), 40.0)  # tanh(40) = 1 to double precision
        n = np.rint(y * _INV_LN2)
        kbits[k] = (np.int64(n) + 1023) << 52  # 2^n as IEEE bits (n in [-116, 0])
        h[k] = n
    scale = kbits[:m].view(np.float64)
    for k in range(m):
        n = h[k]
        y = -2.0 * min(abs(z[k]), 40.0)
        r = (y - n * _LN2_HI) - n * _LN2_LO
        p = 0.0
        for c in _C:
            p = c + r * p
        em1_r = r + r * r * p  # expm1(r)
        s = scale[k]
        em1 = s * em1_r + (s - 1.0)  # expm1(y) = 2^n expm1(r) + 2^n - 1
        h[k] = math.copysign(-em1 / (2.0 + em1), z[k])


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _points(t, p, params, sizes, start, srow, out, q0, q1, scratch, misc, kbits):
    """delta and omega of the flattened grid points q0 <= q < q1 (q = i n_t + j for P1[i], t[j])
    into out[0] and out[1] (2, n_p, n_t, n); P1[i]'s start state is start[i srow] (2, n)."""
    n_t = t.shape[0]
    t_lo, ct, p_lo, cp = params[0], params[1], params[2], params[3]
    hard_ic = sizes[0] == 1
    n_layers = sizes[1]
    n_out = sizes[2 + n_layers]
    nm = sizes[3 + n_layers]
    tangent = n_out == nm
    h, g, z, zt = scratch[0], scratch[1], scratch[2], scratch[3]
    tn, pn = misc[0], misc[1]
    for first in range(q0, q1, _BLOCK):
        m = min(_BLOCK, q1 - first)
        for k in range(m):
            q = first + k
            i = q // n_t
            tn[k] = (t[q - i * n_t] - t_lo) * ct - 1.0
            pn[k] = (p[i] - p_lo) * cp - 1.0
        # first layer: z = tn W_0[0] + pn W_0[1] + b_0, z_t = ct W_0[0]
        off = _N_HEAD
        width = sizes[3]
        for u in range(width):
            a, b, c = params[off + u], params[off + width + u], params[off + 2 * width + u]
            for k in range(m):
                z[u, k] = tn[k] * a + pn[k] * b + c
            _tanh_block(z[u], h[u], kbits, m)
            if tangent:
                a *= ct
                for k in range(m):
                    g[u, k] = (1.0 - h[u, k] * h[u, k]) * a
        off += 3 * width
        for layer in range(1, n_layers - 1):
            n_in, width = sizes[2 + layer], sizes[3 + layer]
            b_off = off + n_in * width
            for v in range(width):
                bias = params[b_off + v]
                for k in range(m):
                    z[v, k] = bias
                    zt[v, k] = 0.0
                for u in range(n_in):
                    w = params[off + u * width + v]
                    for k in range(m):
                        z[v, k] += h[u, k] * w
                    if tangent:
                        for k in range(m):
                            zt[v, k] += g[u, k] * w
            for v in range(width):
                _tanh_block(z[v], h[v], kbits, m)
                if tangent:
                    for k in range(m):
                        g[v, k] = (1.0 - h[v, k] * h[v, k]) * zt[v, k]
            off = b_off + width
        # linear output layer, per machine c: N_c (and its t-tangent, or the omega output N_{n+c})
        n_in = sizes[1 + n_layers]
        b_off = off + n_in * n_out
        for c in range(nm):
            n1, x = misc[2 + c], misc[2 + nm + c]
            c2 = c if tangent else nm + c
            for k in range(m):
                n1[k] = params[b_off + c]
                x[k] = 0.0 if tangent else params[b_off + c2]
            for u in range(n_in):
                w1 = params[off + u * n_out + c]
                w2 = params[off + u * n_out + c2]
                for k in range(m):
                    n1[k] += h[u, k] * w1
                for k in range(m):
                    x[k] += (g[u, k] if tangent else h[u, k]) * w2
        for k in range(m):
            q = first + k
            i = q // n_t
            j = q - i * n_t
            row = i * srow
            for c in range(nm):
                out[0, i, j, c], out[1, i, j, c] = _head(t[j], misc[2 + c, k], misc[2 + nm + c, k],
                                                         start[row, 0, c], start[row, 1, c], hard_ic, tangent)


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _head(tv, n1, x, delta0, omega0, hard_ic, tangent):
    """(delta, omega) at t = tv from the network's N_1 and x = dN_1/dt (one output) or N_2."""
    if not hard_ic:
        return n1, x
    e = math.exp(-tv)
    phi = 1.0 - e
    inner = omega0 + phi * n1
    if tangent:  # d/dt [delta0 + phi (omega0 + phi N_1)] with phi' = e
        return delta0 + phi * inner, e * inner + phi * (e * n1 + phi * x)
    return delta0 + phi * inner, omega0 + phi * x


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _one_point(tv, pv, params, sizes, buf, kbits, start, row, res):
    """(delta, omega) of every machine at one point into res (2, n), vectorised over the units of a
    layer instead of over points: the same operations in the same order as `_points` (so the same
    bits), without its per-loop cost, which dominates for a handful of points."""
    ct, cp = params[1], params[3]
    n_layers = sizes[1]
    n_out = sizes[2 + n_layers]
    nm = sizes[3 + n_layers]
    tangent = n_out == nm
    h, g, z, zt = buf[0], buf[1], buf[2], buf[3]
    tn = (tv - params[0]) * ct - 1.0
    pn = (pv - params[2]) * cp - 1.0
    off = _N_HEAD
    width = sizes[3]
    for u in range(width):
        z[u] = tn * params[off + u] + pn * params[off + width + u] + params[off + 2 * width + u]
    _tanh_block(z, h, kbits, width)
    if tangent:
        for u in range(width):
            g[u] = (1.0 - h[u] * h[u]) * (params[off + u] * ct)
    off += 3 * width
    for layer in range(1, n_layers - 1):
        n_in, width = sizes[2 + layer], sizes[3 + layer]
        b_off = off + n_in * width
        for v in range(width):
            z[v] = params[b_off + v]
            zt[v] = 0.0
        for u in range(n_in):
            hu, gu, r = h[u], g[u], off + u * width
            for v in range(width):
                z[v] += hu * params[r + v]
            if tangent:
                for v in range(width):
                    zt[v] += gu * params[r + v]
        _tanh_block(z, h, kbits, width)
        if tangent:
            for v in range(width):
                g[v] = (1.0 - h[v] * h[v]) * zt[v]
        off = b_off + width
    n_in = sizes[1 + n_layers]
    b_off = off + n_in * n_out
    hard_ic = sizes[0] == 1
    for c in range(nm):
        c2 = c if tangent else nm + c
        n1 = params[b_off + c]
        x = 0.0 if tangent else params[b_off + c2]
        for u in range(n_in):
            n1 += h[u] * params[off + u * n_out + c]
            x += (g[u] if tangent else h[u]) * params[off + u * n_out + c2]
        res[0, c], res[1, c] = _head(tv, n1, x, start[row, 0, c], start[row, 1, c], hard_ic, tangent)


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _scratch(sizes, block):
    """Scratch of the kernels: (4, width, block) for h, h_t, z, z_t; (2 + 2n, block) for the
    normalised inputs and each machine's outputs; int64 (max(width, block),) for `_tanh_block`."""
    n_layers = sizes[1]
    width = 1
    for layer in range(1, n_layers + 1):
        width = max(width, sizes[2 + layer])
    return (np.empty((4, width, block)), np.empty((2 + 2 * sizes[3 + n_layers], block)),
            np.empty(max(width, block), np.int64))


_SMALL = 16  # fewer points than this: one point at a time (`_one_point`)


@numba.njit(error_model="numpy", fastmath=_FASTMATH, cache=True)
def _range(t, p, params, sizes, start, srow, out, q0, q1):
    n_t = t.shape[0]
    if q1 - q0 < _SMALL:
        scratch, _, kbits = _scratch(sizes, 1)
        buf = scratch[:, :, 0]
        res = np.empty((2, out.shape[3]))
        for q in range(q0, q1):
            i = q // n_t
            j = q - i * n_t
            _one_point(t[j], p[i], params, sizes, buf, kbits, start, i * srow, res)
            out[0, i, j, :] = res[0]
            out[1, i, j, :] = res[1]
    else:
        scratch, misc, kbits = _scratch(sizes, _BLOCK)
        _points(t, p, params, sizes, start, srow, out, q0, q1, scratch, misc, kbits)


@numba.njit(nogil=True, error_model="numpy", fastmath=_FASTMATH, cache=True)
def _query(t, p, params, sizes, start, srow):
    out = np.empty((2, p.shape[0], t.shape[0], sizes[3 + sizes[1]]))
    _range(t, p, params, sizes, start, srow, out, 0, p.shape[0] * t.shape[0])
    return out


@numba.njit(nogil=True, parallel=True, error_model="numpy", fastmath=_FASTMATH, cache=True)
def _query_parallel(t, p, params, sizes, start, srow, chunk):
    n = p.shape[0] * t.shape[0]
    out = np.empty((2, p.shape[0], t.shape[0], sizes[3 + sizes[1]]))
    for c in numba.prange((n + chunk - 1) // chunk):
        _range(t, p, params, sizes, start, srow, out, c * chunk, min(n, (c + 1) * chunk))
    return out


@numba.njit(nogil=True, error_model="numpy", fastmath=_FASTMATH, cache=True)
def _pairs(t, p, params, sizes, start, srow):
    """(2, n_s, n): delta and omega at the points (t[q], p[q]), start state start[q srow], one
    `_one_point` each (the same bits as a one-point grid query)."""
    out = np.empty((2, t.shape[0], sizes[3 + sizes[1]]))
    scratch, _, kbits = _scratch(sizes, 1)
    buf = scratch[:, :, 0]
    res = np.empty((2, out.shape[2]))
    for q in range(t.shape[0]):
        _one_point(t[q], p[q], params, sizes, buf, kbits, start, q * srow, res)
        out[0, q, :] = res[0]
        out[1, q, :] = res[1]
    return out


_PARALLEL_MIN = 4096  # points; below this the threads' start-up costs more than they save
_CHUNK = 16 * _BLOCK  # points per parallel task


class NumbaEvaluator(Evaluator):
    """delta (rad) and omega (rad/s), each (len(P1), len(t), n) float64, of networks `arch` (not the
    identification architectures), computed in float64 by numba; compiled and warmed up when made.
    `grid` / `pairs` take each P1's or point's start state (time-marching windows), so a
    `evaluator.MarchingEvaluator` over this one is the compiled query of a time-marching model.

    `threads` > 1: queries of at least `_PARALLEL_MIN` points are split over that many numba threads
    (prange over chunks of the flattened grid). The same point gives the same bits whatever the
    query's shape. A network trained in float32 is evaluated from its float64 weights in float64:
    its answers differ from the framework's float32 query by float32 rounding (measured on the
    100 x 201 grid, 5 x 10 `paper` networks: up to 1.3e-6 of max |delta| or max |omega|)."""

    def __init__(self, arch: Architecture, threads: int = 1) -> None:
        if arch.n_extra:
            raise ValueError("NumbaEvaluator evaluates forward networks, not identification networks")
        self.arch, self.threads = arch, int(threads)
        self._sizes = np.array([int(arch.hard_ic), len(arch.sizes) - 1, *arch.sizes, arch.machines], np.int64)
        self._head = np.array([arch.t_lo, 2.0 / (arch.t_hi - arch.t_lo), arch.p_lo, 2.0 / (arch.p_hi - arch.p_lo)])
        self._start0 = np.array([[arch.delta0, arch.omega0]], np.float64)  # (1, 2, n), row stride 0
        self.load(np.zeros(arch.n_params))
        t_grid = np.linspace(arch.t_lo, arch.t_hi, 201)
        p_grid = np.linspace(arch.p_lo, arch.p_hi, 100)
        for t, p in ((t_grid[:1], p_grid[:1]), (t_grid, p_grid[:1]), (t_grid, p_grid)):
            self(t, p)
        self.points(t_grid[:2], p_grid[:2])

    def prepare(self, theta: np.ndarray) -> np.ndarray:
        theta = np.asarray(theta, np.float64)
        if theta.shape != (self.arch.n_params,):
            raise ValueError(f"theta has shape {theta.shape}, the architecture needs ({self.arch.n_params},)")
        return np.concatenate([self._head, theta])  # one contiguous float64 array

    def load(self, theta: np.ndarray) -> None:
        self._params = self.prepare(theta)

    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # written out, not through `grid`: a single-point query costs ~4 us, a call ~0.3 us of it
        if self.threads > 1 and t.shape[0] * P1.shape[0] >= _PARALLEL_MIN:
            numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
            out = _query_parallel(t, P1, self._params, self._sizes, self._start0, 0, _CHUNK)
        else:
            out = _query(t, P1, self._params, self._sizes, self._start0, 0)
        return out[0], out[1]

    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out = _pairs(t, P1, self._params, self._sizes, self._start0, 0)
        return out[0], out[1]

    def grid(self, params: np.ndarray, t: np.ndarray, P1: np.ndarray, start: np.ndarray, srow: int = 1
             ) -> tuple[np.ndarray, np.ndarray]:
        start = np.ascontiguousarray(start, np.float64)
        if self.threads > 1 and t.shape[0] * P1.shape[0] >= _PARALLEL_MIN:
            numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
            out = _query_parallel(t, P1, params, self._sizes, start, srow, _CHUNK)
        else:
            out = _query(t, P1, params, self._sizes, start, srow)
        return out[0], out[1]

    def pairs(self, params: np.ndarray, t: np.ndarray, P1: np.ndarray, start: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        out = _pairs(np.ascontiguousarray(t, np.float64), np.ascontiguousarray(P1, np.float64), params,
                     self._sizes, np.ascontiguousarray(start, np.float64), 1)
        return out[0], out[1]


def compiled_model(path, threads: int = 1) -> Evaluator:
    """The `NumbaEvaluator` of a model saved by either backend (`save_model`, `<path>.npz`
    and `<path>.json`), loaded with its weights: queries without torch or JAX; for a time-marching
    model the `MarchingEvaluator` over it, for a fault case's switched model the `SwitchedEvaluator`."""
    saved = load_model(path)
    evaluator: Evaluator = NumbaEvaluator(saved["arch"], threads)
    windows = saved["windows"]
    if isinstance(windows, PhaseEdges):
        evaluator = SwitchedEvaluator(evaluator, saved["arch"], windows.on, windows.post, windows.pieces)
    elif windows is not None:
        evaluator = MarchingEvaluator(evaluator, saved["arch"], windows)
    evaluator.load(saved["theta"])
    return evaluator
