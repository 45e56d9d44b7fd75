"""The PINN network's layout and its flat parameter vector (`Architecture`), and the seeded values
it starts from (`init_theta`, `start_guess`).

Plain numpy: slicing and reshaping only, so a backend's arrays (torch, JAX) split the same way. The
network and loss as functions of the backend's ops live in `solvers.pinn.network`.

Units: t in s, P1 in p.u., delta in rad, omega in rad/s, m in p.u. s^2/rad, d in p.u. s/rad.
A case has n machines (`systems.cases.Case`); the network has the inputs (t, P1) and one output per
machine (delta_1..n), or two (delta_1..n, then omega_1..n).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from solvers.pinn.config import PinnConfig
from systems.cases import Case

__all__ = ["Architecture", "glorot_weights", "init_theta", "layer_shapes", "split_flat", "start_guess"]


def layer_shapes(sizes: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Shapes of a dense network's flat parameter vector for layer sizes `sizes`:
    W_0 (sizes[0], sizes[1]), b_0 (sizes[1],), ..., W_L, b_L."""
    out: list[tuple[int, ...]] = []
    for n_in, n_out in itertools.pairwise(sizes):
        out += [(n_in, n_out), (n_out,)]
    return out


def split_flat(shapes: list[tuple[int, ...]], theta: Any) -> tuple[list[Any], int]:
    """Views of the flat vector `theta` (numpy, torch or JAX: slicing and reshape only) in the
    given shapes, and the offset after the last."""
    arrays, start = [], 0
    for shape in shapes:
        size = int(np.prod(shape))
        arrays.append(theta[start:start + size].reshape(shape))
        start += size
    return arrays, start


def glorot_weights(sizes: tuple[int, ...], rng: np.random.Generator) -> list[np.ndarray]:
    """Glorot/Xavier normal weights, std sqrt(2 / (fan_in + fan_out)), and zero biases, flattened
    in `layer_shapes` order."""
    parts = []
    for n_in, n_out in itertools.pairwise(sizes):
        parts += [rng.normal(0.0, np.sqrt(2.0 / (n_in + n_out)), (n_in, n_out)).ravel(), np.zeros(n_out)]
    return parts


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
        if (len(self.omega0) != n or self.sizes[-1] not in (n, 2 * n) or self.n_extra not in (0, 2 * n)
                or self.sizes[0] != 2):
            raise ValueError(f"Architecture: {n} machines (delta0), omega0 {len(self.omega0)}, input layer "
                             f"{self.sizes[0]}, output layer {self.sizes[-1]} and n_extra {self.n_extra} do not "
                             "fit together")

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
    def p_mid(self) -> float:
        """The middle of the P1 range (normalised input 0): the constant scenario input of a fault
        case's fault-on networks, whose trajectory does not depend on the clearing time."""
        return 0.5 * (self.p_lo + self.p_hi)

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
        return layer_shapes(self.sizes)

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
        arrays, start = split_flat(self.shapes, theta)
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
    parts = glorot_weights(arch.sizes, rng)
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
