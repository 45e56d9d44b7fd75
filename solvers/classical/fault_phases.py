"""A fault case's trajectories from an integrator of one phase, for the Python-driven adapters:
the fault-on network from the equilibrium to each clearing time t_c, the post-fault network from
the state at t_c, no step across the switch (`systems.cases.Fault`).

The fault-on phase does not depend on t_c, so it is integrated once for every t_c of a query, to
the largest, with output at the query times before it and at every t_c (the integrator's dense
output); each post-fault trajectory then starts from its own state at its t_c, in the time since
t_c (the system is autonomous). A query at t = t_c answers the state at t_c.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from systems.cases import Case

__all__ = ["STACKED_CELLS", "PhaseIntegrator", "phases", "switched_states"]

# The most (clearing time, output time) pairs of one stacked post-fault call: its output is every
# t_c's state at the union of all their times since t_c, quadratic in the t_c (10,000 clearing times
# x 201 times in one call asked for 2e10 states, and make bench ran out of 24 GiB on CasADi's).
STACKED_CELLS = 2_000_000

# (phase, y0, times, T_c) -> states: `phase` a step case of one phase's network (`Case.phase`),
# y0 (n_b, 2n) the initial states [delta (rad), omega (rad/s)] at time 0 of n_b trajectories,
# times (n_out,) s, sorted, unique, >= 0; returns their states (n_b, n_out, 2n) at those times,
# every machine at P = p_m. T_c (n_b,) s: the clearing times the trajectories are for, to name in
# a SolveError.
PhaseIntegrator = Callable[[Case, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


@functools.lru_cache(maxsize=32)
def phases(case: Case) -> tuple[Case, Case]:
    """`case.phase("on")` and `case.phase("post")` of a fault case, built once (a phase validates
    every field again: ~0.6 ms on ieee39, measured, against a cached look-up's hash of the case)."""
    return case.phase("on"), case.phase("post")


def switched_states(integrate: PhaseIntegrator, case: Case, t: np.ndarray, T_c: np.ndarray,
                    stacked: bool) -> np.ndarray:
    """States (len(T_c), len(t), 2n), [delta (rad), omega (rad/s)] on the last axis, of fault case
    `case` at times t (s, >= 0, any order, repeats allowed) for each clearing time T_c (s, >= 0,
    repeats allowed), from `integrate` (`PhaseIntegrator`): one fault-on call, then the post-fault
    phase of every distinct t_c in one call at the union of their times since t_c (`stacked`: in
    chunks of at most sqrt(STACKED_CELLS / len(t)) clearing times, so that a call outputs at most
    ~STACKED_CELLS states) or one call per t_c at its own."""
    times, t_back = np.unique(t, return_inverse=True)
    clearing, c_back = np.unique(T_c, return_inverse=True)
    n_c = clearing.size
    on_times = np.union1d(times[times < clearing[-1]], clearing)
    y0 = np.array(case.delta0 + case.omega0)[None]
    on_phase, post = phases(case)
    on = integrate(on_phase, y0, on_times, clearing)[0]  # (n_on, 2n)
    before = times[None, :] < clearing[:, None]  # (n_c, n_t): in the fault-on phase
    states = np.empty((n_c, times.size, y0.shape[1]))
    rows, cols = np.nonzero(before)
    states[rows, cols] = on[np.searchsorted(on_times, times[cols])]
    at_clearing = on[np.searchsorted(on_times, clearing)]  # (n_c, 2n)
    if stacked:  # in chunks of clearing times: a call's output grows as (its t_c) x (their times since t_c)
        chunk = max(1, math.isqrt(STACKED_CELLS // max(1, times.size)))
        for lo in range(0, n_c, chunk):
            part = slice(lo, lo + chunk)
            rows, cols = np.nonzero(~before[part])
            since, back = np.unique(times[cols] - clearing[part][rows], return_inverse=True)
            if since.size:
                states[lo + rows, cols] = integrate(post, at_clearing[part], since, clearing[part])[rows, back]
    else:
        for c in range(n_c):
            cols = np.flatnonzero(~before[c])
            if cols.size:
                states[c, cols] = integrate(post, at_clearing[c:c + 1], times[cols] - clearing[c], clearing[c:c + 1])[0]
    return states[c_back][:, t_back]
