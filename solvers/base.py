"""The contract every swingbench solver adapter keeps, and the records it returns."""

from __future__ import annotations

import abc
import time
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, NamedTuple

import numpy as np

from solvers.identification import Estimate, assess, data_shortfall
from solvers.options import OptionSchema, defaults, validate_options
from systems.cases import FAULT_SCENARIO, KINDS, STEP_SCENARIO, Case, Observations, Scenario, check_array

__all__ = [
    "ABLATION",
    "COARSE_RTOL",
    "CONFIG_MARKS",
    "DEFAULT_CONFIG",
    "IDENTIFIES_NETWORKS",
    "LARGE_SYSTEMS",
    "SWEEP_POINT",
    "AbstractSolver",
    "Estimate",
    "FitReport",
    "Identification",
    "NotFittedError",
    "PartialSolveError",
    "Points",
    "SolveError",
    "StepCount",
    "Trajectory",
]


# The named config every adapter has: the schema's defaults.
DEFAULT_CONFIG = "default"

# What a named config is declared for (`AbstractSolver.CONFIG_MARKS`), where the planner needs
# to know more than its options: runs select configs by these marks, never by their names.
IDENTIFIES_NETWORKS = "identifies networks"  # accurate enough to identify a multi-machine case's 2n parameters
LARGE_SYSTEMS = "large systems"  # made for systems of hundreds of machines (the scaling suite's)
ABLATION = "ablation"  # changes one design choice of another config, to measure what that choice is worth
SWEEP_POINT = "sweep point"  # sets only options the adapter's precision sweep sets: a point of the default curve
CONFIG_MARKS = frozenset({IDENTIFIES_NETWORKS, LARGE_SYSTEMS, ABLATION, SWEEP_POINT})
# The scenarios a config may be made for (`AbstractSolver.CASE_SCENARIOS`)
SCENARIOS = (STEP_SCENARIO, FAULT_SCENARIO)

COARSE_RTOL = 1e-3  # ode45's rtol: a work-precision sweep starts here, a verdict's reaches coarser (`step_sweep`)
_INF = float("inf")
_F64 = np.dtype(np.float64)
_FAST_MAX = 16  # entries checked in pure Python; numpy's reductions cost ~1-2 us each below this


def _small_vector(value: Any, nonnegative: bool) -> tuple[np.ndarray | None, float, float]:
    """(value, min, max) when `value` is a 1-D float64 array of 1 to `_FAST_MAX` entries, all
    finite (and >= 0 with `nonnegative`); (None, inf, inf) otherwise: the caller then validates
    with `check_array`, which decides and words the error. Cheap in pure Python for a few entries:
    numpy's own reductions cost ~1-2 us each at this size."""
    if type(value) is not np.ndarray or value.dtype is not _F64:  # float64's descriptor is a singleton
        return None, _INF, _INF
    items = value.tolist()  # 0-D gives a float, 2-D a list of lists
    if type(items) is not list or not 0 < len(items) <= _FAST_MAX or type(items[0]) is not float:
        return None, _INF, _INF
    lowest = 0.0 if nonnegative else -_INF
    lo = hi = items[0]
    for x in items:  # a loop: the builtins sum, min and max cost ~0.2 us each here
        if not lowest <= x < _INF or x == -_INF:  # NaN fails every comparison
            return None, _INF, _INF
        if x < lo:
            lo = x
        elif x > hi:
            hi = x
    return value, lo, hi


class Trajectory(NamedTuple):
    """Solution on a grid: t (n_t,) s, P1 (n_p,) p.u., delta and omega (n_p, n_t, n) rad and rad/s,
    float64, in the order of the query (t as given, repeats kept), one entry per machine on the last
    axis (n = 1 for the SMIB: the shape rule has no special case)."""

    t: np.ndarray
    P1: np.ndarray
    delta: np.ndarray
    omega: np.ndarray


class Points(NamedTuple):
    """Solution at scattered points: sample i is every machine's delta (rad) and omega (rad/s) at
    time t[i] (s) for P1[i] (p.u.); t and P1 float64 (n_s,), delta and omega float64 (n_s, n)."""

    t: np.ndarray
    P1: np.ndarray
    delta: np.ndarray
    omega: np.ndarray


class FitReport(NamedTuple):
    """What `fit()` did: wall seconds, iterations (0 for ODE solvers), final loss (NaN if none).
    `reused_s`: seconds of training done before this fit and reused by it (a model shared by every
    case, loaded from its own cache), which `fit()` adds to the wall seconds: a model's cost is its
    training wherever it was paid."""

    seconds: float
    iterations: int = 0
    loss: float = float("nan")
    message: str = ""
    reused_s: float = 0.0


class Identification(NamedTuple):
    """Estimated inertia m and damping d of every machine, (n,) p.u., wall seconds, iterations,
    success, message, and their uncertainty: standard errors m_se, d_se (n,) p.u. (delta method,
    value x the standard error of its log) and 95 % intervals m_ci95, d_ci95 (n, 2), rows (low,
    high) p.u. (exp(log value +- q se_log), q the Student-t quantile; Gauss-Newton, i.e. linearised
    at the estimate, independent errors of one variance); NaN when unknown. success is False, with
    the reason in message, when the data or the fit cannot support the estimate (the rules of
    `solvers.identification`)."""

    m: np.ndarray
    d: np.ndarray
    seconds: float
    iterations: int
    success: bool
    message: str
    m_se: np.ndarray
    d_se: np.ndarray
    m_ci95: np.ndarray
    d_ci95: np.ndarray


class StepCount(NamedTuple):
    """The work of one trajectory over a step case's horizon [0, t_final] s
    (`AbstractSolver.step_count`): `steps` the accepted steps; `rhs_evals` the right-hand side
    evaluations as the integrator counts them (rejected steps and finite-difference Jacobian
    columns included), None where it does not count them."""

    steps: int
    rhs_evals: int | None = None


_new_trajectory = tuple.__new__


class SolveError(RuntimeError):
    """An integration or evaluation failed; the message names the solver and P1."""


class PartialSolveError(SolveError):
    """A `solve` that failed part-way, with what it had before: `delta` (len(P1), len(t_query), n)
    rad at the query's times, and `held` (len(P1),) s: each trajectory is the model's answer at the
    times before it (inf for one that failed nowhere) and NaN from it on. An adapter that stops a
    trajectory where its model stops holding (a machine leaving a trained domain, a Newton that does
    not converge) may raise it instead of `SolveError`; a caller that can judge a trajectory from
    its beginning (the cct suite's criterion, crossed before the failure) may use it, every other
    caller sees a `SolveError`."""

    def __init__(self, message: str, delta: np.ndarray, held: np.ndarray) -> None:
        super().__init__(message)
        self.delta, self.held = delta, held


class NotFittedError(RuntimeError):
    """`solve` was called before `fit` (or `load`)."""


class AbstractSolver(abc.ABC):
    """Base class of every adapter. A new adapter must:

    1. set `name` (the registry key), `SCHEMA` (a `solvers.options.OptionSchema`: every option
       with its type, range and default, declared once; `OPTIONS`, name -> default, is derived
       from it, and anything else is rejected) and optionally `CONFIGS` (named option sets;
       `DEFAULT_CONFIG`, "default", is {}); checks that need the case go in `_check_options`,
    2. implement `_fit()`: the untimed preparation (build integrators, JIT, train), returning a
       `FitReport` or None; `fit()` times it and marks the solver ready,
    3. implement `_solve(t, P1)` on validated arrays (t: 1-D, >= 0 s, any order, repeats allowed;
       P1: 1-D) returning `(delta, omega)`, each (len(P1), len(t), n) for the case's n machines,
       in the order of t; generator 1's mechanical power is P1, the others' the case's p_m,
    4. implement `_identify(obs)` returning an `Estimate` (`solvers.identification`): m, d (n,),
       iterations, success, message and, where it can, the covariance of (log m, log d) with its
       degrees of freedom and condition number, and the search box; `identify()` validates and
       times it and applies the shared rules (enough distinct samples, bound, conditioning,
       interval width) that decide success,
    5. raise `SolveError` naming itself and P1 when an integration fails.
    An adapter that is only valid on the trained domain sets `bounded_domain = True`: `solve` then
    rejects t outside [0, t_final] or P1 outside [p1_min, p1_max] unless `extrapolate=True`.

    Capabilities are declared here, once, and read everywhere; nothing infers them from option
    names (`tests/test_plan.py` checks each declaration against the adapter's options):
    - `trains`: `fit` trains a model from a seed (option `seed`); runs repeat it over seeds;
    - `trained_per_case`: (with `trains`) a model is trained for each case, so a run's per-case
      training budget (`harness.settings.Settings.case_pinn_options`) applies; False for a model
      trained once for every case, whose budget is its own options;
    - `has_tolerance`: relative and absolute tolerances (options `rtol`, `atol`) set its accuracy;
    - `takes_threads`: option `threads` sets its thread count; runs give it theirs;
    - `can_save`: `save(path)` writes a fitted model and `load(path)` reads it back (the model
      cache keeps trained models so);
    - `compiled`: queries run in compiled code (numba, XLA), not a Python-driven integrator loop;
      the verdicts rank the best Python-driven and the best compiled classical option apart;
    - `does_work`: False only for the do-nothing adapter that measures the interface itself;
    - `handles_faults`: it integrates a fault case (`Case.fault`: the network switched at the
      clearing time t_c, the scenario parameter) with the switch exact; an adapter without it
      refuses a fault case (ValueError), never integrating it as a step case;
    - `identifies`: `identify` estimates m and d (False: a surrogate fitted to the case's own
      parameters, whose `_identify` raises; runs leave identification out for it);
    - `classical_surrogate`: a model fitted to a classical solver's trajectories, no network (it
      `trains` and is `compiled`): the verdicts' second rival of every PINN, ranked by its
      `precision_sweep`;
    - `counts_steps`: `step_count(p1)` reports the steps (and, where its integrator counts them,
      the right-hand side evaluations) of one trajectory, integrated as `solve` integrates it;
    - `VARIANTS`: option sets that runs measure as rows of their own beside each config (a batch
      mode, a compiled query path);
    - `QUERY_OPTIONS`: its options that change only how a model is queried or how fast it is
      made, never what `fit` or `identify` compute (threads: up to the order of floating-point
      sums): a variant that sets only these is not identified again, and the model cache leaves
      them out of a trained model's key;
    - `CASE_KINDS`: config -> the kinds of case (`systems.cases.Case.kind`) it is made for; a
      config it does not list is made for every kind (`made_for`);
    - `CASE_SCENARIOS`: config -> the scenarios (`systems.cases.Case.scenario`: a step of P1,
      `STEP_SCENARIO`, or a fault cleared at t_c, `FAULT_SCENARIO`) it is made for; a config it does
      not list is made for both (`made_for`; an adapter without `handles_faults` still refuses a
      fault case when built);
    - `CONFIG_MARKS`: config -> what it is for, from `solvers.base.CONFIG_MARKS` (`marks`);
    - `blas_threads`: the BLAS thread count its queries are timed with, when it is not the run's
      (the fastest for the adapter, measured; see the class that sets it);
    - `precision_sweep(rtols)`: the option overrides of the work-precision curve (an adaptive
      solver: rtol with atol = rtol / 1000; a fixed-step one: its step), [] for a single point.
    """

    name: ClassVar[str]
    SCHEMA: ClassVar[type[OptionSchema] | None] = None
    OPTIONS: ClassVar[Mapping[str, Any]] = {}  # derived from SCHEMA; set by hand only without one
    CONFIGS: ClassVar[Mapping[str, Mapping[str, Any]]] = {DEFAULT_CONFIG: {}}
    bounded_domain: ClassVar[bool] = False
    trains: ClassVar[bool] = False
    trained_per_case: ClassVar[bool] = True
    has_tolerance: ClassVar[bool] = False
    takes_threads: ClassVar[bool] = False
    can_save: ClassVar[bool] = False
    compiled: ClassVar[bool] = False
    does_work: ClassVar[bool] = True
    handles_faults: ClassVar[bool] = False
    identifies: ClassVar[bool] = True
    classical_surrogate: ClassVar[bool] = False
    counts_steps: ClassVar[bool] = False
    blas_threads: ClassVar[int | None] = None
    VARIANTS: ClassVar[tuple[Mapping[str, Any], ...]] = ()
    QUERY_OPTIONS: ClassVar[frozenset[str]] = frozenset()
    CASE_KINDS: ClassVar[Mapping[str, frozenset[str]]] = {}
    CASE_SCENARIOS: ClassVar[Mapping[str, frozenset[Scenario]]] = {}
    CONFIG_MARKS: ClassVar[Mapping[str, frozenset[str]]] = {}

    def precision_sweep(self, rtols: Sequence[float]) -> list[dict[str, Any]]:
        """Option overrides, one dict per point of this adapter's work-precision curve, from the
        run's relative tolerances `rtols`. Default: a tolerance sweep (rtol, atol = rtol / 1000)
        for an adapter that `has_tolerance`, else no curve (the adapter is a single point).
        A fixed-step adapter overrides this to sweep its step (`step_sweep`)."""
        if not self.has_tolerance:
            return []
        return [{"rtol": float(r), "atol": float(r) * 1e-3} for r in rtols]

    @staticmethod
    def step_sweep(steps: Sequence[float], rtols: Sequence[float],
                   coarse: Sequence[float] = ()) -> list[dict[str, Any]]:
        """The sweep of a fixed step: the coarsest len(rtols) of `steps` (s, coarsest first), as
        many points as the run sweeps tolerances (a quick run's short sweep stays cheap). Each of
        `rtols` coarser than `COARSE_RTOL` (a verdict's sweep reaching for a PINN's error) is
        instead one of `coarse` (s, coarser than `steps`, coarsest first), the finest first."""
        extra = min(len(coarse), sum(r > COARSE_RTOL for r in rtols))
        head = tuple(coarse[len(coarse) - extra:])
        return [{"dt": float(h)} for h in (*head, *steps[:len(rtols) - extra])]

    @classmethod
    def made_for(cls, config: str, kind: str, scenario: Scenario = STEP_SCENARIO) -> bool:
        """Whether named config `config` is made for cases of kind `kind` (`Case.kind`) whose
        scenario is `scenario` (`Case.scenario`)."""
        return kind in cls.CASE_KINDS.get(config, KINDS) and scenario in cls.CASE_SCENARIOS.get(config, SCENARIOS)

    @classmethod
    def marks(cls, config: str) -> frozenset[str]:
        """What named config `config` is declared for (`CONFIG_MARKS`; none by default)."""
        return frozenset(cls.CONFIG_MARKS.get(config, ()))

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        schema = cls.__dict__.get("SCHEMA")  # declared by this class, not inherited
        if schema is not None:
            if "OPTIONS" in cls.__dict__:
                raise TypeError(f"{cls.__name__}: declare options once, in SCHEMA; OPTIONS is derived")
            cls.OPTIONS = defaults(schema)
        declared: tuple[tuple[str, frozenset[Any]], ...] = (
            ("CASE_KINDS", frozenset(KINDS)), ("CASE_SCENARIOS", frozenset(SCENARIOS)), ("CONFIG_MARKS", CONFIG_MARKS))
        for attribute, known in declared:
            for config, values in getattr(cls, attribute).items():
                if config not in cls.CONFIGS:
                    raise TypeError(f"{cls.__name__}.{attribute} names {config!r}, none of its CONFIGS")
                if not set(values) <= known:
                    raise TypeError(f"{cls.__name__}.{attribute}[{config!r}]: unknown "
                                    f"{sorted(map(str, set(values) - known))}; known: {', '.join(sorted(map(str, known)))}")

    def __init__(self, case: Case, config: str = DEFAULT_CONFIG, **options: Any) -> None:
        if not isinstance(case, Case):
            raise ValueError(f"case must be a systems.cases.Case, got {type(case).__name__}")  # noqa: TRY004
        if config not in self.CONFIGS:
            raise ValueError(
                f"unknown config {config!r} for {self.name}; known: {', '.join(self.CONFIGS)}"
            )
        unknown = set(options) - set(self.OPTIONS)
        if unknown:
            raise ValueError(
                f"unknown option(s) {', '.join(sorted(unknown))} for {self.name}; "
                f"known: {', '.join(self.OPTIONS) or 'none'}"
            )
        if case.fault is not None and not self.handles_faults:
            raise ValueError(f"{self.name} does not integrate fault cases (case {case.name!r} switches its network "
                             "at the clearing time); adapters that do: those with handles_faults (solvers.fault_adapters())")
        self.case = case
        self.config = config
        self.options: dict[str, Any] = {**self.OPTIONS, **self.CONFIGS[config], **options}
        if self.SCHEMA is not None:
            self.options = validate_options(self.SCHEMA, self.options, self.name)
        self._check_options()
        self.fitted = False
        self.fit_report: FitReport | None = None  # the last fit's (or the model cache's load's)

    def _check_options(self) -> None:
        """Checks `SCHEMA` cannot express (they depend on the case or the machine), run on the
        validated `self.options`; raise ValueError naming the option. None by default."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(case={self.case.name!r}, config={self.config!r})"

    def fit(self) -> FitReport:
        """Untimed preparation; returns a `FitReport` with its wall time in seconds."""
        start = time.perf_counter()
        report = self._fit()
        seconds = time.perf_counter() - start
        self.fitted = True
        self.fit_report = FitReport(seconds=seconds) if report is None else report._replace(
            seconds=seconds + report.reused_s)
        return self.fit_report

    def solve(self, t_query, P1, extrapolate: bool = False) -> Trajectory:
        """delta (rad) and omega (rad/s) of every machine at times `t_query` (1-D, s, >= 0, any
        order) for each P1 (float or 1-D, the scenario parameter, `Case.scenario`: generator 1's
        mechanical power, p.u.; a fault case's clearing time t_c, s, >= 0); arrays of shape
        (len(P1), len(t_query), n), float64.

        Small float64 arrays and Python floats take a fast path (checked in pure Python: the whole
        call costs ~2 us with an adapter that does nothing); anything else goes through
        `check_array`. Both reject the same inputs."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: call fit() (or load()) before solve()")
        # The fast path, inlined (a Python call costs ~0.1 us here): see `_small_vector`.
        items = t_query.tolist() if type(t_query) is np.ndarray and t_query.dtype is _F64 else None
        t: np.ndarray | None  # None: not taken by the fast path
        p1: np.ndarray | None
        if type(items) is list and 0 < len(items) <= _FAST_MAX and type(items[0]) is float:
            t, t_hi = t_query, items[0]
            for x in items:
                if not 0.0 <= x < _INF:  # NaN fails every comparison
                    t = None
                    break
                if x > t_hi:  # noqa: PLR1730 - the builtin max costs ~0.2 us here
                    t_hi = x
        else:
            t = None
        if t is None:
            t = check_array("t_query", t_query, nonnegative=True)
            t_hi = float(t.max())
        if type(P1) is float and P1 - P1 == 0.0:  # a finite Python float
            p1, p_lo, p_hi = np.array((P1,)), P1, P1
        else:
            p1, p_lo, p_hi = _small_vector(P1, nonnegative=False)
            if p1 is None:
                p1 = check_array("P1", P1, promote=True)
                p_lo, p_hi = float(p1.min()), float(p1.max())
        if p_lo < 0.0 and self.case.fault is not None:
            raise ValueError(f"P1: a clearing time t_c must be >= 0 s, got {p_lo!r}")
        if self.bounded_domain and not extrapolate:
            self._check_domain(t_hi, p_lo, p_hi)
        delta, omega = self._solve(t, p1)
        if type(delta) is not np.ndarray or delta.dtype != _F64:
            delta, omega = np.asarray(delta, np.float64), np.asarray(omega, np.float64)
        return _new_trajectory(Trajectory, (t, p1, delta, omega))  # NamedTuple.__new__ is ~3x slower

    def _check_domain(self, t_max: float, p_min: float, p_max: float) -> None:
        case = self.case
        if t_max > case.t_final:
            raise ValueError(
                f"t_query reaches {t_max!r} s, outside the trained domain [0, {case.t_final}] s "
                "(pass extrapolate=True to evaluate anyway)"
            )
        if p_min < case.p1_min or p_max > case.p1_max:
            symbol, unit = case.scenario.symbol, case.scenario.unit  # P1 p.u., or a fault case's t_c s
            raise ValueError(
                f"{symbol} spans [{p_min!r}, {p_max!r}] {unit}, outside the trained domain "
                f"[{case.p1_min}, {case.p1_max}] {unit} (pass extrapolate=True to evaluate anyway)"
            )

    def solve_points(self, t_query, P1, extrapolate: bool = False) -> Points:
        """delta (rad) and omega (rad/s) at the pairs (t_query[i] s, P1[i] p.u.) of two 1-D arrays
        of one length n (a batch of single-point queries, as a Monte Carlo or an optimiser loop
        makes them): t, P1 (n_s,) and delta, omega (n_s, n) float64. Validated like `solve`, domain
        included."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: call fit() (or load()) before solve_points()")
        t = check_array("t_query", t_query, nonnegative=True)
        p1 = check_array("P1", P1)
        if t.size != p1.size:
            raise ValueError(f"t_query has {t.size} entries, P1 has {p1.size}: solve_points needs pairs")
        if self.case.fault is not None and p1.min() < 0.0:
            raise ValueError(f"P1: a clearing time t_c must be >= 0 s, got {float(p1.min())!r}")
        if self.bounded_domain and not extrapolate:
            self._check_domain(float(t.max()), float(p1.min()), float(p1.max()))
        delta, omega = self._solve_points(t, p1)
        return Points(t, p1, np.asarray(delta, np.float64), np.asarray(omega, np.float64))

    def step_count(self, p1: float) -> StepCount:
        """The steps of one trajectory at generator-1 power `p1` (p.u., within the case's range)
        over [0, t_final] s, integrated as `solve` integrates it, and its right-hand side
        evaluations where the integrator counts them. Adapters that declare `counts_steps`, on a
        step case; otherwise a ValueError saying which."""
        if not self.counts_steps:
            raise ValueError(f"{self.name} does not count its steps (counts_steps is False)")
        if self.case.fault is not None:
            raise ValueError(f"{self.name}: step_count takes a step case; {self.case.name!r} is a fault case")
        if not self.fitted:
            raise NotFittedError(f"{self.name}: call fit() (or load()) before step_count()")
        if not self.case.p1_min <= float(p1) <= self.case.p1_max:
            raise ValueError(f"P1 = {p1!r} p.u. is outside the case's range [{self.case.p1_min}, {self.case.p1_max}] p.u.")
        return self._step_count(float(p1))

    def _step_count(self, p1: float) -> StepCount:
        """`step_count` on a validated p1 (p.u.); an adapter with `counts_steps` overrides it."""
        raise NotImplementedError(f"{self.name} declares counts_steps but does not implement _step_count")

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega), each (n_s, n), at the pairs (t[i], P1[i]). Default: one `_solve` per pair;
        adapters that can do better (one compiled loop, one vectorised network call) override it."""
        delta, omega = np.empty((t.size, self.case.n)), np.empty((t.size, self.case.n))
        for i in range(t.size):
            d, o = self._solve(t[i:i + 1], P1[i:i + 1])
            delta[i], omega[i] = d[0, 0], o[0, 0]
        return delta, omega

    def identify(self, obs: Observations) -> Identification:
        """Estimate every machine's m and d (p.u.) from scattered observations of the case's system
        (obs.delta with one column per machine: a ValueError names it otherwise)."""
        if not isinstance(obs, Observations):
            raise ValueError(f"obs must be systems.cases.Observations, got {type(obs).__name__}")  # noqa: TRY004
        obs.check_machines(self.case)
        if self.case.fault is not None:
            raise ValueError(f"{self.name}: identification on a fault case is not supported (case {self.case.name!r})")
        start = time.perf_counter()
        # too little data is an outcome (success False), not a programming error; fewer samples than
        # unknowns leave nothing to fit, more are fitted and the estimate kept, though not trusted
        if len(obs) < 2:
            reason = data_shortfall(obs)
            assert reason is not None  # fewer than 2 samples are always too few (MIN_DISTINCT_SAMPLES > 1)
            nan = np.full(self.case.n, np.nan)
            return Identification(nan, nan, time.perf_counter() - start, 0, False, reason,
                                  nan, nan, np.full((self.case.n, 2), np.nan), np.full((self.case.n, 2), np.nan))
        est = Estimate(*self._identify(obs))  # a plain 5-tuple is an estimate without uncertainty
        verdict = assess(est, data_shortfall(obs))
        m = np.atleast_1d(np.asarray(est.m, np.float64))
        d = np.atleast_1d(np.asarray(est.d, np.float64))
        return Identification(
            m, d, time.perf_counter() - start, int(est.iterations), verdict.success,
            verdict.message, verdict.m_se, verdict.d_se, verdict.m_ci95, verdict.d_ci95,
        )

    @abc.abstractmethod
    def _fit(self) -> FitReport | None: ...

    @abc.abstractmethod
    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    @abc.abstractmethod
    def _identify(self, obs: Observations) -> Estimate: ...
