"""Options are declared once, typed (`solvers.options`): every registered adapter refuses every
wrong value of every option with a one-line ValueError naming it, accepts its defaults, named
configs and variants; `check_array` refuses strings and booleans. Adapters are constructed, never
fitted."""

from __future__ import annotations

import math
import re
from typing import Any, ClassVar

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from solvers import INTERFACE, SOLVERS, make_solver
from solvers.base import DEFAULT_CONFIG, AbstractSolver
from solvers.classical.common import ToleranceOptions
from solvers.options import OptionSchema, PositiveFloat, describe_option, validate_options
from solvers.pinn.config import PinnConfig
from systems.cases import CASES, FAULT_SCENARIO, SMIB_INFERENCE, check_array

CASE = SMIB_INFERENCE
ADAPTERS = {name: cls for name, cls in SOLVERS.items() if cls is not None}
NAN, INF = float("nan"), float("inf")

WRONG_TYPES = ["abc", [1e-3], {}, {"a": 1}, object()]  # never valid for any option but a list
BAD_NUMBERS = [True, False, "1e-3", "0.1", 0.0, -1e-3, -1.0, NAN, INF, -INF]
BAD_INTS = [True, False, 1.5, 2.0, "2", -1, NAN]
BAD_BOOLS = [1, 0, "True", "false", 1.0]
BAD_BOUNDS = [
    (1.0, 0.5), (0.5, 0.5), (-1.0, 2.0), (0.0, 1.0), (-2.0, -1.0), (0.1, INF), (NAN, 1.0),
    (True, 2.0), ("0.1", 1.0), (0.1,), (0.1, 0.2, 0.3), 0.5, "ab", None, {0.1, 1.0}, [0.1], [2.0, 1.0],
]


def bad_values(description: str) -> list[Any]:
    """Values an option described as `description` (`describe_option`) must refuse."""
    if description.removeprefix("None or ").startswith("a valid "):  # free text (a folder): only non-text is wrong
        return [[1e-3], {}, {"a": 1}, object(), 1.5, True]
    values = [v for v in WRONG_TYPES if not (isinstance(v, list) and description.startswith("a list"))]
    if not description.startswith("None or"):
        values.append(None)
    if description.endswith("a positive finite number"):
        values += BAD_NUMBERS
    elif description.endswith("a finite number >= 0"):
        values += [v for v in BAD_NUMBERS if v != 0.0]
    elif description.endswith("a number in (0, 1]"):
        values += [*BAD_NUMBERS, 1.5, 2]
    elif (low := re.search(r"an integer >= (\d+)$", description)) is not None:
        values += [*BAD_INTS, *range(int(low[1]))]
    elif description.endswith("True or False"):
        values += BAD_BOOLS
    elif description.startswith("one of"):
        values += ["nope", "", True, 1.5]
    elif description.endswith("a list of positive finite numbers"):
        values += [[v] for v in BAD_NUMBERS] + [0.1, "0.1", {0.1}, [0.1, -1.0]]
    elif description.removeprefix("None or ").startswith("a pair"):
        values += [v for v in BAD_BOUNDS if v is not None or not description.startswith("None or")]
    else:
        raise AssertionError(f"no bad values for an option described as {description!r}")
    return values


@pytest.mark.parametrize(("name", "option"), [(name, option) for name, cls in ADAPTERS.items()
                                               for option in cls.OPTIONS])
def test_every_bad_option_value_raises_one_line_value_error_naming_it(name, option):
    cls = ADAPTERS[name]
    for value in bad_values(describe_option(cls.SCHEMA, option)):  # a loop: ~1200 cases in ~1 s
        with pytest.raises(ValueError) as info:  # the message is checked below
            cls(CASE, **{option: value})
        message = str(info.value)
        assert type(info.value) is ValueError, f"{value!r}: a plain ValueError, not pydantic's"
        assert message.startswith(f"{name}: option {option} must be "), (value, message)
        assert "\n" not in message and f"got {value!r}" in message, (value, message)


@pytest.mark.parametrize("name", ADAPTERS)
def test_defaults_configs_and_variants_validate_to_plain_values(name):
    cls = ADAPTERS[name]
    assert set(cls.OPTIONS) == set(cls.SCHEMA.model_fields)
    for config in cls.CONFIGS:
        case = CASE if cls.made_for(config, CASE.kind) else CASES["wscc9"]  # made for networks alone
        if cls.CASE_SCENARIOS.get(config) == frozenset({FAULT_SCENARIO}):  # made for fault cases alone
            case = CASES["wscc9-bus8-line8-9"]
        solver = cls(case, config)
        assert type(solver.options) is dict and list(solver.options) == list(cls.OPTIONS)
        for key in ("m_bounds", "d_bounds"):
            if key in solver.options:  # None: the case's own boxes
                assert solver.options[key] is None or type(solver.options[key]) is tuple
        for variant in cls.VARIANTS:
            cls(case, config, **variant)
    case = CASE if cls.made_for(DEFAULT_CONFIG, CASE.kind) else CASES["wscc9"]
    assert cls(case, **cls.OPTIONS).options == cls(case).options


@pytest.mark.parametrize("name", ADAPTERS)
def test_unknown_options_and_configs_still_list_the_known_ones(name):
    cls = ADAPTERS[name]
    with pytest.raises(ValueError, match=f"unknown option.*bogus.*known: {next(iter(cls.OPTIONS))}"):
        cls(CASE, bogus=1)
    with pytest.raises(ValueError, match="unknown config 'nope'.*default"):
        cls(CASE, config="nope")


def test_several_bad_options_are_named_in_one_line():
    with pytest.raises(ValueError, match=r"^scipy-rk45: option rtol must be a positive finite number, "
                                         r"got 'abc'; option batch must be one of 'loop', 'stacked'"):
        make_solver("scipy-rk45", CASE, rtol="abc", batch="both")


def test_ints_become_floats_bounds_tuples_numpy_scalars_python():
    solver = make_solver("scipy-odeint", CASE, rtol=1, atol=np.float32(0.5), m_bounds=[1, 2])
    assert solver.options["rtol"] == 1.0 and type(solver.options["rtol"]) is float
    assert type(solver.options["atol"]) is float
    assert solver.options["m_bounds"] == (1.0, 2.0) and type(solver.options["m_bounds"]) is tuple


def test_sweep_json_bounds_arrive_as_tuples_and_validate():
    from harness.run.sweep_spec import _frozen

    options = {k: _frozen(v) for k, v in {"m_bounds": [0.05, 1.5], "d_bounds": [0.01, 0.5]}.items()}
    assert make_solver("scipy-rk45", CASE, **options).options["m_bounds"] == (0.05, 1.5)


def test_reversed_or_negative_bounds_fail_at_construction_not_in_identify():
    for bounds in [(-1, 2), (2.0, 0.02)]:
        with pytest.raises(ValueError, match="scipy-rk45: option m_bounds must be None or a pair"):
            make_solver("scipy-rk45", CASE, m_bounds=bounds)


def test_case_dependent_rules_stay_in_the_hooks():
    if "numba-rk" in ADAPTERS:
        with pytest.raises(ValueError, match="numba-rk: option dt must be <= t_final"):
            make_solver("numba-rk", CASE, dt=CASE.t_final * 2)
        with pytest.raises(ValueError, match="numba-rk: option threads must be <="):
            make_solver("numba-rk", CASE, threads=100_000)
    for name in ("torch-pinn", "jax-pinn"):
        if name in ADAPTERS:
            with pytest.raises(ValueError, match=f"{name}: options n_u and n_f are both 0"):
                make_solver(name, CASE, n_u=0, n_f=0)


@pytest.mark.parametrize(("name", "config"), [("numba-rk", "rk4"), ("diffrax", "default")])
def test_a_step_longer_than_the_case_s_horizon_is_refused_by_one_rule_naming_the_case(name, config):
    from systems.cases import CASES

    if name not in ADAPTERS:
        pytest.skip(f"{name} is not installed")
    wscc9 = CASES["wscc9"]  # a 10 s horizon, the SMIB's is 20 s
    assert make_solver(name, CASE, config, dt=15).options["dt"] == 15.0
    assert make_solver(name, wscc9, config, dt=wscc9.t_final).options["dt"] == wscc9.t_final
    with pytest.raises(ValueError) as info:
        make_solver(name, wscc9, config, dt=15)
    assert str(info.value) == (f"{name}: option dt must be <= t_final = 10.0 s, the horizon of case wscc9, "
                               "got 15.0")


def test_a_cuda_device_must_exist_when_the_adapter_is_built(monkeypatch):
    if "torch-pinn" not in ADAPTERS:
        pytest.skip("torch is not installed")
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    with pytest.raises(ValueError) as info:
        make_solver("torch-pinn", CASE, device="cuda")
    message = str(info.value)
    assert message.startswith("torch-pinn: option device must be 'cpu' on this machine")
    assert message.endswith("got 'cuda'") and CASE.name in message and "\n" not in message
    assert make_solver("torch-pinn", CASE, device="cpu").options["device"] == "cpu"
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert make_solver("torch-pinn", CASE, device="cuda").options["device"] == "cuda"  # built, not trained


def test_pinn_config_is_validated_by_the_same_schema():
    config = PinnConfig()
    assert PinnConfig(**config.to_json()) == config  # load_model's round trip
    assert PinnConfig(loss_scale=2).loss_scale == 2.0 and type(PinnConfig(loss_scale=2).loss_scale) is float
    for field, value in [("outputs", True), ("outputs", 3), ("width", 2.0), ("hard_ic", 1), ("dtype", "float16"),
                         ("max_seconds", 0.0), ("seed", -1), ("m_init", "0.2"), ("optimizer", None)]:
        with pytest.raises(ValueError, match=f"^PinnConfig: option {field} must be "):
            PinnConfig(**{field: value})
    with pytest.raises(ValueError, match="n_u and n_f are both 0"):
        PinnConfig(n_u=0, n_f=0)


def test_an_adapter_declares_options_once():
    with pytest.raises(TypeError, match="declare options once"):
        class Twice(AbstractSolver):
            SCHEMA = ToleranceOptions
            OPTIONS: ClassVar = {"rtol": 1e-3}


# ---- properties of the numeric validation ---------------------------------------------------

def _accepts(**options: Any) -> bool:
    try:
        make_solver("scipy-odeint", CASE, **options)
    except ValueError:
        return False
    return True


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=0.0, exclude_min=True, allow_infinity=False, allow_subnormal=True))
def test_any_finite_positive_float_is_a_tolerance(value):
    assert make_solver("scipy-odeint", CASE, rtol=value).options["rtol"] == value


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.floats(max_value=0.0), st.sampled_from([NAN, INF, -INF]), st.integers(max_value=0),
                 st.booleans(), st.text(), st.floats().map(repr)))
def test_any_non_positive_non_finite_or_non_number_tolerance_is_refused(value):
    with pytest.raises(ValueError, match="option rtol must be a positive finite number"):
        make_solver("scipy-odeint", CASE, rtol=value)


positive = st.floats(min_value=0.0, exclude_min=True, allow_infinity=False)


@settings(max_examples=200, deadline=None)
@given(positive, positive)
def test_a_pair_of_positive_floats_is_a_search_box_iff_low_lt_high(low, high):
    assert _accepts(m_bounds=(low, high)) is (low < high)
    assert _accepts(d_bounds=(low, high)) is (low < high)


@settings(max_examples=100, deadline=None)
@given(st.one_of(st.floats(), st.integers(-10**6, 10**6), st.booleans(), st.none(), st.text(max_size=5)))
def test_the_schema_type_agrees_with_its_definition(value):
    """PositiveFloat = a real number, not a bool, finite and > 0 (ints become floats)."""

    class One(OptionSchema):
        x: PositiveFloat = 1.0

    expected = (type(value) in (int, float)) and math.isfinite(value) and value > 0
    try:
        validate_options(One, {"x": value}, "one")
        accepted = True
    except ValueError as exc:
        accepted = False
        assert str(exc).startswith("one: option x must be a positive finite number")
    assert accepted is expected


# ---- check_array refuses strings and booleans -------------------------------------------------

numeric_text = st.one_of(st.floats(allow_nan=False).map(repr), st.integers().map(str), st.text(max_size=8))


@settings(max_examples=150, deadline=None)
@given(st.one_of(numeric_text, st.lists(numeric_text, min_size=1, max_size=5),
                 st.lists(numeric_text, min_size=1, max_size=5).map(np.array),
                 st.lists(numeric_text, min_size=1, max_size=5).map(lambda x: np.array(x, dtype=object)),
                 st.lists(numeric_text, min_size=1, max_size=5).map(lambda x: np.array([s.encode() for s in x]))))
def test_check_array_refuses_strings_even_numeric_ones(value):
    with pytest.raises(ValueError, match="^P1 must be numeric"):
        check_array("P1", np.atleast_1d(value))


@settings(max_examples=50, deadline=None)
@given(st.one_of(st.booleans(), st.lists(st.booleans(), min_size=1, max_size=5),
                 arrays(np.bool_, st.integers(1, 5)),
                 st.lists(st.one_of(st.floats(0, 1), st.text(max_size=3)), min_size=1, max_size=5)
                 .filter(lambda x: any(isinstance(v, str) for v in x))))
def test_check_array_refuses_booleans_and_mixed_strings(value):
    with pytest.raises(ValueError, match="^t_query must be numeric"):
        check_array("t_query", np.atleast_1d(value), nonnegative=True)


@pytest.mark.parametrize("value", ["0.12", ["0.12"], np.array(["0.12"]), np.array([b"0.12"]),
                                   np.array(["0.12"], dtype=object), True, np.array([True]), [0.1, None], 1j])
def test_solve_refuses_what_check_array_refuses(value):
    null = make_solver(INTERFACE, CASE)
    null.fit()
    with pytest.raises(ValueError, match="^P1 must be numeric"):
        null.solve([1.0], value)
    with pytest.raises(ValueError, match="^t_query must be numeric"):
        null.solve(value, 0.1)


def test_check_array_still_takes_ints_and_object_arrays_of_numbers():
    np.testing.assert_array_equal(check_array("x", [1, 2]), [1.0, 2.0])
    np.testing.assert_array_equal(check_array("x", np.array([1.0, 2], dtype=object)), [1.0, 2.0])
    values = np.linspace(0.0, 1.0, 5)
    assert check_array("x", values) is values  # a float64 array is not copied
