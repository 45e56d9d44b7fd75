"""A fault case's switched model split at its own critical clearing time (`PinnConfig.split`).

One smooth chain over the clearing times does not follow the trajectories' split at the CCT: on
one side the machines swing back, on the other one slips poles (docs/pinn-faults.md). So the model
first finds its own CCT and then trains the two sides apart:

1. the fault-on chain (`marching.train_fault_on`), as without the split but with `ON_WEIGHT` times
   `max_iterations` a window: the screen and every post-fault chain start from its state (wscc9,
   150 iterations a window: the fault-on loss stayed at 1e-4 and the stable side at 6e-3);
2. `screen_cct`: bisection over t_c, each evaluation a post-fault chain of that one clearing time
   (the networks' scenario input held at `Architecture.p_mid`), started from the trained fault-on
   chain's state at t_c (its windows after the first evaluation warm-started from the previous
   one's, `WARM_DIVISOR`) and judged by the cct suite's criterion (`systems.stability.is_unstable`,
   every `CRITERION_DT_S` s) window by window, stopped at the first window that crosses it. No
   solver data: the screen is the PINN's own physics residual;
3. `split_pieces`: the pieces of clearing times graded towards the estimate on both sides, whose
   chains `marching.train_posts` trains; the two pieces next to it, whose trajectories pass
   closest to the unstable equilibrium, train `near_weight` times `max_iterations` (and time
   share) a window; the pieces above it (the unstable side) start with their output layers
   `unstable_scale` times Glorot's.

Backend-free, as `marching`: the adapter passes its training and query functions in. Units: times
in s, states (delta rad, omega rad/s).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from solvers.pinn.architecture import Architecture, init_theta, layer_shapes, split_flat
from solvers.pinn.config import PinnConfig
from solvers.pinn.evaluator import Evaluator, SwitchedEvaluator
from solvers.pinn.marching import ON_WEIGHT, Chain, TrainerOf, train_fault_on, train_posts
from solvers.pinn.optim import OptimResult
from solvers.pinn.problems import PhaseEdges, Problem, phase_problem
from systems.cases import Case
from systems.stability import is_unstable

__all__ = ["CRITERION_DT_S", "SCREEN_SHARE", "Screen", "output_scaled", "screen_cct", "split_pieces", "train_split"]

CRITERION_DT_S = 0.01  # s: the spacing the screen judges the criterion at (the cct suite's)
# A window warm-started from the previous evaluation's trains 1 / WARM_DIVISOR of
# `screen_iterations` (late in the bisection the clearing times are less than a ms apart). wscc9,
# 150 iterations a window: a screen of 150 a window took 9300 iterations (122 s on a loaded core)
WARM_DIVISOR = 3
# The screen's share of the time left after the fault-on chain, when the fit has a time budget
SCREEN_SHARE = 0.2
# fit_window(problem, theta0, max_iterations, deadline, label) -> the optimiser's result
FitWindow = Callable[[Problem, np.ndarray, int, float, str], OptimResult]


@dataclass(frozen=True)
class Screen:
    """The screen's outcome: the final bracket [stable_s, unstable_s] (s; NaN on the side the
    range does not reach), the estimate `cct_s` (its midpoint), the chains trained, their windows
    and LM iterations, its wall seconds and `note` ("" or why there is no estimate, or why the
    bracket is wider than asked)."""

    stable_s: float
    unstable_s: float
    chains: int
    windows: int
    iterations: int
    seconds: float
    note: str = ""

    @property
    def cct_s(self) -> float:
        return 0.5 * (self.stable_s + self.unstable_s)

    def summary(self) -> str:
        found = (f"CCT estimate {self.cct_s:.6f} s (bracket {self.stable_s:.6f}..{self.unstable_s:.6f} s)"
                 if math.isfinite(self.cct_s) else "no CCT estimate")
        return (f"{found}: screen of {self.chains} one-clearing-time chains, {self.windows} windows, "
                f"{self.iterations} iterations, {self.seconds:.1f} s" + (f"; {self.note}" if self.note else ""))


def output_scaled(arch: Architecture, theta: np.ndarray, scale: float) -> np.ndarray:
    """`theta` (n_params,) with the output layer's weights and biases times `scale`."""
    if scale == 1.0:
        return theta
    out = np.array(theta, np.float64)
    views, _ = split_flat(layer_shapes(arch.sizes), out)
    views[-2] *= scale
    views[-1] *= scale
    return out


def split_pieces(case: Case, cct_s: float, per_side: int, grading: float) -> np.ndarray:
    """The edges (2 per_side + 1,) s of the pieces of clearing times: `per_side` pieces on each side
    of `cct_s`, edges at cct_s -+ L (j / per_side) ** grading (L the side's length, j = 0..per_side);
    with `cct_s` NaN (no estimate) 2 per_side equal pieces of [p1_min, p1_max]."""
    lo, hi = case.p1_min, case.p1_max
    if not math.isfinite(cct_s):
        return np.linspace(lo, hi, 2 * per_side + 1)
    if not lo < cct_s < hi:
        raise ValueError(f"the CCT estimate {cct_s!r} s lies outside the clearing times ({lo}, {hi}) s")
    j = (np.arange(per_side + 1) / per_side) ** grading
    below = cct_s - (cct_s - lo) * j[::-1]
    above = cct_s + (hi - cct_s) * j
    edges = np.concatenate([below, above[1:]])
    edges[0], edges[per_side], edges[-1] = lo, cct_s, hi  # exact ends: the model file checks them
    return edges


def screen_cct(config: PinnConfig, case: Case, arch: Architecture, edges: PhaseEdges, on: Chain,
               fit_window: FitWindow, walker: Evaluator, deadline: float) -> Screen:
    """The model's own CCT (see the module docstring) by bisection over [p1_min, p1_max] down to
    `config.screen_tol` s, or until `deadline` (`time.perf_counter()` s; the note says so)."""
    start_time = time.perf_counter()
    probe = SwitchedEvaluator(walker, arch, edges.on, edges.post, edges.pieces)
    probe.on.load(np.stack(on.thetas))
    screen = dataclasses.replace(config, n_f=config.screen_n_f)
    lengths = np.diff(edges.post)
    p_in = np.array([arch.p_mid])
    warm: dict[int, np.ndarray] = {}  # window -> the latest evaluation's trained weights
    counts = {"chains": 0, "windows": 0, "iterations": 0}

    def unstable(t_c: float) -> bool:
        counts["chains"] += 1
        state = probe.clearing_state(np.array([t_c]))  # (1, 2, n)
        horizon = case.t_final - t_c
        for w in range(lengths.size):
            if edges.post[w] >= horizon - 1e-12:
                break
            problem = phase_problem(screen, case, edges, "post", w, arch.p_mid)
            problem = dataclasses.replace(problem, p_f=np.full_like(problem.p_f, arch.p_mid),
                                          start_f=np.repeat(state, problem.t_f.size, axis=0))
            theta0, iterations = warm.get(w), max(1, config.screen_iterations // WARM_DIVISOR)
            if theta0 is None:
                theta0, iterations = init_theta(arch, config.seed, window=edges.count + w), config.screen_iterations
            result = fit_window(problem, theta0, iterations, deadline,
                                f"screen t_c={t_c:.5f} s window {w + 1}/{lengths.size}")
            warm[w] = result.theta
            counts["windows"] += 1
            counts["iterations"] += result.iterations
            prepared = walker.prepare(result.theta)
            span = min(float(lengths[w]), horizon - float(edges.post[w]))
            t_local = np.append(np.arange(0.0, span, CRITERION_DT_S), span)
            delta, omega = walker.grid(prepared, t_local, p_in, state)
            if bool(is_unstable(case, delta[0])):
                return True
            state = np.stack([delta[:, -1], omega[:, -1]], axis=1)
        return False

    def done(lo: float, hi: float, note: str = "") -> Screen:
        return Screen(lo, hi, counts["chains"], counts["windows"], counts["iterations"],
                      time.perf_counter() - start_time, note)

    lo, hi = case.p1_min, case.p1_max
    if not unstable(hi):
        return done(hi, math.nan, f"stable at p1_max = {hi} s: the CCT lies above the range, no split")
    if unstable(lo):
        return done(math.nan, lo, f"unstable at p1_min = {lo} s: the CCT lies below the range, no split")
    while hi - lo > config.screen_tol:
        if time.perf_counter() >= deadline:
            return done(lo, hi, f"the screen's time ran out at a bracket of {1e3 * (hi - lo):.3g} ms")
        mid = 0.5 * (lo + hi)
        if unstable(mid):
            hi = mid
        else:
            lo = mid
    return done(lo, hi)


def train_split(config: PinnConfig, case: Case, arch: Architecture, window_edges: PhaseEdges,
                trainer_of: TrainerOf, fit_window: FitWindow, walker: Evaluator, deadline: float
                ) -> tuple[Chain, Chain, PhaseEdges, Screen]:
    """Train the split model: the fault-on chain, the screen, then the post-fault chains of
    `split_pieces` (`config.pieces` a side). `window_edges` gives the fault-on and post-fault
    windows (its pieces are not used). Returns the fault-on chain, the post-fault chains joined,
    the model's `PhaseEdges` and the screen."""
    w_post, sides = window_edges.post.size - 1, 2 * config.pieces
    on = train_fault_on(config, case, arch, window_edges, trainer_of, walker, deadline,
                        windows_after=(sides - 2 + 2 * config.near_weight) * w_post / ON_WEIGHT, iterations=round(ON_WEIGHT * config.max_iterations))
    now = time.perf_counter()
    screen = screen_cct(config, case, arch, window_edges, on, fit_window, walker,
                        now + SCREEN_SHARE * (deadline - now))
    pieces = split_pieces(case, screen.cct_s, config.pieces, config.split_grading)
    edges = window_edges._replace(pieces=pieces)
    found = math.isfinite(screen.cct_s)
    scales = [config.unstable_scale if found and k >= config.pieces else 1.0 for k in range(sides)]
    weights = [config.near_weight if found and k in (config.pieces - 1, config.pieces) else 1.0 for k in range(sides)]
    post = train_posts(config, case, arch, edges, on, trainer_of, walker, deadline, scales, weights)
    return on, post, edges, screen
