"""The paper's cases and the data types that describe a problem: pure data, no solver.

Units: angles in rad, angular speeds in rad/s, times in s, powers and susceptances in p.u.
Nothing here imports the rest of the project; solvers take a `Case`, suites take solvers.

`CASES` is the registry of named cases: the SMIB cases here, and every builder that
`register_case` registers (`systems.grids`, `systems.family`, which the `systems` package imports).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from numbers import Real
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

__all__ = [
    "CASES",
    "FAULT_SCENARIO",
    "IDENTIFICATION_PAIRS",
    "KINDS",
    "NETWORK",
    "NETWORK_CASES",
    "SMIB",
    "SMIB_CASES",
    "SMIB_IDENTIFICATION",
    "SMIB_INFERENCE",
    "STEP_SCENARIO",
    "CarriedNetwork",
    "Case",
    "Fault",
    "Observations",
    "Scenario",
    "case_record",
    "check_array",
    "check_number",
    "per_machine",
    "register_case",
    "smib_case",
    "standard_grid",
]


# numpy dtype kinds check_array takes: signed and unsigned integers, floats
_NUMERIC_KINDS = frozenset("iuf")
_KIND_NAMES = {"b": "booleans", "U": "strings", "S": "bytes", "c": "complex numbers", "O": "objects",
               "M": "datetimes", "m": "timedeltas", "V": "raw bytes"}


def check_array(name: str, value, *, ndim: int = 1, nonnegative: bool = False, promote: bool = False
                ) -> np.ndarray:
    """Return `value` as a float64 array of `ndim` dimensions or raise a ValueError naming `name`.

    Rejects non-numeric input, the wrong number of dimensions, empty arrays, NaN/inf and (with
    `nonnegative`) negative entries: a bad input never becomes a silent wrong number.
    Numeric means integers and floats (Python, numpy, or an object array of them): strings are
    refused even when they spell a number ('0.12'), and so are booleans (True is not 1.0 s or
    1.0 p.u.; the option schemas of `solvers.options` refuse them for numbers too), complex
    numbers and None, also inside a list or tuple. With `promote`, one number is a 1-element
    vector. A float64 array costs one dtype check more than `np.asarray`.
    """
    raw = value
    if type(raw) is not np.ndarray:
        refused = _non_number_inside(value)
        if refused is not None:  # np.asarray([0.0, True]) would be float64, the boolean gone
            raise ValueError(f"{name} must be numeric (integers or floats), got {refused} inside "
                             f"({_short(value)})")
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
    if promote and arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be {ndim}-D, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf")
    if nonnegative and (arr < 0).any():
        raise ValueError(f"{name} must be >= 0, got min {arr.min()!r}")
    return arr


def _non_number_inside(value) -> str | None:
    """What a list or tuple (nested to any depth) holds that is no number: 'booleans', 'strings',
    ...; None when it holds none (or `value` is no list or tuple)."""
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, (list, tuple)):
            stack.extend(item)
        elif isinstance(item, (bool, np.bool_)):
            return "booleans"
        elif isinstance(item, (str, bytes)):
            return "strings" if isinstance(item, str) else "bytes"
        elif isinstance(item, np.ndarray) and item.dtype.kind not in _NUMERIC_KINDS:
            return _KIND_NAMES.get(item.dtype.kind, str(item.dtype))
    return None


def check_number(name: str, value) -> float:
    """Return `value` as a float or raise a ValueError naming `name`: one finite integer or float
    (Python or numpy); booleans, strings (even '0.5'), None and arrays are refused."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (Real, np.floating, np.integer)):
        raise ValueError(f"{name} must be a finite number, got {value!r}")  # noqa: TRY004 - the contract is ValueError
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return number


def per_machine(name: str, value, n: int) -> np.ndarray:
    """`value` (a number, or (n,) numbers) as an (n,) positive float64 array, a number setting every
    machine's; a ValueError naming `name` for anything else (strings, booleans, another length,
    a value <= 0)."""
    arr = check_array(name, value, promote=True)
    if arr.size == 1 and n > 1:
        arr = np.full(n, arr[0])
    if arr.size != n:
        raise ValueError(f"{name} has {arr.size} entries for {n} machine(s)")
    if (arr <= 0).any():
        raise ValueError(f"{name} must be > 0, got {arr.tolist()}")
    return arr


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# The kinds of case (`Case.kind`): the one property that says SMIB or multi-machine network.
SMIB = "smib"
NETWORK = "network"
KINDS = (SMIB, NETWORK)

Vector = tuple[float, ...]
Matrix = tuple[tuple[float, ...], ...]


def _vector(name: str, value, n: int | None = None) -> Vector:
    arr = check_array(f"Case.{name}", value, promote=True)
    if n is not None and arr.size != n:
        raise ValueError(f"Case.{name} has {arr.size} entries, the case has {n} machines")
    return tuple(float(x) for x in arr)


def _matrix(name: str, value, n: int) -> Matrix:
    arr = check_array(f"Case.{name}", value, ndim=2)
    if arr.shape != (n, n):
        raise ValueError(f"Case.{name} must be ({n}, {n}) for {n} machines, got shape {arr.shape}")
    if not np.array_equal(arr, arr.T):
        raise ValueError(f"Case.{name} must be symmetric")
    return tuple(tuple(float(x) for x in row) for row in arr)


def _boxes(name: str, value, n: int) -> tuple[tuple[float, float], ...]:
    arr = check_array(f"Case.{name}", value, ndim=2)
    if arr.shape != (n, 2) or not ((arr[:, 0] > 0) & (arr[:, 0] < arr[:, 1])).all():
        raise ValueError(f"Case.{name} must be ({n}, 2) rows (low, high) with 0 < low < high, got {arr.tolist()}")
    return tuple((float(lo), float(hi)) for lo, hi in arr)


@runtime_checkable
class CarriedNetwork(Protocol):
    """What a `Case` reads of the unreduced network it carries (`systems.sparse_network.SparseNetwork`,
    not imported here: this module imports nothing of the project): the bus of each machine, at
    (n,), and `reduces_to`, the hash of the (G, B) tuples it was reduced to."""

    @property
    def at(self) -> np.ndarray: ...

    @property
    def reduces_to(self) -> int: ...


class Scenario(NamedTuple):
    """What a case's scenario parameter is (`Case.scenario`): its symbol in tables and plots, its
    unit and what it means. Every case has exactly one, the second argument of `solve(t, P1)`,
    ranging over [Case.p1_min, Case.p1_max]."""

    symbol: str
    unit: str
    meaning: str


# A step case's parameter: generator 1's mechanical power, stepped at t = 0 (the paper's scenario).
STEP_SCENARIO = Scenario("P1", "p.u.", "generator 1's mechanical power")
# A fault case's parameter: the time the fault is cleared (`Fault`).
FAULT_SCENARIO = Scenario("t_c", "s", "clearing time")


@dataclass(frozen=True)
class Fault:
    """A switched network (a fault case, issue 23's study): on 0 <= t < t_c the fault-on network
    (G_on, B_on), from the clearing time t_c on the post-fault one (G_post, B_post); each (n, n)
    symmetric p.u., Kron-reduced onto the machines like `Case.G`, `Case.B` (the pre-fault network,
    which set the equilibrium the case starts from). `name` names the contingency
    (`systems.faults.Contingency`). Built by `systems.faults.fault_case`.

    y: optionally the machines' tie admittances 1 / (j x'd_k) (n,) complex p.u. of the unreduced
    network the three reduced ones come from, for the solvers that work from the machine terminals
    (`solvers.pinn.pinnsim`: the impedance seen from them is D^-1 - D^-1 Y_red D^-1, D = diag(y)).
    Derived data, as `Case.network` is: left out of the fault's equality, hash, repr and record; a
    fault case never carries the sparse step network itself (its topology switches)."""

    name: str
    G_on: Matrix
    B_on: Matrix
    G_post: Matrix
    B_post: Matrix
    y: tuple[complex, ...] | None = dataclasses.field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Case:
    """An N-machine classical swing system and its scenario: pure data.

    Machine k (k = 0..n-1, "generator 1" is k = 0) obeys

        m_k delta_k'' + d_k delta_k' + P_e,k(delta) - P_k = 0,
        P_e,k = sum_j E_k E_j (G_kj cos(delta_k - delta_j) + B_kj sin(delta_k - delta_j))
                + E_k V_inf (g_inf_k cos(delta_k) + b_inf_k sin(delta_k)),

    the Kron-reduced network seen from the internal machine nodes (the paper's lossless Eq. 1 is
    G = 0), plus an optional infinite bus: a machine of fixed angle 0 and voltage V_inf = 1 p.u.
    whose coupling column is (g_inf, b_inf), from delta(0) = delta0, omega(0) = omega0, on
    t in [0, t_final] s. Each case has one scenario parameter (`scenario`), in [p1_min, p1_max]:
    - a step case (fault None): P1 p.u., P = p_m with generator 1's entry replaced by P1;
    - a fault case (`fault` a `Fault`): the clearing time t_c s, 0 < p1_min <= p1_max < t_final;
      P = p_m throughout, the network (G, B) replaced by the fault-on one on [0, t_c) and by the
      post-fault one from t_c on (`phase`).

    Units (system base): m (n,) p.u. s^2/rad (M = 2 H S_rated / (omega_s S_base)), d (n,) p.u. s/rad,
    E (n,) p.u., G, B (n, n) symmetric p.u., g_inf, b_inf (n,) p.u., p_m (n,) p.u., delta0 (n,) rad,
    omega0 (n,) rad/s (speed deviation, electrical), t_final s. m_box, d_box (n, 2): each
    machine's (low, high) p.u., the box identification searches (the prior of the problem).
    Sequences are stored as tuples of floats so that a case is hashable and compares by value.
    network: optionally the same network unreduced (`systems.sparse_network.SparseNetwork`, built
    with G and B by `systems.network.classical_model`), for the solvers that keep it sparse; derived
    data, so it is left out of the case's equality, hash, repr and record (`case_record`), and a
    network reduced to other G, B is refused (replace or drop it with them: network=None).

    The paper's SMIB is n = 1, E = (1,), G = B = ((0,),), g_inf = (0,), b_inf = (b,).
    """

    name: str
    m: Vector
    d: Vector
    delta0: Vector
    omega0: Vector
    p_m: Vector
    E: Vector
    G: Matrix
    B: Matrix
    g_inf: Vector
    b_inf: Vector
    t_final: float
    p1_min: float
    p1_max: float
    m_box: tuple[tuple[float, float], ...]
    d_box: tuple[tuple[float, float], ...]
    source: str = ""
    fault: Fault | None = None
    network: CarriedNetwork | None = dataclasses.field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        n = len(_vector("m", self.m))
        if n == 0:
            raise ValueError("Case.m must not be empty")
        for name in ("m", "d", "delta0", "omega0", "p_m", "E", "g_inf", "b_inf"):
            object.__setattr__(self, name, _vector(name, getattr(self, name), n))
        for name in ("G", "B"):
            object.__setattr__(self, name, _matrix(name, getattr(self, name), n))
        for name in ("m_box", "d_box"):
            object.__setattr__(self, name, _boxes(name, getattr(self, name), n))
        for name in ("t_final", "p1_min", "p1_max"):
            object.__setattr__(self, name, check_number(f"Case.{name}", getattr(self, name)))
        for name in ("m", "d", "E"):
            if min(getattr(self, name)) <= 0:
                raise ValueError(f"Case.{name} must be > 0, got {getattr(self, name)!r}")
        if self.t_final <= 0:
            raise ValueError(f"Case.t_final must be > 0, got {self.t_final!r}")
        if not self.p1_min <= self.p1_max:
            raise ValueError(f"Case.p1_min must be <= p1_max, got {self.p1_min!r} > {self.p1_max!r}")
        if self.fault is not None:
            self._check_fault(n)
        if self.network is not None:
            if not isinstance(self.network, CarriedNetwork) or np.size(self.network.at) != n:
                raise ValueError(f"Case.network must be a SparseNetwork of {n} machines or None")
            if self.network.reduces_to != hash((self.G, self.B)):
                raise ValueError("Case.network is not the network of this case's G and B (pass network=None)")

    def _check_fault(self, n: int) -> None:
        if not isinstance(self.fault, Fault):
            raise ValueError(f"Case.fault must be a systems.cases.Fault or None, got {type(self.fault).__name__}")  # noqa: TRY004 - the contract is ValueError
        if self.has_infinite_bus:
            raise ValueError("Case.fault: a fault case has no infinite bus (its networks are the machines' alone)")
        matrices = {key: _matrix(f"fault.{key}", getattr(self.fault, key), n)
                    for key in ("G_on", "B_on", "G_post", "B_post")}
        y = self.fault.y
        if y is not None:
            y = tuple(complex(x) for x in np.asarray(y, complex).ravel())
            if len(y) != n or not all(x != 0 and math.isfinite(abs(x)) for x in y):
                raise ValueError(f"Case.fault.y must be {n} finite nonzero tie admittances or None, got {y!r}")
        object.__setattr__(self, "fault", Fault(name=str(self.fault.name), **matrices, y=y))
        if not 0 < self.p1_min <= self.p1_max < self.t_final:
            raise ValueError(f"Case {self.name!r}: the clearing times [p1_min, p1_max] = [{self.p1_min!r}, "
                             f"{self.p1_max!r}] s must lie in (0, t_final = {self.t_final!r}) s")

    @property
    def scenario(self) -> Scenario:
        """What the scenario parameter (the `P1` of `solve(t, P1)`, over [p1_min, p1_max]) is:
        `STEP_SCENARIO` (P1, p.u.) or, for a fault case, `FAULT_SCENARIO` (t_c, s)."""
        return STEP_SCENARIO if self.fault is None else FAULT_SCENARIO

    def phase(self, which: str) -> Case:
        """A fault case's network in one phase as a step case of its own: `which` 'on' (the
        fault-on network) or 'post' (the post-fault one) in place of G, B, no fault, no carried
        network, and the scenario range the single point P1 = p_m[0] (so that `powers` gives p_m).
        The dynamics of the phase from any state; a ValueError for a step case or another `which`."""
        if self.fault is None:
            raise ValueError(f"case {self.name!r} is no fault case: it has no phases")
        if which not in ("on", "post"):
            raise ValueError(f"phase must be 'on' or 'post', got {which!r}")
        G, B = getattr(self.fault, f"G_{which}"), getattr(self.fault, f"B_{which}")
        return dataclasses.replace(self, name=f"{self.name}[{which}]", G=G, B=B, fault=None, network=None,
                                   p1_min=self.p_m[0], p1_max=self.p_m[0])

    @property
    def n(self) -> int:
        """Number of machines (the infinite bus not counted)."""
        return len(self.m)

    @property
    def has_infinite_bus(self) -> bool:
        """Whether some machine is coupled to the fixed-angle infinite bus (then absolute angles are
        referenced to it; without one they drift together, and angles are compared to the centre of
        inertia)."""
        return any(self.g_inf) or any(self.b_inf)

    @property
    def kind(self) -> str:
        """`SMIB` for a system held by an infinite bus (the paper's single machine against it, any
        case `smib_case` builds), `NETWORK` for machines coupled only to each other. Everything
        that treats the two apart (which configs run, what identification measures, which angles
        are compared) reads this, never a list of cases."""
        return SMIB if self.has_infinite_bus else NETWORK

    def with_params(self, m, d, name: str | None = None) -> Case:
        """The same case with other inertias `m` and dampings `d`: (n,) sequences, or numbers that
        set every machine's."""
        m, d = (tuple(per_machine(f"with_params: {key}", value, self.n).tolist()) for key, value in (("m", m), ("d", d)))
        label = ",".join(f"{x:g}" for x in m), ",".join(f"{x:g}" for x in d)
        return dataclasses.replace(self, m=m, d=d, name=name or f"{self.name}[m={label[0]},d={label[1]}]")

    def powers(self, P1: np.ndarray) -> np.ndarray:
        """Mechanical powers (len(P1), n) p.u.: p_m with generator 1's replaced by each P1 (a step
        case); p_m in every row for a fault case, whose scenario parameter is no power."""
        P = np.tile(np.asarray(self.p_m, np.float64), (np.size(P1), 1))
        if self.fault is None:
            P[:, 0] = P1
        return P


def case_record(case: Case) -> dict[str, Any]:
    """The fields that define `case` (every field but the derived `network` and `Fault.y`), by name, in field
    order, plain data (a `Fault` as a dict): what a case compares and hashes by, and what is saved
    or keyed of it. A step case's record has no `fault` entry."""
    record = {f.name: getattr(case, f.name) for f in dataclasses.fields(case) if f.compare}
    if case.fault is None:
        del record["fault"]
    else:
        compared = {f.name for f in dataclasses.fields(case.fault) if f.compare}  # not the derived y
        record["fault"] = {key: value for key, value in dataclasses.asdict(case.fault).items() if key in compared}
    return record


def smib_case(name: str, m: float, d: float, b: float, delta0: float, omega0: float, t_final: float,
              p1_min: float, p1_max: float, m_box=(0.02, 2.0), d_box=(0.005, 1.0), source: str = "") -> Case:
    """A single-machine infinite-bus case: m delta'' + d delta' + b sin(delta) - P1 = 0 (b = B12 V1 V2,
    p.u.). p_m is the middle of the P1 range (it is replaced by P1 in every trajectory)."""
    return Case(
        name=name, m=(m,), d=(d,), delta0=(delta0,), omega0=(omega0,), p_m=((p1_min + p1_max) / 2,),
        E=(1.0,), G=((0.0,),), B=((0.0,),), g_inf=(0.0,), b_inf=(b,), t_final=t_final,
        p1_min=p1_min, p1_max=p1_max, m_box=(m_box,), d_box=(d_box,), source=source,
    )


@dataclass(frozen=True)
class Observations:
    """Scattered samples of a trajectory family, for identification.

    t (n_s,) s and P1 (n_s,) p.u.: 1-D float64 arrays of one length n_s; delta (n_s, n) rad and
    optionally omega (n_s, n) rad/s, one column per machine: row i is every machine's state at
    time t[i] for P1[i]. A 1-D delta or omega is refused (one shape rule, N = 1 included).
    """

    t: np.ndarray
    P1: np.ndarray
    delta: np.ndarray
    omega: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "t", check_array("Observations.t", self.t, nonnegative=True))
        object.__setattr__(self, "P1", check_array("Observations.P1", self.P1))
        object.__setattr__(self, "delta", check_array("Observations.delta", self.delta, ndim=2))
        if self.omega is not None:
            object.__setattr__(self, "omega", check_array("Observations.omega", self.omega, ndim=2))
        n = self.t.size
        for name in ("P1", "delta", "omega"):
            value = getattr(self, name)
            if value is not None and value.shape[0] != n:
                raise ValueError(
                    f"Observations.{name} has {value.shape[0]} samples, Observations.t has {n}"
                )
        if self.omega is not None and self.omega.shape != self.delta.shape:
            raise ValueError(f"Observations.omega has shape {self.omega.shape}, Observations.delta "
                             f"{self.delta.shape}: the same machines must be observed")

    def __len__(self) -> int:
        return self.t.size

    @property
    def n_machines(self) -> int:
        """Machines observed (columns of delta)."""
        return self.delta.shape[1]

    def check_machines(self, case: Case) -> None:
        """Raise a ValueError naming `obs.delta` unless it has one column per machine of `case`."""
        if self.n_machines != case.n:
            raise ValueError(f"obs.delta has {self.n_machines} machine column(s), case {case.name!r} "
                             f"has {case.n} machines")


# The paper's two SMIB problems (Misyris, Venzke & Chatzivasileiadis 2020, Sec. IV).
SMIB_INFERENCE = smib_case(
    name="smib-inference", m=0.4, d=0.15, b=0.2, delta0=0.1, omega0=0.1,
    t_final=20.0, p1_min=0.08, p1_max=0.18, source="Misyris et al. 2020, Sec. IV-A",
)
SMIB_IDENTIFICATION = smib_case(
    name="smib-identification", m=0.25, d=0.15, b=0.2, delta0=0.1, omega0=0.1,
    t_final=20.0, p1_min=0.10, p1_max=0.18, source="Misyris et al. 2020, Sec. IV-B",
)
SMIB_CASES = (SMIB_INFERENCE, SMIB_IDENTIFICATION)
# The multi-machine cases of the paper's runs (built by `systems.grids`): what a run measures by
# default besides the SMIB. Every registered case can be named on the command line.
NETWORK_CASES = ("wscc9", "kundur4", "ieee39")

CaseBuilder = Callable[[], Case]


class _Cases(Mapping):
    """name -> Case, filled by `register_case`. A case is built on first access, by indexing (a
    network case solves a power flow, pandapower takes seconds to import); iterating and `in`
    give names only. An unknown name is a KeyError that lists the known ones."""

    def __init__(self) -> None:
        self._builders: dict[str, CaseBuilder] = {}
        self._built: dict[str, Case] = {}

    def register(self, name: str, builder: CaseBuilder) -> None:
        if name in self._builders:
            raise ValueError(f"case {name!r} is registered twice")
        self._builders[name] = builder

    def __getitem__(self, name: str) -> Case:
        if name not in self._built:
            if name not in self._builders:
                raise KeyError(f"unknown case {name!r}; known: {', '.join(self._builders)}")
            case = self._builders[name]()
            if case.name != name:
                raise ValueError(f"the builder of case {name!r} returned a case named {case.name!r}")
            self._built[name] = case
        return self._built[name]

    def __contains__(self, name) -> bool:  # by name: never builds a case
        return name in self._builders

    def __iter__(self):
        return iter(list(self._builders))

    def __len__(self) -> int:
        return len(self._builders)


CASES = _Cases()


def register_case(name: str) -> Callable[[CaseBuilder], CaseBuilder]:
    """Decorator: register a function that builds the `Case` called `name` (taking no arguments)
    in `CASES`; it runs on the first `CASES[name]`, once per process. Returns the function."""

    def register(builder: CaseBuilder) -> CaseBuilder:
        CASES.register(name, builder)
        return builder

    return register


def _constant(case: Case) -> CaseBuilder:
    return lambda: case


for _case in SMIB_CASES:
    register_case(_case.name)(_constant(_case))

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
