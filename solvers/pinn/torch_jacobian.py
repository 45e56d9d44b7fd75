"""torch-pinn's Levenberg-Marquardt residuals and Jacobian: the network's t-derivatives propagated
forward by hand (Taylor mode), and every point's gradient from one reverse pass through them.

Each residual depends on its own point only, and layer l's weights W, b enter a point's residual
only through the layer's pre-activation and its t-derivatives, z = s0 W + b, z_t = s1 W,
z_tt = s2 W, where s0, s1, s2 are the layer's input and its first and second t-derivatives
(hidden layers: h = tanh z, h_t = (1 - h^2) z_t, h_tt = (1 - h^2) z_tt - 2 h h_t z_t; the first
layer's input (tn, pn) has the t-derivative (2 / (t_hi - t_lo), 0)). So one reverse pass of the
summed residuals gives every point's sensitivities G_k = dr/dz_k (points x width, k = 0, 1, 2),
and each point's gradient is dr/dW = sum_k s_k^T G_k (an outer product per point),
dr/db = G_0. The output heads, data predictions and swing residuals are `solvers.pinn.network`'s,
applied to the output layer's Taylor polynomial in t (whose value and t-derivatives at the point
are the propagated ones), with their t-derivatives by reverse-mode autograd (`OPS_AUTOGRAD`).
Trained m and d (identification) enter as exp of a per-point copy of (log m, log d).

The same vector and matrix as `network.residual_vector` and `network.jacobian_blocks` (JAX's
path, jitted there); the tests compare them to rounding error. Why by hand: in eager torch, the
same computation by torch.func's vmap of jacrev of nested jvps sends each of its ~450 ops through
four functorch layers, several with forward-mode rules in Python (torch._refs), and forms each
point's weight gradient from several batched outer products (bmm) that it then adds; here each op
is plain autograd, and each point's weight gradient is written once into the Jacobian. The
residuals skip the reverse passes of `OPS_AUTOGRAD`'s t-derivatives through the hidden layers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torch

from solvers.pinn.architecture import Architecture
from solvers.pinn.network import (
    Ops,
    Physics,
    data_predictions,
    normalised_inputs,
    output_heads,
    physics_parameters,
    start_columns,
    swing_residuals,
    weighted,
)
from solvers.pinn.problems import Problem

__all__ = ["taylor_jacobian", "taylor_loss_and_grad", "taylor_residuals"]

Streams = list[torch.Tensor]  # a tensor and its t-derivatives of order 1, 2


def _tanh_streams(z: Streams) -> Streams:
    """h = tanh(z) and its t-derivatives from those of z, as many as z has."""
    h = torch.tanh(z[0])
    out: Streams = [h]
    if len(z) > 1:
        g = 1.0 - h * h
        h_t = g * z[1]
        out.append(h_t)
        if len(z) > 2:
            out.append(torch.addcmul(-2.0 * h * h_t * z[1], g, z[2]))
    return out


def _forward(layers: list[tuple[torch.Tensor, torch.Tensor]], tn: torch.Tensor, pn: torch.Tensor,
             slope: float, order: int) -> list[tuple[Streams, Streams]]:
    """Each layer's (input streams, pre-activation streams), points on the first axis, with
    t-derivatives up to `order`; the last layer's pre-activation is the network's raw output."""
    x = torch.stack([tn, pn], -1)
    streams: Streams = [x]
    if order >= 1:  # d(tn, pn)/dt, one row per point so that each point's z_t has a gradient of its own
        streams.append(torch.tensor([slope, 0.0], dtype=x.dtype, device=x.device).expand_as(x))
    if order >= 2:
        streams.append(torch.zeros_like(x))
    out = []
    for i, (w, b) in enumerate(layers):
        z: Streams = [torch.addmm(b, streams[0], w)] + [s @ w for s in streams[1:]]
        out.append((streams, z))
        if i < len(layers) - 1:
            streams = _tanh_streams(z)
    return out


def _taylor(raw: Streams, t: torch.Tensor) -> Callable[[torch.Tensor], torch.Tensor]:
    """The polynomial s -> sum_k raw_k (s - t)^k / k! (S + (outputs,)), whose value and
    t-derivatives at s = t are exactly raw_0, raw_1, raw_2."""
    def at(s: torch.Tensor) -> torch.Tensor:
        u = (s - t)[..., None]
        acc = raw[-1]
        for k in range(len(raw) - 2, -1, -1):
            acc = raw[k] + u * acc / float(k + 1)
        return acc
    return at


Block = tuple[torch.Tensor, list[tuple[Streams, Streams]], torch.Tensor | None]


def _residual_blocks(arch: Architecture, params: list[torch.Tensor], data: dict, ops: Ops, physics: Physics,
                     problem: Problem) -> list[Block]:
    """The data and collocation blocks of `network.residual_vector` (those with points): each
    block's weighted residuals (points, columns), its layers' (input, pre-activation) streams
    and, for the collocation block of an identification network, the per-point copy of
    (log m, log d) (points, 2n) that m and d are computed from (None otherwise)."""
    w_u, w_f = problem.weights
    columns = problem.targets.shape[1]
    n = arch.machines
    layers = arch.layers(params)
    slope = 2.0 / (arch.t_hi - arch.t_lo)

    def network(t: torch.Tensor, p: torch.Tensor, order: int, start: Any
                ) -> tuple[Callable[[torch.Tensor], tuple], list[tuple[Streams, Streams]]]:
        passes = _forward(layers, *normalised_inputs(arch, t, p), slope, order)
        raw = _taylor(passes[-1][1], t)
        return (lambda s: output_heads(arch, s, raw(s), ops, start)), passes

    blocks: list[Block] = []
    if problem.t_u.size:
        t = data["t_u"]
        order = 0 if columns == n or arch.outputs == 2 else 1
        outputs, passes = network(t, data["p_u"], order, start_columns(data, "start_u"))
        blocks.append((w_u * (data_predictions(outputs, arch, t, ops, columns) - data["targets"]), passes, None))
    if problem.t_f.size:
        t, p = data["t_f"], data["p_f"]
        outputs, passes = network(t, p, 3 - arch.outputs, start_columns(data, "start_f"))
        log_md = None
        if arch.n_extra:
            log_md = params[-1].expand(t.shape[0], 2 * n)  # a per-point copy: its gradient is each point's
            m, d = torch.exp(log_md[:, :n]), torch.exp(log_md[:, n:])
        else:
            m, d = physics_parameters(arch, params, physics, ops, p)
        blocks.append((weighted(w_f, swing_residuals(outputs, arch.outputs, t, p, ops, physics, m, d), ops), passes,
                       log_md))
    return blocks


def _block_jacobian(jac: torch.Tensor, block: Block) -> None:
    """Write the Jacobian of `block`'s residuals into the zeros `jac` (points, columns, n_params)."""
    r, passes, log_md = block
    points, columns = r.shape
    wanted = [z for _, zs in passes for z in zs] + ([] if log_md is None else [log_md])
    for c in range(columns):
        pick = torch.zeros_like(r)  # the gradient of column c summed over the points
        pick[:, c] = 1.0
        grads = iter(torch.autograd.grad(r, wanted, pick, retain_graph=c < columns - 1, allow_unused=True))
        offset = 0
        for inputs, zs in passes:
            n_in, n_out = inputs[0].shape[-1], zs[0].shape[-1]
            w_block = jac[:, c, offset:offset + n_in * n_out].view(points, n_in, n_out)
            for k, s in enumerate(inputs):
                g = next(grads)
                if g is None:
                    continue
                if k == 0:
                    jac[:, c, offset + n_in * n_out:offset + (n_in + 1) * n_out] = g
                w_block.addcmul_(s[:, :, None], g[:, None, :])
            offset += (n_in + 1) * n_out
        if log_md is not None:
            g = next(grads)
            if g is not None:
                jac[:, c, offset:] = g


def taylor_residuals(arch: Architecture, theta: torch.Tensor, data: dict, ops: Ops, physics: Physics,
                     problem: Problem) -> torch.Tensor:
    """`network.residual_vector` (n_residuals,) by the same forward pass as `taylor_jacobian`;
    `ops` as there."""
    with torch.enable_grad():
        blocks = _residual_blocks(arch, arch.split(theta.detach()), data, ops, physics, problem)
    return torch.cat([r.detach().reshape(-1) for r, _, _ in blocks])


def taylor_loss_and_grad(arch: Architecture, theta: torch.Tensor, data: dict, ops: Ops, physics: Physics,
                         problem: Problem) -> tuple[torch.Tensor, torch.Tensor]:
    """The loss (the sum of squares of `taylor_residuals`, a 0-d tensor) and its gradient
    (n_params,), by one reverse pass through the same forward pass; `ops` as there."""
    with torch.enable_grad():
        variable = theta.detach().requires_grad_(True)
        blocks = _residual_blocks(arch, arch.split(variable), data, ops, physics, problem)
        value = torch.stack([torch.sum(r * r) for r, _, _ in blocks]).sum()
        (grad,) = torch.autograd.grad(value, variable)
    return value.detach(), grad


def taylor_jacobian(arch: Architecture, theta: torch.Tensor, data: dict, ops: Ops, physics: Physics,
                    problem: Problem) -> torch.Tensor:
    """d residual_vector / d theta, (n_residuals, n_params), as `network.jacobian_blocks`; `ops`
    must take t-derivatives by reverse-mode autograd (torch_pinn's OPS_AUTOGRAD). `theta`
    (n_params,) is not modified."""
    with torch.enable_grad():
        blocks = _residual_blocks(arch, arch.split(theta.detach().requires_grad_(True)), data, ops, physics,
                                  problem)
    jac = theta.new_zeros(sum(r.numel() for r, _, _ in blocks), arch.n_params)
    row = 0
    with torch.no_grad():  # the reverse passes need no graph of their own, nor the outer products
        for block in blocks:
            points, columns = block[0].shape
            _block_jacobian(jac[row:row + points * columns].view(points, columns, -1), block)
            row += points * columns
    return jac
