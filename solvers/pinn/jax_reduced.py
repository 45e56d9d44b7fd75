"""The reduced-output PINN adapter (`reduced-pinn`): a multi-machine case's angles as k basis
coefficients of a time-marching JAX network, for grids of hundreds to thousands of machines, where
a network with one output per machine does not train (`solvers.pinn.reduced` has the model).

Configs: `default` (hybrid: a POD basis of numba-rk snapshots over the P1 range, trained on those
snapshots plus the projected physics residual) and `physics` (no solver data: the basis is the
linearised swing modes at the equilibrium plus the static response to P1, the loss the projected
physics residual alone).
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from pathlib import Path
from typing import Any, ClassVar, Literal

import jax
import jax.numpy as jnp
import numpy as np
from threadpoolctl import threadpool_limits

from solvers.base import LARGE_SYSTEMS, AbstractSolver, FitReport, NotFittedError
from solvers.classical.snapshots import Basis, chebyshev_nodes, pod_basis, solver_snapshots
from solvers.identification import Estimate
from solvers.options import (
    Fraction,
    NonNegativeInt,
    OptionSchema,
    PositiveFloat,
    PositiveInt,
    StrictBool,
    validate_options,
)
from solvers.pinn.optim import levenberg_marquardt
from solvers.pinn.reduced import (
    Layout,
    WindowData,
    init_weights,
    query_functions,
    walk_starts,
    window_functions,
)
from solvers.threads import configure_threads
from systems.cases import NETWORK, STEP_SCENARIO, Case, Observations, case_record
from systems.model import coupling

__all__ = ["ReducedOptions", "ReducedPinn", "linear_basis"]


class ReducedOptions(OptionSchema):
    """basis "pod" (snapshots' POD) or "linear" (linearised swing modes, `linear_basis`); modes k
    (None: the fewest POD modes keeping all but `pod_tolerance` of the snapshots' squared norm, at
    most `max_modes`; the linear basis takes `max_modes`); snapshots: numba-rk trajectories at that
    many Chebyshev-Lobatto P1 values (>= 2), every `snapshot_dt` s, DOP853 at `snapshot_rtol`;
    data: train on them (False: physics alone), their rates U^T omega too, weighted by `rate_weight` (s: rad/s
    against rad; None: not); window (s): the time-marching windows' length
    (the horizon is cut into ceil(t_final / window) equal windows); hidden_layers x width tanh;
    n_f collocation points per window where the projected physics residual is evaluated (its
    P_e is the full network's, n^2 per point), weighted by `physics_weight` (rad/s^2 against the
    data's rad); max_iterations Levenberg-Marquardt iterations per window, fewer where the last
    10 iterations lowered the window's loss by less than the fraction `ftol` of it (None: all of
    them); max_seconds (None: no limit) the whole fit's budget, shared among the windows left;
    seed draws weights and points."""

    basis: Literal["pod", "linear"] = "pod"
    modes: PositiveInt | None = None
    pod_tolerance: PositiveFloat = 1e-12
    max_modes: PositiveInt = 60
    snapshots: PositiveInt = 9
    snapshot_dt: PositiveFloat = 0.05
    snapshot_rtol: PositiveFloat = 1e-9
    data: StrictBool = True
    rate_weight: PositiveFloat | None = None
    window: PositiveFloat = 1.0
    hidden_layers: PositiveInt = 2
    width: PositiveInt = 20
    n_f: NonNegativeInt = 16
    physics_weight: PositiveFloat = 0.01
    max_iterations: PositiveInt = 150
    ftol: Fraction | None = 0.01
    max_seconds: PositiveFloat | None = None
    seed: NonNegativeInt = 0
    threads: PositiveInt = 2


def linear_basis(case: Case, modes: int) -> Basis:
    """`modes` orthonormal directions from the swing equation alone: the static response K^+ e_1
    to generator 1's power and the `modes` - 1 slowest modes of M^-1 K (K = dP_e/d delta at delta0,
    symmetrised), K the network's synchronising matrix. energy is NaN (no snapshots)."""
    k = coupling(case)
    delta0 = np.asarray(case.delta0, np.float64)
    diff = delta0[:, None] - delta0[None, :]
    X = k.C * np.sin(diff) - k.S * np.cos(diff)  # dP_e,i / d delta_j, i != j
    np.fill_diagonal(X, 0.0)
    K = X - np.diag(X.sum(1) + k.c_inf * np.sin(delta0) - k.s_inf * np.cos(delta0))
    K = 0.5 * (K + K.T)  # the symmetric part: positive semi-definite at a stable equilibrium
    m = np.asarray(case.m, np.float64)
    root = 1.0 / np.sqrt(m)
    _, vectors = np.linalg.eigh(root[:, None] * K * root[None, :])
    slow = root[:, None] * vectors[:, :max(modes - 1, 0)]
    static = np.linalg.lstsq(K, np.eye(case.n)[0], rcond=None)[0]
    q, _ = np.linalg.qr(np.column_stack([static, slow])[:, :modes])
    return Basis(np.ascontiguousarray(q), float("nan"))


def _check_shapes(file: Path, layout: Layout, arrays: dict[str, np.ndarray], case: Case) -> None:
    """A ValueError naming `file` unless its arrays fit `layout` and `case`: thetas (windows covering
    t_final, n_params), U (n, k), delta0 (n,), v0 (k,)."""
    n, k = case.n, layout.sizes[-1]
    windows = max(1, math.ceil(case.t_final / layout.window - 1e-9))
    expected = {"thetas": (windows, layout.n_params), "U": (n, k), "delta0": (n,), "v0": (k,)}
    for key, shape in expected.items():
        if arrays[key].shape != shape:
            raise ValueError(f"{file}: {key} has shape {arrays[key].shape}, its layout and case "
                             f"{case.name!r} need {shape}")


def _record_digest(case: Case) -> str:
    """sha256 of `case_record(case)` (as the model cache's key writes it): a saved model's case."""
    return hashlib.sha256(json.dumps(case_record(case), sort_keys=True, default=str).encode()).hexdigest()


class ReducedPinn(AbstractSolver):
    """A reduced-output PINN on JAX, float64 (`solvers.pinn.reduced`): delta = delta0 + U a(t, P1),
    omega = U a', the coefficients a (k,) from a chain of window networks of (tau, P1).

    `fit` makes the basis (and the snapshots, whose integration counts in its time), then trains
    the windows in turn by Levenberg-Marquardt; its message gives the seconds of the snapshots and
    of the basis apart, k and the energy kept. Multi-machine step cases only. Queries: one jitted
    XLA function a shape (grid or points), every P1 walked through the windows. Shapes as the
    contract: (len(P1), len(t), n) and (n_s, n). Deterministic for a seed and thread count.
    `save(path)` writes `<path>.npz` (the windows' weights, the basis, the start, the network's
    layout and the options), which `load(path)` reads back into a solver of the same case."""

    name: ClassVar[str] = "reduced-pinn"
    SCHEMA = ReducedOptions
    CONFIGS: ClassVar[dict[str, dict[str, Any]]] = {
        "default": {},
        "physics": {"basis": "linear", "data": False, "n_f": 64, "physics_weight": 1.0, "max_modes": 40},
    }
    CASE_KINDS: ClassVar[dict[str, frozenset[str]]] = {c: frozenset({NETWORK}) for c in CONFIGS}
    CASE_SCENARIOS: ClassVar[dict[str, frozenset]] = {c: frozenset({STEP_SCENARIO}) for c in CONFIGS}
    CONFIG_MARKS: ClassVar[dict[str, frozenset[str]]] = {c: frozenset({LARGE_SYSTEMS}) for c in CONFIGS}
    bounded_domain: ClassVar[bool] = True
    trains: ClassVar[bool] = True
    identifies: ClassVar[bool] = False
    takes_threads: ClassVar[bool] = True
    compiled: ClassVar[bool] = True
    can_save: ClassVar[bool] = True
    QUERY_OPTIONS: ClassVar[frozenset[str]] = frozenset({"threads"})

    def _check_options(self) -> None:
        options, case = self.options, self.case
        if case.kind != NETWORK:
            raise ValueError(f"{self.name} is made for multi-machine cases; case {case.name!r} is a {case.kind} case")
        if options["snapshots"] < 2:
            raise ValueError(f"{self.name}: option snapshots must be at least 2 (a basis over the P1 range), "
                             f"got {options['snapshots']}")
        if options["modes"] is not None and options["modes"] > case.n:
            raise ValueError(f"{self.name}: option modes={options['modes']} is larger than the case's "
                             f"{case.n} machines allow")
        if options["basis"] == "linear" and options["data"]:
            raise ValueError(f"{self.name}: option basis='linear' is the physics-only basis: set data=False")

    def _fit(self) -> FitReport:
        options, case = self.options, self.case
        start = time.perf_counter()
        deadline = math.inf if options["max_seconds"] is None else start + options["max_seconds"]
        threads = configure_threads(options["threads"])
        delta0 = np.asarray(case.delta0, np.float64)
        nodes = chebyshev_nodes(case.p1_min, case.p1_max, options["snapshots"])
        t_data = np.linspace(0.0, case.t_final, round(case.t_final / options["snapshot_dt"]) + 1)
        snapshot_s = basis_s = 0.0
        if options["basis"] == "pod":
            snapshots, rates = solver_snapshots(case, nodes, t_data, options["snapshot_rtol"])
            snapshots = snapshots - delta0
            snapshot_s = time.perf_counter() - start
            basis = pod_basis(snapshots, options["modes"], options["pod_tolerance"], most=options["max_modes"])
        else:
            basis = linear_basis(case, options["modes"] or min(options["max_modes"], case.n))
        basis_s = time.perf_counter() - start - snapshot_s
        U = basis.vectors
        count = max(1, math.ceil(case.t_final / options["window"] - 1e-9))
        layout = Layout((2,) + (options["width"],) * options["hidden_layers"] + (basis.modes,),
                        case.t_final / count, case.p1_min, case.p1_max)
        v0 = np.asarray(case.omega0, np.float64) @ U
        targets = (snapshots @ U, rates @ U) if options["data"] else None
        rng = np.random.default_rng(np.random.SeedSequence([options["seed"], 0xC0110C]))
        thetas = np.zeros((0, layout.n_params))
        theta = init_weights(layout, options["seed"])
        iterations, losses = 0, []
        for w in range(count):
            data = self._window_data(layout, thetas, w, nodes, t_data, targets, v0, rng)
            residuals, jacobian, normal_equations = window_functions(case, layout, U, delta0, data,
                                                                     options["physics_weight"], options["rate_weight"] or 0.0)
            if basis.modes <= options["width"]:  # J^T J from J costs n k P^2 against n width P_h^2: k > width pays
                normal_equations = None
            now = time.perf_counter()
            with threadpool_limits(limits=1, user_api="blas"):  # XLA has the threads (as PinnSolver._train)
                result = levenberg_marquardt(residuals, jacobian, theta, max_iterations=options["max_iterations"],
                                             deadline=now + (deadline - now) / (count - w),
                                             normal_equations=normal_equations, ftol=options["ftol"] or 0.0)
            theta = result.theta  # the next window starts from this one's weights
            thetas = np.vstack([thetas, theta])
            iterations += result.iterations
            losses.append(result.loss)
        self._set_model(layout, thetas, U, delta0, v0)
        worst = int(np.argmax(losses))
        message = "; ".join(filter(None, (
            threads, f"basis {options['basis']}: {basis.modes} modes (energy kept {basis.energy:.12g})",
            f"snapshots {nodes.size} x {t_data.size} times in {snapshot_s:.3g} s, basis in {basis_s:.3g} s",
            f"{count} windows, {iterations} LM iterations, largest loss {losses[worst]:.3g} in window {worst + 1}")))
        return FitReport(seconds=0.0, iterations=iterations, loss=float(sum(losses)), message=message)

    def _set_model(self, layout: Layout, thetas: np.ndarray, U: np.ndarray, delta0: np.ndarray,
                   v0: np.ndarray) -> None:
        """Make the queries of a trained model: `thetas` (windows, parameters), `U` (n, k), `delta0`
        (n,) rad, `v0` (k,) rad/s; compiles the common shapes."""
        self._layout, self._queries = layout, query_functions(layout)
        with jax.enable_x64(True):
            self._args = tuple(jnp.asarray(x) for x in (thetas, U, delta0, v0))
        self._solve(np.linspace(0.0, self.case.t_final, 201), np.array([self.case.p1_min]))
        self._solve_points(np.array([self.case.t_final]), np.array([self.case.p1_min]))

    def save(self, path) -> tuple[Path]:
        """Write the fitted model to `<path>.npz`; returns that path."""
        if not self.fitted:
            raise NotFittedError(f"{self.name}: nothing to save before fit() (or load())")
        out = Path(f"{path}.npz")
        layout = self._layout
        thetas, U, delta0, v0 = (np.asarray(x) for x in self._args)
        with open(out, "wb") as fh:
            np.savez(fh, thetas=thetas, U=U, delta0=delta0, v0=v0, sizes=np.asarray(layout.sizes),
                     bounds=np.array([layout.window, layout.p_lo, layout.p_hi]),
                     options=np.array(json.dumps({**self.options, "case": self.case.name})),
                     case_record=np.array(_record_digest(self.case)))
        return (out,)

    def load(self, path) -> ReducedPinn:
        """Load what `save(path)` wrote (its options replace this solver's, but threads) and return
        this solver, fitted. A ValueError naming the file when it holds non-finite weights, was
        saved for another case (its `case_record` differs: machines, parameters, ranges), holds
        options the schema refuses or arrays whose shapes do not fit its layout and the case."""
        file = Path(f"{path}.npz")
        with np.load(file) as saved:
            arrays = {key: saved[key] for key in saved.files}
        if not all(np.isfinite(arrays[key]).all() for key in ("thetas", "U", "delta0", "v0", "bounds")):
            raise ValueError(f"{file}: holds non-finite weights")
        options = json.loads(str(arrays["options"]))
        case = options.pop("case")
        if str(arrays["case_record"]) != _record_digest(self.case):
            raise ValueError(f"{file}: saved for case {case!r} ({arrays['U'].shape[0]} machines), not for this "
                             f"solver's case {self.case.name!r} ({self.case.n} machines; its record differs)")
        merged = {**self.options, **{k: v for k, v in options.items() if k not in self.QUERY_OPTIONS}}
        try:
            merged = validate_options(self.SCHEMA, merged, self.name)
        except ValueError as exc:
            raise ValueError(f"{file}: its options are not {self.name}'s: {exc}") from None
        window, p_lo, p_hi = (float(x) for x in arrays["bounds"])
        layout = Layout(tuple(int(x) for x in arrays["sizes"]), window, p_lo, p_hi)
        hidden = (merged["width"],) * merged["hidden_layers"]
        if layout.sizes[:-1] != (2, *hidden):
            raise ValueError(f"{file}: its layers {layout.sizes} are not those of its options "
                             f"(2, {merged['hidden_layers']} x {merged['width']}, k)")
        _check_shapes(file, layout, arrays, self.case)
        self.options = merged
        configure_threads(self.options["threads"])
        self._set_model(layout, arrays["thetas"], arrays["U"], arrays["delta0"], arrays["v0"])
        self.fitted = True
        return self

    def _window_data(self, layout: Layout, thetas: np.ndarray, w: int, nodes: np.ndarray, t_data: np.ndarray,
                     targets: tuple[np.ndarray, np.ndarray] | None, v0: np.ndarray,
                     rng: np.random.Generator) -> WindowData:
        """Window w's data points (the snapshots' times within it, at every node; `targets` the
        snapshots' (a, a') (n_nodes, n_t, k) each) and `n_f` uniform collocation points, each
        with the start the trained windows reach at P1."""
        t_w, length, k = w * layout.window, layout.window, v0.size
        empty = np.zeros(0), np.zeros(0), *np.zeros((4, 0, k))
        if targets is None:
            data = empty
        else:
            inside = np.flatnonzero((t_data >= t_w - 1e-12) & (t_data <= t_w + length + 1e-12))
            a_s, v_s = walk_starts(layout, thetas, nodes, v0)
            data = (np.tile(t_data[inside] - t_w, nodes.size), np.repeat(nodes, inside.size),
                    np.repeat(a_s, inside.size, 0), np.repeat(v_s, inside.size, 0),
                    *(x[:, inside].reshape(-1, k) for x in targets))
        n_f = self.options["n_f"]
        tau_f = rng.uniform(0.0, length, n_f)
        p_f = rng.uniform(layout.p_lo, layout.p_hi, n_f)
        a_f, v_f = walk_starts(layout, thetas, p_f, v0)
        return WindowData(*data, tau_f, p_f, a_f, v_f)

    def _run(self, fn: Any, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with jax.enable_x64(True):
            both = np.array(fn(*self._args, jnp.asarray(t), jnp.asarray(P1)))
        return both[0], both[1]

    def _solve(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self._queries[0], t, P1)

    def _solve_points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self._queries[1], t, P1)

    def _identify(self, obs: Observations) -> Estimate:
        raise ValueError(f"{self.name} does not identify m and d: its basis and networks are trained for the "
                         "case's own parameters")
