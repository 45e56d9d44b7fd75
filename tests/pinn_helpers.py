"""What the PINN test files share: the cases (the SMIB and a small two-machine system), the backends,
the small budgets, each backend's ops, a tiny fitted model and observations sampled from the
reference."""

from __future__ import annotations

import numpy as np
import pytest

from solvers import make_solver
from systems.cases import SMIB_INFERENCE, Case, Observations
from systems.reference import reference

# torch.func's first jvp registers decompositions through torch.jit.script, deprecated in torch 2.13
TORCH_JIT_SCRIPT_DEPRECATED = pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")

CASE = SMIB_INFERENCE
# Two machines, no infinite bus, lossy (G != 0), generator 1's P1 and the other's p_m unbalanced so
# that the angles drift as well as swing (~0.75 Hz): every term of the N-machine model is exercised.
TWO = Case(
    name="two-machines", m=(0.1, 0.2), d=(0.05, 0.1), delta0=(0.1, -0.05), omega0=(0.05, -0.02),
    p_m=(0.3, -0.25), E=(1.05, 1.0), G=((0.1, -0.05), (-0.05, 0.12)), B=((-3.0, 1.5), (1.5, -2.8)),
    g_inf=(0.0, 0.0), b_inf=(0.0, 0.0), t_final=4.0, p1_min=0.25, p1_max=0.35,
    m_box=((0.01, 1.0), (0.02, 2.0)), d_box=((0.005, 0.5), (0.01, 1.0)),
)
BACKENDS = {"torch-pinn": "torch", "jax-pinn": "jax"}
# for tests whose JAX run is slow (JIT compilation, > 2 s) and whose torch run is not
BACKENDS_SLOW_JAX = ["torch-pinn", pytest.param("jax-pinn", marks=pytest.mark.slow)]
# tiny networks and budgets; threads=1 because 2-thread ops stall on a busy 2-core machine
SMALL = {"hidden_layers": 2, "width": 8, "n_u": 20, "n_f": 150, "max_iterations": 3, "threads": 1,
         "id_hidden_layers": 2, "id_width": 8, "id_n_f": 100, "id_max_iterations": 3}
# smaller still, for TWO
TWO_SMALL = {"hidden_layers": 1, "width": 6, "n_u": 4, "n_f": 30, "max_iterations": 3, "threads": 1,
             "progress": False, "id_hidden_layers": 1, "id_width": 6, "id_n_f": 30, "id_max_iterations": 5}


def need_backend(name: str) -> None:
    pytest.importorskip(BACKENDS[name])


def backend_ops(name: str):
    """The backend's Ops, a float64 array constructor and a to-numpy function; "torch-autograd"
    is torch with reverse-mode t-derivatives (the loss-gradient path)."""
    need_backend("torch-pinn" if name == "torch-autograd" else name)
    if name in ("torch-pinn", "torch-autograd"):
        import torch

        from solvers.pinn.torch_pinn import OPS, OPS_AUTOGRAD
        return ((OPS if name == "torch-pinn" else OPS_AUTOGRAD),
                (lambda x: torch.as_tensor(np.asarray(x), dtype=torch.float64)),
                (lambda x: x.detach().numpy()))
    import jax
    import jax.numpy as jnp

    from solvers.pinn.jax_pinn import OPS

    def array(x):
        with jax.enable_x64(True):
            return jnp.asarray(np.asarray(x), dtype=np.float64)
    return OPS, array, np.asarray


def x64_scope(name: str):
    if name == "jax-pinn":
        import jax
        return jax.enable_x64(True)
    import contextlib
    return contextlib.nullcontext()


def fit_tiny(name: str):
    """A tiny model of backend `name`, fitted for 3 iterations."""
    need_backend(name)
    solver = make_solver(name, CASE, **SMALL)
    solver.fit()
    return solver


def sampled_observations(case, n, seed=0, with_omega=False):
    """n samples of every machine's delta (and omega) at random (t, P1), (n, case.n) each."""
    rng = np.random.default_rng(seed)
    t = np.round(rng.uniform(0.0, case.t_final, n), 1)
    p = rng.choice(np.linspace(case.p1_min, case.p1_max, 10), n)
    rows = [reference(case, [ti], [pi]) for ti, pi in zip(t, p)]
    delta = np.array([d[0, 0] for d, _ in rows])
    omega = np.array([o[0, 0] for _, o in rows]) if with_omega else None
    return Observations(t, p, delta, omega)
