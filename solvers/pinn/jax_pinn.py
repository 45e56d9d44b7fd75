"""The PINN adapter on JAX: the shared network under jax.jit, jvp / vmap / jacrev autodiff; training
on the CPU, or on JAX's first GPU with `device="gpu"`, queries on the CPU.

Threads: XLA's CPU thread pool is sized once per process, before the backend starts
(`solvers.threads.configure_threads`); if it has already started with another size, the message of
fit / identify says so. float64 runs under `jax.enable_x64(True)` only (a context, so other JAX
code in the process keeps its setting).
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, ClassVar, Literal

import jax
import jax.numpy as jnp
import numpy as np

from solvers.pinn.architecture import Architecture
from solvers.pinn.common import PinnOptions, PinnSolver, Trainer
from solvers.pinn.evaluator import Evaluator
from solvers.pinn.network import (
    Ops,
    Physics,
    data_terms,
    delta_omega,
    jacobian_blocks,
    physics_terms,
    residual_vector,
    weighted,
)
from solvers.pinn.problems import Problem
from solvers.threads import configure_threads

__all__ = ["OPS", "JaxOptions", "JaxPinn"]


def _asarray(x: np.ndarray, like: Any) -> Any:
    # a constant of the traced computation, in the dtype it computes in
    return jnp.asarray(x, dtype=like.dtype)


OPS = Ops(
    tanh=jnp.tanh, sin=jnp.sin, cos=jnp.cos, exp=jnp.exp, ones_like=jnp.ones_like, stack=jnp.stack,
    concat=jnp.concatenate, asarray=_asarray, jvp=jax.jvp, vmap=jax.vmap, jacrev=jax.jacrev,
)
_DATA_KEYS = ("t_u", "p_u", "targets", "t_f", "p_f", "start_u", "start_f")
# The jitted training functions by (architecture, problem signature, case, dtype): shared by the
# windows of a time-marching fit and by every solver of one configuration in the process (the seeds
# of a run, a refit): XLA compiles each once. A few entries: each holds compiled executables.
_JIT_CACHE: OrderedDict[tuple, tuple] = OrderedDict()
_JIT_CACHE_SIZE = 8
_DTYPES = {"float32": np.float32, "float64": np.float64}
_DIAGONAL_BATCH = 64  # points per batch of `_squared_column_sums`


def _device(kind: str) -> Any:
    """JAX's first device of `kind` ("cpu" or "gpu"); a RuntimeError when JAX has none."""
    return jax.devices(kind)[0]


class JaxOptions(PinnOptions):
    """`PinnOptions` and where training computes: device "cpu" (default) or "gpu" (JAX's first GPU).
    The optimiser's linear algebra and every query stay on the CPU."""

    device: Literal["cpu", "gpu"] = "cpu"


class JaxPinn(PinnSolver):
    """PINN on JAX; see `solvers.pinn.common.PinnSolver` for the options, configs and files, and
    `JaxOptions` for `device`."""

    name: ClassVar[str] = "jax-pinn"
    SCHEMA = JaxOptions

    def _check_options(self) -> None:
        """The rule that depends on the machine: a "gpu" device must exist (checked when the adapter
        is built, so that a run refuses it before measuring)."""
        super()._check_options()
        if self.options["device"] == "gpu":
            try:
                _device("gpu")
            except RuntimeError:
                raise ValueError(f"{self.name}: option device must be 'cpu' on this machine (jax "
                                 f"{jax.__version__} finds no GPU to train case {self.case.name} on), "
                                 "got 'gpu'") from None

    def _prepare_backend(self) -> str:
        threads = configure_threads(self.options["threads"])
        if self.options["device"] == "cpu":
            return threads
        return "; ".join(filter(None, (threads, f"trained on {_device('gpu').device_kind}")))

    def _compile(self, arch: Architecture, problem: Problem, physics: Physics, dtype: str) -> Trainer:
        npdtype = _DTYPES[dtype]
        x64 = jax.enable_x64(dtype == "float64")
        device = _device(self.options["device"])
        with x64:  # the data committed to the device: the jitted functions run where it is
            data = {key: jax.device_put(jnp.asarray(getattr(problem, key), dtype=npdtype), device)
                    for key in _DATA_KEYS if getattr(problem, key) is not None}
        residual_fn, jacobian_fn, loss_grad_fn, jvp_fn, vjp_fn, diagonal_fn = _jitted(
            arch, problem, physics, self.case, dtype)

        def wrap(fn):
            def call(theta: np.ndarray):
                with x64:
                    return fn(np.asarray(theta, npdtype), data)
            return call

        res, jac, lg, diagonal = wrap(residual_fn), wrap(jacobian_fn), wrap(loss_grad_fn), wrap(diagonal_fn)

        def loss_and_grad(theta: np.ndarray) -> tuple[float, np.ndarray]:
            value, grad = lg(theta)
            return float(value), np.asarray(grad, np.float64)

        def product(fn):
            def call(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
                with x64:
                    return np.asarray(fn(np.asarray(theta, npdtype), np.asarray(v, npdtype), data), np.float64)
            return call

        return Trainer(
            residuals=lambda theta: np.asarray(res(theta), np.float64),
            jacobian=lambda theta: np.asarray(jac(theta), np.float64),
            loss_and_grad=loss_and_grad, jvp=product(jvp_fn), vjp=product(vjp_fn),
            diagonal=lambda theta: np.asarray(diagonal(theta), np.float64),
        )

    def _make_evaluator(self, arch: Architecture, dtype: str) -> Evaluator:
        return _JitEvaluator(arch, dtype)


def _jitted(arch: Architecture, problem: Problem, physics: Physics, case: Any, dtype: str) -> tuple:
    """The jitted residual, Jacobian and loss-and-gradient functions of (theta, data) and the
    Jacobian-vector and vector-Jacobian products of (theta, vector, data) for `problem`
    and the problems of its signature (they use `problem` only for its sizes and weights, and
    `physics` is `case`'s, or its phase's: the key holds what they depend on besides their arguments)."""
    key = (arch, problem.signature, case, physics.phase, dtype)
    if key in _JIT_CACHE:
        _JIT_CACHE.move_to_end(key)
        return _JIT_CACHE[key]

    def vector(theta, data):
        return residual_vector(arch, theta, data, OPS, physics, problem)

    _JIT_CACHE[key] = (
        jax.jit(vector),
        jax.jit(lambda theta, data: jacobian_blocks(arch, theta, data, OPS, physics, problem)),
        jax.jit(jax.value_and_grad(lambda theta, data: jnp.sum(vector(theta, data) ** 2))),
        jax.jit(lambda theta, v, data: jax.jvp(lambda th: vector(th, data), (theta,), (v,))[1]),
        jax.jit(lambda theta, u, data: jax.vjp(lambda th: vector(th, data), theta)[1](u)[0]),
        jax.jit(lambda theta, data: _squared_column_sums(arch, theta, data, physics, problem)),
    )
    while len(_JIT_CACHE) > _JIT_CACHE_SIZE:
        _JIT_CACHE.popitem(last=False)
    return _JIT_CACHE[key]


def _squared_column_sums(arch: Architecture, theta: Any, data: dict, physics: Physics, problem: Problem) -> Any:
    """diag(J^T J), (n_params,), J = d residual_vector / d theta, without forming J: each point's
    Jacobian (reverse mode, as `jacobian_blocks`), squared and summed, `_DIAGONAL_BATCH` points at
    a time (memory batch x residuals per point x n_params)."""
    w_u, w_f = problem.weights
    columns = problem.targets.shape[1]
    params = arch.split(theta)

    def summed(fn: Callable, t: Any, p: Any, s: Any) -> Any:
        def one(point: tuple) -> Any:
            t, p, s = point
            rows = jax.jacrev(lambda ps: fn(ps, t, p, None if s is None else (s[0], s[1])))(params)
            return jnp.concatenate([jnp.sum(j.reshape(j.shape[0], -1) ** 2, 0) for j in rows])
        return jnp.sum(jax.lax.map(one, (t, p, s), batch_size=_DIAGONAL_BATCH), 0)

    total = jnp.zeros(arch.n_params, theta.dtype)
    if problem.t_u.size:
        total += summed(lambda ps, t, p, s: w_u * data_terms(arch, ps, t, p, OPS, columns, s),
                        data["t_u"], data["p_u"], data.get("start_u"))
    if problem.t_f.size:
        total += summed(lambda ps, t, p, s: weighted(w_f, physics_terms(arch, ps, t, p, OPS, physics, s), OPS),
                        data["t_f"], data["p_f"], data.get("start_f"))
    return total


@functools.lru_cache(maxsize=_JIT_CACHE_SIZE)
def _query_functions(arch: Architecture) -> tuple:
    """The jitted query functions of networks `arch` (grid, points, and both with start states),
    shared by every evaluator of the architecture in the process: each shape compiles once."""
    # one stacked (2, n_p, n_t, n) result: one device-to-host conversion per query, not two
    return (
        jax.jit(lambda th, t, p: jnp.stack(delta_omega(arch, th, t[None, :], p[:, None], OPS))),
        jax.jit(lambda th, t, p: jnp.stack(delta_omega(arch, th, t, p, OPS))),
        jax.jit(lambda th, t, p, s: jnp.stack(
            delta_omega(arch, th, t[None, :], p[:, None], OPS, (s[:, None, 0], s[:, None, 1])))),
        jax.jit(lambda th, t, p, s: jnp.stack(delta_omega(arch, th, t, p, OPS, (s[:, 0], s[:, 1])))),
    )


class _JitEvaluator(Evaluator):
    """delta (rad) and omega (rad/s) = d delta/dt by jax.jvp, (len(P1), len(t), n), one jitted
    function of (theta, t, P1) (and of the start states, for time-marching windows); compiled here
    for the paper's query shapes (the 100 x 201 grid, one trajectory, one point), others compile on
    their first call."""

    def __init__(self, arch: Architecture, dtype: str) -> None:
        self.npdtype = _DTYPES[dtype]
        self.x64 = jax.enable_x64(dtype == "float64")
        self.fn, self.paired, self.fn_start, self.paired_start = _query_functions(arch)
        self.load(np.zeros(arch.n_params))
        t_grid = np.linspace(arch.t_lo, arch.t_hi, 201)
        p_grid = np.linspace(arch.p_lo, arch.p_hi, 100)
        for t, p in ((t_grid, p_grid), (t_grid, p_grid[:1]), (t_grid[:1], p_grid[:1])):
            self(t, p)

    def prepare(self, theta: np.ndarray) -> Any:
        with self.x64:  # committed to the CPU: the queries run there whatever JAX's default device
            return jax.device_put(jnp.asarray(theta, self.npdtype), _device("cpu"))

    def load(self, theta: np.ndarray) -> None:
        self.theta = self.prepare(theta)

    # __call__ and points are written out: a single-point query costs ~16 us, a helper call more
    def _run(self, fn: Callable, params: Any, *arrays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(delta, omega) of the jitted `fn(params, *arrays)`, arrays in the network's dtype."""
        with self.x64:
            out = fn(params, *(a.astype(self.npdtype, copy=False) for a in arrays))
        both = np.array(out)  # a writeable copy, like torch-pinn's results (np.asarray is read-only)
        return both[0], both[1]

    def __call__(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self.fn, self.theta, t, P1)

    def points(self, t: np.ndarray, P1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self.paired, self.theta, t, P1)

    def grid(self, params: Any, t: np.ndarray, P1: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self.fn_start, params, t, P1, start)

    def pairs(self, params: Any, t: np.ndarray, P1: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._run(self.paired_start, params, t, P1, start)
