"""Cases, observations, metrics and the reference: pure data and pure functions."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import THREE_MACHINES
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import systems.cases
from harness.measure import metrics
from systems.cases import (
    CASES,
    IDENTIFICATION_PAIRS,
    SMIB_IDENTIFICATION,
    SMIB_INFERENCE,
    Case,
    Observations,
    check_array,
    register_case,
    smib_case,
    standard_grid,
)
from systems.model import center_of_inertia, coupling, electrical_power, relative_angles
from systems.reference import SEED_DIR, load_seed_reference, reference, seed_reference

# Two lossless machines, no infinite bus, equal d/m = 0.5 1/s, generator 2 a motor load (p_m < 0).
TWO_MACHINES = Case(
    name="two-machines", m=(0.4, 0.2), d=(0.2, 0.1), delta0=(0.3, 0.0), omega0=(0.0, 0.05),
    p_m=(0.4, -0.4), E=(1.05, 1.0), G=((0.0, 0.0), (0.0, 0.0)), B=((-1.2, 1.2), (1.2, -1.2)),
    g_inf=(0.0, 0.0), b_inf=(0.0, 0.0), t_final=10.0, p1_min=0.2, p1_max=0.6,
    m_box=((0.1, 1.6), (0.05, 0.8)), d_box=((0.05, 0.8), (0.025, 0.4)),
)


def test_paper_cases_are_one_machine_against_an_infinite_bus():
    assert (SMIB_INFERENCE.m, SMIB_INFERENCE.d, SMIB_INFERENCE.b_inf) == ((0.4,), (0.15,), (0.2,))
    assert (SMIB_IDENTIFICATION.m, SMIB_IDENTIFICATION.p1_min) == ((0.25,), 0.10)
    assert (SMIB_INFERENCE.delta0, SMIB_INFERENCE.omega0, SMIB_INFERENCE.t_final) == ((0.1,), (0.1,), 20.0)
    assert SMIB_INFERENCE.n == 1 and SMIB_INFERENCE.has_infinite_bus
    assert SMIB_INFERENCE.G == SMIB_INFERENCE.B == ((0.0,),) and SMIB_INFERENCE.E == (1.0,)
    with pytest.raises(dataclasses.FrozenInstanceError):
        SMIB_INFERENCE.m = (1.0,)  # type: ignore[misc]


def test_a_case_is_one_registered_builder_built_on_first_use(monkeypatch):
    monkeypatch.setattr(CASES, "_builders", dict(CASES._builders))  # the test's registrations go after it
    monkeypatch.setattr(CASES, "_built", dict(CASES._built))
    calls = []

    @register_case("two-machines")
    def two_machines() -> Case:
        calls.append(1)
        return TWO_MACHINES

    assert "two-machines" in CASES and list(CASES)[-1] == "two-machines" and not calls  # named, not built
    assert CASES["two-machines"] is CASES["two-machines"] is TWO_MACHINES and calls == [1]
    with pytest.raises(ValueError, match="registered twice"):
        register_case("two-machines")(two_machines)
    with pytest.raises(KeyError, match="known: smib-inference, smib-identification, wscc9"):
        CASES["no-such-case"]
    register_case("misnamed")(lambda: TWO_MACHINES)
    with pytest.raises(ValueError, match="returned a case named 'two-machines'"):
        CASES["misnamed"]


def test_the_case_registry_imports_none_of_the_builders():
    """The builders import `systems.cases` to register; it imports nothing of the project."""
    tree = ast.parse(Path(systems.cases.__file__).read_text())
    imported = [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
    imported += [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names]
    assert not [name for name in imported if name.split(".")[0] in ("systems", "solvers", "harness")]


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


@pytest.mark.parametrize("field,value", [("m", (0.0,)), ("m", (-1.0,)), ("d", (0.0,)), ("t_final", -2.0),
                                         ("E", (0.0,)), ("m", (float("nan"),)), ("p1_min", 1.0),
                                         ("d", (0.1, 0.2)), ("G", ((0.0, 1.0),)), ("B", [[0.0, 1.0], [2.0, 0.0]]),
                                         ("m_box", ((0.5, 0.1),)), ("p_m", ("x",))])
def test_case_rejects_bad_parameters(field, value):
    case = SMIB_INFERENCE if field != "B" else TWO_MACHINES
    with pytest.raises(ValueError, match=f"Case.{field}"):
        dataclasses.replace(case, **{field: value})


@pytest.mark.parametrize("field,value", [("g_inf", (True, 0.0)), ("b_inf", [0.0, np.True_]), ("m", (0.4, True)),
                                         ("t_final", True), ("p1_max", np.True_), ("p1_min", "0.1"),
                                         ("m_box", ((0.02, True),)), ("delta0", ["0.1"])])
def test_case_refuses_booleans_and_strings_inside_its_fields(field, value):
    case = TWO_MACHINES if field in ("m", "g_inf", "b_inf") else SMIB_INFERENCE
    with pytest.raises(ValueError, match=f"^Case.{field} must be"):
        dataclasses.replace(case, **{field: value})


@pytest.mark.parametrize("kwargs,message", [
    ({"m": 0.4, "d": "0.5"}, "with_params: d must be numeric"),
    ({"m": [0.4, True, 0.3], "d": 0.1}, "with_params: m must be numeric.*booleans"),
    ({"m": [0.4, 0.3], "d": 0.1}, "with_params: m has 2 entries for 3 machine"),
    ({"m": 0.4, "d": [0.1, 0.1, 0.1, 0.1]}, "with_params: d has 4 entries for 3 machine"),
    ({"m": 0.4, "d": -0.1}, "with_params: d must be > 0"),
])
def test_with_params_refuses_what_is_no_vector_of_the_case(kwargs, message):
    with pytest.raises(ValueError, match=message):
        THREE_MACHINES.with_params(**kwargs)
    assert THREE_MACHINES.with_params(0.3, [0.1, 0.2, 0.3]).d == (0.1, 0.2, 0.3)


def test_observations_refuse_booleans_inside_lists():
    with pytest.raises(ValueError, match="^Observations.t must be numeric.*booleans"):
        Observations([0.0, True, 2.0], [0.1] * 3, [[0.1]] * 3)
    with pytest.raises(ValueError, match="^Observations.delta must be numeric.*booleans"):
        Observations([0.0, 1.0], [0.1] * 2, [[0.1], [True]])


def test_p1_range_must_be_ordered():
    with pytest.raises(ValueError, match="Case.p1_min must be <= p1_max"):
        dataclasses.replace(TWO_MACHINES, p1_min=0.5, p1_max=0.4)


def test_powers_drive_generator_1_with_p1_and_the_others_with_their_operating_power():
    P = TWO_MACHINES.powers(np.array([0.3, 0.5]))
    np.testing.assert_array_equal(P, [[0.3, -0.4], [0.5, -0.4]])


def test_electrical_power_matrix_form_equals_the_double_sum():
    """P_e,k = sum_j E_k E_j (G_kj cos(d_k - d_j) + B_kj sin(d_k - d_j)) + the infinite bus, written
    out term by term, against the matrix form every backend uses."""
    rng = np.random.default_rng(3)
    n = 4
    G = rng.uniform(0, 0.3, (n, n))
    B = rng.uniform(0.5, 2, (n, n))
    case = Case(
        name="random", m=np.ones(n), d=np.ones(n), delta0=np.zeros(n), omega0=np.zeros(n),
        p_m=np.zeros(n), E=rng.uniform(0.9, 1.1, n), G=G + G.T, B=B + B.T, g_inf=rng.uniform(0, 0.1, n),
        b_inf=rng.uniform(0, 1, n), t_final=1.0, p1_min=0.0, p1_max=1.0, m_box=[(0.1, 10)] * n,
        d_box=[(0.1, 10)] * n)
    delta = rng.uniform(-1, 1, (5, n))
    E, G, B = np.array(case.E), np.array(case.G), np.array(case.B)
    expected = np.zeros_like(delta)
    for k in range(n):
        for j in range(n):
            diff = delta[:, k] - delta[:, j]
            expected[:, k] += E[k] * E[j] * (G[k, j] * np.cos(diff) + B[k, j] * np.sin(diff))
        expected[:, k] += E[k] * (case.g_inf[k] * np.cos(delta[:, k]) + case.b_inf[k] * np.sin(delta[:, k]))
    np.testing.assert_allclose(electrical_power(coupling(case), delta), expected, rtol=1e-13, atol=1e-13)


def test_two_machines_with_equal_damping_ratio_reduce_to_one_smib_equation():
    """Lossless, no infinite bus, d_1/m_1 = d_2/m_2 = a: the angle difference x = delta_1 - delta_2
    obeys m x'' + d x' + B12 E1 E2 sin(x) = P with m = m_1 m_2 / (m_1 + m_2), d = a m and
    P = m (P_1/m_1 - P_2/m_2): the paper's SMIB equation, against the reference of both."""
    two = TWO_MACHINES
    m1, m2 = two.m
    m = m1 * m2 / (m1 + m2)
    a = two.d[0] / m1
    P1 = np.array([0.3, 0.5])
    b = two.B[0][1] * two.E[0] * two.E[1]
    t = np.linspace(0.0, two.t_final, 101)
    delta, omega = reference(two, t, P1)
    for i, p1 in enumerate(P1):
        p = m * (p1 / m1 - two.p_m[1] / m2)
        smib = smib_case("reduced", m=m, d=a * m, b=b, delta0=two.delta0[0] - two.delta0[1],
                         omega0=two.omega0[0] - two.omega0[1], t_final=two.t_final, p1_min=p, p1_max=p)
        x, x_dot = reference(smib, t, [p])
        np.testing.assert_allclose(delta[i, :, 0] - delta[i, :, 1], x[0, :, 0], atol=1e-9)
        np.testing.assert_allclose(omega[i, :, 0] - omega[i, :, 1], x_dot[0, :, 0], atol=1e-9)


def test_relative_angles_remove_the_common_drift_only_without_an_infinite_bus():
    delta = np.array([[[0.1, 0.3]], [[1.1, 1.3]]])  # (2, 1, 2): the second is the first + 1 rad
    rel = relative_angles(TWO_MACHINES, delta)
    np.testing.assert_allclose(rel[0], rel[1], atol=1e-15)
    np.testing.assert_allclose(center_of_inertia(TWO_MACHINES, delta[0]), (0.4 * 0.1 + 0.2 * 0.3) / 0.6)
    np.testing.assert_array_equal(relative_angles(SMIB_INFERENCE, delta[..., :1]), delta[..., :1])


def test_observations_validation():
    with pytest.raises(ValueError, match="Observations.delta has 2 samples, Observations.t has 3"):
        Observations([0, 1, 2], [0.1, 0.1, 0.1], [[0.1], [0.2]])
    with pytest.raises(ValueError, match="Observations.t must be >= 0"):
        Observations([-1.0, 1.0], [0.1, 0.1], [[0.1], [0.2]])
    with pytest.raises(ValueError, match="Observations.omega contains NaN"):
        Observations([0.0, 1.0], [0.1, 0.1], [[0.1], [0.2]], [[0.0], [np.nan]])
    with pytest.raises(ValueError, match="Observations.delta must be 2-D"):
        Observations([0.0, 1.0], [0.1, 0.1], [0.1, 0.2])
    with pytest.raises(ValueError, match="Observations.omega has shape"):
        Observations([0.0, 1.0], [0.1, 0.1], [[0.1], [0.2]], [[0.0, 1.0], [0.0, 1.0]])
    obs = Observations([0.0, 1.0], [0.1, 0.1], [[0.1], [0.2]])
    with pytest.raises(ValueError, match="obs.delta has 1 machine column"):
        obs.check_machines(TWO_MACHINES)


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
        Observations(t, np.full(t.size, 0.1), np.zeros((t.size, 1)))


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 10), st.integers(1, 10))
def test_observations_reject_mismatched_lengths(n, k):
    if n == k:
        return
    with pytest.raises(ValueError, match="Observations.P1 has"):
        Observations(np.zeros(n), np.zeros(k), np.zeros((n, 1)))


def test_metrics():
    ref = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert metrics.rel_l2(ref, ref) == 0.0
    assert metrics.rel_l2(ref * 1.01, ref) == pytest.approx(0.01)
    assert metrics.max_abs(ref + [[0, 0.5], [0, -2]], ref) == 2.0
    assert metrics.rel_error(0.2525, 0.25) == pytest.approx(0.01)
    np.testing.assert_allclose(metrics.rel_l2_per_row(ref[:1] * 1.1, ref[:1]), [0.1])
    with pytest.raises(ValueError, match="shapes differ"):
        metrics.rel_l2(ref, ref[0])


@pytest.mark.slow
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
    assert delta.shape == (100, 201, 1)


def test_reference_is_cached_read_only_and_keeps_query_order():
    t = np.array([5.0, 1.0, 5.0])
    delta, _ = reference(SMIB_INFERENCE, t, [0.1])
    again, _ = reference(SMIB_INFERENCE, t, [0.1])
    assert again is delta and not delta.flags.writeable
    assert delta.shape == (1, 3, 1)
    assert delta[0, 0, 0] == delta[0, 2, 0] != delta[0, 1, 0]
    # energy-like sanity: delta'' = (P1 - d omega - b sin delta) / m at t = 0
    h = 1e-4
    d_plus, _ = reference(SMIB_INFERENCE, [h], [0.1])
    expected = 0.1 + 0.1 * h + 0.5 * h**2 * (0.1 - 0.15 * 0.1 - 0.2 * np.sin(0.1)) / 0.4
    assert d_plus[0, 0, 0] == pytest.approx(expected, abs=1e-11)
