"""Identification of m and d from N_u scattered samples, over (m, d) pairs and noise levels."""

from __future__ import annotations

import numpy as np

from harness import metrics
from harness.cases import Case, Observations, standard_grid
from harness.reference import reference
from harness.runs import Settings
from solvers.base import AbstractSolver


def observations(case: Case, n_u: int = 100, noise: float = 0.0, seed: int = 0) -> Observations:
    """`n_u` distinct points drawn at random from the paper's 100 x 201 grid of `case`, delta from
    the tight reference, times (1 + noise * N(0, 1)) when `noise` > 0 (relative Gaussian, seeded)."""
    if noise < 0:
        raise ValueError(f"noise must be >= 0, got {noise!r}")
    t, P1 = standard_grid(case)
    delta, _ = reference(case, t, P1)
    rng = np.random.default_rng(seed)
    flat = rng.choice(delta.size, size=n_u, replace=False)
    i, j = np.unravel_index(flat, delta.shape)
    values = delta[i, j] * (1.0 + noise * rng.standard_normal(n_u)) if noise > 0 else delta[i, j]
    return Observations(t[j], P1[i], values)


def pair_observations(case: Case, settings: Settings, pair_index: int, noise: float) -> Observations:
    """The observations of pair `pair_index` of `settings.pairs` (the rest of `case` fixed) at a
    noise level: seed 1000 + pair index, so every adapter sees the same samples."""
    m, d = settings.pairs[pair_index]
    return observations(case.with_params(m, d), settings.n_u, noise, seed=1000 + pair_index)


def identification(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """For each (m, d) pair of `settings.pairs` (the rest of `case` fixed) and each noise level:
    estimate m and d from `settings.n_u` samples; relative errors and wall time (s)."""
    if solver.config in settings.skip_identify_configs:
        return [{"status": f"skipped: config {solver.config} not identified in the {settings.name} run "
                           "(--full runs it)"}]
    rows = []
    for pair_index, (m, d) in enumerate(settings.pairs):
        for noise in settings.noise_levels:
            obs = pair_observations(case, settings, pair_index, noise)
            est = solver.identify(obs)
            rows.append({
                "pair": pair_index, "m_true": m, "d_true": d, "noise": noise, "n_u": settings.n_u,
                "m_est": est.m, "d_est": est.d, "m_rel_error": metrics.rel_error(est.m, m),
                "d_rel_error": metrics.rel_error(est.d, d), "identify_s": est.seconds,
                "iterations": est.iterations, "success": est.success, "message": est.message,
            })
    return rows
