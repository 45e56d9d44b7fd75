"""The PINN's network, derivatives and loss, written once over the backend's ops.

Like `systems.model` takes the backend's `sin`, these functions take an `Ops` bundle: the
elementwise functions and the functional autodiff transforms, which torch.func and JAX spell the
same way (`jvp(f, primals, tangents)`, `vmap(f, in_dims)`, `jacrev(f)`). A backend supplies its
`Ops` and compiles (jax.jit) or calls (torch) these functions; nothing here imports a framework.

Shapes: t (s) and P1 (p.u.) are arrays of one broadcast shape S (a batch (n,), a grid
(n_p, n_t) from (1, n_t) and (n_p, 1), or scalars for per-point Jacobians); every output has shape
S. `theta` is the flat parameter vector of `spec.Architecture` or its split list
(`Architecture.split`); Jacobians are taken with respect to the split list.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from systems.model import SwingSystem, residual
from solvers.pinn.spec import Architecture, Problem

__all__ = [
    "Ops",
    "data_terms",
    "delta_omega",
    "jacobian_blocks",
    "network_outputs",
    "physics_parameters",
    "physics_terms",
    "residual_vector",
    "swing_residuals",
]


@dataclass(frozen=True)
class Ops:
    """A backend's elementwise functions (tanh, sin, exp), array helpers (ones_like, stack(seq, axis),
    concat(seq, axis)) and functional autodiff (jvp, vmap, jacrev with JAX's call signatures).

    The t-derivatives are forward-mode (`jvp`) unless the backend supplies `d_dt` and `d2_dt2`
    (torch's reverse-mode autograd is faster for the loss gradient, see torch_pinn):
    d_dt(f, t) -> (f(t), f'(t)) for f returning an array or a tuple of arrays, each output
    depending on its own entry of t only; d2_dt2(f, t) -> (f, f', f'') for an array f."""

    tanh: Callable
    sin: Callable
    exp: Callable
    ones_like: Callable
    stack: Callable
    concat: Callable
    jvp: Callable
    vmap: Callable
    jacrev: Callable
    d_dt: Callable | None = None
    d2_dt2: Callable | None = None


def network_outputs(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops) -> tuple[Any, ...]:
    """The network's physical outputs: (delta,) rad, or (delta rad, omega rad/s) for two outputs.

    Inputs are normalised to [-1, 1]; tanh hidden layers, linear output layer. With `hard_ic`,
    phi = 1 - exp(-t) (t in s) and delta = delta0 + omega0 phi + phi^2 N_1 (so delta(0) = delta0
    and delta'(0) = omega0 exactly), omega = omega0 + phi N_2. (A t^2 factor instead of phi^2 grows
    to 400 over 20 s and scales the network's output badly; phi saturates at 1 after a few s.)"""
    layers = arch.layers(_params(arch, theta))
    tn = (t - arch.t_lo) * (2.0 / (arch.t_hi - arch.t_lo)) - 1.0
    pn = (p - arch.p_lo) * (2.0 / (arch.p_hi - arch.p_lo)) - 1.0
    w0, b0 = layers[0]
    h = ops.tanh(tn[..., None] * w0[0] + pn[..., None] * w0[1] + b0)  # first layer without a stack
    for w, b in layers[1:-1]:
        h = ops.tanh(h @ w + b)
    w, b = layers[-1]
    raw = h @ w + b
    outs = tuple(raw[..., k] for k in range(arch.outputs))
    if not arch.hard_ic:
        return outs
    phi = 1.0 - ops.exp(-t)
    delta = arch.delta0 + phi * (arch.omega0 + phi * outs[0])
    if arch.outputs == 1:
        return (delta,)
    return delta, arch.omega0 + phi * outs[1]


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


def delta_omega(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops) -> tuple[Any, Any]:
    """delta (rad) and omega (rad/s): omega = d delta / dt by forward-mode autodiff of the network,
    or the network's second output for two-output networks."""
    if arch.outputs == 2:
        return network_outputs(arch, theta, t, p, ops)
    delta, delta_t = _d_dt(lambda s: network_outputs(arch, theta, s, p, ops)[0], t, ops)
    return delta, delta_t


def physics_parameters(arch: Architecture, theta: Any, system: SwingSystem, ops: Ops) -> tuple[Any, Any]:
    """(m, d): the system's, or exp of the last two entries of theta for identification."""
    if arch.n_extra:
        log_md = _params(arch, theta)[-1]
        return ops.exp(log_md[0]), ops.exp(log_md[1])
    return system.m[0], system.d[0]


def data_terms(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, columns: int) -> Any:
    """Predictions for the data targets, shape S + (columns,): delta, and omega when columns = 2."""
    if columns == 1:
        return network_outputs(arch, theta, t, p, ops)[0][..., None]
    return ops.stack(delta_omega(arch, theta, t, p, ops), -1)


def swing_residuals(outputs: Callable[[Any], tuple[Any, ...]], n_outputs: int, t: Any, p: Any, ops: Ops,
                    system: SwingSystem, m: Any, d: Any) -> Any:
    """Swing-equation residuals (p.u.) of any differentiable `outputs(t) -> (delta,)` or
    `(delta, omega)` (n_outputs 1 or 2), shape S + (r,), from `systems.model.residual` with
    t-derivatives by (nested) forward-mode autodiff:
    one output: r = 1, f = m delta_tt + d delta_t + b sin(delta) - P1;
    two outputs: r = 2, f_omega = delta_t - omega (rad/s), f_delta = m omega_t + d omega + b sin(delta) - P1."""
    if n_outputs == 1:
        delta, delta_t, delta_tt = _d2_dt2(lambda x: outputs(x)[0], t, ops)
        (f,) = residual(system, [delta], [delta_t], [delta_tt], [p], sin=ops.sin, m=[m], d=[d])
        return f[..., None]
    (delta, omega), (delta_t, omega_t) = _d_dt(outputs, t, ops)
    (f_delta,) = residual(system, [delta], [omega], [omega_t], [p], sin=ops.sin, m=[m], d=[d])
    return ops.stack([delta_t - omega, f_delta], -1)


def physics_terms(arch: Architecture, theta: Any, t: Any, p: Any, ops: Ops, system: SwingSystem) -> Any:
    """The network's swing-equation residuals, shape S + (r,) (see `swing_residuals`)."""
    m, d = physics_parameters(arch, theta, system, ops)
    return swing_residuals(lambda s: network_outputs(arch, theta, s, p, ops), arch.outputs, t, p, ops,
                           system, m, d)


def residual_vector(arch: Architecture, theta: Any, data: dict, ops: Ops, system: SwingSystem,
                    problem: Problem) -> Any:
    """The weighted residual vector whose sum of squares is the loss:
    [w_u (prediction - target) for each data point and column, w_f f for each collocation point and
    residual]; `data` holds the problem's arrays in the backend (t_u, p_u, targets, t_f, p_f)."""
    w_u, w_f = problem.weights
    columns = problem.targets.shape[1]
    blocks = []
    if problem.t_u.size:
        pred = data_terms(arch, theta, data["t_u"], data["p_u"], ops, columns)
        blocks.append(w_u * (pred - data["targets"]).reshape(-1))
    if problem.t_f.size:
        blocks.append(w_f * physics_terms(arch, theta, data["t_f"], data["p_f"], ops, system).reshape(-1))
    return ops.concat(blocks, 0)


def jacobian_blocks(arch: Architecture, theta: Any, data: dict, ops: Ops, system: SwingSystem,
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
    if problem.t_u.size:
        j_u = ops.vmap(ops.jacrev(lambda ps, t, p: w_u * data_terms(arch, ps, t, p, ops, columns)),
                       (None, 0, 0))(params, data["t_u"], data["p_u"])
        blocks.append(_flat_jacobian(j_u, ops))
    if problem.t_f.size:
        j_f = ops.vmap(ops.jacrev(lambda ps, t, p: w_f * physics_terms(arch, ps, t, p, ops, system)),
                       (None, 0, 0))(params, data["t_f"], data["p_f"])
        blocks.append(_flat_jacobian(j_f, ops))
    return blocks[0] if len(blocks) == 1 else ops.concat(blocks, 0)


def _flat_jacobian(per_array: list[Any], ops: Ops) -> Any:
    """Per-point Jacobians w.r.t. each array of the split list, (n, k) + array shape each, as one
    (n k, n_params) matrix in the order of the flat vector."""
    n_rows = per_array[0].shape[0] * per_array[0].shape[1]
    return ops.concat([j.reshape(n_rows, -1) for j in per_array], 1)
