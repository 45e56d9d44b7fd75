"""The paper's cases and the data types that describe a problem: pure data, no solver.

Units: angles in rad, angular speeds in rad/s, times in s, powers and susceptances in p.u.
Nothing here imports the rest of the project; solvers take a `Case`, suites take solvers.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from numbers import Real

import numpy as np

__all__ = [
    "CASES",
    "IDENTIFICATION_PAIRS",
    "SMIB_IDENTIFICATION",
    "SMIB_INFERENCE",
    "Case",
    "Observations",
    "check_array",
    "standard_grid",
]


# numpy dtype kinds check_array takes: signed and unsigned integers, floats
_NUMERIC_KINDS = frozenset("iuf")
_KIND_NAMES = {"b": "booleans", "U": "strings", "S": "bytes", "c": "complex numbers", "O": "objects",
               "M": "datetimes", "m": "timedeltas", "V": "raw bytes"}


def check_array(name: str, value, *, ndim: int = 1, nonnegative: bool = False) -> np.ndarray:
    """Return `value` as a float64 array of `ndim` dimensions or raise a ValueError naming `name`.

    Rejects non-numeric input, the wrong number of dimensions, empty arrays, NaN/inf and (with
    `nonnegative`) negative entries: a bad input never becomes a silent wrong number.
    Numeric means integers and floats (Python, numpy, or an object array of them): strings are
    refused even when they spell a number ('0.12'), and so are booleans (True is not 1.0 s or
    1.0 p.u.; the option schemas of `solvers.options` refuse them for numbers too), complex
    numbers and None. A float64 array costs one dtype check more than `np.asarray`.
    """
    raw = value
    if type(raw) is not np.ndarray:
        try:
            raw = np.asarray(value)
        except (TypeError, ValueError) as exc:  # ragged nesting
            raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    kind = raw.dtype.kind
    if kind not in _NUMERIC_KINDS:
        bad = kind != "O" or any(isinstance(x, (bool, np.bool_)) or not isinstance(x, Real) for x in raw.flat)
        if bad:
            raise ValueError(f"{name} must be numeric (integers or floats), got {_KIND_NAMES.get(kind, raw.dtype)}"
                             f" ({_short(value)})")
    try:
        arr = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numeric, got {type(value).__name__}") from exc
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf")
    if nonnegative and (arr < 0).any():
        raise ValueError(f"{name} must be >= 0, got min {arr.min()!r}")
    return arr


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


@dataclass(frozen=True)
class Case:
    """A single-machine infinite-bus (SMIB) swing-equation problem.

    m * delta'' + d * delta' + b * sin(delta) - P1 = 0,  delta(0) = delta0, delta'(0) = omega0,
    on t in [0, t_final] s for P1 in [p1_min, p1_max] p.u.

    m: inertia (p.u. s^2/rad), d: damping (p.u. s/rad), b = B12*V1*V2 (p.u.), delta0 (rad),
    omega0 (rad/s), t_final (s). A multi-machine case is a `harness.model.SwingSystem`; a `Case`
    is its one-machine view, see `harness.model.smib_system`.
    """

    name: str
    m: float
    d: float
    b: float
    delta0: float
    omega0: float
    t_final: float
    p1_min: float
    p1_max: float

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            if field.name == "name":
                continue
            value = getattr(self, field.name)
            if not isinstance(value, (int, float, np.floating, np.integer)) or not np.isfinite(value):
                raise ValueError(f"Case.{field.name} must be a finite number, got {value!r}")
            object.__setattr__(self, field.name, float(value))
        for positive in ("m", "d", "t_final"):
            if getattr(self, positive) <= 0:
                raise ValueError(f"Case.{positive} must be > 0, got {getattr(self, positive)!r}")
        if self.b < 0:
            raise ValueError(f"Case.b must be >= 0, got {self.b!r}")
        if not self.p1_min <= self.p1_max:
            raise ValueError(f"Case.p1_min must be <= p1_max, got {self.p1_min!r} > {self.p1_max!r}")

    def with_params(self, m: float, d: float, name: str | None = None) -> Case:
        """The same case with another inertia `m` and damping `d`."""
        return dataclasses.replace(self, m=m, d=d, name=name or f"{self.name}[m={m:g},d={d:g}]")


@dataclass(frozen=True)
class Observations:
    """Scattered samples of a trajectory family, for identification.

    t (s), P1 (p.u.), delta (rad) and optionally omega (rad/s): 1-D float64 arrays of one length n,
    sample i being delta(t[i]; P1[i]).
    """

    t: np.ndarray
    P1: np.ndarray
    delta: np.ndarray
    omega: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", check_array("Observations.t", self.t, nonnegative=True))
        object.__setattr__(self, "P1", check_array("Observations.P1", self.P1))
        object.__setattr__(self, "delta", check_array("Observations.delta", self.delta))
        if self.omega is not None:
            object.__setattr__(self, "omega", check_array("Observations.omega", self.omega))
        n = self.t.size
        for name in ("P1", "delta", "omega"):
            value = getattr(self, name)
            if value is not None and value.size != n:
                raise ValueError(
                    f"Observations.{name} has length {value.size}, Observations.t has length {n}"
                )

    def __len__(self) -> int:
        return self.t.size


SMIB_INFERENCE = Case(
    name="smib-inference", m=0.4, d=0.15, b=0.2, delta0=0.1, omega0=0.1,
    t_final=20.0, p1_min=0.08, p1_max=0.18,
)
SMIB_IDENTIFICATION = Case(
    name="smib-identification", m=0.25, d=0.15, b=0.2, delta0=0.1, omega0=0.1,
    t_final=20.0, p1_min=0.10, p1_max=0.18,
)
CASES = {case.name: case for case in (SMIB_INFERENCE, SMIB_IDENTIFICATION)}

# The paper identifies 10 (m, d) pairs in m in [0.1, 0.4], d in [0.05, 0.15] but does not list them.
# Ours: m and d both evenly spaced over their ranges, paired in order (m_i, d_i), i = 0..9, so the
# pairs run from light and weakly damped (0.1, 0.05) to heavy and strongly damped (0.4, 0.15).
IDENTIFICATION_PAIRS: tuple[tuple[float, float], ...] = tuple(
    (round(float(m), 10), round(float(d), 10))
    for m, d in zip(np.linspace(0.1, 0.4, 10), np.linspace(0.05, 0.15, 10))
)


def standard_grid(case: Case, n_p1: int = 100, n_t: int = 201) -> tuple[np.ndarray, np.ndarray]:
    """The paper's query grid: `n_t` evenly spaced times on [0, t_final] s (step 0.1 s for the
    defaults) and `n_p1` evenly spaced P1 values on [p1_min, p1_max]. Returns (t, P1)."""
    return np.linspace(0.0, case.t_final, n_t), np.linspace(case.p1_min, case.p1_max, n_p1)
