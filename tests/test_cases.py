"""Cases, observations, metrics and the reference: pure data and pure functions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from harness import metrics
from systems.cases import (
    IDENTIFICATION_PAIRS,
    SMIB_IDENTIFICATION,
    SMIB_INFERENCE,
    Observations,
    check_array,
    standard_grid,
)
from systems.reference import SEED_DIR, load_seed_reference, reference, seed_reference


def test_paper_cases():
    assert (SMIB_INFERENCE.m, SMIB_INFERENCE.d, SMIB_INFERENCE.b) == (0.4, 0.15, 0.2)
    assert (SMIB_IDENTIFICATION.m, SMIB_IDENTIFICATION.p1_min) == (0.25, 0.10)
    assert (SMIB_INFERENCE.delta0, SMIB_INFERENCE.omega0, SMIB_INFERENCE.t_final) == (0.1, 0.1, 20.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        SMIB_INFERENCE.m = 1.0  # type: ignore[misc]


def test_identification_pairs_are_ten_evenly_spaced_in_the_papers_box():
    m, d = np.array(IDENTIFICATION_PAIRS).T
    assert len(IDENTIFICATION_PAIRS) == 10
    assert (m.min(), m.max(), d.min(), d.max()) == (0.1, 0.4, 0.05, 0.15)
    np.testing.assert_allclose(np.diff(m), 0.3 / 9)
    np.testing.assert_allclose(np.diff(d), 0.1 / 9)


def test_standard_grid_is_the_papers():
    t, P1 = standard_grid(SMIB_INFERENCE)
    assert t.shape == (201,) and P1.shape == (100,)
    np.testing.assert_allclose(np.diff(t), 0.1)
    assert (P1[0], P1[-1]) == (0.08, 0.18)


@pytest.mark.parametrize("field,value", [("m", 0.0), ("m", -1.0), ("d", 0.0), ("t_final", -2.0),
                                         ("b", -0.1), ("m", float("nan")), ("p1_min", 1.0)])
def test_case_rejects_bad_parameters(field, value):
    with pytest.raises(ValueError, match=f"Case.{field}"):
        dataclasses.replace(SMIB_INFERENCE, **{field: value})


def test_observations_validation():
    with pytest.raises(ValueError, match="Observations.delta has length 2, Observations.t has length 3"):
        Observations([0, 1, 2], [0.1, 0.1, 0.1], [0.1, 0.2])
    with pytest.raises(ValueError, match="Observations.t must be >= 0"):
        Observations([-1.0, 1.0], [0.1, 0.1], [0.1, 0.2])
    with pytest.raises(ValueError, match="Observations.omega contains NaN"):
        Observations([0.0, 1.0], [0.1, 0.1], [0.1, 0.2], [0.0, np.nan])


finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6)


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=1, min_side=1, max_side=20), elements=finite))
def test_check_array_accepts_finite_1d_and_returns_float64(values):
    out = check_array("x", values)
    assert out.dtype == np.float64 and out.shape == values.shape
    np.testing.assert_array_equal(out, values)


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=1, min_side=1, max_side=20), elements=finite),
       st.integers(min_value=0, max_value=19), st.sampled_from([np.nan, np.inf, -np.inf]))
def test_check_array_rejects_any_non_finite_entry(values, where, bad):
    values = values.copy()
    values[where % values.size] = bad
    with pytest.raises(ValueError, match="x contains NaN or inf"):
        check_array("x", values)


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=3, min_side=1, max_side=4), elements=finite))
def test_check_array_rejects_wrong_dimensions(values):
    with pytest.raises(ValueError, match="x must be 1-D"):
        check_array("x", values)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(min_value=-1e3, max_value=-1e-9), min_size=1, max_size=5),
       st.lists(st.floats(min_value=0, max_value=1e3), max_size=5))
def test_observations_reject_negative_times(negative, positive):
    t = np.array(negative + positive)
    with pytest.raises(ValueError, match="Observations.t must be >= 0"):
        Observations(t, np.full(t.size, 0.1), np.zeros(t.size))


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 10), st.integers(1, 10))
def test_observations_reject_mismatched_lengths(n, k):
    if n == k:
        return
    with pytest.raises(ValueError, match="Observations.P1 has length"):
        Observations(np.zeros(n), np.zeros(k), np.zeros(n))


def test_metrics():
    ref = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert metrics.rel_l2(ref, ref) == 0.0
    assert metrics.rel_l2(ref * 1.01, ref) == pytest.approx(0.01)
    assert metrics.max_abs(ref + [[0, 0.5], [0, -2]], ref) == 2.0
    assert metrics.rel_error(0.2525, 0.25) == pytest.approx(0.01)
    np.testing.assert_allclose(metrics.rel_l2_per_row(ref[:1] * 1.1, ref[:1]), [0.1])
    with pytest.raises(ValueError, match="shapes differ"):
        metrics.rel_l2(ref, ref[0])


def test_reference_agrees_with_the_papers_ode45_data_to_their_accuracy():
    for case, filename in [(SMIB_INFERENCE, "swingEquation_inference.mat"),
                           (SMIB_IDENTIFICATION, "swingEquation_identification.mat")]:
        t, P1, delta = load_seed_reference(SEED_DIR / filename)
        np.testing.assert_allclose(t, np.linspace(0, 20, 201), atol=1e-12)
        np.testing.assert_allclose(P1, np.linspace(case.p1_min, case.p1_max, 100), atol=1e-12)
        ref_delta, _ = reference(case, t, P1)
        error = metrics.max_abs(ref_delta, delta)
        # ode45 at its default tolerances is off by ~1.2e-3 rad; a wrong model, unit or initial
        # condition would be off by orders of magnitude more
        assert 1e-4 < error < 1.5e-3
        assert seed_reference(case) is not None
    assert seed_reference(SMIB_INFERENCE.with_params(0.3, 0.1)) is None


def test_reference_is_cached_read_only_and_keeps_query_order():
    t = np.array([5.0, 1.0, 5.0])
    delta, _ = reference(SMIB_INFERENCE, t, [0.1])
    again, _ = reference(SMIB_INFERENCE, t, [0.1])
    assert again is delta and not delta.flags.writeable
    assert delta[0, 0] == delta[0, 2] != delta[0, 1]
    # energy-like sanity: delta'' = (P1 - d omega - b sin delta) / m at t = 0
    h = 1e-4
    d_plus, _ = reference(SMIB_INFERENCE, [h], [0.1])
    expected = 0.1 + 0.1 * h + 0.5 * h**2 * (0.1 - 0.15 * 0.1 - 0.2 * np.sin(0.1)) / 0.4
    assert d_plus[0, 0] == pytest.approx(expected, abs=1e-11)
