"""The adapter base class both PINN backends share: options, fit, identify, solve, save/load.

A backend subclass provides three hooks: `_prepare_backend` (threads, precision),
`_compile` (the training functions of one problem as numpy-in, numpy-out callables) and
`_make_evaluator` (the fast, warm query function of one network architecture). Everything else is
here, once: time-marching (`PinnConfig.window`) trains and queries its windows through the same
hooks (`solvers.pinn.evaluator.MarchingEvaluator`).
"""

from __future__ import annotations

import abc
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from solvers.base import (
    ABLATION,
    IDENTIFIES_NETWORKS,
    LARGE_SYSTEMS,
    AbstractSolver,
    FitReport,
    NotFittedError,
)
from solvers.identification import Estimate, linearised_covariance
from solvers.options import PositiveInt, StrictBool
from solvers.pinn.architecture import Architecture, init_theta, start_guess
from solvers.pinn.config import CONFIGS, PinnConfig, PinnConfigSchema
from solvers.pinn.evaluator import Evaluator, MarchingEvaluator, SwitchedEvaluator
from solvers.pinn.marching import TrainWindow, train_chain, train_phases
from solvers.pinn.model_file import load_model, save_model
from solvers.pinn.network import Physics
from solvers.pinn.optim import OptimResult, gauss_newton_cg, lbfgs, levenberg_marquardt
from solvers.pinn.problems import (
    PhaseEdges,
    Problem,
    forward_problem,
    identification_p_range,
    identification_problem,
    observations_within,
    phase_edges,
    window_edges,
    window_problem,
)
from solvers.pinn.split import output_scaled, train_split
from solvers.progress import progress_enabled
from systems.cases import FAULT_SCENARIO, NETWORK, SMIB, STEP_SCENARIO, Observations, Scenario, case_record

__all__ = ["PinnSolver", "Trainer"]


@dataclass(frozen=True)
class Trainer:
    """One problem's training functions, numpy float64 in and out (theta (P,)):
    residuals -> r (N,) (the loss is r @ r), jacobian -> dr/dtheta (N, P),
    loss_and_grad -> (loss, gradient (P,)); for the matrix-free optimiser, where the backend
    provides them, jvp (theta, v (P,)) -> J v (N,), vjp (theta, u (N,)) -> J^T u (P,) and
    diagonal -> diag(J^T J) (P,) (None: from `jacobian`)."""

    residuals: Callable[[np.ndarray], np.ndarray]
    jacobian: Callable[[np.ndarray], np.ndarray]
    loss_and_grad: Callable[[np.ndarray], tuple[float, np.ndarray]]
    jvp: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    vjp: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    diagonal: Callable[[np.ndarray], np.ndarray] | None = None

    def gauss_newton_diagonal(self, theta: np.ndarray) -> np.ndarray:
        """diag(J^T J) (P,): `diagonal`, or from the whole `jacobian` when the backend has none."""
        if self.diagonal is not None:
            return self.diagonal(theta)
        J = self.jacobian(theta)
        return np.einsum("ij,ij->j", J, J)


class PinnOptions(PinnConfigSchema):
    """Every `PinnConfig` field, and the adapter's own options (see `PinnSolver`)."""

    threads: PositiveInt = 2
    progress: StrictBool | None = None
    query: Literal["framework", "numba"] = "framework"


class PinnSolver(AbstractSolver):
    """A physics-informed neural network u(t, P1) -> delta for the case's swing equation.

    `fit()` trains on the paper's data (initial and boundary points whose delta comes from the tight
    reference `systems.reference.reference`, where the paper used MATLAB ode45) plus the physics
    residual on collocation points (see `PinnConfig` and `forward_problem`); `solve`
    evaluates delta (rad) and omega = d delta/dt (rad/s, forward-mode autodiff of the same network,
    or the second output of a two-output network) on the trained domain; `identify` trains a
    network with m = exp(log m), d = exp(log d) as extra parameters on the observations and the
    residual. `save(path)` / `load(path)` write and read `<path>.npz` (weights) and `<path>.json`
    (config, case, architecture, identified m and d); a model saved by one backend loads into the
    other.

    Shapes: `solve` gives (len(P1), len(t), n) for the case's n machines, `solve_points` (n_s, n);
    generator 1's mechanical power is P1, the others' the case's p_m. With `window` (the `marching`
    config) the model is a chain of window networks (`MarchingEvaluator`): `theta` is then
    (W, n_params) and `windows` the window edges (s); otherwise `windows` is None.

    Options: every `PinnConfig` field (seed, max_seconds, max_iterations, window, ...; the named
    CONFIGS set several), threads (2: the backend's intra-op threads; the optimiser's BLAS runs on one, see `_train`),
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
    handles_faults: ClassVar[bool] = True  # with `phases` (the fault-marching config), and only so
    takes_threads: ClassVar[bool] = True
    can_save: ClassVar[bool] = True
    # the compiled query path of the same trained model (the model cache ignores `query`)
    VARIANTS: ClassVar[tuple[dict[str, Any], ...]] = ({"query": "numba"},)
    QUERY_OPTIONS: ClassVar[frozenset[str]] = frozenset({"threads", "progress", "query"})
    SCHEMA = PinnOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = CONFIGS
    # One network learns the SMIB's swing; a multi-machine case's lightly damped 1-2 Hz swings need
    # time-marching windows (`solvers.pinn.config.CONFIGS`), which the SMIB does not.
    CASE_KINDS: ClassVar[dict[str, frozenset[str]]] = {
        "default": frozenset({SMIB}), "paper": frozenset({SMIB}), "paper-two-outputs": frozenset({SMIB}),
        "two-outputs": frozenset({SMIB}), "marching": frozenset({NETWORK}), "fault-marching": frozenset({NETWORK}),
        "fault-split": frozenset({NETWORK}), "marching-large": frozenset({NETWORK})}
    # a fault case's switched phases (`PinnConfig.phases`) are the fault-marching config's alone
    CASE_SCENARIOS: ClassVar[dict[str, frozenset[Scenario]]] = {
        config: frozenset({FAULT_SCENARIO if options.get("phases") else STEP_SCENARIO})
        for config, options in CONFIGS.items()}
    # the two-output networks weigh the paper's second formulation against its first; fault-split
    # fault-marching's one chain per piece against chains split at the model's own CCT
    CONFIG_MARKS: ClassVar[dict[str, frozenset[str]]] = {
        "paper-two-outputs": frozenset({ABLATION}), "two-outputs": frozenset({ABLATION}),
        "fault-split": frozenset({ABLATION}),
        "marching": frozenset({IDENTIFIES_NETWORKS}), "marching-large": frozenset({LARGE_SYSTEMS})}

    def _check_options(self) -> None:
        """A fault case needs the switched phases (option phases, the fault-marching config); a
        step case refuses them."""
        self.pinn_config = PinnConfig.from_options(self.options)  # validated already, by PinnOptions
        fault = self.case.fault is not None
        if self.pinn_config.phases != fault:
            raise ValueError(f"{self.name}: option phases must be {fault} for case {self.case.name!r} ("
                             + ("a fault case: use config fault-marching or fault-split)" if fault
                                else "a step case)"))

    # ---- backend hooks ---------------------------------------------------------------------

    @abc.abstractmethod
    def _prepare_backend(self) -> str:
        """Set threads and precision before the first computation; return a note ("" if none)."""

    @abc.abstractmethod
    def _compile(self, arch: Architecture, problem: Problem, physics: Physics, dtype: str) -> Trainer:
        """The training functions of `problem` for a network `arch` computing in `dtype`."""

    @abc.abstractmethod
    def _make_evaluator(self, arch: Architecture, dtype: str) -> Evaluator:
        """The query function of networks `arch` computing in `dtype`, compiled and warmed up."""

    # ---- training ----------------------------------------------------------------------------

    @property
    def physics(self) -> Physics:
        """The case's swing equations (`network.Physics`), built once."""
        if getattr(self, "_physics_case", None) is not self.case:
            self._physics, self._physics_case = Physics.of(self.case), self.case
        return self._physics

    def _train(self, arch: Architecture, problem: Problem, theta0: np.ndarray, max_iterations: int,
               deadline: float, what: str, trainer: Trainer | None = None) -> OptimResult:
        """Minimise `problem`'s loss from `theta0` with the configured optimiser, using `trainer`
        (compiled here when None)."""
        config = self.pinn_config
        trainer = trainer or self._compile(arch, problem, self.physics, config.dtype)
        bar = None
        progress = None
        if progress_enabled(self.options["progress"]):
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
                if config.optimizer == "gn-cg":
                    if trainer.jvp is None or trainer.vjp is None:
                        raise ValueError(f"{self.name}: optimizer 'gn-cg' needs Jacobian-vector products, "
                                         "which this backend does not provide")
                    return gauss_newton_cg(
                        trainer.residuals, trainer.jvp, trainer.vjp, trainer.gauss_newton_diagonal, theta0,
                        max_iterations=max_iterations, deadline=deadline, cg_iterations=config.cg_iterations,
                        cg_tol=config.cg_tol, progress=progress)
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
        if config.window is not None:
            return self._fit_marching(arch, deadline, note)
        problem = forward_problem(config, self.case)
        theta0 = init_theta(arch, config.seed)
        evaluator = self._query_evaluator(arch)  # compiled within the time budget
        result = self._train(arch, problem, theta0, config.max_iterations, deadline, "fit")
        self._set_model(arch, result.theta, evaluator)
        return FitReport(seconds=0.0, iterations=result.iterations, loss=result.loss,
                         message=result.message + (f"; {note}" if note else ""))

    def _fit_marching(self, arch: Architecture, deadline: float, note: str) -> FitReport:
        """Train the windows of a time-marching model in turn (`marching.train_chain`): window w's
        points get the start states the trained windows 0..w-1 reach at their P1 (from the
        framework's evaluator whatever `query` says, so that training does not depend on it); each
        window has `max_iterations` and an equal share of the time left. A fault case's switched
        model (`PinnConfig.phases`): `_fit_phases`."""
        config = self.pinn_config
        if config.phases:
            return self._fit_phases(arch, deadline, note)
        edges = window_edges(self.case.t_final, config.window)
        evaluator = self._query_evaluator(arch, edges)  # compiled within the time budget
        start0 = np.array([arch.delta0, arch.omega0], np.float64)
        chain = train_chain(self._window_trainer(arch, self.physics), lambda w: window_problem(config, self.case, edges, w),
                            np.diff(edges), lambda P1: start0, self._walker(arch, evaluator), deadline, label="fit window")
        self.windows = edges
        self._set_model(arch, np.stack(chain.thetas), evaluator)
        return FitReport(seconds=0.0, iterations=sum(chain.iterations), loss=float(np.sum(chain.losses)),
                         message=chain.summary(f"windows of {config.window:g} s") + (f"; {note}" if note else ""))

    def _fit_phases(self, arch: Architecture, deadline: float, note: str) -> FitReport:
        """Train a fault case's switched model (`PinnConfig.phases`, `marching.train_phases`; split
        at its own CCT with `split`, `split.train_split`: `split_s` is then the estimate, s, NaN
        without one)."""
        config = self.pinn_config
        edges = phase_edges(self.case, config.window, config.pieces)
        evaluator = self._query_evaluator(arch, edges)  # compiled within the time budget
        walker = self._walker(arch, evaluator)

        def trainer_of(physics: Physics, first: int, scale: float, iterations: int) -> TrainWindow:
            return self._window_trainer(arch, physics, first, scale, iterations)

        screen = ""
        if config.split:
            post_physics = Physics.of_phase(self.case, "post")

            def fit_window(problem: Problem, theta0: np.ndarray, iterations: int, until: float,
                           what: str) -> OptimResult:
                return self._train(arch, problem, theta0, iterations, until, what,
                                   self._compile(arch, problem, post_physics, config.dtype))

            on, post, edges, found = train_split(config, self.case, arch, edges, trainer_of, fit_window, walker,
                                                 deadline)
            screen = f"{found.summary()}; "
            evaluator = self._query_evaluator(arch, edges)
        else:
            on, post = train_phases(config, self.case, arch, edges, trainer_of, walker, deadline)
        self.windows = edges
        self._set_model(arch, np.stack(on.thetas + post.thetas), evaluator)
        message = (f"{screen}{on.summary(f'fault-on windows of {config.window:g} s')}; "
                   f"{post.summary(f'post-fault windows of {config.window:g} s')}")
        return FitReport(seconds=0.0, iterations=sum(on.iterations) + sum(post.iterations),
                         loss=float(np.sum(on.losses) + np.sum(post.losses)),
                         message=message + (f"; {note}" if note else ""))

    @property
    def split_s(self) -> float:
        """The clearing time (s) at which a model split at its own CCT (`PinnConfig.split`) passes
        from its stable side's chains to its unstable side's (a t_c at it is the unstable side's);
        NaN for any other model, and for a split model whose screen found no CCT (its pieces of
        clearing times equal; a split exactly at the range's midpoint reads the same)."""
        windows = getattr(self, "windows", None)
        if not (self.pinn_config.split and isinstance(windows, PhaseEdges)):
            return math.nan
        widths = np.diff(windows.pieces)
        return math.nan if np.allclose(widths, widths[0], rtol=1e-12) else float(windows.pieces[self.pinn_config.pieces])

    def _window_trainer(self, arch: Architecture, physics: Physics, first: int = 0, scale: float = 1.0,
                        iterations: int | None = None) -> TrainWindow:
        """`marching.train_chain`'s training function: window w (the model's window first + w,
        which seeds its initial weights; their output layer times `scale`) under `physics`,
        `iterations` (default `max_iterations`). The windows' problems differ in their arrays
        only: the backends compile once (`Problem.signature`)."""
        config = self.pinn_config
        trained: list[np.ndarray] = []  # the chain's windows so far, in order

        def train(problem: Problem, w: int, deadline: float, what: str) -> OptimResult:
            trainer = self._compile(arch, problem, physics, config.dtype)
            warm = config.warm_start and trained
            theta0 = trained[-1] if warm else output_scaled(arch, init_theta(arch, config.seed, window=first + w),
                                                            scale)
            result = self._train(arch, problem, theta0, iterations or config.max_iterations, deadline, what,
                                 trainer)
            trained.append(result.theta)
            return result

        return train

    def _walker(self, arch: Architecture, evaluator: Evaluator) -> Evaluator:
        """The framework's evaluator of one window (the query evaluator's own, unless `query` is
        "numba"): what training walks the windows' start states with."""
        if self.options["query"] != "framework":
            return self._make_evaluator(arch, self.pinn_config.dtype)
        if isinstance(evaluator, SwitchedEvaluator):
            return evaluator.on.inner
        assert isinstance(evaluator, MarchingEvaluator)  # a time-marching model's
        return evaluator.inner

    def _set_model(self, arch: Architecture, theta: np.ndarray, evaluator: Evaluator | None = None) -> None:
        """Use the network(s) `theta` ((n_params,), or (W, n_params) with `self.windows`)."""
        self.arch, self.theta = arch, np.asarray(theta, np.float64)
        if self.theta.ndim == 1:
            self.windows = None
        self._evaluate = evaluator or self._query_evaluator(arch, self.windows)
        self._evaluate.load(self.theta)

    def _query_evaluator(self, arch: Architecture, edges: np.ndarray | PhaseEdges | None = None) -> Evaluator:
        """The evaluator the `query` option names, compiled and warmed up; for a time-marching model
        (window `edges` s) the `MarchingEvaluator` over it, for a fault case's switched model
        (`PhaseEdges`) the `SwitchedEvaluator`."""
        if self.options["query"] == "numba":
            # numba is an optional dependency: a PINN queried through its framework works without it
            from solvers.pinn.compiled import NumbaEvaluator

            inner = NumbaEvaluator(arch, threads=self.options["threads"])
        else:
            inner = self._make_evaluator(arch, self.pinn_config.dtype)
        if isinstance(edges, PhaseEdges):
            return SwitchedEvaluator(inner, arch, edges.on, edges.post, edges.pieces)
        return inner if edges is None else MarchingEvaluator(inner, arch, edges)

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._evaluate(t, P1)

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._evaluate.points(t, P1)

    def _identify(self, obs: Observations) -> Estimate:
        """Train a network with log m_1..n, log d_1..n as its last 2n parameters (LM or L-BFGS, as
        configured), from `start_guess` (one network over the whole horizon, also in
        time-marching configurations).

        Uncertainty: the linearised covariance (2n x 2n) of (log m_1..n, log d_1..n) over every
        parameter of the trained network (`linearised_covariance`): how far the estimate moves with
        the observations' noise, the network's weights free to trade off against m and d, with
        the noise variance from the leave-one-out data residuals (a network that nearly
        interpolates its samples hides the noise in its own residuals)."""
        config = self.pinn_config
        deadline = config.deadline(time.perf_counter(), identification=True)
        note = self._prepare_backend()
        n = self.case.n
        obs = observations_within(config, obs)
        arch = Architecture.of(config, self.case, identification=True,
                               p_range=identification_p_range(self.case, obs))
        problem = identification_problem(config, self.case, obs)
        theta0 = init_theta(arch, config.seed, *start_guess(config, self.case))
        trainer = self._compile(arch, problem, self.physics, config.dtype)
        result = self._train(arch, problem, theta0, config.id_max_iterations, deadline, "identify", trainer)
        m, d = np.exp(result.theta[-2 * n:-n]), np.exp(result.theta[-n:])
        self.identification = {"m": m, "d": d, "arch": arch, "theta": result.theta}
        success = result.success and bool(np.isfinite(np.concatenate([m, d])).all())
        message = result.message + (f"; {note}" if note else "")
        if not success:
            return Estimate(m, d, result.iterations, False, message)
        # the Jacobian in float64 also for a float32 network (torch's nested forward mode, which
        # float32 training never uses, mixes the two precisions)
        exact = trainer if config.dtype == "float64" else self._compile(arch, problem, self.physics, "float64")
        cov, dof, condition = linearised_covariance(
            exact.jacobian(result.theta), exact.residuals(result.theta), problem.targets.size, 2 * n,
            rcond=100 * float(np.finfo(config.dtype).eps))
        return Estimate(m, d, result.iterations, True, message, cov, dof, condition)

    # ---- persistence -------------------------------------------------------------------------

    def save(self, path) -> tuple:
        """Write `<path>.npz` (weights, every window's for a time-marching model) and `<path>.json`
        (config, case, architecture, window edges, the last identification); returns the two paths.
        Loadable by either backend."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: nothing to save before fit() (or load())")
        return save_model(path, solver=self.name, config=self.pinn_config, case=self.case,
                          arch=self.arch, theta=self.theta, windows=self.windows,
                          identification=getattr(self, "identification", None))

    def load(self, path) -> PinnSolver:
        """Load what either backend saved at `path` (its config replaces this solver's config
        fields; threads, progress and query stay) and return this solver, fitted. A ValueError
        naming the file when the model is not of this solver's case: its case record differs, or
        (`load_model`, `check_model_case`) its networks are not those of its config for
        the case it records (machines, initial state, P1 and t ranges, window edges)."""
        saved = load_model(path)
        if saved["case"] != self.case:
            theirs = case_record(saved["case"])
            differ = [name for name, value in case_record(self.case).items() if theirs.get(name) != value]
            raise ValueError(f"{path}: saved for case {saved['case'].name!r}, this solver has case "
                             f"{self.case.name!r} (fields that differ: {', '.join(differ)})")
        self.options.update(saved["config"].to_json())
        self.pinn_config = saved["config"]
        self._prepare_backend()
        self.windows = saved["windows"]
        self._set_model(saved["arch"], saved["theta"])
        if saved["identification"] is not None:
            self.identification = saved["identification"]
        self.fitted = True
        return self
