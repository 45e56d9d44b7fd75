"""The PINN's network, derivatives and loss, written once over the backend's ops.

Like `systems.model` takes the backend's `sin`, these functions take an `Ops` bundle: the
elementwise functions and the functional autodiff transforms, which torch.func and JAX spell the
same way (`jvp(f, primals, tangents)`, `vmap(f, in_dims)`, `jacrev(f)`). A backend supplies its
`Ops` and compiles (jax.jit) or calls (torch) these functions; nothing here imports a framework.

Shapes: t (s) and P1 (p.u.) are arrays of one broadcast shape S (a batch (n_s,), a grid
(n_p, n_t) from (1, n_t) and (n_p, 1), or scalars for per-point Jacobians); every output has shape
S + (n,), one entry per machine on the last axis (n = 1 for the SMIB). `theta` is the flat
parameter vector of an `Architecture` or its split list (`Architecture.split`); Jacobians are
taken with respect to the split list. A time-marching window's network takes each point's start
state `start` = (delta_s, omega_s), arrays broadcasting to S + (n,), in place of the architecture's
fixed initial condition, and t is the time since the window's start.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from solvers.pinn.architecture import Architecture
from solvers.pinn.problems import Problem
from systems.cases import Case
from systems.model import Coupling, coupling, residual

__all__ = [
    "Ops",
    "Physics",
    "data_predictions",
    "data_terms",
    "delta_omega",
    "jacobian_blocks",
    "network_outputs",
    "normalised_inputs",
    "observed",
    "output_heads",
    "physics_parameters",
    "physics_terms",
    "powers",
    "residual_vector",
    "start_columns",
    "swing_residuals",
    "weighted",
]

Start = tuple[Any, Any] | None  # (delta_s rad, omega_s rad/s), each broadcasting to S + (n,)


@dataclass(frozen=True)
class Ops:
    """A backend's elementwise functions (tanh, sin, cos, exp), array helpers (ones_like,
    stack(seq, axis), concat(seq, axis), asarray(numpy array, like) -> a constant of `like`'s
    dtype) and functional autodiff (jvp, vmap, jacrev with JAX's call signatures).

    The t-derivatives are forward-mode (`jvp`) unless the backend supplies `d_dt` and `d2_dt2`
    (torch's reverse-mode autograd is faster for the loss gradient, see torch_pinn):
    d_dt(f, t) -> (f(t), f'(t)) for f returning an array or a tuple of arrays, each S + (n,), each
    output depending on its own entry of t only; d2_dt2(f, t) -> (f, f', f'') for an array f."""

    tanh: Callable
    sin: Callable
    cos: Callable
    exp: Callable
    ones_like: Callable
    stack: Callable
    concat: Callable
    asarray: Callable
    jvp: Callable
    vmap: Callable
    jacrev: Callable
    d_dt: Callable | None = None
    d2_dt2: Callable | None = None


@dataclass(frozen=True, eq=False)
class Physics:
    """The swing equations a forward network satisfies, numpy float64 (each backend converts them to
    its dtype where it uses them): the coupling of `systems.model.coupling`, m and d (n,) p.u., and
    the mechanical powers P = P1 first + rest (p.u.; first = e_1, rest = p_m with generator 1's
    entry 0: generator 1 gets P1, the others the case's p_m, as `Case.powers`). `phase` names a
    fault case's phase ('on' or 'post', `of_phase`), "" for a step case: what compiled training
    functions are keyed by besides the case."""

    coupling: Coupling
    m: np.ndarray
    d: np.ndarray
    first: np.ndarray
    rest: np.ndarray
    phase: str = ""

    @classmethod
    def of(cls, case: Case) -> Physics:
        """A step case's equations: generator 1's power is the scenario input P1."""
        if case.fault is not None:
            raise ValueError(f"case {case.name!r} is a fault case: its equations are those of a phase (of_phase)")
        first = np.zeros(case.n)
        first[0] = 1.0
        rest = np.asarray(case.p_m, np.float64) * (1.0 - first)
        return cls(coupling(case), np.asarray(case.m, np.float64), np.asarray(case.d, np.float64), first, rest)

    @classmethod
    def of_phase(cls, case: Case, which: str) -> Physics:
        """Fault case `case`'s equations in phase `which` ('on' or 'post'): the coupling of
        `Case.phase(which)`'s network and P = p_m whatever the scenario input (the clearing time)."""
        step = cls.of(case.phase(which))
        return dataclasses.replace(step, first=np.zeros_like(step.first),
                                   rest=np.asarray(case.p_m, np.float64), phase=which)

    @property
    def n(self) -> int:
        return self.m.size


def network_outputs(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, start: Start = None
                    ) -> tuple[Any, ...]:
    """The network's physical outputs, each S + (n,): (delta,) rad, or (delta rad, omega rad/s) for
    two outputs per machine.

    Inputs are normalised to [-1, 1]; tanh hidden layers, linear output layer (columns delta_1..n,
    then omega_1..n). With `hard_ic`, phi = 1 - exp(-t) (t in s) and per machine
    delta = delta0 + omega0 phi + phi^2 N_1 (so delta(0) = delta0 and delta'(0) = omega0 exactly),
    omega = omega0 + phi N_2, with (delta0, omega0) the architecture's or each point's `start`.
    (A t^2 factor instead of phi^2 grows to 400 over 20 s and scales the network's output badly;
    phi saturates at 1 after a few s.)"""
    layers = arch.layers(_params(arch, theta))
    tn, pn = normalised_inputs(arch, t, p)
    w0, b0 = layers[0]
    h = ops.tanh(tn[..., None] * w0[0] + pn[..., None] * w0[1] + b0)  # first layer without a stack
    for w, b in layers[1:-1]:
        h = ops.tanh(h @ w + b)
    w, b = layers[-1]
    return output_heads(arch, t, h @ w + b, ops, start)


def normalised_inputs(arch: Architecture, t: Any, p: Any) -> tuple[Any, Any]:
    """The network's inputs t (s) and P1 (p.u.) mapped to [-1, 1] over the architecture's ranges,
    each of shape S; dtn/dt is the constant 2 / (t_hi - t_lo) (1/s)."""
    return ((t - arch.t_lo) * (2.0 / (arch.t_hi - arch.t_lo)) - 1.0,
            (p - arch.p_lo) * (2.0 / (arch.p_hi - arch.p_lo)) - 1.0)


def output_heads(arch: Architecture, t: Any, raw: Any, ops: Ops, start: Start = None) -> tuple[Any, ...]:
    """The physical outputs (`network_outputs`) from the output layer's values `raw`, S + (outputs n,),
    at times t (s), shape S: the hard initial condition's heads, or the columns of `raw` as they are
    without `hard_ic`."""
    n = arch.machines
    outs = (raw,) if arch.outputs == 1 else (raw[..., :n], raw[..., n:])
    if not arch.hard_ic:
        return outs
    if start is None:
        delta0, omega0 = ops.asarray(np.asarray(arch.delta0), t), ops.asarray(np.asarray(arch.omega0), t)
    else:
        delta0, omega0 = start
    phi = (1.0 - ops.exp(-t))[..., None]
    delta = delta0 + phi * (omega0 + phi * outs[0])
    if arch.outputs == 1:
        return (delta,)
    return delta, omega0 + phi * outs[1]


def _params(arch: Architecture, theta: Any) -> list[Any]:
    return theta if isinstance(theta, (list, tuple)) else arch.split(theta)


def _d_dt(f: Callable, t: Any, ops: Ops) -> tuple[Any, Any]:
    """(f(t), df/dt) by forward-mode autodiff (or the backend's d_dt); f may return a tuple,
    then both are tuples."""
    if ops.d_dt is not None:
        return ops.d_dt(f, t)
    return ops.jvp(f, (t,), (ops.ones_like(t),))


def _d2_dt2(f: Callable, t: Any, ops: Ops) -> tuple[Any, Any, Any]:
    """(f(t), f'(t), f''(t)) by nested forward-mode autodiff (or the backend's d2_dt2)."""
    if ops.d2_dt2 is not None:
        return ops.d2_dt2(f, t)
    (y, y_t), (_, y_tt) = ops.jvp(lambda s: ops.jvp(f, (s,), (ops.ones_like(s),)), (t,), (ops.ones_like(t),))
    return y, y_t, y_tt


def delta_omega(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, start: Start = None
                ) -> tuple[Any, Any]:
    """delta (rad) and omega (rad/s), each S + (n,): omega = d delta / dt by forward-mode autodiff of
    the network, or the network's second outputs for two-output networks."""
    return observed(lambda s: network_outputs(arch, theta, s, p, ops, start), arch.outputs, t, ops)


def observed(outputs: Callable[[Any], tuple[Any, ...]], n_outputs: int, t: Any, ops: Ops) -> tuple[Any, Any]:
    """(delta, omega) of any differentiable `outputs(t) -> (delta,)` or `(delta, omega)` (each
    S + (n,); n_outputs 1 or 2 per machine): omega = d delta / dt for one output."""
    if n_outputs == 2:
        return outputs(t)
    delta, delta_t = _d_dt(lambda s: outputs(s)[0], t, ops)
    return delta, delta_t


def physics_parameters(arch: Architecture, theta: Any, physics: Physics, ops: Ops, like: Any
                       ) -> tuple[Any, Any]:
    """(m, d), each (n,) in `like`'s dtype: the case's, or exp of the last 2n entries of theta
    (log m_1..n, log d_1..n) for identification."""
    if arch.n_extra:
        log_md = _params(arch, theta)[-1]
        n = arch.machines
        return ops.exp(log_md[:n]), ops.exp(log_md[n:])
    return ops.asarray(physics.m, like), ops.asarray(physics.d, like)


def powers(p: Any, physics: Physics, ops: Ops) -> Any:
    """Mechanical powers S + (n,) p.u. for generator 1's P1 = p (shape S): P1 and the others' p_m.
    For one machine just p (no column of other machines to append)."""
    if physics.n == 1:
        return p[..., None]
    return p[..., None] * ops.asarray(physics.first, p) + ops.asarray(physics.rest, p)


def data_terms(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, columns: int,
               start: Start = None) -> Any:
    """Predictions for the data targets, shape S + (columns,): delta_1..n, and omega_1..n when
    columns = 2n."""
    return data_predictions(lambda s: network_outputs(arch, theta, s, p, ops, start), arch, t, ops, columns)


def data_predictions(outputs: Callable[[Any], tuple[Any, ...]], arch: Architecture, t: Any, ops: Ops,
                     columns: int) -> Any:
    """`data_terms` of any differentiable `outputs(t)` of a network `arch` (see `observed`)."""
    if columns == arch.machines:
        return outputs(t)[0]
    return ops.concat(observed(outputs, arch.outputs, t, ops), -1)


def swing_residuals(outputs: Callable[[Any], tuple[Any, ...]], n_outputs: int, t: Any, p: Any, ops: Ops,
                    physics: Physics, m: Any, d: Any) -> Any:
    """Swing-equation residuals (p.u.) of any differentiable `outputs(t) -> (delta,)` or
    `(delta, omega)` (each S + (n,); n_outputs 1 or 2 per machine), shape S + (r,), from
    `systems.model.residual` (the backend's sin and cos, machines on the last axis) with
    t-derivatives by (nested) forward-mode autodiff:
    one output: r = n, f_k = m_k delta_k'' + d_k delta_k' + P_e,k(delta) - P_k;
    two outputs: r = 2n, first f_omega,k = delta_k' - omega_k (rad/s), then
    f_delta,k = m_k omega_k' + d_k omega_k + P_e,k(delta) - P_k."""
    k = physics.coupling.map(lambda x: ops.asarray(x, p))
    P = powers(p, physics, ops)
    if n_outputs == 1:
        delta, delta_t, delta_tt = _d2_dt2(lambda x: outputs(x)[0], t, ops)
        return residual(k, m, d, delta, delta_t, delta_tt, P, sin=ops.sin, cos=ops.cos)
    (delta, omega), (delta_t, omega_t) = _d_dt(outputs, t, ops)
    f_delta = residual(k, m, d, delta, omega, omega_t, P, sin=ops.sin, cos=ops.cos)
    return ops.concat([delta_t - omega, f_delta], -1)


def physics_terms(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, physics: Physics,
                  start: Start = None) -> Any:
    """The network's swing-equation residuals, shape S + (r,) (see `swing_residuals`)."""
    m, d = physics_parameters(arch, theta, physics, ops, p)
    return swing_residuals(lambda s: network_outputs(arch, theta, s, p, ops, start), arch.outputs, t, p, ops,
                           physics, m, d)


def weighted(weight: float | np.ndarray, f: Any, ops: Ops) -> Any:
    """weight * f for a weight that is a number or a numpy array (r,) over f's last axis (a
    constant of f's dtype)."""
    return weight * f if isinstance(weight, float) else ops.asarray(weight, f) * f


def start_columns(data: dict, key: str) -> Start:
    """The (delta_s, omega_s) columns of a (points, 2, n) start array in `data`, or None."""
    s = data.get(key)
    return None if s is None else (s[..., 0, :], s[..., 1, :])


def residual_vector(arch: Architecture, theta: Any, data: dict, ops: Ops, physics: Physics,
                    problem: Problem) -> Any:
    """The weighted residual vector whose sum of squares is the loss:
    [w_u (prediction - target) for each data point and column, w_f f for each collocation point and
    residual]; `data` holds the problem's arrays in the backend (t_u, p_u, targets, t_f, p_f, and
    start_u, start_f (points, 2, n) for a time-marching window)."""
    w_u, w_f = problem.weights
    columns = problem.targets.shape[1]
    blocks = []
    if problem.t_u.size:
        pred = data_terms(arch, theta, data["t_u"], data["p_u"], ops, columns, start_columns(data, "start_u"))
        blocks.append(w_u * (pred - data["targets"]).reshape(-1))
    if problem.t_f.size:
        f = physics_terms(arch, theta, data["t_f"], data["p_f"], ops, physics, start_columns(data, "start_f"))
        blocks.append(weighted(w_f, f, ops).reshape(-1))
    return ops.concat(blocks, 0)


def jacobian_blocks(arch: Architecture, theta: Any, data: dict, ops: Ops, physics: Physics,
                    problem: Problem) -> Any:
    """d residual_vector / d theta, shape (n_residuals, n_params): per-point reverse-mode
    gradients, vmapped over the points (each residual depends on one point only, so this costs
    O(points x parameters), where jacrev of the whole vector would cost O(points^2 x parameters)).
    Taken with respect to the split list and concatenated once: with respect to the flat vector,
    torch builds each slice's gradient as a zero-filled (points x parameters) array and adds them
    (measured: 2/3 of the time of torch's Jacobian)."""
    w_u, w_f = problem.weights
    columns = problem.targets.shape[1]
    params = arch.split(theta)
    blocks = []

    def per_point(fn: Callable, t: Any, p: Any, s: Any) -> Any:
        # each point's start state is mapped with it, when it has one
        if s is None:
            return ops.vmap(ops.jacrev(lambda ps, t, p: fn(ps, t, p, None)), (None, 0, 0))(params, t, p)
        return ops.vmap(ops.jacrev(lambda ps, t, p, s: fn(ps, t, p, (s[0], s[1]))), (None, 0, 0, 0))(
            params, t, p, s)

    if problem.t_u.size:
        j_u = per_point(lambda ps, t, p, s: w_u * data_terms(arch, ps, t, p, ops, columns, s),
                        data["t_u"], data["p_u"], data.get("start_u"))
        blocks.append(_flat_jacobian(j_u, ops))
    if problem.t_f.size:
        j_f = per_point(lambda ps, t, p, s: weighted(w_f, physics_terms(arch, ps, t, p, ops, physics, s), ops),
                        data["t_f"], data["p_f"], data.get("start_f"))
        blocks.append(_flat_jacobian(j_f, ops))
    return blocks[0] if len(blocks) == 1 else ops.concat(blocks, 0)


def _flat_jacobian(per_array: list[Any], ops: Ops) -> Any:
    """Per-point Jacobians w.r.t. each array of the split list, (points, k) + array shape each, as one
    (points k, n_params) matrix in the order of the flat vector."""
    n_rows = per_array[0].shape[0] * per_array[0].shape[1]
    return ops.concat([j.reshape(n_rows, -1) for j in per_array], 1)
