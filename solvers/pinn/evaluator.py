"""The query functions of a trained PINN: `Evaluator`, the interface every backend's (and the
compiled) query path implements, and `MarchingEvaluator`, a time-marching model's windows queried
through any one of them.

Imports no backend: the adapter base class (`solvers.pinn.common`) and the compiled query
(`solvers.pinn.compiled`) both build on it.
"""

from __future__ import annotations

import abc
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

import numpy as np

from solvers.pinn.architecture import Architecture

__all__ = ["Evaluator", "MarchingEvaluator", "SwitchedEvaluator", "walk"]


class Evaluator(abc.ABC):
    """The warm query function of one network architecture: compiled (and warmed up) when made,
    so that `load(theta)` after training costs no compilation.

    `load` / `__call__` / `points` serve one network (the fast path of a query); `prepare` / `grid`
    / `pairs` evaluate any prepared parameters with each P1's or point's own start state (the
    windows of a time-marching model, see `MarchingEvaluator`)."""

    @abc.abstractmethod
    def load(self, theta: np.ndarray) -> None:
        """Use the flat float64 parameters `theta` from now on."""

    @abc.abstractmethod
    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s), each (len(P1), len(t), n), for t (s) and P1 (p.u.), 1-D
        float64 numpy; float64 or float32 numpy out (the network's dtype)."""

    @abc.abstractmethod
    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s) at the pairs (t[i] s, P1[i] p.u.), each (n_s, n), one
        vectorised evaluation; dtypes as `__call__`."""

    @abc.abstractmethod
    def prepare(self, theta: np.ndarray) -> Any:
        """The flat float64 parameters `theta` in the form `grid` and `pairs` take."""

    @abc.abstractmethod
    def grid(self, params: Any, t: np.ndarray, P1: np.ndarray, start: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """As `__call__` for the `prepare`d `params`, with P1[i]'s start state start[i] (len(P1),
        2, n) float64 (rows delta rad, omega rad/s) in place of the architecture's initial
        condition."""

    @abc.abstractmethod
    def pairs(self, params: Any, t: np.ndarray, P1: np.ndarray, start: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        """As `points` for the `prepare`d `params`, with point i's start state start[i] (n_s, 2, n)."""


class MarchingEvaluator(Evaluator):
    """delta (rad) and omega (rad/s) of a time-marching model: one network per window
    [edges[w], edges[w + 1]] s, each evaluated by `inner` (an `Evaluator` of the window
    architecture, any backend or the compiled one) at the time since its window's start.

    Window w's initial condition at P1 is the state window w - 1 reaches at t_w for that P1, so a
    point needs every earlier window at its P1. Those start states are kept per P1 value in an LRU
    cache (`cache_size` P1 values, each (W, 2, n) float64): a grid query computes the P1 values it
    has not seen once (W batched network calls, n_p points each); a repeated single-point query
    looks them up. A time t belongs to the window with edges[w] <= t < edges[w + 1] (a window's
    start to itself, where phi = 0 and its state is exactly the start state); t beyond the last
    edge (extrapolation) to the last window.

    Window 0 starts from the architecture's initial state, or, with `start_of`, from
    start_of(P1) (len(P1), 2, n) float64, each P1's own (a fault case's post-fault chain: the
    state at clearing time P1)."""

    def __init__(self, inner: Evaluator, arch: Architecture, edges: np.ndarray, cache_size: int = 4096,
                 start_of: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        self.inner, self.arch = inner, arch
        self.edges = np.asarray(edges, np.float64)
        self.lengths = np.diff(self.edges)
        self.cache_size = int(cache_size)
        self._inner_edges = self.edges[1:-1]
        start0 = np.array([arch.delta0, arch.omega0], np.float64)  # (2, n)
        self.start_of = start_of or (lambda P1: np.broadcast_to(start0, (P1.size,) + start0.shape))
        self.params: list[Any] = []
        self._cache: OrderedDict[float, np.ndarray] = OrderedDict()

    def load(self, theta: np.ndarray) -> None:
        """Use the windows' parameters `theta` (W, n_params) float64 from now on."""
        theta = np.asarray(theta, np.float64)
        if theta.shape != (self.lengths.size, self.arch.n_params):
            raise ValueError(f"theta has shape {theta.shape}, {self.lengths.size} windows of this "
                             f"architecture need ({self.lengths.size}, {self.arch.n_params})")
        self.params = [self.inner.prepare(row) for row in theta]
        self._cache.clear()

    def starts(self, P1: np.ndarray) -> np.ndarray:
        """Every window's start state for each P1: (len(P1), W, 2, n) float64, from the cache or
        computed (for the P1 values not in it, together) and cached."""
        keys = P1.tolist()
        cache = self._cache
        if len(keys) == 1 and keys[0] in cache:  # the single-point query's path
            cache.move_to_end(keys[0])
            return cache[keys[0]][None]
        missing = [key for key in dict.fromkeys(keys) if key not in cache]
        if missing:
            values = np.array(missing, np.float64)
            walked = walk(self.inner, self.params, self.lengths, values, self.start_of(values))
            for key, row in zip(missing, walked):
                cache[key] = row
        out = np.stack([cache[key] for key in keys])
        for key in dict.fromkeys(keys):
            cache.move_to_end(key)
        while len(cache) > self.cache_size:
            cache.popitem(last=False)
        return out

    def window_of(self, t: np.ndarray) -> np.ndarray:
        """The window index of each time t (s)."""
        return np.searchsorted(self._inner_edges, t, side="right")

    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        starts = self.starts(P1)
        which = self.window_of(t)
        if t.size == 1:  # one window: no scatter
            w = int(which[0])
            return self.inner.grid(self.params[w], t - self.edges[w], P1, starts[:, w])
        delta = np.empty((P1.size, t.size, self.arch.machines))
        omega = np.empty_like(delta)
        for w in np.unique(which).tolist():
            idx = np.flatnonzero(which == w)
            d, o = self.inner.grid(self.params[w], t[idx] - self.edges[w], P1, starts[:, w])
            delta[:, idx], omega[:, idx] = d, o
        return delta, omega

    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        starts = self.starts(P1)
        which = self.window_of(t)
        delta = np.empty((t.size, self.arch.machines))
        omega = np.empty_like(delta)
        for w in np.unique(which).tolist():
            idx = np.flatnonzero(which == w)
            d, o = self.inner.pairs(self.params[w], t[idx] - self.edges[w], P1[idx], starts[idx, w])
            delta[idx], omega[idx] = d, o
        return delta, omega

    def prepare(self, theta: np.ndarray) -> Any:
        raise TypeError("a time-marching model is not a window: use load()")

    def grid(self, params, t, P1, start):
        raise TypeError("a time-marching model is not a window: use __call__()")

    def pairs(self, params, t, P1, start):
        raise TypeError("a time-marching model is not a window: use points()")


def walk(inner: Evaluator, params: list[Any], lengths: np.ndarray, P1: np.ndarray, start0: np.ndarray
         ) -> np.ndarray:
    """The start states (len(P1), len(params) + 1, 2, n) float64 of windows 0..len(params) for each
    P1: window 0 starts at `start0` (2, n) (the case's initial state) or (len(P1), 2, n) (each P1's
    own), window w + 1 at the end of window w (its network `params[w]` at the window's length
    `lengths[w]` s from its start state)."""
    out = np.empty((P1.size, len(params) + 1) + start0.shape[-2:])
    out[:, 0] = start0
    for w, prepared in enumerate(params):
        delta, omega = inner.pairs(prepared, np.full(P1.size, lengths[w]), P1, out[:, w])
        out[:, w + 1, 0], out[:, w + 1, 1] = delta, omega
    return out


class SwitchedEvaluator(Evaluator):
    """delta (rad) and omega (rad/s) of a fault case's switched model (`PinnConfig.phases`) at
    (t s, t_c s): for t < t_c the fault-on chain of windows `on_edges` (t s) at the constant
    scenario input `arch.p_mid`, from the architecture's initial state; for t >= t_c the
    post-fault chain of windows `post_edges` (tau = t - t_c s) of the piece of clearing times
    [pieces[k], pieces[k + 1]] that holds t_c, at (tau, u) with u the position of t_c in its
    piece mapped onto [arch.p_lo, arch.p_hi], starting from the fault-on chain's state at t_c
    (so the state is continuous at t_c). All chains through `inner` (an `Evaluator` of the one
    window architecture); parameters (W_on + K W_post, n_params): fault-on windows, then each
    piece's post-fault windows. Every (t, t_c) pair after the switch is its own point (tau
    differs per t_c): a grid costs one paired evaluation per point."""

    def __init__(self, inner: Evaluator, arch: Architecture, on_edges: np.ndarray, post_edges: np.ndarray,
                 pieces: np.ndarray | None = None) -> None:
        self.arch = arch
        self.pieces = np.array([arch.p_lo, arch.p_hi]) if pieces is None else np.asarray(pieces, np.float64)
        self.on = MarchingEvaluator(inner, arch, on_edges)
        self.posts = [MarchingEvaluator(inner, arch, post_edges, start_of=self._starts_of(k))
                      for k in range(self.pieces.size - 1)]
        self._p_on = np.array([arch.p_mid])

    def _starts_of(self, k: int) -> Callable[[np.ndarray], np.ndarray]:
        return lambda u: self.clearing_state(self.clearing_time(k, u))

    def load(self, theta: np.ndarray) -> None:
        """Use the parameters `theta` (W_on + K W_post, n_params) float64 from now on."""
        theta = np.asarray(theta, np.float64)
        w_on, w_post = self.on.lengths.size, self.posts[0].lengths.size
        if theta.ndim != 2 or theta.shape[0] != w_on + len(self.posts) * w_post:
            raise ValueError(f"theta has shape {theta.shape}, a switched model of {w_on} fault-on and "
                             f"{len(self.posts)} x {w_post} post-fault windows needs one row per window")
        self.on.load(theta[:w_on])
        for k, post in enumerate(self.posts):
            post.load(theta[w_on + k * w_post:w_on + (k + 1) * w_post])

    def piece_of(self, t_c: np.ndarray) -> np.ndarray:
        """The piece index of each clearing time t_c (s)."""
        return np.searchsorted(self.pieces[1:-1], t_c, side="right")

    def position(self, k: int, t_c: np.ndarray) -> np.ndarray:
        """The input u in [arch.p_lo, arch.p_hi] of clearing times t_c (s) of piece k."""
        lo, hi = self.pieces[k], self.pieces[k + 1]
        return self.arch.p_lo + (t_c - lo) * ((self.arch.p_hi - self.arch.p_lo) / (hi - lo))

    def clearing_time(self, k: int, u: np.ndarray) -> np.ndarray:
        """The clearing times (s) of inputs u of piece k (the inverse of `position`)."""
        lo, hi = self.pieces[k], self.pieces[k + 1]
        return lo + (u - self.arch.p_lo) * ((hi - lo) / (self.arch.p_hi - self.arch.p_lo))

    def fault_on(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s) of the fault-on phase at times t (s), each (len(t), n)."""
        return self.on.points(t, np.full(t.size, self.arch.p_mid))

    def clearing_state(self, t_c: np.ndarray) -> np.ndarray:
        """The state (len(t_c), 2, n) float64 (rows delta rad, omega rad/s) at each clearing time
        t_c (s): the fault-on phase's end, the post-fault phase's start."""
        delta, omega = self.fault_on(t_c)
        return np.stack([delta, omega], axis=1)

    def post_fault(self, tau: np.ndarray, t_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s), each (len(tau), n), at tau = t - t_c >= 0 s after
        clearing times t_c (s), pair by pair."""
        delta = np.empty((tau.size, self.arch.machines))
        omega = np.empty_like(delta)
        which = self.piece_of(t_c)
        for k in np.unique(which).tolist():
            idx = np.flatnonzero(which == k)
            delta[idx], omega[idx] = self.posts[k].points(tau[idx], self.position(k, t_c[idx]))
        return delta, omega

    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        delta = np.empty((P1.size, t.size, self.arch.machines))
        omega = np.empty_like(delta)
        early = np.flatnonzero(t < P1.max())  # before some clearing time: the fault-on chain
        if early.size:
            d_on, o_on = self.on(t[early], self._p_on)
            delta[:, early], omega[:, early] = d_on, o_on
        i, j = np.nonzero(t[None, :] >= P1[:, None])
        if i.size:
            delta[i, j], omega[i, j] = self.post_fault(t[j] - P1[i], P1[i])
        return delta, omega

    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        after = t >= P1
        delta = np.empty((t.size, self.arch.machines))
        omega = np.empty_like(delta)
        if (~after).any():
            delta[~after], omega[~after] = self.fault_on(t[~after])
        if after.any():
            delta[after], omega[after] = self.post_fault(t[after] - P1[after], P1[after])
        return delta, omega

    def prepare(self, theta: np.ndarray) -> Any:
        raise TypeError("a switched model is not a window: use load()")

    def grid(self, params, t, P1, start):
        raise TypeError("a switched model is not a window: use __call__()")

    def pairs(self, params, t, P1, start):
        raise TypeError("a switched model is not a window: use points()")
