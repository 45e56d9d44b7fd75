"""The reduced-output PINN's model: the machine angles as a basis expansion whose coefficients a
small time-marching network predicts, trained window by window on solver data and the physics
residual projected onto the basis (Galerkin), in JAX (float64).

    delta(t, P1) = delta0 + U a(t, P1),   omega = U a'(t, P1),
    a = a_s(P1) + v_s(P1) phi + phi^2 NN_w(tau, P1),   phi = 1 - exp(-tau / 1 s),  tau = t - t_w,

U (n, k) orthonormal, (a_s, v_s) the coefficients and their rates that windows 0..w-1 reach at
t_w (zero and U^T omega0 at t = 0), so delta and omega are continuous across windows. The physics
residual of a collocation point is the swing equation in acceleration units projected onto U,

    g = U^T M^-1 (P(P1) - D U a' - P_e(delta0 + U a)) - a''   (k,) rad/s^2,

whose Jacobian is assembled by the chain rule through the k coefficients (k tangents through the
network's P_e, not one per parameter); the small network's own derivatives are reverse-mode, k
outputs against hundreds of parameters. Units: t and tau in s, P1 in p.u., a in rad, a' in rad/s.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from solvers.pinn.architecture import glorot_weights, layer_shapes, split_flat
from solvers.pinn.optim import NormalEquations
from solvers.pinn.reduced_normal import data_normal_equations, jets, physics_jacobian
from systems.cases import Case
from systems.model import Coupling, coupling, electrical_power

__all__ = ["Layout", "WindowData", "init_weights", "query_functions", "window_functions"]


@dataclass(frozen=True)
class Layout:
    """The window network (inputs (tau, P1) normalised to [-1, 1] over [0, window] s and
    [p_lo, p_hi] p.u.; tanh hidden layers; k linear outputs) and its flat parameter vector."""

    sizes: tuple[int, ...]
    window: float
    p_lo: float
    p_hi: float

    @property
    def shapes(self) -> list[tuple[int, ...]]:
        return layer_shapes(self.sizes)

    @property
    def n_params(self) -> int:
        return sum(int(np.prod(s)) for s in self.shapes)

    @property
    def n_hidden(self) -> int:
        """The hidden layers' parameters, the first entries of the flat vector (the output
        layer's W (width, k) and b (k,) follow)."""
        return sum(int(np.prod(s)) for s in self.shapes[:-2])

    def split(self, theta: Any) -> list[tuple[Any, Any]]:
        """[(W, b), ...] views of the flat vector `theta`."""
        arrays = split_flat(self.shapes, theta)[0]
        return list(zip(arrays[0::2], arrays[1::2]))


def init_weights(layout: Layout, seed: int) -> np.ndarray:
    """Glorot-normal weights and zero biases (float64), drawn from `seed`."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x5EED, 0xBA515]))
    return np.concatenate(glorot_weights(layout.sizes, rng))


def _features(layout: Layout, theta: Any, tau: Any, p: Any) -> Any:
    """The last hidden layer (width,) at scalar tau (s) and P1 (p.u.); `theta` the whole flat
    vector or its first `layout.n_hidden` entries (the hidden layers')."""
    x = jnp.stack([tau * (2.0 / layout.window) - 1.0, (p - layout.p_lo) * (2.0 / (layout.p_hi - layout.p_lo)) - 1.0])
    arrays = split_flat(layout.shapes[:-2], theta)[0]
    h = x
    for w, b in zip(arrays[0::2], arrays[1::2]):
        h = jnp.tanh(h @ w + b)
    return h


def _coefficients(layout: Layout, theta: Any, tau: Any, p: Any, a_s: Any, v_s: Any) -> Any:
    """a (k,) at scalar tau (s) and P1 (p.u.) from the start (a_s, v_s) (k,) each."""
    w, b = layout.split(theta)[-1]
    phi = 1.0 - jnp.exp(-tau)
    return a_s + phi * (v_s + phi * (_features(layout, theta, tau, p) @ w + b))


def _rates(layout: Layout, theta: Any, tau: Any, p: Any, a_s: Any, v_s: Any) -> tuple[Any, Any]:
    """(a, a') at scalar tau, p."""
    return jax.jvp(lambda s: _coefficients(layout, theta, s, p, a_s, v_s), (tau,), (jnp.ones_like(tau),))


def _accelerations(layout: Layout, theta: Any, tau: Any, p: Any, a_s: Any, v_s: Any) -> tuple[Any, Any, Any]:
    """(a, a', a'') at scalar tau, p."""
    (a, a_t), (_, a_tt) = jax.jvp(lambda s: _rates(layout, theta, s, p, a_s, v_s), (tau,), (jnp.ones_like(tau),))
    return a, a_t, a_tt


def _starts(layout: Layout, thetas: Any, p: Any, v0: Any) -> tuple[tuple[Any, Any], tuple[Any, Any]]:
    """((a_s, v_s) (W, k) each: every window's start at P1 = p, walked through the windows;
    (a, a') (k,) each at the last window's end)."""
    def step(state: tuple[Any, Any], theta: Any) -> tuple[tuple[Any, Any], tuple[Any, Any]]:
        return _rates(layout, theta, jnp.asarray(layout.window, theta.dtype), p, *state), state
    end, starts = jax.lax.scan(step, (jnp.zeros_like(v0), v0), thetas)
    return starts, end


def _state_at(layout: Layout, thetas: Any, a_s: Any, v_s: Any, t: Any, p: Any) -> tuple[Any, Any]:
    """(a, a') at scalar t (s) of the window that holds t, from the windows' starts (W, k)."""
    w = jnp.clip(jnp.floor(t / layout.window).astype(jnp.int32), 0, thetas.shape[0] - 1)
    return _rates(layout, thetas[w], t - w * layout.window, p, a_s[w], v_s[w])


@functools.lru_cache(maxsize=8)
def query_functions(layout: Layout) -> tuple[Any, Any]:
    """Jitted (grid, points) of (thetas, U, delta0, v0, t, P1) -> stacked (delta, omega): the grid
    (2, n_p, n_t, n) for t (n_t,) x P1 (n_p,), the points (2, n_s, n) for pairs (t_i, P1_i)."""
    def one_p(thetas, v0, t, p):
        (a_s, v_s), _ = _starts(layout, thetas, p, v0)
        return jax.vmap(lambda s: _state_at(layout, thetas, a_s, v_s, s, p))(t)

    def grid(thetas, U, delta0, v0, t, P1):
        a, a_t = jax.vmap(lambda p: one_p(thetas, v0, t, p))(P1)
        return jnp.stack([delta0 + a @ U.T, a_t @ U.T])

    def points(thetas, U, delta0, v0, t, P1):
        a, a_t = jax.vmap(lambda s, p: tuple(x[0] for x in one_p(thetas, v0, s[None], p)))(t, P1)
        return jnp.stack([delta0 + a @ U.T, a_t @ U.T])

    return jax.jit(grid), jax.jit(points)


@functools.lru_cache(maxsize=8)
def _walk_jit(layout: Layout) -> Any:
    return jax.jit(jax.vmap(lambda p, thetas, v0: _starts(layout, thetas, p, v0)[1], (0, None, None)))


def walk_starts(layout: Layout, thetas: np.ndarray, P1: np.ndarray, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, a') (len(P1), k) each: the state the trained windows `thetas` (W, n_params) reach at
    their end, t = W window, for each P1 (zero and v0 with no window trained)."""
    if thetas.shape[0] == 0:
        return np.zeros((P1.size, v0.size)), np.tile(v0, (P1.size, 1))
    with jax.enable_x64(True):
        a_end, v_end = _walk_jit(layout)(jnp.asarray(P1), jnp.asarray(thetas), jnp.asarray(v0))
    return np.asarray(a_end), np.asarray(v_end)


@dataclass(frozen=True)
class WindowData:
    """One window's training points: data (tau_u, p_u, starts (a_s, v_s) (n_u, k) each, targets
    (n_u, k) rad: U^T (delta - delta0) of the snapshots, rate_targets (n_u, k) rad/s: U^T omega,
    or (0, k) where the rates are not trained on) and collocation points (tau_f, p_f, their
    starts). Either set may be empty."""

    tau_u: np.ndarray
    p_u: np.ndarray
    a_u: np.ndarray
    v_u: np.ndarray
    targets: np.ndarray
    rate_targets: np.ndarray
    tau_f: np.ndarray
    p_f: np.ndarray
    a_f: np.ndarray
    v_f: np.ndarray


def _constants(case: Case, U: np.ndarray, delta0: np.ndarray) -> dict[str, Any]:
    """The projected swing equation's constants, JAX float64: U, delta0, M^-1 U ("Um": U^T M^-1 x
    = x @ Um), the coupling (C, S, c_inf, s_inf), q0 + P1 q1 = U^T M^-1 P(P1) (k,) and
    Dk = U^T M^-1 D U (k, k)."""
    m, d = np.asarray(case.m, np.float64), np.asarray(case.d, np.float64)
    first = np.zeros(case.n)
    first[0] = 1.0
    rest = np.asarray(case.p_m, np.float64) * (1.0 - first)
    values = {"U": U, "delta0": delta0, "Um": U / m[:, None], "q0": (rest / m) @ U, "q1": (first / m) @ U,
              "Dk": U.T @ ((d / m)[:, None] * U), **coupling(case)._asdict()}
    return {name: jnp.asarray(value) for name, value in values.items()}


def _forcing(c: dict[str, Any], a: Any) -> Any:
    """U^T M^-1 P_e(delta0 + U a) (k,)."""
    k = Coupling(c["C"], c["S"], c["c_inf"], c["s_inf"])
    return electrical_power(k, c["delta0"] + c["U"] @ a, sin=jnp.sin, cos=jnp.cos) @ c["Um"]


@functools.lru_cache(maxsize=8)
def _window_jit(layout: Layout, physics_weight: float, with_data: bool, with_physics: bool,
                rate_weight: float = 0.0) -> tuple[Any, Any]:
    """The jitted residuals and Jacobian of (theta, points, constants) of windows of `layout`:
    compiled once for every window of a fit (and every fit of the same shapes in the process)."""
    def data_rows(theta, tau, p, a_s, v_s, target):
        return _coefficients(layout, theta, tau, p, a_s, v_s) - target

    def rate_rows(theta, tau, p, a_s, v_s, target):
        return rate_weight * (_rates(layout, theta, tau, p, a_s, v_s)[1] - target)

    def physics_rows(theta, c, tau, p, a_s, v_s):
        a, a_t, a_tt = _accelerations(layout, theta, tau, p, a_s, v_s)
        return physics_weight * (c["q0"] + p * c["q1"] - _forcing(c, a) - c["Dk"] @ a_t - a_tt)

    def physics_jacobian(theta, c, tau, p, a_s, v_s):
        derivs = jax.jacrev(lambda th: _accelerations(layout, th, tau, p, a_s, v_s))(theta)  # 3 x (k, P)
        stiffness = jax.jacfwd(lambda a: _forcing(c, a))(_coefficients(layout, theta, tau, p, a_s, v_s))  # (k, k)
        return -physics_weight * (stiffness @ derivs[0] + c["Dk"] @ derivs[1] + derivs[2])

    def stacked(row, jac_row, theta, x, c, jacobian):
        blocks = []
        if with_data:
            fn = jax.jacrev(data_rows) if jacobian else data_rows
            blocks.append(jax.vmap(fn, (None, 0, 0, 0, 0, 0))(theta, x["tau_u"], x["p_u"], x["a_u"], x["v_u"],
                                                              x["targets"]))
        if with_data and rate_weight > 0:
            fn = jax.jacrev(rate_rows) if jacobian else rate_rows
            blocks.append(jax.vmap(fn, (None, 0, 0, 0, 0, 0))(theta, x["tau_u"], x["p_u"], x["a_u"], x["v_u"],
                                                              x["rate_targets"]))
        if with_physics:
            fn = jac_row if jacobian else row
            blocks.append(jax.vmap(fn, (None, None, 0, 0, 0, 0))(theta, c, x["tau_f"], x["p_f"], x["a_f"], x["v_f"]))
        shape = (-1, layout.n_params) if jacobian else (-1,)
        return jnp.concatenate([b.reshape(shape) for b in blocks])

    return (jax.jit(lambda theta, x, c: stacked(physics_rows, physics_jacobian, theta, x, c, False)),
            jax.jit(lambda theta, x, c: stacked(physics_rows, physics_jacobian, theta, x, c, True)))


@functools.lru_cache(maxsize=8)
def _features_jit(layout: Layout, order: int) -> Any:
    """Jitted (theta_h, tau (n,), P1 (n,)) -> (the last hidden layer and its tau derivatives up to
    `order` (0, 1 or 2), (n, order + 1, width), and their Jacobians of the hidden parameters
    theta_h, (n, order + 1, width, n_hidden))."""
    def jet(theta_h, tau, p):
        f = functools.partial(_features, layout, theta_h, p=p)
        first = lambda s: jax.jvp(lambda u: f(tau=u), (s,), (jnp.ones_like(s),))
        if order < 2:
            return jnp.stack(first(tau)[:order + 1])
        (h, h_t), (_, h_tt) = jax.jvp(first, (tau,), (jnp.ones_like(tau),))
        return jnp.stack([h, h_t, h_tt])

    def one(theta_h, tau, p):
        return jet(theta_h, tau, p), jax.jacrev(jet)(theta_h, tau, p)
    return jax.jit(jax.vmap(one, (None, 0, 0)))


@functools.lru_cache(maxsize=8)
def _stiffness_jit(layout: Layout) -> Any:
    """Jitted (theta, constants, tau, P1, a_s, v_s) (n points) -> d U^T M^-1 P_e / da (n, k, k)."""
    def one(theta, c, tau, p, a_s, v_s):
        return jax.jacfwd(lambda a: _forcing(c, a))(_coefficients(layout, theta, tau, p, a_s, v_s))
    return jax.jit(jax.vmap(one, (None, None, 0, 0, 0, 0)))


def window_functions(case: Case, layout: Layout, U: np.ndarray, delta0: np.ndarray, data: WindowData,
                     physics_weight: float, rate_weight: float = 0.0) -> tuple[Any, Any, NormalEquations]:
    """(residuals, jacobian, normal_equations) of theta (numpy float64 in and out) for one window:
    rows [a - target for each data point and coefficient (rad), rate_weight (a' - rate target)
    for each (rad; none where rate_weight is 0 (s)), physics_weight g for each collocation point
    and coefficient (rad/s^2)], their Jacobian (rows, n_params) by automatic
    differentiation, and (J^T J, J^T r) at (theta, r) from the Jacobian's structure
    (`solvers.pinn.reduced_normal`; the same products, several times cheaper)."""
    with jax.enable_x64(True):
        constants = _constants(case, U, delta0)
        points = {name: jnp.asarray(getattr(data, name)) for name in WindowData.__dataclass_fields__}
    with_data, with_physics = bool(data.tau_u.size), bool(data.tau_f.size)
    with_rates = with_data and rate_weight > 0
    res_fn, jac_fn = _window_jit(layout, float(physics_weight), with_data, with_physics,
                                 float(rate_weight) if with_rates else 0.0)
    rows_u = data.targets.size * (2 if with_rates else 1)
    width, k, n_h = layout.sizes[-2], layout.sizes[-1], layout.n_hidden
    identity, damping = np.eye(k), np.asarray(constants["Dk"])

    def call(fn):
        def run(theta: np.ndarray) -> np.ndarray:
            with jax.enable_x64(True):
                return np.asarray(fn(jnp.asarray(theta), points, constants), np.float64)
        return run

    def features(theta: np.ndarray, tau: str, p: str, order: int) -> tuple[np.ndarray, np.ndarray]:
        with jax.enable_x64(True):
            h, dh = _features_jit(layout, order)(jnp.asarray(theta[:n_h]), points[tau], points[p])
        return np.asarray(h, np.float64), np.asarray(dh, np.float64)

    def normal_equations(theta: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        A, g = np.zeros((theta.size, theta.size)), np.zeros(theta.size)
        W = theta[n_h:n_h + width * k].reshape(width, k)
        if with_data:
            h, dh = features(theta, "tau_u", "p_u", int(with_rates))
            e, de = jets(0, data.tau_u, h, dh)
            if with_rates:
                e_t, de_t = jets(1, data.tau_u, h, dh)
                e, de = np.concatenate([e, rate_weight * e_t]), np.concatenate([de, rate_weight * de_t])
            A, g = data_normal_equations(e, de, W, r[:rows_u].reshape(-1, k))
        if with_physics:
            h, dh = features(theta, "tau_f", "p_f", 2)
            e, de = zip(*(jets(order, data.tau_f, h, dh) for order in range(3)))
            with jax.enable_x64(True):
                S = np.asarray(_stiffness_jit(layout)(jnp.asarray(theta), constants, points["tau_f"], points["p_f"],
                                                      points["a_f"], points["v_f"]))
            mix = -physics_weight * np.stack([S, *np.broadcast_arrays(damping, identity, S)[:2]], axis=1)
            J = physics_jacobian(np.stack(e, 1), np.stack(de, 1), W, mix)
            A += J.T @ J
            g += J.T @ r[rows_u:]
        return A, g

    return call(res_fn), call(jac_fn), normal_equations
