"""The timing protocol of verdicts: interleaved samples, the ratio's bootstrap interval, the label."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy import stats

from harness.measure.paired import (
    CLASSICAL_FASTER,
    PINN_FASTER,
    RUN_TO_RUN,
    SAMPLE_S,
    TIE,
    TIE_FACTOR,
    calls_per_sample,
    interleaved,
    ratio_interval,
    verdict_label,
    warm_call_s,
)


def test_interleaved_alternates_the_two_calls_and_swaps_their_order_every_pair():
    order = []
    a, b = interleaved(lambda: order.append("a"), lambda: order.append("b"), pairs=4, calls_a=2, calls_b=1)
    assert len(a) == len(b) == 4 and all(s >= 0 for s in a + b)
    # one untimed call of each first, then a a b | b a a | a a b | b a a
    assert order == ["a", "b", "a", "a", "b", "b", "a", "a", "a", "a", "b", "b", "a", "a"]


def test_a_warm_call_is_timed_after_an_untimed_one():
    calls = []
    assert warm_call_s(lambda: calls.append(1), calls=3) >= 0 and len(calls) == 4


def test_a_call_over_the_limit_is_not_called_again():
    calls = []

    def slow():
        calls.append(1)
        time.sleep(0.02)

    assert warm_call_s(slow, calls=3, slow_s=0.001) >= 0.02 and len(calls) == 2  # slow: one timed call
    calls.clear()
    assert warm_call_s(slow, calls=3, limit_s=0.01) >= 0.02 and len(calls) == 1  # over the limit: none


def test_a_fast_call_is_timed_in_blocks_that_last_a_sample():
    assert calls_per_sample(1.0) == 1
    assert calls_per_sample(SAMPLE_S / 10) == 10
    assert calls_per_sample(0.0) == 1 and calls_per_sample(float("nan")) == 1


def test_the_interval_holds_the_ratio_of_medians_and_is_reproducible():
    rng = np.random.default_rng(1)
    pinn = 1e-3 * (1 + 0.05 * rng.standard_normal(8))
    rival = 3e-3 * (1 + 0.05 * rng.standard_normal(8))
    ratio, low, high = ratio_interval(pinn, rival, run_to_run=0, repeat=False)
    assert ratio == pytest.approx(np.median(rival) / np.median(pinn))
    assert low < ratio < high and 2.5 < low and high < 3.5
    # seeded: the same samples, the same interval
    assert ratio_interval(pinn, rival, run_to_run=0, repeat=False) == (ratio, low, high)


def test_the_run_to_run_spread_widens_each_side_on_the_log_scale_and_a_repeat_run_by_sqrt_2():
    rng = np.random.default_rng(1)
    pinn, rival = 1e-3 * (1 + 0.05 * rng.standard_normal(8)), 3e-3 * (1 + 0.05 * rng.standard_normal(8))
    ratio, low, high = ratio_interval(pinn, rival, run_to_run=0, repeat=False)
    z = stats.norm.ppf(0.975)
    over_runs = ratio_interval(pinn, rival, run_to_run=0.1, repeat=False)
    assert over_runs[0] == ratio
    assert np.log(ratio / over_runs[1]) == pytest.approx(np.hypot(np.log(ratio / low), 0.1 * z))
    assert np.log(over_runs[2] / ratio) == pytest.approx(np.hypot(np.log(high / ratio), 0.1 * z))
    repeat = ratio_interval(pinn, rival, run_to_run=0.1)
    assert repeat[0] == ratio
    assert np.log(ratio / repeat[1]) == pytest.approx(np.sqrt(2) * np.log(ratio / over_runs[1]))
    assert np.log(repeat[2] / ratio) == pytest.approx(np.sqrt(2) * np.log(over_runs[2] / ratio))
    assert ratio_interval(pinn, rival) == ratio_interval(pinn, rival, run_to_run=RUN_TO_RUN, repeat=True)


def test_a_repeat_run_s_ratio_falls_in_the_interval_95_percent_of_the_time():
    """Two runs of the same ratio, each with its own run-to-run shift of log-sd RUN_TO_RUN and its
    own sample noise: B's ratio lies inside A's repeat-run interval about 95 % of the time."""
    rng = np.random.default_rng(3)
    inside = 0
    trials = 200
    for _ in range(trials):
        shift_a, shift_b = RUN_TO_RUN * rng.standard_normal(2)
        runs = [(1e-3 * np.exp(0.03 * rng.standard_normal(8)), 2e-3 * np.exp(shift + 0.03 * rng.standard_normal(8)))
                for shift in (shift_a, shift_b)]
        _, low, high = ratio_interval(*runs[0], resamples=499)
        ratio_b = np.median(runs[1][1]) / np.median(runs[1][0])
        inside += low <= ratio_b <= high
    assert 0.9 <= inside / trials <= 0.99


def test_samples_without_spread_give_a_point_interval_and_bad_samples_are_refused():
    assert ratio_interval([1.0, 1.0], [2.0, 2.0], run_to_run=0) == (2.0, 2.0, 2.0)
    _, low, high = ratio_interval([1.0, 1.0], [2.0, 2.0])
    width = np.sqrt(2) * 1.959964 * RUN_TO_RUN
    assert (low, high) == pytest.approx((2 * np.exp(-width), 2 * np.exp(width)))
    with pytest.raises(ValueError, match="equal 1-D"):
        ratio_interval([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="positive"):
        ratio_interval([1.0, 0.0], [1.0, 1.0])


@pytest.mark.parametrize(("low", "high", "expected"), [
    (1.3, 2.0, PINN_FASTER), (0.3, 0.8, CLASSICAL_FASTER), (0.9, 1.5, TIE), (1.1, 1.4, TIE),
    (TIE_FACTOR, 2.0, TIE), (0.5, 1 / TIE_FACTOR, TIE),
])
def test_a_side_wins_only_when_the_whole_interval_is_beyond_the_tie_factor(low, high, expected):
    assert verdict_label(low, high) == expected
