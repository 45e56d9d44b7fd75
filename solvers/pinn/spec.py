"""The one specification of the swingbench PINNs, shared by the torch and JAX backends.

Plain numpy and frozen dataclasses only (the configuration's fields are typed with the option
types of `solvers.options`, which validate them): the configuration (`PinnConfig`, `CONFIGS`), the network
layout and its flat parameter vector (`Architecture`), the seeded initial weights (`init_theta`),
the seeded training points (`forward_problem`, `identification_problem`), the loss weights and
the save/load format (`save_model`, `load_model`). The network and loss as functions of the
backend's ops live in `solvers.pinn.network`, the optimisers in `solvers.pinn.optim`.

Units: t in s, P1 in p.u., delta in rad, omega in rad/s, m in p.u. s^2/rad, d in p.u. s/rad.
A case has n machines (`systems.cases.Case`); the network has the inputs (t, P1) and one output per
machine (delta_1..n), or two (delta_1..n, then omega_1..n).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import model_validator
from scipy.stats import qmc

from solvers.atomic import write_atomically
from solvers.options import (
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    StrictBool,
    StrictChoice,
    dataclass_schema,
    validate_options,
)
from systems.cases import Case, Observations, standard_grid

__all__ = [
    "CONFIGS",
    "CONFIG_FIELDS",
    "FORMAT_VERSION",
    "Architecture",
    "CorruptModelError",
    "PinnConfig",
    "PinnConfigSchema",
    "Problem",
    "check_model_case",
    "forward_problem",
    "identification_problem",
    "init_theta",
    "load_model",
    "observations_within",
    "save_model",
    "start_guess",
    "weights_sha256",
    "window_edges",
    "window_problem",
]

# 2: the .json records the weights' sha256 (version 1 files, without it, still load);
# 3: N machines (tuples in case and architecture, per-machine m, d of an identification) and
#    time-marching models ("windows": the window edges, "theta" one row per window)
FORMAT_VERSION = 3


@dataclass(frozen=True)
class PinnConfig:
    """Everything that defines a PINN run; the defaults are the `default` configuration.

    Network: `hidden_layers` x `width` tanh, inputs (t, P1) normalised to [-1, 1] over the domain;
    `outputs` 1 (delta of each of the case's n machines: n network outputs) or 2 (delta and omega of
    each machine: 2n outputs); `hard_ic` builds delta(0) = delta0, delta'(0) = omega0 into the
    output of every machine (phi = 1 - exp(-t / 1 s); delta = delta0 + omega0 phi + phi^2 NN, and
    for two outputs omega = omega0 + phi NN_2), otherwise the initial condition is learnt from data
    only. `dtype` "float32" or "float64" for the network and its derivatives.
    Training data of `fit`: `n_u` points drawn without replacement from the t = 0 line and the
    P1 = p1_min / p1_max edges of the standard grid (values of every machine from
    `systems.reference.reference`), plus `n_f` Latin-hypercube collocation points (the data points
    are collocation points too); the physics residual is that of every machine.
    Time-marching (`window` s, None: one network over the whole horizon): [0, t_final] is cut into
    windows [t_w, t_w + window] (the last one ends at t_final), each with a network of its own,
    trained in turn: window w's hard initial condition is the state the trained earlier windows
    reach at t_w, as a function of P1 (delta = delta_w(P1) + omega_w(P1) phi + phi^2 NN(t - t_w, P1),
    phi = 1 - exp(-(t - t_w) / 1 s)), so the solution is continuous in delta and omega across
    window boundaries. `n_u` and `n_f` are then per window (`window_problem`: the data at random
    times of the window on the P1 edges), and so is `max_iterations`; `max_seconds` is the budget of
    the whole fit, shared among the windows still to train. Requires `hard_ic`.
    Loss = loss_scale * (MSE of the data + MSE of each residual) (Levenberg-Marquardt is invariant
    to the scale, and scipy's L-BFGS-B tests curvature pairs relatively: unlike torch.optim.LBFGS,
    neither needs it; it stays for experiments).
    `optimizer`: "lm" (Levenberg-Marquardt on the stacked residuals) or "lbfgs" (scipy L-BFGS-B,
    `lbfgs_history` pairs, as in the paper's TensorFlow ScipyOptimizerInterface). Training stops at
    `max_iterations` or on convergence: bounded by iterations, a seed gives the same network on a
    busy machine as on an idle one. `max_seconds` (None by default: no limit) adds a wall-clock
    budget counted from the start of `fit` (data, compilation and warm-up included): training then
    also stops before an iteration would end after it, and the result depends on the machine's load.
    Identification (`identify`, one network over the whole horizon, also in time-marching
    configurations): an `id_hidden_layers` x `id_width` network, the observations as data and
    `id_n_f` Latin-hypercube collocation points (0: the residual on the observations only, as in
    the paper); every machine's m_k and d_k are trained as exp(log m_k), exp(log d_k), starting at
    `m_init`, `d_init` (p.u., every machine) or, when None, at the geometric centre of each
    machine's search box (`Case.m_box`, `Case.d_box`; see `start_guess`); budgets
    `id_max_iterations` and optionally `id_max_seconds`. `id_t_max` (s; None: the whole horizon)
    restricts identification to the observations at t <= id_t_max and collocates on [0, id_t_max]:
    a single network does not learn a multi-machine case's swings beyond a few seconds (see
    "marching"), and a network that cannot represent the trajectory biases m and d.
    `seed` draws weights and points.
    """

    hidden_layers: PositiveInt = 2
    width: PositiveInt = 16
    outputs: Annotated[Literal[1, 2], StrictChoice] = 1
    hard_ic: StrictBool = True
    dtype: Literal["float32", "float64"] = "float64"
    n_u: NonNegativeInt = 40
    n_f: NonNegativeInt = 2000
    optimizer: Literal["lm", "lbfgs"] = "lm"
    loss_scale: PositiveFloat = 1.0
    lbfgs_history: PositiveInt = 50
    max_iterations: PositiveInt = 2000
    max_seconds: PositiveFloat | None = None
    seed: NonNegativeInt = 0
    id_hidden_layers: PositiveInt = 2
    id_width: PositiveInt = 16
    id_n_f: NonNegativeInt = 2000
    id_max_iterations: PositiveInt = 1000
    id_max_seconds: PositiveFloat | None = None
    id_t_max: PositiveFloat | None = None
    m_init: PositiveFloat | None = None
    d_init: PositiveFloat | None = None
    window: PositiveFloat | None = None

    def __post_init__(self) -> None:
        # the field types above, checked by `PinnConfigSchema`; the values it returns (an int
        # given for a float field becomes a float) replace the ones given
        checked = validate_options(PinnConfigSchema, dataclasses.asdict(self), type(self).__name__)
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    def deadline(self, start: float, identification: bool = False) -> float:
        """The `time.perf_counter()` value training must not pass: `start` + `max_seconds` (or
        `id_max_seconds`), infinite when that budget is None."""
        budget = self.id_max_seconds if identification else self.max_seconds
        return float("inf") if budget is None else start + budget

    @classmethod
    def from_options(cls, options: Mapping[str, Any]) -> PinnConfig:
        """The config from an adapter's options dict (other keys are ignored)."""
        return cls(**{name: options[name] for name in CONFIG_FIELDS if name in options})

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


class PinnConfigSchema(dataclass_schema(PinnConfig)):
    """`PinnConfig`'s fields as an option schema (the PINN adapters' options extend it), with the
    one rule between fields."""

    @model_validator(mode="after")
    def _has_training_points(self) -> PinnConfigSchema:
        if self.n_u + self.n_f == 0:
            raise ValueError("options n_u and n_f are both 0: fit would have no training points")
        return self

    @model_validator(mode="after")
    def _marching_has_hard_ic(self) -> PinnConfigSchema:
        if self.window is not None and not self.hard_ic:
            raise ValueError("option window (time-marching) needs hard_ic=True: each window starts "
                             "from the state the previous one reaches, built into its output")
        return self


CONFIG_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(PinnConfig))

# Named option sets of both adapters (overrides of the PinnConfig defaults).
CONFIGS: dict[str, dict[str, Any]] = {
    # The best we found (measured on 2 threads with a 55 s budget, seeds 0-2, rel. L2 of delta / omega:
    # JAX 1.2e-6..2.1e-6 / 4.5e-6..6.1e-6 in ~4500 LM iterations, torch 7.7e-6..1.3e-5 / 1.9e-5..4.1e-5
    # in ~1600; now bounded by 2000 LM iterations, 1000 for identification; the choices below were
    # made with JAX on 1 thread): float64 (float32 stalls the loss near 1e-7 relative), hard initial conditions (the paper's data-only initial condition leaves
    # 4e-3..8e-3 in float64), Levenberg-Marquardt (optim.py), and a small 2 x 16 network on 2000
    # points: a smaller Jacobian buys more LM iterations in the budget (Marquardt scaling, seed 0:
    # 3 x 20 reached 3.2e-5, 2 x 20 1.1e-5, 2 x 24 1.3e-5, 2 x 30 6.8e-4, 2 x 16 5.3e-6) and a
    # cheaper query. 1000 points left LM stuck at 7e-3 (too few for the parameters); 3000 or 4000
    # points gave the same accuracy as 2000 for more time per iteration.
    "default": {},
    # As published (Misyris et al. 2020): 5 x 10 tanh, N_u = 40 initial/boundary points,
    # N_f = 8000 LHS points, L-BFGS, float32, no hard constraints; identification 5 x 30 on the
    # observations only (no extra collocation points). L-BFGS runs until its line search stalls
    # (1600-2700 iterations: 16-25 s with JAX, 26-53 s with torch, 2 threads) or at 5000 iterations. The result depends on the seed: with the initial condition given only as data at a
    # few t = 0 points, omega(0) of the interior P1 is left to the network's interpolation
    # (measured rel. L2 delta, seeds 0-2: JAX 9.9e-3..2.0e-2, torch 9.3e-3..3.4e-2; the paper: 1.34e-2).
    "paper": {
        "hidden_layers": 5, "width": 10, "outputs": 1, "hard_ic": False, "dtype": "float32",
        "n_u": 40, "n_f": 8000, "optimizer": "lbfgs", "max_iterations": 5000,
        "id_hidden_layers": 5, "id_width": 30, "id_n_f": 0, "id_max_iterations": 5000,
    },
    # The paper's second variant: delta and omega as two outputs with the first-order residuals
    # f_omega = delta_t - omega and f_delta = m omega_t + d omega + b sin(delta) - P1; otherwise
    # as "paper" (measured: delta 9.5e-3..1.3e-2, omega 3.1e-2..4.2e-2; the paper: 9.43e-2 and
    # 1.51e-1; float64 did not do better within 120 s: 6.3e-3..1.2e-2).
    "paper-two-outputs": {
        "hidden_layers": 5, "width": 10, "outputs": 2, "hard_ic": False, "dtype": "float32",
        "n_u": 40, "n_f": 8000, "optimizer": "lbfgs", "max_iterations": 5000,
        "id_hidden_layers": 5, "id_width": 30, "id_n_f": 0, "id_max_iterations": 5000,
    },
    # The two-output formulation trained as "default" (hard initial conditions on delta and
    # omega, float64, Levenberg-Marquardt); measured, seed 0, 55 s: delta 2.5e-5 / omega 7.3e-5
    # (JAX), 1.3e-4 / 3.8e-4 (torch).
    "two-outputs": {"outputs": 2},
    # Time-marching for the multi-machine cases, whose 1-2 Hz lightly damped swings a single network
    # does not learn beyond ~2 s (a probe: COI rel. L2 ~1e-2 at 5 and 10 s): 0.5 s windows, each a
    # 2 x 20 tanh network on 400 collocation points (denser at the window's ends and the P1 edges),
    # no data points (the initial condition is exact), Levenberg-Marquardt in float64, up to 2000
    # iterations a window within 300 s for the whole fit (the windows share it; the result depends
    # on the machine's load). Measured with this config (seed 0, the full 300 s, 2 cores shared with
    # other jobs, load 1.2-4): COI rel. L2 over 10 s, JAX (threads 2) 2.8e-6 (wscc9, 16347 LM
    # iterations) and 1.3e-5 (kundur4, 10614); torch (threads 1) 1.4e-5 and 4.2e-5 (5775 and 4601
    # iterations). torch on 2 threads of a loaded machine stalls (one residual evaluation 0.87 s
    # against 9.5 ms on 1 thread, load 3.4: OpenMP waits on a descheduled thread). A 2 x 24
    # network reached 1.4e-5 on kundur4 with JAX in the same time (fewer LM iterations: the
    # Gauss-Newton matrix costs P^2 per point); 200 or 300 points per window generalised worse.
    # Identification (one network, not marched) on the first 1.5 s only (`id_t_max`), up to 5000 LM
    # iterations. A probe on wscc9 (JAX, seed 0, the bench's 100 noise-free samples, 60 s, start at
    # twice the truth), worst machine m / d: the whole 10 s 17 % / 3.6 %; id_t_max 3 s 0.08 % /
    # 3.7 %; 2 s 0.07 % / 0.9 %; 1.5 s 0.018 % / 0.12 % (the samples left: 15 of 100).
    "marching": {
        "window": 0.5, "hidden_layers": 2, "width": 20, "outputs": 1, "hard_ic": True, "dtype": "float64",
        "n_u": 0, "n_f": 400, "optimizer": "lm", "max_iterations": 2000, "max_seconds": 300.0,
        "id_t_max": 1.5, "id_max_iterations": 5000,
    },
}


@dataclass(frozen=True)
class Architecture:
    """The network and what its output means: layer sizes [2, width.., outputs x n], the input
    normalisation (t in [t_lo, t_hi] s and P1 in [p_lo, p_hi] p.u. map to [-1, 1]), the hard
    initial condition of the n machines (delta0 rad, omega0 rad/s, (n,) tuples; used when `hard_ic`
    unless the caller gives each point's own start state, as time-marching does) and `n_extra`
    trailing entries of the flat parameter vector (2n for identification: log m_1..n, log d_1..n).

    The output layer's columns are delta_1..n, then, for two outputs, omega_1..n. A time-marching
    window's network is the architecture of window length: t is the time since the window's start
    (t_lo = 0, t_hi = `PinnConfig.window`), the same network layout for every window."""

    sizes: tuple[int, ...]
    t_lo: float
    t_hi: float
    p_lo: float
    p_hi: float
    hard_ic: bool
    delta0: tuple[float, ...]
    omega0: tuple[float, ...]
    n_extra: int = 0

    def __post_init__(self) -> None:
        # tuples (hashable: the architecture keys compiled functions) of floats, also from JSON lists
        for name in ("delta0", "omega0"):
            object.__setattr__(self, name, tuple(float(x) for x in np.atleast_1d(getattr(self, name))))
        object.__setattr__(self, "sizes", tuple(int(x) for x in self.sizes))
        n = len(self.delta0)
        if len(self.omega0) != n or self.sizes[-1] not in (n, 2 * n) or self.n_extra not in (0, 2 * n):
            raise ValueError(f"Architecture: {n} machines (delta0), omega0 {len(self.omega0)}, output "
                             f"layer {self.sizes[-1]} and n_extra {self.n_extra} do not fit together")

    @classmethod
    def of(cls, config: PinnConfig, case: Case, identification: bool = False,
           p_range: tuple[float, float] | None = None) -> Architecture:
        """The network of `config` for `case`: the forward network (of one time-marching window when
        `config.window` is set) or, with `identification`, the identification network over the P1
        range `p_range` (default the case's)."""
        depth, width = ((config.id_hidden_layers, config.id_width) if identification
                        else (config.hidden_layers, config.width))
        p_lo, p_hi = p_range if p_range is not None else (case.p1_min, case.p1_max)
        if p_hi <= p_lo:  # a single P1: any positive width keeps the map finite
            p_lo, p_hi = p_lo - 0.5, p_hi + 0.5
        if identification:
            t_hi = config.id_t_max if config.id_t_max is not None else case.t_final
        else:
            t_hi = config.window if config.window is not None else case.t_final
        return cls(
            sizes=(2,) + (width,) * depth + (config.outputs * case.n,), t_lo=0.0, t_hi=float(t_hi),
            p_lo=float(p_lo), p_hi=float(p_hi), hard_ic=config.hard_ic,
            delta0=case.delta0, omega0=case.omega0, n_extra=2 * case.n if identification else 0,
        )

    @property
    def machines(self) -> int:
        """n, the number of machines."""
        return len(self.delta0)

    @property
    def outputs(self) -> int:
        """Outputs per machine: 1 (delta) or 2 (delta, omega)."""
        return self.sizes[-1] // self.machines

    @property
    def shapes(self) -> list[tuple[int, ...]]:
        """Shapes in the flat vector: W_0 (2, w), b_0 (w,), ..., W_L (w, outputs), b_L (outputs,)."""
        out: list[tuple[int, ...]] = []
        for n_in, n_out in zip(self.sizes[:-1], self.sizes[1:]):
            out += [(n_in, n_out), (n_out,)]
        return out

    @property
    def n_weights(self) -> int:
        return sum(int(np.prod(s)) for s in self.shapes)

    @property
    def n_params(self) -> int:
        return self.n_weights + self.n_extra

    def split(self, theta: Any) -> list[Any]:
        """The flat vector `theta` (numpy, torch or JAX: slicing and reshape only) as a list of
        views: W_0, b_0, ..., W_L, b_L in `shapes` order, then the (2n,) vector (log m_1..n,
        log d_1..n) when the architecture has the identification entries."""
        arrays, start = [], 0
        for shape in self.shapes:
            size = int(np.prod(shape))
            arrays.append(theta[start:start + size].reshape(shape))
            start += size
        if self.n_extra:
            arrays.append(theta[start:start + self.n_extra])
        return arrays

    def layers(self, params: list[Any]) -> list[tuple[Any, Any]]:
        """[(W, b), ...] of a split parameter list."""
        n = 2 * (len(self.sizes) - 1)
        return list(zip(params[0:n:2], params[1:n:2]))

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


def init_theta(arch: Architecture, seed: int, m_init=1.0, d_init=1.0, window: int = 0) -> np.ndarray:
    """The initial flat parameter vector (float64): Glorot/Xavier normal weights,
    std sqrt(2 / (fan_in + fan_out)), zero biases (as the paper's code), drawn from `seed` (and,
    for time-marching window `window` > 0, from the window number too: window 0 draws what a single
    network draws); then log m_init, log d_init (numbers or (n,) p.u.) when the architecture has the
    2n identification entries."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x5EED, *([window] if window else [])]))
    parts = []
    for n_in, n_out in zip(arch.sizes[:-1], arch.sizes[1:]):
        parts += [rng.normal(0.0, np.sqrt(2.0 / (n_in + n_out)), (n_in, n_out)).ravel(), np.zeros(n_out)]
    if arch.n_extra:
        n = arch.machines
        parts.append(np.log(np.concatenate([np.broadcast_to(np.asarray(m_init, np.float64), (n,)),
                                            np.broadcast_to(np.asarray(d_init, np.float64), (n,))])))
    return np.concatenate(parts)


def start_guess(config: PinnConfig, case: Case) -> tuple[np.ndarray, np.ndarray]:
    """Where identification starts, m and d (n,) p.u.: `config.m_init` / `d_init` for every machine,
    or where that is None the geometric centre sqrt(low high) of each machine's search box
    (`Case.m_box`, `Case.d_box`): the middle of the box on the log scale it is searched on. (For the
    SMIB cases, boxes (0.02, 2) and (0.005, 1): m 0.2, as the old default m_init, and d 0.0707,
    where the old default d_init was 0.1.)"""
    def centre(boxes) -> np.ndarray:
        box = np.asarray(boxes, np.float64)
        return np.sqrt(box[:, 0] * box[:, 1])

    m = centre(case.m_box) if config.m_init is None else np.full(case.n, config.m_init)
    d = centre(case.d_box) if config.d_init is None else np.full(case.n, config.d_init)
    return m, d


@dataclass(frozen=True)
class Problem:
    """The training points of one run, numpy float64.

    Data: t_u (s), p_u (p.u.), targets (n_u, k) with columns delta_1..n (rad) and, when k = 2n,
    omega_1..n (rad/s); collocation: t_f (s), p_f (p.u.). The loss is
    loss_scale * (sum over columns of mean((prediction - target)^2) + sum over residuals of
    mean(f^2)); `weights` gives the square roots of those factors, so that the loss is the sum of
    squares of the weighted residual vector that Levenberg-Marquardt works on.
    m, d: the physics, (n,) p.u. (None in identification, where they are trained).
    A time-marching window's problem has times since the window's start and each point's start
    state: start_u (n_u, 2, n) and start_f (n_f, 2, n), rows (delta rad, omega rad/s) of every
    machine at the window's start for that point's P1 (None for a single network)."""

    t_u: np.ndarray
    p_u: np.ndarray
    targets: np.ndarray
    t_f: np.ndarray
    p_f: np.ndarray
    loss_scale: float
    m: tuple[float, ...] | None = None
    d: tuple[float, ...] | None = None
    start_u: np.ndarray | None = None
    start_f: np.ndarray | None = None

    @property
    def weights(self) -> tuple[float, float]:
        """(weight of each data residual, weight of each physics residual)."""
        return (float(np.sqrt(self.loss_scale / max(self.t_u.size, 1))),
                float(np.sqrt(self.loss_scale / max(self.t_f.size, 1))))

    def loss(self, data_residuals: np.ndarray, physics_residuals: np.ndarray) -> float:
        """The loss (numpy reference) from data residuals (n_u, k) and physics residuals (n_f, r)."""
        w_u, w_f = self.weights
        return float(w_u ** 2 * np.sum(data_residuals ** 2) + w_f ** 2 * np.sum(physics_residuals ** 2))

    @property
    def signature(self) -> tuple:
        """What a compiled training function depends on besides the arrays (which it takes as
        arguments): the sizes, the loss weights and whether points carry start states. Problems
        of one signature (the windows of a time-marching fit) share one compilation."""
        return (self.t_u.size, self.t_f.size, self.targets.shape[1], self.weights, self.start_f is not None)


def latin_hypercube(case_t: tuple[float, float], p_range: tuple[float, float], n: int, seed: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """n seeded Latin-hypercube points (t s, P1 p.u.) on [t_lo, t_hi] x [p_lo, p_hi]."""
    if n == 0:
        return np.zeros(0), np.zeros(0)
    unit = qmc.LatinHypercube(d=2, rng=np.random.default_rng(np.random.SeedSequence([seed, 0xC011]))).random(n)
    return (case_t[0] + (case_t[1] - case_t[0]) * unit[:, 0],
            p_range[0] + (p_range[1] - p_range[0]) * unit[:, 1])


def forward_problem(config: PinnConfig, case: Case) -> Problem:
    """The training set of `fit`, as in the paper: `n_u` points drawn without replacement from the
    t = 0 line and the P1 = p1_min / p1_max edges of the standard 201 x 100 grid, with delta from
    the tight reference `systems.reference.reference` (the paper used MATLAB ode45 there), and
    `n_f` Latin-hypercube collocation points on [0, t_final] x [p1_min, p1_max] to which the data
    points are appended (as in the paper's code)."""
    from systems.reference import reference

    t_grid, p_grid = standard_grid(case)
    edges = np.array([case.p1_min, case.p1_max])
    delta_edges, _ = reference(case, t_grid, edges)
    delta_start, _ = reference(case, [0.0], p_grid)
    t_cand = np.concatenate([np.zeros(p_grid.size), t_grid, t_grid])
    p_cand = np.concatenate([p_grid, np.full(t_grid.size, edges[0]), np.full(t_grid.size, edges[1])])
    d_cand = np.concatenate([delta_start[:, 0], delta_edges[0], delta_edges[1]])  # (candidates, n)
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xDA7A]))
    pick = np.sort(rng.choice(t_cand.size, size=min(config.n_u, t_cand.size), replace=False))
    t_f, p_f = latin_hypercube((0.0, case.t_final), (case.p1_min, case.p1_max), config.n_f, config.seed)
    return Problem(
        t_u=t_cand[pick], p_u=p_cand[pick], targets=d_cand[pick],
        t_f=np.concatenate([t_f, t_cand[pick]]), p_f=np.concatenate([p_f, p_cand[pick]]),
        loss_scale=config.loss_scale, m=case.m, d=case.d,
    )


def window_edges(t_final: float, window: float) -> np.ndarray:
    """The edges 0 = t_0 < t_1 < ... < t_W = t_final (s) of time-marching windows of `window` s:
    W = ceil(t_final / window) windows, the last one shorter when `window` does not divide t_final
    (a remainder below 1e-9 of a window is dropped rather than made a window of its own)."""
    count = max(1, int(np.ceil(t_final / window - 1e-9)))
    return np.append(window * np.arange(count, dtype=np.float64), float(t_final))


def window_problem(config: PinnConfig, case: Case, edges: np.ndarray, w: int) -> Problem:
    """The training set of time-marching window w, on [edges[w], edges[w + 1]], in times since the
    window's start (s): `n_u` data points at seeded uniform times of the window on the P1 = p1_min
    and p1_max edges, alternately (every machine's delta from `systems.reference.reference`: the
    paper's boundary data, window by window), and `n_f` collocation points, a Latin hypercube
    denser towards the window's ends and the P1 edges, to which the data points are appended. The start states (`Problem.start_u`, `start_f`) are left None:
    they come from the trained earlier windows (`PinnSolver`)."""
    from systems.reference import reference

    t0, length = float(edges[w]), float(edges[w + 1] - edges[w])
    # a Latin hypercube on the unit square, each coordinate mapped by u -> (1 - cos(pi u)) / 2
    # (Chebyshev-like density): denser at the window's end, whose state starts the next window, and
    # at the P1 edges, where a network has no points beyond to lean on. Measured (kundur4, 2 x 20,
    # 400 points, 250 LM iterations per window): uniform points left 1.7e-4 rms angle error at
    # P1 = p1_max against 6e-6 inside (COI rel. L2 1.4e-4); mapped, 1.5e-5 at the edge (3.5e-5).
    u_t, u_p = latin_hypercube((0.0, 1.0), (0.0, 1.0), config.n_f, config.seed + 7919 * w)
    t_f = length * (1.0 - np.cos(np.pi * u_t)) / 2.0
    p_f = case.p1_min + (case.p1_max - case.p1_min) * (1.0 - np.cos(np.pi * u_p)) / 2.0
    t_u, p_u = np.zeros(0), np.zeros(0)
    targets = np.zeros((0, case.n))
    if config.n_u:
        rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xDA7A, w]))
        t_u = np.sort(rng.uniform(0.0, length, config.n_u))
        on_max = np.arange(config.n_u) % 2 == 1
        p_u = np.where(on_max, case.p1_max, case.p1_min)
        delta_edges, _ = reference(case, t0 + t_u, np.array([case.p1_min, case.p1_max]))  # (2, n_u, n)
        targets = np.where(on_max[:, None], delta_edges[1], delta_edges[0])
    return Problem(
        t_u=t_u, p_u=p_u, targets=targets, t_f=np.concatenate([t_f, t_u]), p_f=np.concatenate([p_f, p_u]),
        loss_scale=config.loss_scale, m=case.m, d=case.d,
    )


def identification_p_range(case: Case, obs: Observations) -> tuple[float, float]:
    """The P1 range (p.u.) an identification network is normalised over: the case's domain and the
    observations' extent together."""
    return float(min(case.p1_min, obs.P1.min())), float(max(case.p1_max, obs.P1.max()))


def observations_within(config: PinnConfig, obs: Observations) -> Observations:
    """The observations identification uses: those at t <= `config.id_t_max` (all when None).
    ValueError when none is."""
    if config.id_t_max is None:
        return obs
    keep = obs.t <= config.id_t_max
    if not keep.any():
        raise ValueError(f"id_t_max={config.id_t_max:g} s: no observation at t <= {config.id_t_max:g} s "
                         f"(the earliest is at {obs.t.min():g} s)")
    return Observations(obs.t[keep], obs.P1[keep], obs.delta[keep],
                        None if obs.omega is None else obs.omega[keep])


def identification_problem(config: PinnConfig, case: Case, obs: Observations) -> Problem:
    """The training set of `identify`: the observations (`observations_within` the identification
    horizon; delta (n_s, n), and omega when given) as data (targets (n_s, n) or (n_s, 2n)), and
    as collocation points the observations plus `id_n_f` Latin-hypercube points on
    [0, id_t_max] (None: [0, max(t_final, t_obs)]) x the P1 range."""
    obs = observations_within(config, obs)
    p_range = identification_p_range(case, obs)
    horizon = config.id_t_max if config.id_t_max is not None else max(case.t_final, float(obs.t.max()))
    t_f, p_f = latin_hypercube((0.0, horizon), p_range, config.id_n_f, config.seed)
    targets = obs.delta if obs.omega is None else np.concatenate([obs.delta, obs.omega], axis=1)
    return Problem(
        t_u=obs.t.copy(), p_u=obs.P1.copy(), targets=targets,
        t_f=np.concatenate([t_f, obs.t]), p_f=np.concatenate([p_f, obs.P1]),
        loss_scale=config.loss_scale,
    )


# ---------------------------------------------------------------------------------------------
# Save / load: <path>.npz holds the flat parameter vector(s) (float64; a time-marching model's
# "theta" has one row per window), <path>.json the rest.
# A model may come from a cache another process writes or a file a user copied: load checks it all.


def _paths(path) -> tuple[Path, Path]:
    path = Path(path)
    if path.suffix in (".npz", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".npz"), path.with_name(path.name + ".json")


class CorruptModelError(ValueError):
    """A saved model that cannot be used as it is: unreadable, incomplete, of another format
    version, inconsistent with itself (its networks not those of its config for its case: see
    `check_model_case`) or with non-finite weights. The message starts with the file."""


def weights_sha256(arrays: Mapping[str, np.ndarray]) -> str:
    """sha256 of named weight arrays: each name, dtype, shape and C-order bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape};".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


_RECORD_FIELDS = ("config", "case", "architecture", "windows", "identification")


def record_sha256(info: Mapping) -> str:
    """sha256 of what a model's .json says it is (config, case, architecture, windows, the
    identification's m, d and architecture), as canonical JSON: `save_model` stores it among the
    weights, so a .json edited after saving (another case's name and data over these weights) no
    longer matches them."""
    text = json.dumps({key: info.get(key) for key in _RECORD_FIELDS}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def save_model(path, *, solver: str, config: PinnConfig, case: Case, arch: Architecture,
               theta: np.ndarray, identification: dict | None = None,
               windows: np.ndarray | None = None) -> tuple[Path, Path]:
    """Write the weights to `<path>.npz` (key "theta": the flat float64 vector in
    `Architecture.shapes` order, or for a time-marching model with window edges `windows` (W + 1,)
    s one such row per window, (W, n_params)) and config, case, architecture, the window edges, the
    saving backend, the last identification (m, d (n,), its architecture and parameters in the .npz
    as "id_theta") and the `weights_sha256` of all the .npz arrays (every window's included) to
    `<path>.json`, each file atomically. Returns the two paths."""
    npz, meta = _paths(path)
    arrays = {"theta": np.asarray(theta, np.float64)}
    info = None
    if identification is not None:
        arrays["id_theta"] = np.asarray(identification["theta"], np.float64)
        info = {"m": np.atleast_1d(np.asarray(identification["m"], np.float64)).tolist(),
                "d": np.atleast_1d(np.asarray(identification["d"], np.float64)).tolist(),
                "architecture": identification["arch"].to_json()}
    record = {"config": config.to_json(), "case": dataclasses.asdict(case), "architecture": arch.to_json(),
              "windows": None if windows is None else np.asarray(windows, np.float64).tolist(),
              "identification": info}
    arrays["record_sha256"] = np.frombuffer(record_sha256(record).encode(), np.uint8)
    text = json.dumps({
        "format": "swingbench-pinn", "version": FORMAT_VERSION, "saved_by": solver, **record,
        "weights_sha256": weights_sha256(arrays),
    }, indent=2)
    write_atomically(npz, lambda fh: np.savez(fh, **arrays))
    write_atomically(meta, lambda fh: fh.write(text.encode()))
    return npz, meta


def _arch_from_json(data: dict) -> Architecture:
    return Architecture(**{**data, "sizes": tuple(data["sizes"])})


def _read_info(meta: Path) -> dict:
    if not meta.is_file():
        raise FileNotFoundError(f"{meta}: no such model file")
    try:
        info = json.loads(meta.read_bytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CorruptModelError(f"{meta}: not valid JSON (truncated or overwritten?): {exc}") from exc
    if not isinstance(info, dict) or info.get("format") != "swingbench-pinn":
        raise CorruptModelError(f"{meta}: not a swingbench PINN model")
    if info.get("version") not in range(1, FORMAT_VERSION + 1):
        raise CorruptModelError(f"{meta}: format version {info.get('version')!r}, this code reads 1 to "
                                f"{FORMAT_VERSION}")
    if info["version"] >= 2 and not isinstance(info.get("weights_sha256"), str):
        raise CorruptModelError(f"{meta}: no weights_sha256 (format version {info['version']} records one)")
    return info


def _read_arrays(npz: Path) -> dict[str, np.ndarray]:
    if not npz.is_file():
        raise FileNotFoundError(f"{npz}: no such model file")
    try:
        data = np.load(npz)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise CorruptModelError(f"{npz}: not an .npz archive")
        with data:
            return {name: data[name].copy() for name in data.files}
    except CorruptModelError:
        raise
    except Exception as exc:  # zipfile, zlib and numpy each raise their own on a damaged file
        raise CorruptModelError(f"{npz}: unreadable (truncated or overwritten?): "
                                f"{type(exc).__name__}: {exc}") from exc


def _check_weights(npz: Path, name: str, array: np.ndarray | None, arch: Architecture,
                   rows: int | None = None) -> np.ndarray:
    """`array` if it is float64 of shape (n_params,), or (rows, n_params) for `rows` windows."""
    if array is None:
        raise CorruptModelError(f"{npz}: no array {name!r}")
    shape = (arch.n_params,) if rows is None else (rows, arch.n_params)
    if array.dtype != np.float64 or array.shape != shape:
        raise CorruptModelError(f"{npz}: {name!r} is {array.dtype} of shape {array.shape}, the "
                                f"architecture needs float64 of shape {shape}")
    return array


def _edges(meta: Path, value, case: Case) -> np.ndarray | None:
    """The window edges of a time-marching model, checked: increasing from 0 to t_final."""
    if value is None:
        return None
    edges = np.asarray(value, np.float64)
    ok = (edges.ndim == 1 and edges.size >= 2 and np.isfinite(edges).all() and edges[0] == 0.0
          and edges[-1] == case.t_final and (np.diff(edges) > 0).all())
    if not ok:
        raise CorruptModelError(f"{meta}: windows {value!r} are not edges from 0 to t_final = {case.t_final} s")
    return edges


def _machine_values(meta: Path, ident: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The identified m and d (n,) of the .json (numbers of format versions 1 and 2: one machine)."""
    values = []
    for name in ("m", "d"):
        value = ident.get(name)
        items = value if isinstance(value, list) else [value]
        if len(items) != n or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                      and np.isfinite(v) for v in items):
            raise CorruptModelError(f"{meta}: identification m = {ident.get('m')!r}, d = {ident.get('d')!r}, "
                                    f"not {n} finite numbers each")
        values.append(np.array(items, np.float64))
    return values[0], values[1]


def _short(values) -> str:
    """A tuple or number for a one-line message (floats in full: they differ in any digit), at most
    6 entries of a long tuple."""
    if isinstance(values, tuple):
        text = ", ".join(map(repr, values[:6]))
        return f"({text}{', ...' if len(values) > 6 else ''}{',' if len(values) == 1 else ''})"
    return repr(values)


# The fields of an architecture a message names, under its label (the machine count is checked first)
_ARCH_FIELDS = (("layer sizes", ("sizes",)), ("t range (s)", ("t_lo", "t_hi")),
                ("P1 range (p.u.)", ("p_lo", "p_hi")), ("hard_ic", ("hard_ic",)),
                ("initial angles delta0 (rad)", ("delta0",)), ("initial speeds omega0 (rad/s)", ("omega0",)),
                ("extra parameters", ("n_extra",)))


def _arch_differences(arch: Architecture, expected: Architecture) -> list[str]:
    """'label got, expected want' for each field of `arch` that differs from `expected`."""
    out = []
    for label, fields in _ARCH_FIELDS:
        got, want = ([getattr(a, name) for name in fields] for a in (arch, expected))
        if got != want:
            got, want = (values[0] if len(fields) == 1 else tuple(values) for values in (got, want))
            out.append(f"{label} {_short(got)}, expected {_short(want)}")
    return out


def check_model_case(record: Mapping, case: Case, file) -> None:
    """Raise `CorruptModelError` starting with `file` unless the networks of `record` (what
    `load_model` returns) are those its config makes for `case`: the forward architecture equal to
    `Architecture.of(config, case)` (machines, layers, the t and P1 ranges it normalises over, the
    initial state built into its output), time-marching windows no longer than the window network's
    t range, and an identification network for case.n machines (its m, d of that length), of the
    config's layers and identification horizon, starting from the case's initial state, over a P1
    range that covers the case's. The weights' shapes are checked against the architecture by
    `load_model`. A few comparisons of short tuples: cheap."""
    config, arch, windows = record["config"], record["arch"], record["windows"]
    if arch.machines != case.n:
        raise CorruptModelError(f"{file}: trained for {arch.machines} machine{'s' * (arch.machines != 1)}, "
                                f"case {case.name} has {case.n}")
    problems = _arch_differences(arch, Architecture.of(config, case))
    longest = None if windows is None else float(np.diff(windows).max())
    if longest is not None and longest > arch.t_hi * (1 + 1e-9):  # `window_edges`' last window may overrun by less
        problems.append(f"windows up to {longest!r} s long, the window network covers {arch.t_hi!r} s")
    ident = record["identification"]
    if ident is not None:
        id_arch = ident["arch"]
        if id_arch.machines != case.n or ident["m"].shape != (case.n,) or ident["d"].shape != (case.n,):
            raise CorruptModelError(f"{file}: identification of {ident['m'].size} machine"
                                    f"{'s' * (ident['m'].size != 1)} (m and d), case {case.name} has {case.n}")
        # its P1 range is the case's and the observations' together (`identification_p_range`)
        expected = Architecture.of(config, case, identification=True, p_range=(id_arch.p_lo, id_arch.p_hi))
        problems += [f"identification {text}" for text in _arch_differences(id_arch, expected)]
        if id_arch.p_lo > case.p1_min or id_arch.p_hi < case.p1_max:
            problems.append(f"identification P1 range ({id_arch.p_lo!r}, {id_arch.p_hi!r}) p.u. does not "
                            f"cover the case's ({case.p1_min!r}, {case.p1_max!r})")
    if problems:
        raise CorruptModelError(f"{file}: not the network of its config for case {case.name}: "
                                + "; ".join(problems))


def load_model(path) -> dict:
    """Read what `save_model` wrote: a dict with config (PinnConfig), case (Case), arch
    (Architecture), theta (float64 (n_params,), or (W, n_params) for a time-marching model),
    windows (None, or the window edges (W + 1,) s), identification (None or dict m, d (n,), arch,
    theta), saved_by. Raises FileNotFoundError for a missing file and `CorruptModelError` for one
    that is unreadable, of another format version, incomplete, of the wrong shapes, not the weights
    its .json records (`weights_sha256`, format versions 2 and 3: every array, each window's
    included), non-finite, or whose networks are not those of its config for the case it records
    (`check_model_case`), or whose .json differs from the record saved among the weights
    (`record_sha256`; files saved before it was stored are checked by `check_model_case` alone);
    each message starts with the file."""
    npz, meta = _paths(path)
    info = _read_info(meta)
    arrays = _read_arrays(npz)
    try:
        arch = _arch_from_json(info["architecture"])
        config, case = PinnConfig(**info["config"]), Case(**info["case"])
        ident = info.get("identification")
        id_arch = None if ident is None else _arch_from_json(ident["architecture"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptModelError(f"{meta}: missing or bad field: {type(exc).__name__}: {exc}") from exc
    windows = _edges(meta, info.get("windows"), case)
    if (windows is None) != (config.window is None):
        raise CorruptModelError(f"{meta}: config window = {config.window!r} but windows = {info.get('windows')!r}")
    theta = _check_weights(npz, "theta", arrays.get("theta"), arch, None if windows is None else windows.size - 1)
    identification = None
    if ident is not None:
        m, d = _machine_values(meta, ident, id_arch.machines)
        identification = {"m": m, "d": d, "arch": id_arch,
                          "theta": _check_weights(npz, "id_theta", arrays.get("id_theta"), id_arch)}
    if "weights_sha256" in info and weights_sha256(arrays) != info["weights_sha256"]:
        raise CorruptModelError(f"{npz}: the weights' sha256 is not the one {meta.name} records "
                                "(another model's file, or a damaged one)")
    for name, array in [("theta", theta), *([("id_theta", identification["theta"])] if identification else [])]:
        if not np.isfinite(array).all():
            raise CorruptModelError(f"{npz}: {name!r} has {int(array.size - np.isfinite(array).sum())} "
                                    "non-finite weights")
    record = {"config": config, "case": case, "arch": arch, "theta": theta, "windows": windows,
              "identification": identification, "saved_by": info.get("saved_by")}
    check_model_case(record, case, meta)  # first: its message names what differs
    saved = arrays.get("record_sha256")  # files saved before it was stored have none
    if saved is not None and saved.tobytes().decode(errors="replace") != record_sha256(info):
        raise CorruptModelError(f"{meta}: its config, case or architecture is not what was saved with "
                                f"{npz.name} (the .json was edited after saving)")
    return record
