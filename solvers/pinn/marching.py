"""Training a chain of time-marching windows (`PinnConfig.window`): each window's network learns
its span from the state the trained earlier windows reach, built into its output.

Shared by a step case's time-marching fit (one chain over [0, t_final], `train_chain`) and a fault
case's switched fit (`PinnConfig.phases`, `train_phases`: a fault-on chain, then a post-fault chain
per piece of clearing times starting from the fault-on state at each clearing time).
Backend-free: the adapter passes its training and query functions in. Units: times in s, states
(delta rad, omega rad/s).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from solvers.pinn.architecture import Architecture
from solvers.pinn.config import PinnConfig
from solvers.pinn.evaluator import Evaluator, SwitchedEvaluator, walk
from solvers.pinn.network import Physics
from solvers.pinn.optim import OptimResult
from solvers.pinn.problems import PhaseEdges, Problem, phase_problem
from systems.cases import Case

__all__ = ["ON_WEIGHT", "Chain", "TrainWindow", "TrainerOf", "train_chain", "train_fault_on", "train_phases",
           "train_posts"]

# train(problem, w, deadline, label) -> the optimiser's result for window w of the chain
TrainWindow = Callable[[Problem, int, float, str], OptimResult]
# A fault-on window's share of a switched fit's time, in post-fault windows: every post-fault
# chain starts from its state (wscc9, 4 pieces, 300 s: an equal share left its loss at 1e-4
# after 175 LM iterations and the stable rows at 1e-3; four shares, 5.5e-13 after 1077 and 1e-5).
ON_WEIGHT = 4.0


@dataclass(frozen=True)
class Chain:
    """The trained windows of one chain: `thetas` one flat float64 vector per window, in order,
    with the LM (or L-BFGS) iterations, final loss and stopping message of each."""

    thetas: list[np.ndarray]
    iterations: list[int]
    losses: list[float]
    messages: list[str]

    @classmethod
    def join(cls, chains: list[Chain]) -> Chain:
        """The windows of `chains`, one after the other."""
        return cls([x for c in chains for x in c.thetas], [x for c in chains for x in c.iterations],
                   [x for c in chains for x in c.losses], [x for c in chains for x in c.messages])

    def summary(self, what: str) -> str:
        """'<W> <what>, <iterations> iterations; largest loss <l> in window <w>: <why>'."""
        worst = int(np.argmax(self.losses))
        return (f"{len(self.thetas)} {what}, {sum(self.iterations)} iterations; largest loss "
                f"{self.losses[worst]:.3g} in window {worst + 1}: {self.messages[worst]}")


def train_chain(train: TrainWindow, problem_of: Callable[[int], Problem], lengths: np.ndarray,
                start_of: Callable[[np.ndarray], np.ndarray], walker: Evaluator, deadline: float,
                windows_after: float = 0, label: str = "window", weight: float = 1.0) -> Chain:
    """Train the windows of lengths `lengths` (s) in turn. Window w's problem is `problem_of(w)`
    with each point's start state (`Problem.start_u`, `start_f`) the state the trained windows
    0..w-1 reach from `start_of(P1)` ((len(P1), 2, n) float64, window 0's start at each point's
    scenario input), walked by `walker` (constants of its training). Each window gets a share of
    the time left to `deadline` (`time.perf_counter()` s) among it, the chain's later windows and
    `windows_after` windows' worth of training after the chain: `weight` windows' worth each."""
    prepared: list = []
    thetas, iterations, losses, messages = [], [], [], []
    count = lengths.size

    def starts(P1: np.ndarray) -> np.ndarray:
        return walk(walker, prepared, lengths, P1, start_of(P1))[:, -1]

    for w in range(count):
        problem = problem_of(w)
        problem = dataclasses.replace(problem, start_u=starts(problem.p_u) if problem.t_u.size else None,
                                      start_f=starts(problem.p_f))
        now = time.perf_counter()
        window_deadline = now + (deadline - now) * weight / (weight * (count - w) + windows_after)
        result = train(problem, w, window_deadline, f"{label} {w + 1}/{count}")
        thetas.append(result.theta)
        prepared.append(walker.prepare(result.theta))
        iterations.append(result.iterations)
        losses.append(result.loss)
        messages.append(result.message)
    return Chain(thetas, iterations, losses, messages)


# trainer_of(physics, first, scale, iterations) -> the training function of a chain's windows from
# the model's window `first` on, under `physics`, their output layers starting `scale` times
# Glorot's, at most `iterations` optimiser iterations a window
TrainerOf = Callable[[Physics, int, float, int], TrainWindow]


def train_fault_on(config: PinnConfig, case: Case, arch: Architecture, edges: PhaseEdges, trainer_of: TrainerOf,
                   walker: Evaluator, deadline: float, windows_after: float, iterations: int | None = None
                   ) -> Chain:
    """The fault-on chain of `edges` at the constant scenario input `arch.p_mid` with the fault-on
    network's residual (`Physics.of_phase`), from the case's initial state, `iterations` (default
    `config.max_iterations`) a window; `windows_after` windows' worth of training after it share
    `deadline`."""
    start0 = np.array([arch.delta0, arch.omega0], np.float64)
    iterations = config.max_iterations if iterations is None else iterations
    return train_chain(trainer_of(Physics.of_phase(case, "on"), 0, 1.0, iterations),
                       lambda w: phase_problem(config, case, edges, "on", w, arch.p_mid),
                       np.diff(edges.on), lambda P1: start0, walker, deadline,
                       windows_after=windows_after, label="fit fault-on window")


def train_posts(config: PinnConfig, case: Case, arch: Architecture, edges: PhaseEdges, on: Chain,
                trainer_of: TrainerOf, walker: Evaluator, deadline: float,
                scales: list[float] | None = None, weights: list[float] | None = None) -> Chain:
    """For each piece k of `edges.pieces`, the post-fault chain over (tau = t - t_c, t_c in the
    piece) with the post-fault network's residual, its first window starting from the trained
    fault-on chain `on`'s state at each point's t_c (`SwitchedEvaluator.clearing_state`), its
    output layers starting `scales[k]` (default 1) times Glorot's, `weights[k]` (default 1) times
    `max_iterations` and the time share of other windows a window; the chains joined, in
    parameter order."""
    w_on, w_post, pieces = edges.on.size - 1, edges.post.size - 1, edges.pieces.size - 1
    probe = SwitchedEvaluator(walker, arch, edges.on, edges.post, edges.pieces)
    probe.on.load(np.stack(on.thetas))
    physics = Physics.of_phase(case, "post")
    scales = [1.0] * pieces if scales is None else scales
    weights = [1.0] * pieces if weights is None else weights
    posts = [train_chain(trainer_of(physics, w_on + k * w_post, scales[k], round(weights[k] * config.max_iterations)),
                         functools.partial(phase_problem, config, case, edges, "post", p_mid=arch.p_mid, piece=k),
                         np.diff(edges.post), probe.posts[k].start_of, walker, deadline,
                         windows_after=sum(weights[k + 1:]) * w_post,
                         label=f"fit post-fault piece {k + 1}/{pieces} window", weight=weights[k])
             for k in range(pieces)]
    return Chain.join(posts)


def train_phases(config: PinnConfig, case: Case, arch: Architecture, edges: PhaseEdges,
                 trainer_of: TrainerOf, walker: Evaluator, deadline: float) -> tuple[Chain, Chain]:
    """Train fault case `case`'s switched model (`PinnConfig.phases`) on `edges`: the fault-on
    chain (`train_fault_on`), then the post-fault chain of each piece of clearing times
    (`train_posts`). Returns the fault-on chain and the post-fault chains joined, in parameter
    order."""
    pieces, w_post = edges.pieces.size - 1, edges.post.size - 1
    on = train_fault_on(config, case, arch, edges, trainer_of, walker, deadline, pieces * w_post / ON_WEIGHT)
    return on, train_posts(config, case, arch, edges, on, trainer_of, walker, deadline)
