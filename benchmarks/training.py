"""Preparation cost: `fit()` of every registered adapter and config on each forward case that the
run measures it on, from a fresh adapter each call (asv re-runs setup before every timed call). For
an ODE solver that is building its integrator; for an adapter that trains (a PINN) it is compiling
and training with FIT_BUDGET: a fixed number of iterations (50, or 5 under `make asv-quick`).
The trained models of the other benchmarks are not these: see `_common.train_and_score`.
"""

from __future__ import annotations

from benchmarks._common import FORWARD_SKIP_PARAMS, PARAM_NAMES, PARAMS, case_for, fit_options, spec_for


class Fit:
    params = PARAMS
    param_names = PARAM_NAMES
    skip_params = FORWARD_SKIP_PARAMS
    number = 1  # one fit per sample, each on a fresh adapter
    warmup_time = 0  # no untimed training before the samples
    min_run_count = 1
    repeat = (1, 10, 10.0)  # one sample of a fit that takes 10 s or more, up to 10 of quicker ones
    rounds = 1
    timeout = 600.0

    def setup(self, case, solver, config):
        spec = spec_for(case, solver, config)
        self.solver = spec.make(case_for(case), **fit_options(spec))

    def time_fit(self, case, solver, config):
        """Wall time (s) of `fit()` of a fresh adapter (build, JIT, training with FIT_BUDGET)."""
        self.solver.fit()

    def peakmem_fit(self, case, solver, config):
        """Peak resident memory (bytes) of the benchmark process through one `fit()`, as asv
        measures peakmem: it includes the imports (numpy, scipy, casadi, torch, jax, pandapower),
        setup and the forward cases built at import."""
        self.solver.fit()
