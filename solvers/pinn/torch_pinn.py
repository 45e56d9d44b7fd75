"""The PINN adapter on PyTorch (training on the CPU, or a CUDA GPU with `device="cuda"`): torch.autograd
and hand-rolled Taylor-mode passes for training, a hand-rolled forward-mode pass for queries.

Training evaluates the shared `solvers.pinn.network`'s heads and residuals with torch ops, the
network's t-derivatives propagated by hand and one reverse pass for every point's gradient
(Levenberg-Marquardt's Jacobian) or for the loss gradient (L-BFGS): `solvers.pinn.torch_jacobian`.
`OPS` (torch.func's jvp / vmap / jacrev, the same functional API as JAX) evaluates the shared
network as JAX does, for the tests. Queries use
`_FastForward`: the same network with its tangent in t propagated layer by layer. torch's eager
per-op overhead (~2-3 us) dominates small queries, and torch.func.jvp / forward_ad dual tensors
cost ~10x more per op; the hand-rolled pass folds the input normalisation into the first layer
and uses fused addmm / addcmul, ~25 torch ops in all. Tests check it against torch.func.jvp of
the shared network to rounding error.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Literal

import numpy as np
import torch
from torch import func as tfunc

from solvers.pinn.architecture import Architecture
from solvers.pinn.common import PinnOptions, PinnSolver, Trainer
from solvers.pinn.evaluator import Evaluator
from solvers.pinn.network import Ops, Physics
from solvers.pinn.problems import Problem
from solvers.pinn.torch_jacobian import taylor_jacobian, taylor_loss_and_grad, taylor_residuals

__all__ = ["OPS", "OPS_AUTOGRAD", "TorchOptions", "TorchPinn"]


def _asarray(x: np.ndarray, like: torch.Tensor) -> torch.Tensor:
    return torch.as_tensor(x, dtype=like.dtype, device=like.device)


OPS = Ops(
    tanh=torch.tanh, sin=torch.sin, cos=torch.cos, exp=torch.exp, ones_like=torch.ones_like,
    stack=torch.stack, concat=torch.cat, asarray=_asarray, jvp=tfunc.jvp, vmap=tfunc.vmap,
    jacrev=tfunc.jacrev,
)


def _as_variable(t: torch.Tensor) -> torch.Tensor:
    return t if t.requires_grad else t.detach().requires_grad_(True)


def _grad_t(y: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """dy/dt of y (S + (n,)) for t (S): d(sum y_k)/dt is dy_k/dt pointwise (each output depends on its
    own t only), one reverse pass per machine (n = 1: one, as for the SMIB)."""
    columns = [torch.autograd.grad(y[..., k].sum(), t, create_graph=True)[0] for k in range(y.shape[-1])]
    return torch.stack(columns, -1)


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


# t-derivatives by reverse-mode torch.autograd with create_graph: 21 ms per loss and gradient for
# the paper's 5 x 10 net on 8040 points in float32, against 84 ms with torch.func's nested jvp
# under grad. `solvers.pinn.torch_jacobian` takes the output heads' t-derivatives with it.
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
    """delta (rad) and omega (rad/s) of a trained network on the grid P1 x t, (n_p, n_t, n) each.

    Forward-mode differentiation by hand: for each hidden layer z = h W + b, z_t = h_t W,
    h = tanh(z), h_t = (1 - h^2) z_t; the input map (t, P1) -> [-1, 1]^2 is folded into the first
    layer, whose t-tangent is then the constant row W_t. Output heads as in
    `network.network_outputs` (the hard initial condition with phi = 1 - exp(-t), from the
    architecture's initial state or, in `grid` / `pairs`, each P1's or point's own)."""

    def __init__(self, arch: Architecture, dtype: torch.dtype) -> None:
        self.arch, self.dtype = arch, dtype
        self.npdtype = np.float64 if dtype == torch.float64 else np.float32
        self.tangent = arch.outputs == 1  # two-output networks give omega directly
        self.n = arch.machines
        self.delta0 = np.array(arch.delta0, self.npdtype)
        self.omega0 = np.array(arch.omega0, self.npdtype)

    def prepare(self, theta: np.ndarray) -> tuple:
        arch, dtype = self.arch, self.dtype
        layers = [(torch.as_tensor(np.asarray(w), dtype=dtype), torch.as_tensor(np.asarray(b), dtype=dtype))
                  for w, b in arch.layers(arch.split(np.asarray(theta, np.float64)))]
        ct, cp = 2.0 / (arch.t_hi - arch.t_lo), 2.0 / (arch.p_hi - arch.p_lo)
        w0, b0 = layers[0]
        w_t = (w0[0] * ct).contiguous()
        w_p = (w0[1] * cp).contiguous()
        b_0 = (b0 - w0[0] * (1.0 + arch.t_lo * ct) - w0[1] * (1.0 + arch.p_lo * cp)).contiguous()
        hidden = [(b.contiguous(), w.contiguous()) for w, b in layers[1:-1]]
        return w_t, w_p, b_0, hidden, layers[-1][0].contiguous(), layers[-1][1].contiguous()

    def load(self, theta: np.ndarray) -> None:
        self.params = self.prepare(theta)
        arch = self.arch
        self(np.array([0.5 * arch.t_hi]), np.array([0.5 * (arch.p_lo + arch.p_hi)]))  # warm-up

    def __call__(self, t_np: np.ndarray, p_np: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(self.params, t_np, p_np, False, None)

    def points(self, t_np: np.ndarray, p_np: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(self.params, t_np, p_np, True, None)

    def grid(self, params: Any, t_np: np.ndarray, p_np: np.ndarray, start: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(params, t_np, p_np, False, start)

    def pairs(self, params: Any, t_np: np.ndarray, p_np: np.ndarray, start: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return self._forward(params, t_np, p_np, True, start)

    def _forward(self, params: tuple, t_np: np.ndarray, p_np: np.ndarray, paired: bool,
                 start: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The grid (len(P1), len(t), n), or with `paired` the points (t[i], P1[i]), (n_s, n); start
        states `start` (len(P1), 2, n) (None: the architecture's)."""
        # No autograd context needed: no tensor here requires grad, so nothing is recorded.
        w_t, w_p, b_0, hidden, w_out, b_out = params
        n = self.n
        n_t, n_p = (1, p_np.shape[0]) if paired else (t_np.shape[0], p_np.shape[0])
        t_np, p_np = t_np.astype(self.npdtype, copy=False), p_np.astype(self.npdtype, copy=False)
        t = torch.from_numpy(t_np)
        z = torch.addcmul(torch.addcmul(b_0, torch.from_numpy(p_np).view(n_p, 1, 1), w_p),
                          t.view(n_p if paired else 1, n_t, 1), w_t)
        h = _tanh_(z.view(n_p * n_t, -1))
        h_t = torch.addcmul(w_t, h * h, w_t, value=-1.0) if self.tangent else None
        for b, w in hidden:
            z_t = torch.mm(h_t, w) if self.tangent else None
            h = _tanh_(torch.addmm(b, h, w))
            if self.tangent:
                h_t = z_t.addcmul_(h * h, z_t, value=-1.0)
        shape = (n_p, n) if paired else (n_p, n_t, n)
        out = torch.addmm(b_out, h, w_out)
        if self.tangent:
            n1, x = out.view(shape), torch.mm(h_t, w_out).view(shape)
        else:  # views (splitting the rows keeps the column stride): no copies
            n1, x = out[:, :n].view(shape), out[:, n:].view(shape)
        if not self.arch.hard_ic:
            return n1.numpy(), x.numpy()
        # delta = a0 + a1 N_1, omega = b0 + b1 N_1 + b2 X (X = dN_1/dt, or N_2 for two outputs),
        # the coefficients of the hard initial condition computed in numpy (cheaper per op)
        if start is None:
            delta0, omega0 = self.delta0, self.omega0
        else:
            start = start.astype(self.npdtype, copy=False)
            delta0, omega0 = start[..., 0, :], start[..., 1, :]
            if not paired:  # (n_p, 1, n): one start per P1, broadcast over t
                delta0, omega0 = delta0[:, None], omega0[:, None]
        a0, a1, b0, b1, b2 = (None if c is None else torch.from_numpy(c)
                              for c in self._coefficients(t_np, delta0, omega0))
        delta = torch.addcmul(a0, a1, n1)
        omega = torch.addcmul(b0 if b1 is None else torch.addcmul(b0, b1, n1), b2, x)
        return delta.numpy(), omega.numpy()

    def _coefficients(self, t: np.ndarray, delta0: np.ndarray, omega0: np.ndarray) -> tuple[np.ndarray, ...]:
        """(a0, a1, b0, b1, b2) of the hard-IC head at times t (s), broadcasting against the output
        (..., n): phi = 1 - e, e = exp(-t), start state (delta0, omega0) (..., n); one output:
        delta = delta0 + omega0 phi + phi^2 N, omega = omega0 e + 2 e phi N + phi^2 N_t;
        two outputs: omega = omega0 + phi N_2 (b1 None: no N_1 term)."""
        e = np.exp(-t)[:, None]
        phi = 1.0 - e
        phi2 = phi * phi
        a0 = delta0 + omega0 * phi
        if self.tangent:
            return a0, phi2, omega0 * e, 2.0 * e * phi, phi2
        return a0, phi2, np.ascontiguousarray(omega0), None, phi


class TorchOptions(PinnOptions):
    """`PinnOptions` and where training computes: device "cpu" (default) or "cuda" (the first
    CUDA GPU). The optimiser's linear algebra and every query stay on the CPU."""

    device: Literal["cpu", "cuda"] = "cpu"


class TorchPinn(PinnSolver):
    """PINN on PyTorch; see `solvers.pinn.common.PinnSolver` for the options, configs and files,
    and `TorchOptions` for `device`."""

    name: ClassVar[str] = "torch-pinn"
    SCHEMA = TorchOptions

    def _check_options(self) -> None:
        """The optimiser must be one this backend trains with, and (the rule that depends on the
        machine) a "cuda" device must exist: checked when the adapter is built, not when training
        starts, so that a run refuses them before measuring."""
        super()._check_options()
        if self.pinn_config.optimizer == "gn-cg":
            raise ValueError(f"{self.name}: option optimizer must be 'lm' or 'lbfgs' (the matrix-free "
                             "'gn-cg' needs Jacobian-vector products, which jax-pinn provides), got 'gn-cg'")
        if self.options["device"] == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"{self.name}: option device must be 'cpu' on this machine (torch "
                             f"{torch.__version__} finds no CUDA device to train case {self.case.name} on), "
                             "got 'cuda'")

    def _prepare_backend(self) -> str:
        torch.set_num_threads(self.options["threads"])
        return "" if self.options["device"] == "cpu" else f"trained on {torch.cuda.get_device_name(0)}"

    def _compile(self, arch: Architecture, problem: Problem, physics: Physics, dtype: str) -> Trainer:
        tdtype, device = _DTYPES[dtype], torch.device(self.options["device"])
        data = {key: torch.as_tensor(getattr(problem, key), dtype=tdtype, device=device)
                for key in ("t_u", "p_u", "targets", "t_f", "p_f", "start_u", "start_f")
                if getattr(problem, key) is not None}

        def tensor(theta: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.asarray(theta, np.float64)).to(device=device, dtype=tdtype)

        def numpy(x: torch.Tensor) -> np.ndarray:
            return x.detach().to(torch.float64).cpu().numpy()

        def residuals(theta: np.ndarray) -> np.ndarray:
            return numpy(taylor_residuals(arch, tensor(theta), data, OPS_AUTOGRAD, physics, problem))

        def jacobian(theta: np.ndarray) -> np.ndarray:
            return numpy(taylor_jacobian(arch, tensor(theta), data, OPS_AUTOGRAD, physics, problem))

        def loss_and_grad(theta: np.ndarray) -> tuple[float, np.ndarray]:
            value, grad = taylor_loss_and_grad(arch, tensor(theta), data, OPS_AUTOGRAD, physics, problem)
            return float(value), numpy(grad)

        return Trainer(residuals, jacobian, loss_and_grad)

    def _make_evaluator(self, arch: Architecture, dtype: str) -> Evaluator:
        return _FastForward(arch, _DTYPES[dtype])
