"""The adapter base class both PINN backends share: options, fit, identify, solve, save/load.

A backend subclass provides four hooks: `_prepare_backend` (threads, precision),
`_compile` (the training functions of one problem as numpy-in, numpy-out callables),
`_make_evaluator` (the fast, warm query function of one trained network) and `_ops` (its
`network.Ops`, for tests and tools). Everything else is here, once.
"""

from __future__ import annotations

import abc
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from systems.cases import Observations
from systems.model import SwingSystem, smib_system
from solvers.base import AbstractSolver, FitReport, NotFittedError
from solvers.identification import Estimate, gauss_newton_covariance
from solvers.options import PositiveInt, StrictBool
from solvers.pinn import spec
from solvers.pinn.optim import OptimResult, lbfgs, levenberg_marquardt
from solvers.pinn.spec import Architecture, PinnConfig, PinnConfigSchema, Problem

__all__ = ["Evaluator", "PinnSolver", "Trainer"]



class Evaluator(abc.ABC):
    """The warm query function of one network architecture: compiled (and warmed up) when made,
    so that `load(theta)` after training costs no compilation."""

    @abc.abstractmethod
    def load(self, theta: np.ndarray) -> None:
        """Use the flat float64 parameters `theta` from now on."""

    @abc.abstractmethod
    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s), each (len(P1), len(t)), for t (s) and P1 (p.u.), 1-D
        float64 numpy; float64 or float32 numpy out (the network's dtype)."""

    @abc.abstractmethod
    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """delta (rad) and omega (rad/s) at the pairs (t[i] s, P1[i] p.u.), each (n,), one
        vectorised evaluation; dtypes as `__call__`."""


@dataclass(frozen=True)
class Trainer:
    """One problem's training functions, numpy float64 in and out (theta (P,)):
    residuals -> r (N,) (the loss is r @ r), jacobian -> dr/dtheta (N, P),
    loss_and_grad -> (loss, gradient (P,))."""

    residuals: Callable[[np.ndarray], np.ndarray]
    jacobian: Callable[[np.ndarray], np.ndarray]
    loss_and_grad: Callable[[np.ndarray], tuple[float, np.ndarray]]


def _progress_enabled(setting: bool | None) -> bool:
    """None = auto: on for an interactive terminal, off under pytest, CI or a pipe."""
    if setting is not None:
        return bool(setting)
    if "PYTEST_CURRENT_TEST" in os.environ or "pytest" in sys.modules or os.environ.get("CI"):
        return False
    return sys.stderr.isatty()


class PinnOptions(PinnConfigSchema):
    """Every `PinnConfig` field, and the adapter's own options (see `PinnSolver`)."""

    threads: PositiveInt = 2
    progress: StrictBool | None = None
    query: Literal["framework", "numba"] = "framework"


class PinnSolver(AbstractSolver):
    """A physics-informed neural network u(t, P1) -> delta for the case's swing equation.

    `fit()` trains on the paper's data (initial and boundary points whose delta comes from the tight
    reference `systems.reference.reference`, where the paper used MATLAB ode45) plus the physics
    residual on collocation points (see `spec.PinnConfig` and `spec.forward_problem`); `solve`
    evaluates delta (rad) and omega = d delta/dt (rad/s, forward-mode autodiff of the same network,
    or the second output of a two-output network) on the trained domain; `identify` trains a
    network with m = exp(log m), d = exp(log d) as extra parameters on the observations and the
    residual. `save(path)` / `load(path)` write and read `<path>.npz` (weights) and `<path>.json`
    (config, case, architecture, identified m and d); a model saved by one backend loads into the
    other.

    Options: every `PinnConfig` field (seed, max_seconds, max_iterations, ...; the named CONFIGS
    set several), threads (2: the backend's intra-op threads; the optimiser's BLAS runs on one, see `_train`),
    progress (None: a tqdm bar on a terminal, quiet under pytest / CI / a pipe; True / False),
    query ("framework": `solve` runs the backend's own evaluator, in the config's dtype;
    "numba": `solvers.pinn.compiled.NumbaEvaluator`, the same network compiled by numba in float64,
    one native call a query, on `threads` threads for large grids; compiled within `fit` / `load`.
    Training does not depend on it. Both give the same numbers to ~1e-15 for float64 networks;
    for a float32 network "numba" evaluates the float32-trained weights in float64, so it differs
    from "framework" by float32 rounding, ~1e-6 of the largest value).
    Deterministic for a given seed and thread count.
    """

    bounded_domain: ClassVar[bool] = True
    trains: ClassVar[bool] = True
    # the compiled query path of the same trained model (the model cache ignores `query`)
    VARIANTS: ClassVar[tuple[dict[str, Any], ...]] = ({"query": "numba"},)
    SCHEMA = PinnOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = spec.CONFIGS

    def _check_options(self) -> None:
        self.pinn_config = PinnConfig.from_options(self.options)  # validated already, by PinnOptions

    # ---- backend hooks ---------------------------------------------------------------------

    @abc.abstractmethod
    def _prepare_backend(self) -> str:
        """Set threads and precision before the first computation; return a note ("" if none)."""

    @abc.abstractmethod
    def _compile(self, arch: Architecture, problem: Problem, system: SwingSystem, dtype: str) -> Trainer:
        """The training functions of `problem` for a network `arch` computing in `dtype`."""

    @abc.abstractmethod
    def _make_evaluator(self, arch: Architecture, dtype: str) -> Evaluator:
        """The query function of networks `arch` computing in `dtype`, compiled and warmed up."""

    # ---- training ----------------------------------------------------------------------------

    def _train(self, arch: Architecture, problem: Problem, theta0: np.ndarray, max_iterations: int,
               deadline: float, what: str, trainer: Trainer | None = None) -> OptimResult:
        """Minimise `problem`'s loss from `theta0` with the configured optimiser, using `trainer`
        (compiled here when None)."""
        config = self.pinn_config
        trainer = trainer or self._compile(arch, problem, smib_system(self.case), config.dtype)
        bar = None
        progress = None
        if _progress_enabled(self.options["progress"]):
            from tqdm.auto import tqdm

            bar = tqdm(desc=f"{self.name} {what}", unit="it", leave=False)  # budget: time or iterations

            def progress(iteration: int, loss: float) -> None:
                bar.set_postfix_str(f"loss {loss:.3e}", refresh=False)
                bar.update(iteration - bar.n)  # redraws at most every 0.1 s, with the elapsed time

        from threadpoolctl import threadpool_limits

        # The framework computes on `threads` threads; the optimiser's own numpy/scipy BLAS (J^T J,
        # a Cholesky of P x P, L-BFGS-B) runs on one. Both on 2 threads oversubscribe 2 cores:
        # OpenBLAS threads spin-wait between calls while torch's OpenMP or XLA's pool works
        # (measured, 2 threads, 2 cores, seed 0: torch `paper` 300 L-BFGS iterations 16.0 s -> 6.0 s,
        # torch `default` 100 LM iterations 15.3 s -> 4.4 s, JAX `default` 300 LM iterations
        # 8.8 s -> 5.5 s; the same iterates, bit for bit).
        try:
            with threadpool_limits(limits=1, user_api="blas"):
                if config.optimizer == "lm":
                    return levenberg_marquardt(
                        trainer.residuals, trainer.jacobian, theta0, max_iterations=max_iterations,
                        deadline=deadline, progress=progress)
                return lbfgs(trainer.loss_and_grad, theta0, history=config.lbfgs_history,
                             max_iterations=max_iterations, deadline=deadline, progress=progress)
        finally:
            if bar is not None:
                bar.close()

    def _fit(self) -> FitReport:
        deadline = self.pinn_config.deadline(time.perf_counter())
        note = self._prepare_backend()
        config = self.pinn_config
        arch = Architecture.of(config, self.case)
        problem = spec.forward_problem(config, self.case)
        theta0 = spec.init_theta(arch, config.seed)
        evaluator = self._query_evaluator(arch)  # compiled within the time budget
        result = self._train(arch, problem, theta0, config.max_iterations, deadline, "fit")
        self._set_model(arch, result.theta, evaluator)
        return FitReport(seconds=0.0, iterations=result.iterations, loss=result.loss,
                         message=result.message + (f"; {note}" if note else ""))

    def _set_model(self, arch: Architecture, theta: np.ndarray, evaluator: Evaluator | None = None) -> None:
        self.arch, self.theta = arch, np.asarray(theta, np.float64)
        self._evaluate = evaluator or self._query_evaluator(arch)
        self._evaluate.load(self.theta)

    def _query_evaluator(self, arch: Architecture) -> Evaluator:
        """The evaluator the `query` option names, compiled and warmed up."""
        if self.options["query"] == "numba":
            from solvers.pinn.compiled import NumbaEvaluator

            return NumbaEvaluator(arch, threads=self.options["threads"])
        return self._make_evaluator(arch, self.pinn_config.dtype)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._evaluate(t, P1)

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._evaluate.points(t, P1)

    def _identify(self, obs: Observations) -> Estimate:
        """Train a network with log m, log d as its last two parameters (LM or L-BFGS, as configured).

        Uncertainty: the Gauss-Newton covariance of (log m, log d) conditional on the trained network,
        held fixed: the swing residual f = m delta_tt + d delta_t + b sin(delta) - P1 (or its omega
        form) at the collocation points is linear in m and d, so its Jacobian columns m delta_tt and
        d delta_t are exactly r(2 m) - r(m) and r(2 d) - r(d) (two residual evaluations, no (N, P)
        Jacobian, the same for both optimisers); the data residuals do not depend on m, d. The
        residual variance is that of the swing residuals, s^2 = ||f||^2 / (n_f - 2). It ignores the
        network's own uncertainty (its weights trade off against m, d; the full Jacobian over all
        weights is rank-deficient), so it is a lower bound on the spread, not a calibrated interval."""
        config = self.pinn_config
        deadline = config.deadline(time.perf_counter(), identification=True)
        note = self._prepare_backend()
        arch = Architecture.of(config, self.case, identification=True,
                               p_range=spec.identification_p_range(self.case, obs))
        problem = spec.identification_problem(config, self.case, obs)
        theta0 = spec.init_theta(arch, config.seed, config.m_init, config.d_init)
        trainer = self._compile(arch, problem, smib_system(self.case), config.dtype)
        result = self._train(arch, problem, theta0, config.id_max_iterations, deadline, "identify", trainer)
        m, d = np.exp(result.theta[-2:])
        self.identification = {"m": float(m), "d": float(d), "arch": arch, "theta": result.theta}
        success = result.success and bool(np.isfinite([m, d]).all())
        message = result.message + (f"; {note}" if note else "")
        if not success:
            return Estimate(float(m), float(d), result.iterations, False, message)
        residuals = trainer.residuals
        n_data = problem.targets.size

        def swing(theta: np.ndarray) -> np.ndarray:  # the m, d-dependent swing residuals, weighted
            return residuals(theta)[n_data:].reshape(problem.t_f.size, -1)[:, -1]

        f = swing(result.theta)
        columns = []
        for k in (-2, -1):  # log m, log d: the residual is linear in exp of each
            doubled = result.theta.copy()
            doubled[k] += np.log(2.0)
            columns.append(swing(doubled) - f)
        cov, dof, condition = gauss_newton_covariance(np.stack(columns, axis=1), f)
        return Estimate(float(m), float(d), result.iterations, True, message, cov, dof, condition)

    # ---- persistence -------------------------------------------------------------------------

    def save(self, path) -> tuple:
        """Write `<path>.npz` (weights) and `<path>.json` (config, case, architecture, the last
        identification); returns the two paths. Loadable by either backend."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: nothing to save before fit() (or load())")
        return spec.save_model(path, solver=self.name, config=self.pinn_config, case=self.case,
                               arch=self.arch, theta=self.theta,
                               identification=getattr(self, "identification", None))

    def load(self, path) -> PinnSolver:
        """Load what either backend saved at `path` (its config replaces this solver's config
        fields; threads and progress stay) and return this solver, fitted."""
        saved = spec.load_model(path)
        if saved["case"] != self.case:
            raise ValueError(f"{path}: saved for case {saved['case']!r}, this solver has {self.case!r}")
        self.options.update(saved["config"].to_json())
        self.pinn_config = saved["config"]
        self._prepare_backend()
        self._set_model(saved["arch"], saved["theta"])
        if saved["identification"] is not None:
            self.identification = saved["identification"]
        self.fitted = True
        return self
