"""The one specification of the swingbench PINNs, shared by the torch and JAX backends.

Plain numpy and frozen dataclasses only (the configuration's fields are typed with the option
types of `solvers.options`, which validate them): the configuration (`PinnConfig`, `CONFIGS`), the network
layout and its flat parameter vector (`Architecture`), the seeded initial weights (`init_theta`),
the seeded training points (`forward_problem`, `identification_problem`), the loss weights and
the save/load format (`save_model`, `load_model`). The network and loss as functions of the
backend's ops live in `solvers.pinn.network`, the optimisers in `solvers.pinn.optim`.

Units: t in s, P1 in p.u., delta in rad, omega in rad/s, m in p.u. s^2/rad, d in p.u. s/rad.
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

from harness.atomic import write_atomically
from systems.cases import Case, Observations, standard_grid
from solvers.options import (
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    StrictBool,
    StrictChoice,
    dataclass_schema,
    validate_options,
)

__all__ = [
    "CONFIGS",
    "CONFIG_FIELDS",
    "FORMAT_VERSION",
    "Architecture",
    "CorruptModelError",
    "PinnConfig",
    "PinnConfigSchema",
    "Problem",
    "forward_problem",
    "identification_problem",
    "init_theta",
    "load_model",
    "save_model",
    "weights_sha256",
]

# 2: the .json records the weights' sha256 (version 1 files, without it, still load)
FORMAT_VERSION = 2


@dataclass(frozen=True)
class PinnConfig:
    """Everything that defines a PINN run; the defaults are the `default` configuration.

    Network: `hidden_layers` x `width` tanh, inputs (t, P1) normalised to [-1, 1] over the domain;
    `outputs` 1 (delta) or 2 (delta, omega); `hard_ic` builds delta(0) = delta0, delta'(0) = omega0
    into the output (phi = 1 - exp(-t / 1 s); delta = delta0 + omega0 phi + phi^2 NN, and for two
    outputs omega = omega0 + phi NN_2), otherwise the initial condition is learnt from data only.
    `dtype` "float32" or "float64" for the network and its derivatives.
    Training data of `fit`: `n_u` points drawn without replacement from the t = 0 line and the
    P1 = p1_min / p1_max edges of the standard grid (values from `systems.reference.reference`),
    plus `n_f` Latin-hypercube collocation points (the data points are collocation points too).
    Loss = loss_scale * (MSE of the data + MSE of each residual) (Levenberg-Marquardt is invariant
    to the scale, and scipy's L-BFGS-B tests curvature pairs relatively: unlike torch.optim.LBFGS,
    neither needs it; it stays for experiments).
    `optimizer`: "lm" (Levenberg-Marquardt on the stacked residuals) or "lbfgs" (scipy L-BFGS-B,
    `lbfgs_history` pairs, as in the paper's TensorFlow ScipyOptimizerInterface). Training stops at
    `max_iterations` or on convergence: bounded by iterations, a seed gives the same network on a
    busy machine as on an idle one. `max_seconds` (None by default: no limit) adds a wall-clock
    budget counted from the start of `fit` (data, compilation and warm-up included): training then
    also stops before an iteration would end after it, and the result depends on the machine's load.
    Identification (`identify`): an `id_hidden_layers` x `id_width` network, the observations as data
    and `id_n_f` Latin-hypercube collocation points (0: the residual on the observations only, as
    in the paper); m and d start at `m_init`, `d_init` and are trained as exp(log m), exp(log d);
    budgets `id_max_iterations` and optionally `id_max_seconds`. `seed` draws weights and points.
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
    m_init: PositiveFloat = 0.2
    d_init: PositiveFloat = 0.1

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
}


@dataclass(frozen=True)
class Architecture:
    """The network and what its output means: layer sizes [2, width.., outputs], the input
    normalisation (t in [t_lo, t_hi] s and P1 in [p_lo, p_hi] p.u. map to [-1, 1]), the hard
    initial condition (delta0 rad, omega0 rad/s) if any, and `n_extra` trailing entries of the flat
    parameter vector (2 for identification: log m, log d)."""

    sizes: tuple[int, ...]
    t_lo: float
    t_hi: float
    p_lo: float
    p_hi: float
    hard_ic: bool
    delta0: float
    omega0: float
    n_extra: int = 0

    @classmethod
    def of(cls, config: PinnConfig, case: Case, identification: bool = False,
           p_range: tuple[float, float] | None = None) -> Architecture:
        depth, width = ((config.id_hidden_layers, config.id_width) if identification
                        else (config.hidden_layers, config.width))
        p_lo, p_hi = p_range if p_range is not None else (case.p1_min, case.p1_max)
        if p_hi <= p_lo:  # a single P1: any positive width keeps the map finite
            p_lo, p_hi = p_lo - 0.5, p_hi + 0.5
        return cls(
            sizes=(2,) + (width,) * depth + (config.outputs,), t_lo=0.0, t_hi=case.t_final,
            p_lo=float(p_lo), p_hi=float(p_hi), hard_ic=config.hard_ic,
            delta0=case.delta0, omega0=case.omega0, n_extra=2 if identification else 0,
        )

    @property
    def outputs(self) -> int:
        return self.sizes[-1]

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
        views: W_0, b_0, ..., W_L, b_L in `shapes` order, then the (2,) vector (log m, log d) when
        the architecture has the identification entries."""
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


def init_theta(arch: Architecture, seed: int, m_init: float = 1.0, d_init: float = 1.0) -> np.ndarray:
    """The initial flat parameter vector (float64): Glorot/Xavier normal weights,
    std sqrt(2 / (fan_in + fan_out)), zero biases (as the paper's code), drawn from `seed`; then
    log m_init, log d_init when the architecture has the two identification entries."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x5EED]))
    parts = []
    for n_in, n_out in zip(arch.sizes[:-1], arch.sizes[1:]):
        parts += [rng.normal(0.0, np.sqrt(2.0 / (n_in + n_out)), (n_in, n_out)).ravel(), np.zeros(n_out)]
    if arch.n_extra:
        parts.append(np.log([m_init, d_init]))
    return np.concatenate(parts)


@dataclass(frozen=True)
class Problem:
    """The training points of one run, numpy float64.

    Data: t_u (s), p_u (p.u.), targets (n_u, k) with columns delta (rad) and, when k = 2, omega
    (rad/s); collocation: t_f (s), p_f (p.u.). The loss is
    loss_scale * (sum over columns of mean((prediction - target)^2) + sum over residuals of
    mean(f^2)); `weights` gives the square roots of those factors, so that the loss is the sum of
    squares of the weighted residual vector that Levenberg-Marquardt works on.
    m, d: the physics (None in identification, where they are trained)."""

    t_u: np.ndarray
    p_u: np.ndarray
    targets: np.ndarray
    t_f: np.ndarray
    p_f: np.ndarray
    loss_scale: float
    m: float | None = None
    d: float | None = None

    @property
    def weights(self) -> tuple[float, float]:
        """(weight of each data residual, weight of each physics residual)."""
        return (float(np.sqrt(self.loss_scale / max(self.t_u.size, 1))),
                float(np.sqrt(self.loss_scale / max(self.t_f.size, 1))))

    def loss(self, data_residuals: np.ndarray, physics_residuals: np.ndarray) -> float:
        """The loss (numpy reference) from data residuals (n_u, k) and physics residuals (n_f, r)."""
        w_u, w_f = self.weights
        return float(w_u ** 2 * np.sum(data_residuals ** 2) + w_f ** 2 * np.sum(physics_residuals ** 2))


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
    d_cand = np.concatenate([delta_start[:, 0], delta_edges[0], delta_edges[1]])
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 0xDA7A]))
    pick = np.sort(rng.choice(t_cand.size, size=min(config.n_u, t_cand.size), replace=False))
    t_f, p_f = latin_hypercube((0.0, case.t_final), (case.p1_min, case.p1_max), config.n_f, config.seed)
    return Problem(
        t_u=t_cand[pick], p_u=p_cand[pick], targets=d_cand[pick][:, None],
        t_f=np.concatenate([t_f, t_cand[pick]]), p_f=np.concatenate([p_f, p_cand[pick]]),
        loss_scale=config.loss_scale, m=case.m, d=case.d,
    )


def identification_p_range(case: Case, obs: Observations) -> tuple[float, float]:
    """The P1 range (p.u.) an identification network is normalised over: the case's domain and the
    observations' extent together."""
    return float(min(case.p1_min, obs.P1.min())), float(max(case.p1_max, obs.P1.max()))


def identification_problem(config: PinnConfig, case: Case, obs: Observations) -> Problem:
    """The training set of `identify`: the observations (delta, and omega when given) as data, and
    as collocation points the observations plus `id_n_f` Latin-hypercube points on
    [0, max(t_final, t_obs)] x the P1 range."""
    p_range = identification_p_range(case, obs)
    t_f, p_f = latin_hypercube((0.0, max(case.t_final, float(obs.t.max()))), p_range, config.id_n_f,
                               config.seed)
    targets = obs.delta[:, None] if obs.omega is None else np.stack([obs.delta, obs.omega], axis=1)
    return Problem(
        t_u=obs.t.copy(), p_u=obs.P1.copy(), targets=targets,
        t_f=np.concatenate([t_f, obs.t]), p_f=np.concatenate([p_f, obs.P1]),
        loss_scale=config.loss_scale,
    )


# ---------------------------------------------------------------------------------------------
# Save / load: <path>.npz holds the flat parameter vector(s) (float64), <path>.json the rest.
# A model may come from a cache another process writes or a file a user copied: load checks it all.


def _paths(path) -> tuple[Path, Path]:
    path = Path(path)
    if path.suffix in (".npz", ".json"):
        path = path.with_suffix("")
    return path.with_name(path.name + ".npz"), path.with_name(path.name + ".json")


class CorruptModelError(ValueError):
    """A saved model that cannot be used as it is: unreadable, incomplete, of another format
    version, inconsistent with itself or with non-finite weights. The message starts with the file."""


def weights_sha256(arrays: Mapping[str, np.ndarray]) -> str:
    """sha256 of named weight arrays: each name, dtype, shape and C-order bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape};".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def save_model(path, *, solver: str, config: PinnConfig, case: Case, arch: Architecture,
               theta: np.ndarray, identification: dict | None = None) -> tuple[Path, Path]:
    """Write the weights to `<path>.npz` (key "theta", the flat float64 vector in
    `Architecture.shapes` order) and config, case, architecture, the saving backend, the last
    identification (m, d, its architecture and parameters in the .npz as "id_theta") and the
    `weights_sha256` of the .npz arrays to `<path>.json`, each file atomically. Returns the two
    paths."""
    npz, meta = _paths(path)
    arrays = {"theta": np.asarray(theta, np.float64)}
    info = None
    if identification is not None:
        arrays["id_theta"] = np.asarray(identification["theta"], np.float64)
        info = {"m": float(identification["m"]), "d": float(identification["d"]),
                "architecture": identification["arch"].to_json()}
    text = json.dumps({
        "format": "swingbench-pinn", "version": FORMAT_VERSION, "saved_by": solver,
        "config": config.to_json(), "case": dataclasses.asdict(case), "architecture": arch.to_json(),
        "identification": info, "weights_sha256": weights_sha256(arrays),
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
    if info.get("version") not in (1, FORMAT_VERSION):
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


def _check_weights(npz: Path, name: str, array: np.ndarray | None, arch: Architecture) -> np.ndarray:
    if array is None:
        raise CorruptModelError(f"{npz}: no array {name!r}")
    if array.dtype != np.float64 or array.shape != (arch.n_params,):
        raise CorruptModelError(f"{npz}: {name!r} is {array.dtype} of shape {array.shape}, the "
                                f"architecture needs float64 of shape ({arch.n_params},)")
    return array


def load_model(path) -> dict:
    """Read what `save_model` wrote: a dict with config (PinnConfig), case (Case), arch
    (Architecture), theta (float64), identification (None or dict m, d, arch, theta), saved_by.
    Raises FileNotFoundError for a missing file and `CorruptModelError` for one that is unreadable,
    of another format version, incomplete, of the wrong shapes, not the weights its .json records
    (`weights_sha256`, format version 2) or non-finite; each message starts with the file."""
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
    theta = _check_weights(npz, "theta", arrays.get("theta"), arch)
    identification = None
    if ident is not None:
        m, d = ident.get("m"), ident.get("d")
        if not all(isinstance(v, (int, float)) and np.isfinite(v) for v in (m, d)):
            raise CorruptModelError(f"{meta}: identification m = {m!r}, d = {d!r}, not finite numbers")
        identification = {"m": m, "d": d, "arch": id_arch,
                          "theta": _check_weights(npz, "id_theta", arrays.get("id_theta"), id_arch)}
    if "weights_sha256" in info and weights_sha256(arrays) != info["weights_sha256"]:
        raise CorruptModelError(f"{npz}: the weights' sha256 is not the one {meta.name} records "
                                "(another model's file, or a damaged one)")
    for name, array in [("theta", theta), *([("id_theta", identification["theta"])] if identification else [])]:
        if not np.isfinite(array).all():
            raise CorruptModelError(f"{npz}: {name!r} has {int(array.size - np.isfinite(array).sum())} "
                                    "non-finite weights")
    return {"config": config, "case": case, "arch": arch, "theta": theta,
            "identification": identification, "saved_by": info.get("saved_by")}
