"""The PINN configuration: its fields and their rules (`PinnConfig`, `PinnConfigSchema`) and the
named configurations of both adapters (`CONFIGS`).

Plain frozen dataclasses; the fields are typed with the option types of `solvers.options`, which
validate them. Units: t in s, P1 in p.u., m in p.u. s^2/rad, d in p.u. s/rad.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import model_validator

from solvers.options import (
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    StrictBool,
    StrictChoice,
    dataclass_schema,
    validate_options,
)

__all__ = ["CONFIGS", "CONFIG_FIELDS", "DEFAULT_CONFIG", "PAPER_CONFIG", "PAPER_TWO_OUTPUTS_CONFIG", "PinnConfig",
           "PinnConfigSchema"]

# The configs the report sets beside the paper's own figures: the paper's setup, its two-output
# variant, and ours.
PAPER_CONFIG = "paper"
PAPER_TWO_OUTPUTS_CONFIG = "paper-two-outputs"
DEFAULT_CONFIG = "default"


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
    `optimizer`: "lm" (Levenberg-Marquardt on the stacked residuals), "lbfgs" (scipy L-BFGS-B,
    `lbfgs_history` pairs, as in the paper's TensorFlow ScipyOptimizerInterface) or "gn-cg"
    (jax-pinn only: Levenberg-Marquardt with the damped Gauss-Newton system solved by at most
    `cg_iterations` Jacobi-preconditioned conjugate-gradient steps to a relative residual `cg_tol`,
    on Jacobian-vector products, never forming J^T J; `optim.gauss_newton_cg`).
    `residual_units`: the swing residuals in "power" (p.u., m delta'' + d delta' + P_e - P) or in
    "acceleration" (rad/s^2: machine k's divided by m_k), which weighs every machine's angle error
    alike where inertias and powers differ by orders of magnitude (a large grid's generator 1 has
    its P1 of several p.u. and dominates a loss in p.u.); `fit` only (identification, which trains
    m, keeps p.u.). `warm_start` (time-marching): window
    w > 0 starts from window w - 1's trained weights instead of fresh ones. Training stops at
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
    Switched phases (`phases`, fault cases only, with `window` and no data points): the fault-on
    phase is a chain of windows over t in [0, p1_max] (the longest clearing time) whose networks
    take the constant `Architecture.p_mid` as their scenario input (the fault-on trajectory
    does not depend on t_c), the residual that of the fault-on network; the post-fault phase a
    chain of windows over tau = t - t_c in [0, t_final - p1_min] whose networks take (tau, t_c),
    the first starting from the fault-on chain's state at t = t_c (a function of t_c), the residual
    that of the post-fault network (`problems.PhaseEdges`); with `pieces` K > 1, K such chains,
    each for an equal piece of the clearing times (its t_c rescaled onto the whole range as the
    networks' input). `max_iterations` is per window of every chain. The state is continuous at
    t_c by construction; a step case refuses the option, and a fault case every configuration
    without it.
    Split at the model's own CCT (`split`, with `phases`; `solvers.pinn.split`): after the fault-on
    chain, which trains 4 x `max_iterations` a window here (`marching.ON_WEIGHT`: every chain starts
    from it), a screen finds the model's own critical clearing time by bisection to `screen_tol` s,
    each evaluation a post-fault chain of one clearing time (`screen_n_f` points and
    `screen_iterations` LM iterations a window, a third of them for a window warm-started from the
    previous evaluation's, stopped at the first window whose trajectory crosses the stability
    criterion, `systems.stability.is_unstable`); no solver data, its time counted in `fit`'s.
    The post-fault phase is then `pieces` pieces of clearing times on each side of the estimate
    t*, graded towards it (edges at t* -+ L (j / pieces) ** `split_grading`, L the side's
    length), so that a t_c < t* is answered by a stable side's chain and t_c >= t* by an unstable
    side's; the two pieces next to t* train `near_weight` x `max_iterations` a window (and that
    many windows' share of the time); the unstable side's output layers start `unstable_scale`
    times Glorot's (Moré-scaled Levenberg-Marquardt is invariant to a constant output factor, a
    diagonal change of parameters, so this is that factor). A screen that finds no CCT in the
    range (unstable at p1_min or stable at p1_max) leaves 2 `pieces` equal pieces, and fit's
    message says so.
    `seed` draws weights and points.
    """

    hidden_layers: PositiveInt = 2
    width: PositiveInt = 16
    outputs: Annotated[Literal[1, 2], StrictChoice] = 1
    hard_ic: StrictBool = True
    dtype: Literal["float32", "float64"] = "float64"
    n_u: NonNegativeInt = 40
    n_f: NonNegativeInt = 2000
    optimizer: Literal["lm", "lbfgs", "gn-cg"] = "lm"
    loss_scale: PositiveFloat = 1.0
    lbfgs_history: PositiveInt = 50
    cg_iterations: PositiveInt = 100
    cg_tol: PositiveFloat = 1e-3
    residual_units: Literal["power", "acceleration"] = "power"
    warm_start: StrictBool = False
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
    phases: StrictBool = False
    pieces: PositiveInt = 1
    split: StrictBool = False
    split_grading: PositiveFloat = 1.0
    screen_n_f: PositiveInt = 100
    screen_iterations: PositiveInt = 150
    screen_tol: PositiveFloat = 1e-4
    unstable_scale: PositiveFloat = 1.0
    near_weight: PositiveFloat = 1.0

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

    @model_validator(mode="after")
    def _phases_march_without_data(self) -> PinnConfigSchema:
        if self.phases and (self.window is None or self.n_u):
            raise ValueError("option phases (a fault case's switched phases) needs window set and n_u=0: each "
                             "phase is a chain of windows whose initial state is exact, without data points")
        if self.pieces > 1 and not self.phases:
            raise ValueError("option pieces needs phases=True (a fault case's switched phases)")
        if self.split and not self.phases:
            raise ValueError("option split (the post-fault phase split at the model's own CCT) needs phases=True")
        for name in ("unstable_scale", "near_weight"):
            if getattr(self, name) != 1.0 and not self.split:
                raise ValueError(f"option {name} (of a model split at its own CCT) needs split=True")
        return self


CONFIG_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(PinnConfig))

# Named option sets of both adapters (overrides of the PinnConfig defaults).
CONFIGS: dict[str, dict[str, Any]] = {
    # The best we found (measured on 2 threads with a 55 s budget, seeds 0-2, rel. L2 of delta / omega:
    # JAX 1.2e-6..2.1e-6 / 4.5e-6..6.1e-6 in ~4500 LM iterations, torch 7.7e-6..1.3e-5 / 1.9e-5..4.1e-5
    # in ~1600; the configs bound training by 2000 LM iterations instead, 1000 for identification; the choices below were
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
    # A fault case (issue 23): the switched phases (`phases`), windows as "marching" trains them,
    # the post-fault phase in 8 pieces of clearing times. Measured (JAX, threads 1, seed 0, 300 s on
    # 1 core of a machine shared with other jobs; COI rel. L2 over 36 t_c x 301 t, CCT from the
    # surrogate's answers against the reference's; docs/pinn-faults.md): kundur4-bus7-line7-8a
    # 2.0e-5, CCT +0.002 ms (12373 LM iterations); wscc9-bus8-line8-9 0.18, CCT -0.85 ms (11793):
    # beyond its CCT one machine slips poles and those rows stay at 1e-2..5e-1 (the stable rows of
    # the first pieces: 1e-5). 4 pieces: kundur4 4.9e-5 / +0.02 ms, wscc9 0.17 / -4.8 ms; one
    # chain over all clearing times: wscc9 0.64 / -18 ms (a network smooth in t_c does not follow
    # the trajectories' split at the CCT); 0.25 s windows (4 pieces): wscc9 0.20 / -7.1 ms.
    "fault-marching": {
        "window": 0.5, "phases": True, "pieces": 8, "hidden_layers": 2, "width": 20, "outputs": 1,
        "hard_ic": True, "dtype": "float64", "n_u": 0, "n_f": 400, "optimizer": "lm", "max_iterations": 2000,
        "max_seconds": 300.0,
    },
    # A fault case split at the model's own CCT (issue 33; `split`, `solvers.pinn.split`): as
    # "fault-marching", with the post-fault phase in 6 pieces on each side of the screen's estimate,
    # graded towards it, the two next to it trained 4 x the iterations. Chosen on wscc9-bus8-line8-9 at
    # the bench's 150 iterations a window, seed 0, threads 1 (scripts/fault_split_probe.py; COI rel. L2
    # over the standard grid's stable / unstable clearing times): 4 pieces a side, the fault-on window
    # at 150 iterations: 5.8e-3 / 0.16 (the fault-on loss 1e-4); its window at 600: 1.5e-3 / 0.17;
    # 6 a side, output scale 10: 1.9e-3 / 0.11 (the row 2.4 ms below the CCT 8e-3, the others
    # <= 1e-4); near_weight 4, output scale 1: 7.9e-5 / 0.23. Every variant: CCT estimate within
    # 0.07 ms of the reference, every clearing time classified right.
    "fault-split": {
        "window": 0.5, "phases": True, "split": True, "pieces": 6, "split_grading": 2.0, "near_weight": 4.0,
        "unstable_scale": 10.0, "screen_n_f": 50, "hidden_layers": 2, "width": 20, "outputs": 1, "hard_ic": True,
        "dtype": "float64", "n_u": 0, "n_f": 400, "optimizer": "lm", "max_iterations": 2000, "max_seconds": 300.0,
    },
    # Time-marching for grids of tens of machines and more, where "marching"'s Levenberg-Marquardt
    # costs N P^2 per iteration (case118, 54 machines: J and J^T J ~1.6 s on 1 core, 21600 x 1614):
    # L-BFGS (a gradient per iteration), the residuals in acceleration units (in p.u. generator 1,
    # with P1 of 4-8 p.u., dominates the loss), a 2 x 40 network (window 17 of case118, 30 s of
    # L-BFGS: loss 2.3e-2 at width 20, 9e-3 at 40), 4000 iterations a window. Measured on case118
    # (seed 0, 1 core): COI rel. L2 2.4e-3 in 473 CPU s (1000 iterations of `marching` with
    # L-BFGS: 1.9e-2); warm starts (`warm_start`) 3.2e-3. The matrix-free Gauss-Newton ("gn-cg")
    # lowered the loss less per second than L-BFGS on case118's windows (docs/scaling.md).
    "marching-large": {
        "window": 0.5, "hidden_layers": 2, "width": 40, "outputs": 1, "hard_ic": True, "dtype": "float64",
        "n_u": 0, "n_f": 400, "optimizer": "lbfgs", "residual_units": "acceleration",
        "max_iterations": 4000, "id_t_max": 1.5, "id_max_iterations": 5000,
    },
}
