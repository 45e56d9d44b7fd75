"""Paired, interleaved timing of two calls and the verdict it supports: the ratio of their medians,
its bootstrap 95 % interval and a label (one side faster, or a tie).

The protocol of every timing that enters a verdict (`harness.suites.verdict`): preparation and
compilation happen before (each call is made untimed first); the two calls are timed alternately
(A B A B ..., the order swapped every other pair) so that a change in the machine's load hits
both; a sample is the mean of `calls` back-to-back calls, `calls` chosen from the untimed call so
that a sample lasts about `SAMPLE_S` (a call of microseconds is not timed alone); the samples of a
verdict come from several rounds taken at different moments of the run.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

import numpy as np
from scipy import stats

__all__ = ["CLASSICAL_FASTER", "CONFIDENCE", "INTERVAL", "NOT_APPLICABLE", "NO_RIVAL", "PINN_FASTER", "RUN_TO_RUN", "SAMPLE_S", "TIE", "TIE_FACTOR",
           "calls_per_sample", "interleaved", "ratio_interval", "verdict_label", "warm_call_s"]

SAMPLE_S = 2e-3  # a sample lasts at least this long (s): fast calls are timed in blocks
CONFIDENCE = 0.95
# A side is called faster only when the whole 95 % interval of the ratio lies beyond this factor;
# otherwise the verdict is a tie (between two runs on this machine a median moves by up to ~1.2x).
TIE_FACTOR = 1.2
# The spread of a ratio from one run to the next on this machine beyond what one run's paired samples
# show: the standard deviation of log(ratio) between two runs of the same seeds with retrained models
# (0.104 between the bench and the verdict run, rounded up: `swingbench compare results results/verdicts`;
# docs/methods.md, "Intervals across runs").
RUN_TO_RUN = 0.11
# What a verdict's interval states: where the ratio of a repeat run falls (a prediction interval), so
# that "faster" means a second run would say so too; each row records it (`interval`), and rows under
# another rule are restated from their samples (`harness.report.verdicts.restated`).
INTERVAL = f"repeat run, run-to-run {RUN_TO_RUN:g}"
PINN_FASTER, CLASSICAL_FASTER, TIE = "PINN faster", "classical faster", "tie"
NO_RIVAL = "no rival"  # no sweep point as accurate as the PINN, or every such point out of time
NOT_APPLICABLE = "not applicable"  # no rival of that kind is made for the case (a surrogate of step cases on a fault)


def calls_per_sample(call_s: float) -> int:
    """How many back-to-back calls make one sample of a call that takes `call_s` seconds warm:
    enough to last `SAMPLE_S`, at least 1."""
    if not math.isfinite(call_s) or call_s <= 0:
        return 1
    return max(1, math.ceil(SAMPLE_S / call_s))


def warm_call_s(fn: Callable[[], Any], calls: int = 3, slow_s: float = math.inf,
                limit_s: float = math.inf) -> float:
    """Seconds of one warm call of `fn`: the least of `calls` timed calls after one untimed call
    (compilation, caches and lazy set-up paid by it); of one timed call when the untimed one took
    longer than `slow_s`; the untimed call's own seconds, and no timed call, when it took longer
    than `limit_s` (a caller that refuses calls over `limit_s` need not pay for a second one)."""
    start = time.perf_counter()
    fn()
    first = time.perf_counter() - start
    if first > limit_s:
        return first
    if first > slow_s:
        calls = 1
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _sample(fn: Callable[[], Any], calls: int,
            context: Callable[[], AbstractContextManager] = contextlib.nullcontext) -> float:
    with context():  # entered and left outside the timed calls
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        return (time.perf_counter() - start) / calls


def interleaved(a: Callable[[], Any], b: Callable[[], Any], pairs: int, calls_a: int = 1, calls_b: int = 1,
                context_b: Callable[[], AbstractContextManager] = contextlib.nullcontext,
                ) -> tuple[list[float], list[float]]:
    """`pairs` samples (s per call) of each of `a` and `b`, taken alternately: a b, b a, a b, ...
    (the order swapped every pair, so neither always runs right after the other), after one
    untimed call of each (the caches warm again for these two after whatever ran before). Each
    sample is the mean over `calls_a` (`calls_b`) calls; `b`'s are made inside `context_b()`,
    entered untimed (an adapter's own BLAS thread count, `harness.measure.timing.blas_threads`)."""
    a()
    with context_b():
        b()
    samples_a, samples_b = [], []
    for i in range(pairs):
        if i % 2 == 0:
            samples_a.append(_sample(a, calls_a))
            samples_b.append(_sample(b, calls_b, context_b))
        else:
            samples_b.append(_sample(b, calls_b, context_b))
            samples_a.append(_sample(a, calls_a))
    return samples_a, samples_b


def _median_ratio(rival: np.ndarray, pinn: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.median(rival, axis=axis) / np.median(pinn, axis=axis)


def ratio_interval(pinn_s, rival_s, seed: int = 0, resamples: int = 4999,
                   run_to_run: float = RUN_TO_RUN, repeat: bool = True) -> tuple[float, float, float]:
    """(ratio, low, high): the rival's median time over the PINN's (> 1: the PINN is faster) and
    its `CONFIDENCE` interval. Two parts, added on the log scale: the percentile bootstrap over the
    paired samples (`scipy.stats.bootstrap`, paired: a resample keeps the two samples of one moment
    together; seeded, so the same samples give the same interval), the spread within one run; and a
    normal term of standard deviation `run_to_run` (of log(ratio)), the spread between runs that
    one run's samples cannot show (`RUN_TO_RUN`). Each side's half-width is sqrt(b**2 + (z s)**2),
    b that side's bootstrap half-width, z the normal quantile: an interval for the ratio this
    machine gives over runs. With `repeat` (`INTERVAL`) each half-width is sqrt(2) times that: the
    interval of a repeat run's ratio, whose log differs from this run's by its own within-run and
    run-to-run errors as well (twice the variance, the repeat's within-run spread taken as this
    run's). Needs >= 2 pairs of positive times."""
    pinn, rival = np.asarray(pinn_s, float), np.asarray(rival_s, float)
    if pinn.shape != rival.shape or pinn.ndim != 1 or pinn.size < 2:
        raise ValueError(f"ratio_interval needs two equal 1-D samples of >= 2 times, got {pinn.shape}, {rival.shape}")
    if not (np.all(pinn > 0) and np.all(rival > 0)):
        raise ValueError("ratio_interval needs positive times")
    ratio = float(_median_ratio(rival, pinn))
    low = high = ratio
    if np.ptp(pinn) > 0 or np.ptp(rival) > 0:  # without spread the bootstrap has nothing to resample
        res = stats.bootstrap((rival, pinn), _median_ratio, paired=True, vectorized=True, n_resamples=resamples,
                              confidence_level=CONFIDENCE, method="percentile", rng=np.random.default_rng(seed))
        low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    between = float(stats.norm.ppf(0.5 + CONFIDENCE / 2)) * run_to_run
    widen = math.sqrt(2.0) if repeat else 1.0
    below, above = (widen * math.hypot(math.log(x), between) for x in (ratio / low, high / ratio))
    return ratio, ratio * math.exp(-below), ratio * math.exp(above)


def verdict_label(low: float, high: float) -> str:
    """`PINN_FASTER` when the whole interval of the ratio (rival / PINN) lies above `TIE_FACTOR`,
    `CLASSICAL_FASTER` when it lies below 1 / `TIE_FACTOR`, else `TIE`."""
    if low > TIE_FACTOR:
        return PINN_FASTER
    if high < 1.0 / TIE_FACTOR:
        return CLASSICAL_FASTER
    return TIE
