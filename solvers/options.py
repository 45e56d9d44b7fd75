"""Adapter options declared once, with their types and ranges: the shared field types and the one
function that validates an adapter's merged options against its schema.

An adapter sets `SCHEMA` to an `OptionSchema` subclass (one field per option, its default the
option's default); `AbstractSolver` derives `OPTIONS` (name -> default) from it and validates the
merged options with `validate_options` at construction. Rules that depend on the case or the
machine (a step no longer than the case's horizon, `solvers.classical.common.check_step`; a device that
exists) stay in the adapter's `_check_options` hook, which construction runs too: building an
adapter for its case is the one validation, for the harness and the Python API alike.

Why pydantic (v2): its strict mode refuses a boolean for a number and a numeric string such as
'1e-3' (the conversions that made bad options pass or fail with a raw TypeError); constraints are
declared per field (gt, ge, finite); cross-field rules are model validators; every error names
its field. Validation runs once per adapter construction, so its speed does not matter. (msgspec
covers the per-field constraints too, but its rules beyond them, such as ordered bounds, are
hand-written `__post_init__` code again, which is what this module replaces.)

Conventions: integers given for a float option become floats; numpy scalars are taken as the
Python scalars they hold; a list of two numbers is accepted for bounds (a JSON array, or a Python
user's [low, high]: unambiguous) and stored as a tuple.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    create_model,
)

__all__ = [
    "Bounds",
    "Fraction",
    "NonNegativeFloat",
    "NonNegativeInt",
    "OptionSchema",
    "PositiveFloat",
    "PositiveFloats",
    "PositiveInt",
    "StrictBool",
    "StrictChoice",
    "dataclass_schema",
    "defaults",
    "describe_option",
    "int_at_least",
    "validate_options",
]


@dataclass(frozen=True)
class Describe:
    """What an option must be, in words ("a positive finite number"): completes the error message
    "option X must be ..."."""

    text: str


def _python_scalar(value: Any) -> Any:
    """numpy scalars as the Python scalars they hold (np.bool_ -> bool, so strict numbers refuse it)."""
    return value.item() if isinstance(value, np.generic) else value


def _exact_int(value: Any) -> Any:
    """Integer choices (Literal[1, 2]) match True and 2.0 in pydantic's lax mode: refuse them."""
    value = _python_scalar(value)
    if type(value) is not int:
        raise ValueError("not an integer")  # pydantic turns a ValueError into its error
    return value


def _pair(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def _ordered(pair: tuple[float, float]) -> tuple[float, float]:
    if not pair[0] < pair[1]:
        raise ValueError("low >= high")
    return pair


PositiveFloat = Annotated[float, BeforeValidator(_python_scalar), Strict(),
                          Field(gt=0, allow_inf_nan=False), Describe("a positive finite number")]
NonNegativeFloat = Annotated[float, BeforeValidator(_python_scalar), Strict(),
                             Field(ge=0, allow_inf_nan=False), Describe("a finite number >= 0")]


def int_at_least(low: int) -> Any:
    """The type of an integer option >= `low` (described as "an integer >= low")."""
    return Annotated[int, BeforeValidator(_python_scalar), Strict(), Field(ge=low), Describe(f"an integer >= {low}")]


PositiveInt = int_at_least(1)
NonNegativeInt = int_at_least(0)
# a fraction of a whole (0 < x <= 1), e.g. the energy a truncated basis keeps
Fraction = Annotated[float, BeforeValidator(_python_scalar), Strict(), Field(gt=0, le=1, allow_inf_nan=False),
                     Describe("a number in (0, 1]")]
StrictBool = Annotated[bool, BeforeValidator(_python_scalar), Strict(), Describe("True or False")]
# (low, high) with 0 < low < high, both finite (the search box of identify, p.u.)
Bounds = Annotated[tuple[PositiveFloat, PositiveFloat], BeforeValidator(_pair), Strict(),
                   AfterValidator(_ordered),
                   Describe("a pair (low, high) of finite numbers with 0 < low < high")]
# zero or more positive finite numbers, in the order given (e.g. steps to try in turn, s)
PositiveFloats = Annotated[tuple[PositiveFloat, ...], BeforeValidator(_pair), Strict(),
                           Describe("a list of positive finite numbers")]
# Put on an integer Literal: `Annotated[Literal[1, 2], StrictChoice]`
StrictChoice = BeforeValidator(_exact_int)


class OptionSchema(BaseModel):
    """Base of the adapters' option schemas: one field per option, its default the option's default.
    Unknown options are refused, and defaults are validated too."""

    model_config = ConfigDict(extra="forbid", validate_default=True, frozen=True)


def defaults(schema: type[BaseModel]) -> dict[str, Any]:
    """name -> default of every field of `schema`, in declaration order (an adapter's `OPTIONS`)."""
    return {name: field.default for name, field in schema.model_fields.items()}


def dataclass_schema(cls: type, base: type[OptionSchema] = OptionSchema) -> type[OptionSchema]:
    """An `OptionSchema` with the fields (annotations and defaults) of the dataclass `cls`, so a
    frozen dataclass can declare its fields once and be validated like the adapters' options."""
    hints = typing.get_type_hints(cls, include_extras=True)
    fields: dict[str, Any] = {f.name: (hints[f.name], f.default) for f in dataclasses.fields(cls)}
    return create_model(f"{cls.__name__}Schema", __base__=base, __module__=cls.__module__, **fields)


def _describe(annotation: Any, metadata: tuple | list = ()) -> str | None:
    """'a positive finite number', "one of 'loop', 'stacked'", 'None or ...' for an annotation."""
    for item in metadata:
        if isinstance(item, Describe):
            return item.text
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is Annotated:
        return _describe(args[0], args[1:])
    if origin is Literal:
        return "one of " + ", ".join(map(repr, args))
    if annotation is bool:
        return "True or False"
    if args and type(None) in args:  # Optional[X] or X | None
        inner = [_describe(a) for a in args if a is not type(None)]
        if all(inner):
            return "None or " + " or ".join(inner)  # type: ignore[arg-type]
    return None


def describe_option(schema: type[BaseModel], name: str) -> str:
    """What option `name` of `schema` must be, in words: 'a positive finite number',
    "one of 'loop', 'stacked'", 'None or an integer >= 1', ..."""
    field = schema.model_fields[name]
    return _describe(field.annotation, field.metadata) or f"a valid {name}"


def _message(schema: type[BaseModel], exc: ValidationError, values: Mapping[str, Any]) -> str:
    """One line for all errors: "option X must be <description>, got <value>"; model-level rules
    (cross-field) give their own message."""
    parts: list[str] = []
    seen: set[str] = set()
    for error in exc.errors():
        loc = error["loc"]
        if not loc:  # a model validator: its ValueError's own text
            context = error.get("ctx") or {}
            parts.append(str(context.get("error", error["msg"])))
            continue
        name = str(loc[0])
        if name in seen:
            continue
        seen.add(name)
        if error["type"] == "extra_forbidden":
            parts.append(f"unknown option {name}; known: {', '.join(schema.model_fields) or 'none'}")
            continue
        what = describe_option(schema, name)
        got = values.get(name, error.get("input"))
        parts.append(f"option {name} must be {what}, got {got!r}")
    return "; ".join(parts)


def validate_options(schema: type[BaseModel], values: Mapping[str, Any], owner: str) -> dict[str, Any]:
    """`values` validated by `schema`: a plain dict of every field in declaration order (floats,
    ints, bools, strings, tuples, None as declared). Raises ValueError, one line starting with
    `owner` (the adapter's name) and naming each bad option, what it must be and the value given."""
    try:
        model = schema.model_validate(dict(values))
    except ValidationError as exc:
        raise ValueError(f"{owner}: {_message(schema, exc, values)}") from None
    return {name: getattr(model, name) for name in schema.model_fields}

