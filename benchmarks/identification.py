"""Identification of inertia m and damping d on the identification case (smib-identification), from
the identification suite's observations: N_u = 100 noise-free samples of delta for the (m, d) pair
of the harness's quick run."""

from __future__ import annotations

from benchmarks._common import (
    IDENTIFICATION_CASE,
    PARAM_NAMES,
    PARAMS,
    SETUP_CACHE_TIMEOUT,
    SKIP_PARAMS,
    cached_entry,
    identification_observations,
    identify_all,
    spec_for,
)

_READY: dict = {}


class Identify:
    params = PARAMS
    param_names = PARAM_NAMES
    skip_params = SKIP_PARAMS
    number = 1
    warmup_time = 0
    min_run_count = 1
    repeat = (1, 5, 10.0)  # one sample of an identification that takes 10 s or more, up to 5
    rounds = 1
    timeout = 600.0

    def setup(self, solver, config):
        spec = spec_for(solver, config)
        if (solver, config) not in _READY:
            adapter = spec.make(IDENTIFICATION_CASE)
            obs = identification_observations()
            adapter.identify(obs)  # warm-up of every adapter alike: JIT, integrators, caches
            _READY[(solver, config)] = (adapter, obs)
        self.solver, self.obs = _READY[(solver, config)]

    def time_identify(self, solver, config):
        """Wall time (s) of a warm `identify` on the identification suite's first observations (pair 0
        of the quick run's pairs, no noise, 100 samples): every adapter identifies once untimed first
        (compilation, caches); for an adapter that trains, each call is a training of SETTINGS'
        iterations (400, 20 under `make asv-quick`)."""
        self.solver.identify(self.obs)


class _Identified:
    params = PARAMS
    param_names = PARAM_NAMES
    skip_params = SKIP_PARAMS

    def setup_cache(self):
        return identify_all()

    setup_cache.timeout = SETUP_CACHE_TIMEOUT


class IdentifyError(_Identified):
    """Relative errors |estimate - truth| / truth of m and d from `harness.suites.identification`
    (the worst over SETTINGS' pairs and noise levels: one pair, no noise), run in `setup_cache`."""

    def setup(self, cache, solver, config):
        self.entry = cached_entry(cache, solver, config)

    def track_identify_error_m(self, cache, solver, config):
        """Relative error of the identified inertia m."""
        return self.entry["m_rel_error"]

    track_identify_error_m.unit = "relative error"

    def track_identify_error_d(self, cache, solver, config):
        """Relative error of the identified damping d."""
        return self.entry["d_rel_error"]

    track_identify_error_d.unit = "relative error"
