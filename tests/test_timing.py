"""The timing of one call (`harness.measure.timing.time_call`): repeats, warm-up, a slow call timed once."""

from __future__ import annotations

import time

from harness.measure.timing import time_call


def test_time_call_counts_repeats():
    calls = []
    timing = time_call(lambda: calls.append(1), warmup=2, min_repeats=4, budget_s=0.0)
    assert timing.repeats == 4 and len(calls) == 6
    assert 0 <= timing.min_s <= timing.median_s


def test_a_slow_call_is_timed_once_but_a_slow_cold_start_is_not():
    calls = []

    def cold_then_fast(cold_s: float = 0.05):
        calls.append(1)
        if len(calls) == 1:
            time.sleep(cold_s)

    assert time_call(cold_then_fast, min_repeats=4, budget_s=0.0, slow_s=0.02).repeats == 4
    assert time_call(lambda: time.sleep(0.03), min_repeats=4, budget_s=0.0, slow_s=0.02).repeats == 1
