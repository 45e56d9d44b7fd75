"""The PINN adapter on PyTorch (CPU): torch.func / torch.autograd for training, a hand-rolled
forward-mode pass for queries.

Training evaluates the shared `solvers.pinn.network` with torch ops: the Jacobian of
Levenberg-Marquardt with torch.func's jvp / vmap / jacrev (the same functional API as JAX), the
residuals and the loss gradient of L-BFGS with reverse-mode torch.autograd (see OPS_AUTOGRAD). Queries use
`_FastForward`: the same network with its tangent in t propagated layer by layer. torch's eager
per-op overhead (~2-3 us) dominates small queries, and torch.func.jvp / forward_ad dual tensors
cost ~10x more per op; the hand-rolled pass folds the input normalisation into the first layer
and uses fused addmm / addcmul, ~25 torch ops in all. Tests check it against torch.func.jvp of
the shared network to rounding error.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
import torch
from torch import func as tfunc

from systems.model import SwingSystem
from solvers.pinn.common import Evaluator, PinnSolver, Trainer
from solvers.pinn.network import Ops, jacobian_blocks, residual_vector
from solvers.pinn.spec import Architecture, Problem

__all__ = ["OPS", "OPS_AUTOGRAD", "TorchPinn"]

OPS = Ops(
    tanh=torch.tanh, sin=torch.sin, exp=torch.exp, ones_like=torch.ones_like, stack=torch.stack,
    concat=torch.cat, jvp=tfunc.jvp, vmap=tfunc.vmap, jacrev=tfunc.jacrev,
)


def _as_variable(t: torch.Tensor) -> torch.Tensor:
    return t if t.requires_grad else t.detach().requires_grad_(True)


def _grad_t(y: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    # d(sum y)/dt is dy/dt pointwise: each output depends on its own t only
    return torch.autograd.grad(y.sum(), t, create_graph=True)[0]


def _autograd_d_dt(f, t):
    t = _as_variable(t)
    y = f(t)
    if isinstance(y, tuple):
        return y, tuple(_grad_t(v, t) for v in y)
    return y, _grad_t(y, t)


def _autograd_d2_dt2(f, t):
    t = _as_variable(t)
    y = f(t)
    y_t = _grad_t(y, t)
    return y, y_t, _grad_t(y_t, t)


# The residuals and the loss gradient take their t-derivatives by reverse-mode torch.autograd
# with create_graph: 21 ms per loss and gradient for the paper's 5 x 10 net on 8040 points in
# float32, against 84 ms with torch.func's nested jvp under grad; the default's residuals 1.9 ms
# against 10.5 ms (1 thread). The Jacobian (vmap/jacrev) needs torch.func's jvp:
# torch.autograd.grad does not run inside torch.func transforms (and per-sample gradients by
# autograd through expanded weights measured no faster: 31 ms against 34 ms).
OPS_AUTOGRAD = dataclasses.replace(OPS, d_dt=_autograd_d_dt, d2_dt2=_autograd_d2_dt2)
_DTYPES = {"float32": torch.float32, "float64": torch.float64}


_SIGMOID_TANH_MIN = 4096  # entries; below it the 3 extra ops cost more than tanh saves


def _tanh_(z: torch.Tensor) -> torch.Tensor:
    """tanh(z) in place in `z` (which it returns); for large tensors as 2 sigmoid(2 z) - 1. torch's
    vectorised sigmoid is ~4x cheaper than its tanh (float64, 20100 x 16, 2 threads: 0.20 ms
    against 0.83 ms): grid query 4.4 -> 2.6 ms, measured interleaved in one process; the absolute
    rounding error is < 5e-16 (the tests compare the query with torch.tanh under autodiff)."""
    if z.numel() < _SIGMOID_TANH_MIN:
        return z.tanh_()
    return z.mul_(2.0).sigmoid_().mul_(2.0).sub_(1.0)


class _FastForward(Evaluator):
    """delta (rad) and omega (rad/s) of a trained network on the grid P1 x t, (n_p, n_t) each.

    Forward-mode differentiation by hand: for each hidden layer z = h W + b, z_t = h_t W,
    h = tanh(z), h_t = (1 - h^2) z_t; the input map (t, P1) -> [-1, 1]^2 is folded into the first
    layer, whose t-tangent is then the constant row W_t. Output heads as in
    `network.network_outputs` (the hard initial condition with phi = 1 - exp(-t))."""

    def __init__(self, arch: Architecture, dtype: torch.dtype) -> None:
        self.arch, self.dtype = arch, dtype
        self.npdtype = np.float64 if dtype == torch.float64 else np.float32
        self.tangent = arch.outputs == 1  # two-output networks give omega directly

    def load(self, theta: np.ndarray) -> None:
        arch, dtype = self.arch, self.dtype
        layers = [(torch.as_tensor(np.asarray(w), dtype=dtype), torch.as_tensor(np.asarray(b), dtype=dtype))
                  for w, b in arch.layers(arch.split(np.asarray(theta, np.float64)))]
        ct, cp = 2.0 / (arch.t_hi - arch.t_lo), 2.0 / (arch.p_hi - arch.p_lo)
        w0, b0 = layers[0]
        self.w_t = (w0[0] * ct).contiguous()
        self.w_p = (w0[1] * cp).contiguous()
        self.b0 = (b0 - w0[0] * (1.0 + arch.t_lo * ct) - w0[1] * (1.0 + arch.p_lo * cp)).contiguous()
        self.hidden = [(b.contiguous(), w.contiguous()) for w, b in layers[1:-1]]
        self.w_out, self.b_out = layers[-1][0].contiguous(), layers[-1][1].contiguous()
        self(np.array([0.5 * arch.t_hi]), np.array([0.5 * (arch.p_lo + arch.p_hi)]))  # warm-up

    def __call__(self, t_np: np.ndarray, p_np: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(t_np, p_np, paired=False)

    def points(self, t_np: np.ndarray, p_np: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(t_np, p_np, paired=True)

    def _forward(self, t_np: np.ndarray, p_np: np.ndarray, paired: bool) -> tuple[np.ndarray, np.ndarray]:
        """The grid (len(P1), len(t)), or with `paired` the points (t[i], P1[i]), shape (n,)."""
        # No autograd context needed: no tensor here requires grad, so nothing is recorded.
        n_t, n_p = (1, p_np.shape[0]) if paired else (t_np.shape[0], p_np.shape[0])
        t_np, p_np = t_np.astype(self.npdtype, copy=False), p_np.astype(self.npdtype, copy=False)
        t = torch.from_numpy(t_np)
        z = torch.addcmul(torch.addcmul(self.b0, torch.from_numpy(p_np).view(n_p, 1, 1), self.w_p),
                          t.view(n_p if paired else 1, n_t, 1), self.w_t)
        h = _tanh_(z.view(n_p * n_t, -1))
        h_t = torch.addcmul(self.w_t, h * h, self.w_t, value=-1.0) if self.tangent else None
        for b, w in self.hidden:
            z_t = torch.mm(h_t, w) if self.tangent else None
            h = _tanh_(torch.addmm(b, h, w))
            if self.tangent:
                h_t = z_t.addcmul_(h * h, z_t, value=-1.0)
        shape = (n_p,) if paired else (n_p, n_t)
        out = torch.addmm(self.b_out, h, self.w_out).view(*shape, -1)
        n1 = out[..., 0]
        x = torch.mm(h_t, self.w_out).view(*shape) if self.tangent else out[..., 1]
        if not self.arch.hard_ic:
            return n1.numpy(), x.numpy()
        # delta = a0 + a1 N_1, omega = b0 + b1 N_1 + b2 X (X = dN_1/dt, or N_2 for two outputs),
        # the t-only coefficients of the hard initial condition computed in numpy (cheaper per op)
        a0, a1, b0, b1, b2 = (torch.from_numpy(c) for c in self._coefficients(t_np))
        delta = torch.addcmul(a0, a1, n1)
        omega = torch.addcmul(torch.addcmul(b0, b1, n1), b2, x)
        return delta.numpy(), omega.numpy()

    def _coefficients(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """(a0, a1, b0, b1, b2) of the hard-IC head at times t (s): phi = 1 - e, e = exp(-t);
        one output: delta = delta0 + omega0 phi + phi^2 N, omega = omega0 e + 2 e phi N + phi^2 N_t;
        two outputs: omega = omega0 + phi N_2."""
        arch = self.arch
        e = np.exp(-t)
        phi = 1.0 - e
        phi2 = phi * phi
        a0 = arch.delta0 + arch.omega0 * phi
        if self.tangent:
            return a0, phi2, arch.omega0 * e, 2.0 * e * phi, phi2
        return a0, phi2, np.full_like(t, arch.omega0), np.zeros_like(t), phi


class TorchPinn(PinnSolver):
    """PINN on PyTorch; see `solvers.pinn.common.PinnSolver` for the options, configs and files."""

    name: ClassVar[str] = "torch-pinn"

    def _prepare_backend(self) -> str:
        torch.set_num_threads(self.options["threads"])
        return ""

    def _compile(self, arch: Architecture, problem: Problem, system: SwingSystem, dtype: str) -> Trainer:
        tdtype = _DTYPES[dtype]
        data = {key: torch.as_tensor(getattr(problem, key), dtype=tdtype)
                for key in ("t_u", "p_u", "targets", "t_f", "p_f")}

        def tensor(theta: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.asarray(theta, np.float64)).to(tdtype)

        def numpy(x: torch.Tensor) -> np.ndarray:
            return x.detach().to(torch.float64).numpy()

        def residuals(theta: np.ndarray) -> np.ndarray:
            with torch.enable_grad():  # reverse-mode t-derivatives: 1.9 ms against 10.5 ms (2 x 16)
                return numpy(residual_vector(arch, tensor(theta), data, OPS_AUTOGRAD, system, problem))

        def jacobian(theta: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                return numpy(jacobian_blocks(arch, tensor(theta), data, OPS, system, problem))

        def loss_and_grad(theta: np.ndarray) -> tuple[float, np.ndarray]:
            variable = tensor(theta).requires_grad_(True)
            r = residual_vector(arch, variable, data, OPS_AUTOGRAD, system, problem)
            value = r @ r
            (grad,) = torch.autograd.grad(value, variable)
            return float(value.detach()), numpy(grad)

        return Trainer(residuals, jacobian, loss_and_grad)

    def _make_evaluator(self, arch: Architecture, dtype: str) -> Evaluator:
        return _FastForward(arch, _DTYPES[dtype])
