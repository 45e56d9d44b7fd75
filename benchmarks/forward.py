"""Forward problem on each forward case (`SETTINGS.cases`: smib-inference and the networks): warm
query latency of `solve` and accuracy on the paper's 100 x 201 grid, for every registered adapter
and config that the run measures on the case.

Models are prepared once per asv run in `setup_cache` (see `_common.train_and_score`); each
benchmark process loads them from the harness's model cache and answers its query once untimed
(JIT compilation, integrator build) before asv times it.
"""

from __future__ import annotations

from benchmarks._common import (
    COI,
    COI_SKIP_PARAMS,
    FORWARD_SKIP_PARAMS,
    PARAM_NAMES,
    PARAMS,
    SETUP_CACHE_TIMEOUT,
    cached_entry,
    train_and_score,
    warm_solver,
)


class _Trained:
    """Base of the forward benchmarks: one shared `setup_cache` (asv keys it by this function)."""

    params = PARAMS
    param_names = PARAM_NAMES
    skip_params = FORWARD_SKIP_PARAMS

    def setup_cache(self):
        return train_and_score()

    setup_cache.timeout = SETUP_CACHE_TIMEOUT


class _Query(_Trained):
    """Warm latency (s) of one `solve` call on a query of `harness.suites.latency.queries`, as the
    latency suite times it (delta and omega of every machine together), asv's repeats and
    statistics."""

    query = ""
    # a warm-up and asv's samples of the slowest query: scipy-rk45 tight answers a network's grid
    # in about a minute (wscc9, 2 busy cores)
    timeout = 600.0

    def setup(self, cache, case, solver, config):
        self.solver, self.t, self.P1 = warm_solver(cache, case, solver, config, self.query)


class SolveGrid(_Query):
    query = "grid"

    def time_solve_grid(self, cache, case, solver, config):
        """`solve` on the paper's grid: 201 times on [0, t_final] x 100 P1 values (the latency
        suite's "grid 100x201" query)."""
        self.solver.solve(self.t, self.P1)


class SolveSinglePoint(_Query):
    query = "single point"

    def time_solve_single_point(self, cache, case, solver, config):
        """`solve` at one time t1 = 10 s for the middle P1 (the latency suite's "single point
        t1=10 s" query, the paper's single-time-point comparison; within every case's horizon)."""
        self.solver.solve(self.t, self.P1)


class Omega(_Query):
    query = "one trajectory"

    def time_omega(self, cache, case, solver, config):
        """The cost of getting omega(t) on the grid's 201 times for one P1 (the middle one): the
        latency suite's "1 trajectories x 201 times" query. There is no omega-only API: `solve`
        returns delta and omega together, so this is one `solve` call on that query, of which omega
        is taken. An adapter with a cheaper way to omega would change what this measures."""
        return self.solver.solve(self.t, self.P1).omega


class Accuracy(_Trained):
    """Relative L2 error over the paper's 100 x 201 grid and every machine against the tight
    reference (DOP853, rtol = atol = 1e-12), from `harness.suites.accuracy.accuracy` in
    `setup_cache`."""

    def setup(self, cache, case, solver, config):
        self.entry = cached_entry(cache, case, solver, config)

    def track_rel_l2_delta(self, cache, case, solver, config):
        """||delta - delta_ref||_2 / ||delta_ref||_2 over the whole grid and every machine (the
        paper's measure)."""
        return self.entry["rel_l2_delta"]

    track_rel_l2_delta.unit = "relative L2"

    def track_rel_l2_omega(self, cache, case, solver, config):
        """||omega - omega_ref||_2 / ||omega_ref||_2 over the whole grid and every machine."""
        return self.entry["rel_l2_omega"]

    track_rel_l2_omega.unit = "relative L2"


class AccuracyCOI(_Trained):
    """The same relative L2 error of the angles relative to the centre of inertia (quantity
    `harness.suites.accuracy.COI_DELTA`), on the cases without an infinite bus only (skipped on the
    SMIB, whose angles are against the infinite bus): without one, the absolute angles drift
    together, and their error hides or inflates the swings."""

    skip_params = COI_SKIP_PARAMS

    def setup(self, cache, case, solver, config):
        self.entry = cached_entry(cache, case, solver, config, COI)

    def track_rel_l2_delta_coi(self, cache, case, solver, config):
        """||(delta - delta_COI) - (delta - delta_COI)_ref||_2 / ||(delta - delta_COI)_ref||_2 over
        the whole grid and every machine."""
        return self.entry["rel_l2_delta_coi"]

    track_rel_l2_delta_coi.unit = "relative L2"
