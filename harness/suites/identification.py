"""Identification of every machine's m and d from N_u scattered samples of all angles: on the SMIB
over the (m, d) pairs, the noise levels and, for the paper's own case, the paper's MATLAB ode45
data; on a multi-machine case, its own parameters at each noise level."""

from __future__ import annotations

import numpy as np

from harness.settings import Settings
from harness.suites._base import Suite
from solvers.base import AbstractSolver
from systems.cases import SMIB, SMIB_IDENTIFICATION, Case, Observations, standard_grid
from systems.reference import PAPER_DATA, REFERENCE_DATA, reference, seed_reference


def identification_case(case: Case) -> Case:
    """The case identification measures for a forward case: the paper's own identification case
    (m = 0.25, with the (m, d) pairs) for a SMIB case (`Case.kind`), the case itself otherwise."""
    return SMIB_IDENTIFICATION if case.kind == SMIB else case


def observations(case: Case, n_u: int = 100, noise: float = 0.0, seed: int = 0,
                 data: str = REFERENCE_DATA) -> Observations:
    """`n_u` distinct (t, P1) points drawn at random from the paper's 100 x 201 grid of `case`, each
    with the angles of every machine (delta (n_u, n)), from
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
    flat = rng.choice(delta.shape[0] * delta.shape[1], size=n_u, replace=False)
    i, j = np.unravel_index(flat, delta.shape[:2])
    values = delta[i, j]  # (n_u, n)
    # Drawn as (n, n_u) and transposed: for the SMIB (n = 1) the same draws as one a sample, so its
    # noisy data does not depend on the machine axis; one a machine and sample otherwise.
    if noise > 0:
        values = values * (1.0 + noise * rng.standard_normal(values.shape[::-1]).T)
    return Observations(t[j], P1[i], values)


def truths(case: Case, settings: Settings) -> list[tuple[np.ndarray, np.ndarray]]:
    """The (m (n,), d (n,)) p.u. to identify on `case`: the run's (m, d) pairs on a SMIB case (the
    paper's setting), the case's own parameters on a multi-machine one."""
    if case.kind == SMIB:
        return [(np.array([m]), np.array([d])) for m, d in settings.pairs]
    return [(np.array(case.m), np.array(case.d))]


def pair_observations(case: Case, settings: Settings, pair_index: int, noise: float,
                      data: str = REFERENCE_DATA, draw: int = 0) -> Observations:
    """The observations of truth `pair_index` of `truths` (the rest of `case` fixed) at a
    noise level, the `draw`-th draw of its noise: seed 1000 + pair index + 100000 x draw, so every
    adapter sees the same samples and noise."""
    m, d = truths(case, settings)[pair_index]
    return observations(case.with_params(m, d), settings.n_u, noise, seed=1000 + pair_index + 100_000 * draw,
                        data=data)


def _runs(case: Case, settings: Settings) -> list[tuple[int, float, str, int]]:
    """(truth index, noise, data, draw) of every identification: each truth at each noise level on
    the reference (a multi-machine case: `settings.network_noise_levels`), `settings.noise_draws`
    draws of the noise at a level above 0 (how often an interval holds the truth is measured over
    them), and noise-free on the paper's ode45 data for a pair the paper published data of."""
    runs = []
    noise_levels = settings.noise_levels if case.kind == SMIB else settings.network_noise_levels
    for pair_index, (m, d) in enumerate(truths(case, settings)):
        for noise in noise_levels:
            runs += [(pair_index, noise, REFERENCE_DATA, draw)
                     for draw in range(settings.noise_draws if noise > 0 else 1)]
        if seed_reference(case.with_params(m, d)) is not None:
            runs.append((pair_index, 0.0, PAPER_DATA, 0))
    return runs


def _per_machine(values: np.ndarray) -> float | list[float]:
    """A row's value of a per-machine quantity: a number for one machine, a list for several."""
    values = np.asarray(values, np.float64)
    return float(values[0]) if values.size == 1 else values.tolist()


def _columns(name: str, est: np.ndarray, se: np.ndarray, ci95: np.ndarray, truth: np.ndarray) -> dict:
    """The row's columns of one parameter (m or d): estimates, per-machine relative errors, their
    worst (`{name}_rel_error`) and mean, standard errors, intervals, whether every machine's truth
    lies in its interval (None when some interval is unknown: NaN; an unbounded one, (0, inf), holds
    it) and the worst relative half-width (inf for an unbounded interval)."""
    errors = np.abs(est - truth) / np.abs(truth)
    low, high = ci95[:, 0], ci95[:, 1]
    known = not bool(np.isnan(ci95).any())
    return {
        f"{name}_true": _per_machine(truth), f"{name}_est": _per_machine(est),
        f"{name}_rel_error": float(errors.max()), f"{name}_rel_error_mean": float(errors.mean()),
        f"{name}_rel_errors": _per_machine(errors), f"{name}_se": _per_machine(se),
        f"{name}_ci95_low": _per_machine(low), f"{name}_ci95_high": _per_machine(high),
        f"{name}_in_ci95": bool(((low <= truth) & (truth <= high)).all()) if known else None,
        f"{name}_rel_half_width": float(np.max((high - low) / 2 / est)) if known else float("nan"),
    }


def identification(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """For each truth of `truths` (the SMIB's (m, d) pairs, or a multi-machine case's own
    parameters), each noise level and each data source (see `_runs`): estimate every machine's m
    and d from `settings.n_u` samples of all angles; relative errors (per machine, their worst and
    mean), wall time (s), standard errors (p.u.), 95 % intervals (p.u., NaN when the adapter has
    none) and whether the true values lie in them (None when there is no interval). Per-machine
    columns hold a number for one machine and a list for several. Which configs identify on which
    cases is the planner's (`harness.run.plan`): it runs this suite only where the run identifies."""
    rows = []
    for pair_index, noise, data, draw in _runs(case, settings):
        m, d = truths(case, settings)[pair_index]
        obs = pair_observations(case, settings, pair_index, noise, data, draw)
        est = solver.identify(obs)
        rows.append({
            "pair": pair_index, "noise": noise, "data": data, "draw": draw, "n_u": settings.n_u,
            "machines": case.n,
            **_columns("m", est.m, est.m_se, est.m_ci95, m), **_columns("d", est.d, est.d_se, est.d_ci95, d),
            "identify_s": est.seconds, "iterations": est.iterations, "success": est.success,
            "message": est.message,
        })
    return rows


SUITE = Suite("identification", identification, needs_fit=False, own_case=identification_case, queries=False,
              identifies=True)
