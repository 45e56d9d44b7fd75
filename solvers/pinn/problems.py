"""The training points of a PINN run and their loss weights (`Problem`): the seeded data and
collocation points of `fit` (`forward_problem`; `window_problem` for a time-marching window) and of
`identify` (`identification_problem`).

Plain numpy, float64. Units: t in s, P1 in p.u., delta in rad, omega in rad/s, m in p.u. s^2/rad,
d in p.u. s/rad.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.stats import qmc

from solvers.pinn.config import PinnConfig
from systems.cases import Case, Observations, standard_grid

__all__ = ["PhaseEdges", "Problem", "forward_problem", "identification_p_range", "identification_problem",
           "observations_within", "phase_edges", "phase_problem", "residual_weights", "window_edges", "window_problem"]


@dataclass(frozen=True)
class Problem:
    """The training points of one run, numpy float64.

    Data: t_u (s), p_u (p.u.), targets (n_u, k) with columns delta_1..n (rad) and, when k = 2n,
    omega_1..n (rad/s); collocation: t_f (s), p_f (p.u.). The loss is
    loss_scale * (sum over columns of mean((prediction - target)^2) + sum over residuals of
    mean(f^2)); `weights` gives the square roots of those factors, so that the loss is the sum of
    squares of the weighted residual vector that Levenberg-Marquardt works on.
    m, d: the physics, (n,) p.u. (None in identification, where they are trained).
    A time-marching window's problem has times since the window's start and each point's start
    state: start_u (n_u, 2, n) and start_f (n_f, 2, n), rows (delta rad, omega rad/s) of every
    machine at the window's start for that point's P1 (None for a single network).
    `residual_weights` (r,): a factor for each residual column (None: 1), see `residual_weights`."""

    t_u: np.ndarray
    p_u: np.ndarray
    targets: np.ndarray
    t_f: np.ndarray
    p_f: np.ndarray
    loss_scale: float
    m: tuple[float, ...] | None = None
    d: tuple[float, ...] | None = None
    start_u: np.ndarray | None = None
    start_f: np.ndarray | None = None
    residual_weights: tuple[float, ...] | None = None

    @property
    def weights(self) -> tuple[float, float | np.ndarray]:
        """(weight of each data residual, weight of each physics residual): a number, or with
        `residual_weights` one weight per residual column, (r,)."""
        w_f = float(np.sqrt(self.loss_scale / max(self.t_f.size, 1)))
        return (float(np.sqrt(self.loss_scale / max(self.t_u.size, 1))),
                w_f if self.residual_weights is None else w_f * np.asarray(self.residual_weights))

    def loss(self, data_residuals: np.ndarray, physics_residuals: np.ndarray) -> float:
        """The loss (numpy reference) from data residuals (n_u, k) and physics residuals (n_f, r)."""
        w_u, w_f = self.weights
        return float(w_u ** 2 * np.sum(data_residuals ** 2) + np.sum(w_f ** 2 * physics_residuals ** 2))

    @property
    def signature(self) -> tuple:
        """What a compiled training function depends on besides the arrays (which it takes as
        arguments): the sizes, the loss weights and whether points carry start states. Problems
        of one signature (the windows of a time-marching fit) share one compilation."""
        return (self.t_u.size, self.t_f.size, self.targets.shape[1], self.loss_scale, self.residual_weights,
                self.start_f is not None)


def residual_weights(config: PinnConfig, case: Case) -> tuple[float, ...] | None:
    """The factors of the swing residuals' columns (`Problem.residual_weights`) for
    `config.residual_units`: None for "power" (p.u., as `network.swing_residuals` gives them);
    1 / m_k for "acceleration", so that machine k's residual is in rad/s^2 (for two outputs the
    f_omega columns, already rad/s, keep 1)."""
    if config.residual_units == "power":
        return None
    inverse = tuple(1.0 / float(m) for m in case.m)
    return inverse if config.outputs == 1 else (1.0,) * case.n + inverse


def latin_hypercube(case_t: tuple[float, float], p_range: tuple[float, float], n: int, seed: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """n seeded Latin-hypercube points (t s, P1 p.u.) on [t_lo, t_hi] x [p_lo, p_hi]."""
    if n == 0:
        return np.zeros(0), np.zeros(0)
    unit = qmc.LatinHypercube(d=2, rng=np.random.default_rng(np.random.SeedSequence([seed, 0xC011]))).random(n)
    return (case_t[0] + (case_t[1] - case_t[0]) * unit[:, 0],
            p_range[0] + (p_range[1] - p_range[0]) * unit[:, 1])


def forward_problem(config: PinnConfig, case: Case) -> Problem:
    """The training set of `fit`, as in the paper: `n_u` points drawn without replacement from the
    t = 0 line and the P1 = p1_min / p1_max edges of the standard 201 x 100 grid, with delta from
    the tight reference `systems.reference.reference` (the paper used MATLAB ode45 there), and
    `n_f` Latin-hypercube collocation points on [0, t_final] x [p1_min, p1_max] to which the data
    points are appended (as in the paper's code)."""
    from systems.reference import reference

    t_grid, p_grid = standard_grid(case)
    edges = np.array([case.p1_min, case.p1_max])
    delta_edges, _ = reference(case, t_grid, edges)
    delta_start, _ = reference(case, [0.0], p_grid)
    t_cand = np.concatenate([np.zeros(p_grid.size), t_grid, t_grid])
    p_cand = np.concatenate([p_grid, np.full(t_grid.size, edges[0]), np.full(t_grid.size, edges[1])])
    d_cand = np.concatenate([delta_start[:, 0], delta_edges[0], delta_edges[1]])  # (candidates, n)
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xDA7A]))
    pick = np.sort(rng.choice(t_cand.size, size=min(config.n_u, t_cand.size), replace=False))
    t_f, p_f = latin_hypercube((0.0, case.t_final), (case.p1_min, case.p1_max), config.n_f, config.seed)
    return Problem(
        t_u=t_cand[pick], p_u=p_cand[pick], targets=d_cand[pick],
        t_f=np.concatenate([t_f, t_cand[pick]]), p_f=np.concatenate([p_f, p_cand[pick]]),
        loss_scale=config.loss_scale, m=case.m, d=case.d, residual_weights=residual_weights(config, case),
    )


def window_edges(t_final: float, window: float) -> np.ndarray:
    """The edges 0 = t_0 < t_1 < ... < t_W = t_final (s) of time-marching windows of `window` s:
    W = ceil(t_final / window) windows, the last one shorter when `window` does not divide t_final
    (a remainder below 1e-9 of a window is dropped rather than made a window of its own)."""
    count = max(1, int(np.ceil(t_final / window - 1e-9)))
    return np.append(window * np.arange(count, dtype=np.float64), float(t_final))


class PhaseEdges(NamedTuple):
    """The windows of a fault case's switched model (`PinnConfig.phases`): `on` (W_on + 1,) edges
    in t s from 0 to p1_max (the longest clearing time), `post` (W_post + 1,) edges in
    tau = t - t_c s from 0 to t_final - p1_min (the longest post-fault horizon), and `pieces`
    (K + 1,) the clearing times (s) from p1_min to p1_max that cut the post-fault phase into K
    chains of those windows, one per piece."""

    on: np.ndarray
    post: np.ndarray
    pieces: np.ndarray

    @property
    def count(self) -> int:
        """W_on + K W_post, the rows of the model's parameters (fault-on windows first)."""
        return self.on.size - 1 + (self.pieces.size - 1) * (self.post.size - 1)


def phase_edges(case: Case, window: float, pieces: int = 1) -> PhaseEdges:
    """The `PhaseEdges` of fault case `case` with windows of `window` s (`window_edges` of each
    phase's span) and `pieces` equal pieces of its clearing times."""
    return PhaseEdges(window_edges(case.p1_max, window), window_edges(case.t_final - case.p1_min, window),
                      np.linspace(case.p1_min, case.p1_max, pieces + 1))


def phase_problem(config: PinnConfig, case: Case, edges: PhaseEdges, phase: str, w: int, p_mid: float,
                  piece: int = 0) -> Problem:
    """The training set of window w of a fault case's `phase` ('on' or 'post'): `window_problem`'s
    collocation points over that phase's edges, times since the window's start; the scenario input
    over [p1_min, p1_max] for the post-fault phase (piece `piece`'s clearing times mapped onto it,
    `evaluator.SwitchedEvaluator.position`), the constant `p_mid` for the fault-on phase (whose
    trajectory does not depend on t_c). Seeds differ between phases and pieces."""
    if phase == "on":
        problem = window_problem(config, case, edges.on, w)
        return dataclasses.replace(problem, p_f=np.full_like(problem.p_f, p_mid))
    return window_problem(dataclasses.replace(config, seed=config.seed + 104729 * (1 + piece)), case, edges.post, w)


def window_problem(config: PinnConfig, case: Case, edges: np.ndarray, w: int) -> Problem:
    """The training set of time-marching window w, on [edges[w], edges[w + 1]], in times since the
    window's start (s): `n_u` data points at seeded uniform times of the window on the P1 = p1_min
    and p1_max edges, alternately (every machine's delta from `systems.reference.reference`: the
    paper's boundary data, window by window), and `n_f` collocation points, a Latin hypercube
    denser towards the window's ends and the P1 edges, to which the data points are appended. The start states (`Problem.start_u`, `start_f`) are left None:
    they come from the trained earlier windows (`PinnSolver`)."""
    from systems.reference import reference

    t0, length = float(edges[w]), float(edges[w + 1] - edges[w])
    # a Latin hypercube on the unit square, each coordinate mapped by u -> (1 - cos(pi u)) / 2
    # (Chebyshev-like density): denser at the window's end, whose state starts the next window, and
    # at the P1 edges, where a network has no points beyond to lean on. Measured (kundur4, 2 x 20,
    # 400 points, 250 LM iterations per window): uniform points left 1.7e-4 rms angle error at
    # P1 = p1_max against 6e-6 inside (COI rel. L2 1.4e-4); mapped, 1.5e-5 at the edge (3.5e-5).
    u_t, u_p = latin_hypercube((0.0, 1.0), (0.0, 1.0), config.n_f, config.seed + 7919 * w)
    t_f = length * (1.0 - np.cos(np.pi * u_t)) / 2.0
    p_f = case.p1_min + (case.p1_max - case.p1_min) * (1.0 - np.cos(np.pi * u_p)) / 2.0
    t_u, p_u = np.zeros(0), np.zeros(0)
    targets = np.zeros((0, case.n))
    if config.n_u:
        rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xDA7A, w]))
        t_u = np.sort(rng.uniform(0.0, length, config.n_u))
        on_max = np.arange(config.n_u) % 2 == 1
        p_u = np.where(on_max, case.p1_max, case.p1_min)
        delta_edges, _ = reference(case, t0 + t_u, np.array([case.p1_min, case.p1_max]))  # (2, n_u, n)
        targets = np.where(on_max[:, None], delta_edges[1], delta_edges[0])
    return Problem(
        t_u=t_u, p_u=p_u, targets=targets, t_f=np.concatenate([t_f, t_u]), p_f=np.concatenate([p_f, p_u]),
        loss_scale=config.loss_scale, m=case.m, d=case.d, residual_weights=residual_weights(config, case),
    )


def identification_p_range(case: Case, obs: Observations) -> tuple[float, float]:
    """The P1 range (p.u.) an identification network is normalised over: the case's domain and the
    observations' extent together."""
    return float(min(case.p1_min, obs.P1.min())), float(max(case.p1_max, obs.P1.max()))


def observations_within(config: PinnConfig, obs: Observations) -> Observations:
    """The observations identification uses: those at t <= `config.id_t_max` (all when None).
    ValueError when none is."""
    if config.id_t_max is None:
        return obs
    keep = obs.t <= config.id_t_max
    if not keep.any():
        raise ValueError(f"id_t_max={config.id_t_max:g} s: no observation at t <= {config.id_t_max:g} s "
                         f"(the earliest is at {obs.t.min():g} s)")
    return Observations(obs.t[keep], obs.P1[keep], obs.delta[keep],
                        None if obs.omega is None else obs.omega[keep])


def identification_problem(config: PinnConfig, case: Case, obs: Observations) -> Problem:
    """The training set of `identify`: the observations (`observations_within` the identification
    horizon; delta (n_s, n), and omega when given) as data (targets (n_s, n) or (n_s, 2n)), and
    as collocation points the observations plus `id_n_f` Latin-hypercube points on
    [0, id_t_max] (None: [0, max(t_final, t_obs)]) x the P1 range."""
    obs = observations_within(config, obs)
    p_range = identification_p_range(case, obs)
    horizon = config.id_t_max if config.id_t_max is not None else max(case.t_final, float(obs.t.max()))
    t_f, p_f = latin_hypercube((0.0, horizon), p_range, config.id_n_f, config.seed)
    targets = obs.delta if obs.omega is None else np.concatenate([obs.delta, obs.omega], axis=1)
    return Problem(
        t_u=obs.t.copy(), p_u=obs.P1.copy(), targets=targets,
        t_f=np.concatenate([t_f, obs.t]), p_f=np.concatenate([p_f, obs.P1]),
        loss_scale=config.loss_scale,
    )
