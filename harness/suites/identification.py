"""Identification of m and d from N_u scattered samples, over (m, d) pairs, noise levels and, for the
paper's own case, the paper's MATLAB ode45 data."""

from __future__ import annotations

import numpy as np

from harness import metrics
from systems.cases import Case, Observations, standard_grid
from systems.reference import PAPER_DATA, REFERENCE_DATA, reference, seed_reference
from harness.runs import Settings
from solvers.base import AbstractSolver


def observations(case: Case, n_u: int = 100, noise: float = 0.0, seed: int = 0,
                 data: str = REFERENCE_DATA) -> Observations:
    """`n_u` distinct points drawn at random from the paper's 100 x 201 grid of `case`, delta from
    the tight reference (`data="reference"`) or from the paper's ode45 data of the case
    (`data="paper ode45"`, which the paper published for its two cases only), times
    (1 + noise * N(0, 1)) when `noise` > 0 (relative Gaussian, seeded). The same `seed` picks the
    same grid points from either data."""
    if noise < 0:
        raise ValueError(f"noise must be >= 0, got {noise!r}")
    if data == REFERENCE_DATA:
        t, P1 = standard_grid(case)
        delta, _ = reference(case, t, P1)
    elif data == PAPER_DATA:
        published = seed_reference(case)
        if published is None:
            raise ValueError(f"data {PAPER_DATA!r}: the paper published no data for case {case.name!r}")
        t, P1, delta = published
    else:
        raise ValueError(f"data must be {REFERENCE_DATA!r} or {PAPER_DATA!r}, got {data!r}")
    rng = np.random.default_rng(seed)
    flat = rng.choice(delta.size, size=n_u, replace=False)
    i, j = np.unravel_index(flat, delta.shape)
    values = delta[i, j] * (1.0 + noise * rng.standard_normal(n_u)) if noise > 0 else delta[i, j]
    return Observations(t[j], P1[i], values)


def pair_observations(case: Case, settings: Settings, pair_index: int, noise: float,
                      data: str = REFERENCE_DATA) -> Observations:
    """The observations of pair `pair_index` of `settings.pairs` (the rest of `case` fixed) at a
    noise level: seed 1000 + pair index, so every adapter sees the same samples."""
    m, d = settings.pairs[pair_index]
    return observations(case.with_params(m, d), settings.n_u, noise, seed=1000 + pair_index, data=data)


def _runs(case: Case, settings: Settings) -> list[tuple[int, float, str]]:
    """(pair index, noise, data) of every identification: each pair at each noise level on the
    reference, and noise-free on the paper's ode45 data for a pair the paper published data of."""
    runs = []
    for pair_index, (m, d) in enumerate(settings.pairs):
        runs += [(pair_index, noise, REFERENCE_DATA) for noise in settings.noise_levels]
        if seed_reference(case.with_params(m, d)) is not None:
            runs.append((pair_index, 0.0, PAPER_DATA))
    return runs


def _interval(name: str, ci95: tuple[float, float], truth: float) -> dict:
    low, high = ci95
    known = bool(np.isfinite([low, high]).all())
    return {f"{name}_ci95_low": low, f"{name}_ci95_high": high,
            f"{name}_in_ci95": bool(low <= truth <= high) if known else None}


def identification(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """For each (m, d) pair of `settings.pairs` (the rest of `case` fixed), each noise level and
    each data source (see `_runs`): estimate m and d from `settings.n_u` samples; relative errors,
    wall time (s), standard errors (p.u.), 95 % intervals (p.u., NaN when the adapter has none) and
    whether the true value lies in its interval (None when there is no interval)."""
    if solver.config in settings.skip_identify_configs:
        return [{"status": f"skipped: config {solver.config} not identified in the {settings.name} run "
                           "(--full runs it)"}]
    rows = []
    for pair_index, noise, data in _runs(case, settings):
        m, d = settings.pairs[pair_index]
        obs = pair_observations(case, settings, pair_index, noise, data)
        est = solver.identify(obs)
        rows.append({
            "pair": pair_index, "m_true": m, "d_true": d, "noise": noise, "data": data, "n_u": settings.n_u,
            "m_est": est.m, "d_est": est.d, "m_rel_error": metrics.rel_error(est.m, m),
            "d_rel_error": metrics.rel_error(est.d, d), "identify_s": est.seconds,
            "iterations": est.iterations, "success": est.success, "message": est.message,
            "m_se": est.m_se, "d_se": est.d_se, **_interval("m", est.m_ci95, m), **_interval("d", est.d_ci95, d),
        })
    return rows
