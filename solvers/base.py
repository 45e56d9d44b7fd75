"""The contract every swingbench solver adapter keeps, and the records it returns."""

from __future__ import annotations

import abc
import time
from collections.abc import Mapping
from typing import Any, ClassVar, NamedTuple

import numpy as np

from harness.cases import Case, Observations, check_array

__all__ = [
    "AbstractSolver",
    "FitReport",
    "Identification",
    "NotFittedError",
    "SolveError",
    "Trajectory",
]


class Trajectory(NamedTuple):
    """Solution on a grid: t (n_t,) s, P1 (n_p,) p.u., delta and omega (n_p, n_t) rad and rad/s,
    float64, in the order of the query (t as given, repeats kept)."""

    t: np.ndarray
    P1: np.ndarray
    delta: np.ndarray
    omega: np.ndarray


class FitReport(NamedTuple):
    """What `fit()` did: wall seconds, iterations (0 for ODE solvers), final loss (NaN if none)."""

    seconds: float
    iterations: int = 0
    loss: float = float("nan")
    message: str = ""


class Identification(NamedTuple):
    """Estimated inertia m and damping d (p.u.), wall seconds, iterations, success, message."""

    m: float
    d: float
    seconds: float
    iterations: int
    success: bool
    message: str


class SolveError(RuntimeError):
    """An integration or evaluation failed; the message names the solver and P1."""


class NotFittedError(RuntimeError):
    """`solve` was called before `fit` (or `load`)."""


class AbstractSolver(abc.ABC):
    """Base class of every adapter. A new adapter must:

    1. set `name` (the registry key), `OPTIONS` (every option with its default; anything else is
       rejected) and optionally `CONFIGS` (named option sets; "default" is {}),
    2. implement `_fit()`: the untimed preparation (build integrators, JIT, train), returning a
       `FitReport` or None; `fit()` times it and marks the solver ready,
    3. implement `_solve(t, P1)` on validated arrays (t: 1-D, >= 0 s, any order, repeats allowed;
       P1: 1-D) returning `(delta, omega)`, each (len(P1), len(t)), in the order of t,
    4. implement `_identify(obs)` returning `(m, d, iterations, success, message)`; `identify()`
       validates and times it,
    5. raise `SolveError` naming itself and P1 when an integration fails.
    An adapter that is only valid on the trained domain sets `bounded_domain = True`: `solve` then
    rejects t outside [0, t_final] or P1 outside [p1_min, p1_max] unless `extrapolate=True`.
    """

    name: ClassVar[str]
    OPTIONS: ClassVar[Mapping[str, Any]] = {}
    CONFIGS: ClassVar[Mapping[str, Mapping[str, Any]]] = {"default": {}}
    bounded_domain: ClassVar[bool] = False

    def __init__(self, case: Case, config: str = "default", **options: Any) -> None:
        if not isinstance(case, Case):
            raise ValueError(f"case must be a harness.cases.Case, got {type(case).__name__}")  # noqa: TRY004
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
        self.case = case
        self.config = config
        self.options: dict[str, Any] = {**self.OPTIONS, **self.CONFIGS[config], **options}
        self._check_options()
        self.fitted = False

    def _check_options(self) -> None:
        """Validate `self.options`; raise ValueError naming the option. Override to add checks."""
        for key in ("rtol", "atol"):
            if key in self.options and not (np.isfinite(self.options[key]) and self.options[key] > 0):
                raise ValueError(f"option {key} must be a positive number, got {self.options[key]!r}")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(case={self.case.name!r}, config={self.config!r})"

    def fit(self) -> FitReport:
        """Untimed preparation; returns a `FitReport` with its wall time in seconds."""
        start = time.perf_counter()
        report = self._fit()
        seconds = time.perf_counter() - start
        self.fitted = True
        if report is None:
            return FitReport(seconds=seconds)
        return report._replace(seconds=seconds)

    def solve(self, t_query, P1, extrapolate: bool = False) -> Trajectory:
        """delta (rad) and omega (rad/s) at times `t_query` (1-D, s, >= 0, any order) for each P1
        (float or 1-D, p.u.); arrays of shape (len(P1), len(t_query)), float64."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: call fit() (or load()) before solve()")
        t = check_array("t_query", t_query, nonnegative=True)
        p1 = check_array("P1", np.atleast_1d(P1))
        if self.bounded_domain and not extrapolate:
            self._check_domain(t, p1)
        delta, omega = self._solve(t, p1)
        return Trajectory(t, p1, np.asarray(delta, np.float64), np.asarray(omega, np.float64))

    def _check_domain(self, t: np.ndarray, p1: np.ndarray) -> None:
        case = self.case
        if t.max() > case.t_final:
            raise ValueError(
                f"t_query reaches {t.max()!r} s, outside the trained domain [0, {case.t_final}] s "
                "(pass extrapolate=True to evaluate anyway)"
            )
        if p1.min() < case.p1_min or p1.max() > case.p1_max:
            raise ValueError(
                f"P1 spans [{p1.min()!r}, {p1.max()!r}], outside the trained domain "
                f"[{case.p1_min}, {case.p1_max}] (pass extrapolate=True to evaluate anyway)"
            )

    def identify(self, obs: Observations) -> Identification:
        """Estimate m and d (p.u.) from scattered observations of the case's system."""
        if not isinstance(obs, Observations):
            raise ValueError(f"obs must be harness.cases.Observations, got {type(obs).__name__}")  # noqa: TRY004
        if len(obs) < 2:
            raise ValueError(f"identify needs at least 2 samples (the unknowns m, d), got {len(obs)}")
        start = time.perf_counter()
        m, d, iterations, success, message = self._identify(obs)
        return Identification(
            float(m), float(d), time.perf_counter() - start, int(iterations), bool(success), message
        )

    @abc.abstractmethod
    def _fit(self) -> FitReport | None: ...

    @abc.abstractmethod
    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    @abc.abstractmethod
    def _identify(self, obs: Observations) -> tuple[float, float, int, bool, str]: ...
