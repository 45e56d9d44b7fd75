"""Identification of every machine's inertia m and damping d on each forward case's identification
case (`harness.suites.identification_case`: the SMIB's smib-identification with the (m, d) pair of
the harness's quick run; a network itself, with its own parameters as the truth), from the
identification suite's observations: N_u = 100 noise-free samples of every machine's angle."""

from __future__ import annotations

from benchmarks._common import (
    IDENTIFICATION,
    IDENTIFICATION_SKIP_PARAMS,
    PARAM_NAMES,
    PARAMS,
    SETUP_CACHE_TIMEOUT,
    cached_entry,
    cached_observations,
    case_for,
    identify_all,
    spec_for,
)

_READY: dict = {}


class _Identified:
    """Base of the identification benchmarks: one shared `setup_cache` (asv keys it by this
    function) with the observations and the identification suite's results."""

    params = PARAMS
    param_names = PARAM_NAMES
    skip_params = IDENTIFICATION_SKIP_PARAMS

    def setup_cache(self):
        return identify_all()

    setup_cache.timeout = SETUP_CACHE_TIMEOUT


class Identify(_Identified):
    number = 1
    warmup_time = 0
    min_run_count = 1
    repeat = (1, 5, 10.0)  # one sample of an identification that takes 10 s or more, up to 5
    rounds = 1
    timeout = 600.0

    def setup(self, cache, case, solver, config):
        spec = spec_for(case, solver, config, IDENTIFICATION)
        key = (case, solver, config)
        if key not in _READY:
            adapter = spec.make(IDENTIFICATION.case_of(case_for(case)))
            obs = cached_observations(cache, case)
            adapter.identify(obs)  # warm-up of every adapter alike: JIT, integrators, caches
            _READY[key] = (adapter, obs)
        self.solver, self.obs = _READY[key]

    def time_identify(self, cache, case, solver, config):
        """Wall time (s) of a warm `identify` on the identification suite's first observations of
        the case's identification case (SMIB: pair 0 of the quick run's pairs; a network: its own
        parameters; no noise, 100 samples of every angle): every adapter identifies once untimed
        first (compilation, caches); for an adapter that trains, each call is a training of
        SETTINGS' iterations (400, 20 under `make asv-quick`)."""
        self.solver.identify(self.obs)


class IdentifyError(_Identified):
    """Relative errors |estimate - truth| / truth of m and d from `harness.suites.identification`,
    the worst over the machines and over SETTINGS' truths and noise levels (the SMIB: one pair; a
    network: its own parameters; no noise), run in `setup_cache`."""

    def setup(self, cache, case, solver, config):
        self.entry = cached_entry(cache, case, solver, config, IDENTIFICATION)

    def track_identify_error_m(self, cache, case, solver, config):
        """Relative error of the identified inertia m (the worst machine)."""
        return self.entry["m_rel_error"]

    track_identify_error_m.unit = "relative error"

    def track_identify_error_d(self, cache, case, solver, config):
        """Relative error of the identified damping d (the worst machine)."""
        return self.entry["d_rel_error"]

    track_identify_error_d.unit = "relative error"
