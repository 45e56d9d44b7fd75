"""The query functions of a trained PINN: `Evaluator`, the interface every backend's (and the
compiled) query path implements, and `MarchingEvaluator`, a time-marching model's windows queried
through any one of them.

Imports no backend: the adapter base class (`solvers.pinn.common`) and the compiled query
(`solvers.pinn.compiled`) both build on it.
"""

from __future__ import annotations

import abc
from collections import OrderedDict
from typing import Any

import numpy as np

from solvers.pinn.architecture import Architecture

__all__ = ["Evaluator", "MarchingEvaluator", "walk"]


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
    edge (extrapolation) to the last window."""

    def __init__(self, inner: Evaluator, arch: Architecture, edges: np.ndarray, cache_size: int = 4096) -> None:
        self.inner, self.arch = inner, arch
        self.edges = np.asarray(edges, np.float64)
        self.lengths = np.diff(self.edges)
        self.cache_size = int(cache_size)
        self._inner_edges = self.edges[1:-1]
        self._start0 = np.array([arch.delta0, arch.omega0], np.float64)  # (2, n)
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
            walked = walk(self.inner, self.params, self.lengths, np.array(missing, np.float64), self._start0)
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
    P1: window 0 starts at `start0` (2, n) (the case's initial state), window w + 1 at the end of
    window w (its network `params[w]` at the window's length `lengths[w]` s from its start state)."""
    out = np.empty((P1.size, len(params) + 1) + start0.shape)
    out[:, 0] = start0
    for w, prepared in enumerate(params):
        delta, omega = inner.pairs(prepared, np.full(P1.size, lengths[w]), P1, out[:, w])
        out[:, w + 1, 0], out[:, w + 1, 1] = delta, omega
    return out
