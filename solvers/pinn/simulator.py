"""The PINNSim simulator: every machine a component PINN (`solvers.pinn.component`), coupled through
the network at a fixed step h, in JAX (float64), every P1 of a query in one compiled call.

Per step, each machine's terminal voltage is a quadratic in the time since the step's start,
V_k(t) = (v0 + v1 t + v2 t^2) e^{j (theta0 + theta1 t + theta2 t^2)}. Its value at t = 0 is the
network's for the step's start angles (theta0, v0 known); the 4 n coefficients (theta1, theta2,
v1, v2) solve, by Gauss-Newton, the network equation at s collocation points t_j = h j / s:

    V(t_j) = Z (w e^{j delta(t_j)}),   w = y E,   Z = (Y_bb^-1)[at, at],

delta(t_j) each machine's component PINN for its own coefficients. Z, the network's impedance
seen from the machine terminals with the machines' tie admittances in Y_bb
(`systems.sparse_network`), is made from one SuperLU factorisation of Y_bb (n right-hand sides)
and kept dense (n x n): the Newton matrix is dense in the machines (the coupling), and each
machine's PINN sensitivity d delta_k(t_j) / d c_k (s x 4) is its own block (forward mode, 4
tangents). The update solves the Gauss-Newton normal equations with that matrix formed, or
matrix-free by preconditioned CGLS with products by Z (`solvers.pinn.simulator_newton`). A step
of h is ceil(h / h_net) equal network intervals (the network is trained on [0, h_net]), the
voltage polynomial re-centred at each; the state at any t inside a step comes from the same
networks (dense output).
"""

from __future__ import annotations

import functools
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from solvers.pinn.component import Component, phi_rate
from solvers.pinn.simulator_newton import CG_DTYPES, CgDtype, Newton, column_norms, gauss_newton_update

__all__ = ["chain", "impedance", "query_function", "simulate_function", "state_at", "substeps"]


def impedance(network: Any) -> np.ndarray:
    """(Y_bb^-1)[at, at] (n, n) complex p.u. of a `SparseNetwork`, from one SuperLU factorisation."""
    from scipy.sparse.linalg import splu

    nb, at = network.n_buses, np.asarray(network.at)
    rhs = np.zeros((nb, at.size), complex)
    rhs[at, np.arange(at.size)] = 1.0
    return np.ascontiguousarray(splu(network.Y_bb.tocsc()).solve(rhs)[at])


def substeps(component: Component, h: float) -> tuple[int, float]:
    count = max(1, int(np.ceil(h / component.domain.h - 1e-9)))
    return count, h / count


def _local(coef: Any, ts: Any) -> tuple[Any, Any, Any, Any]:
    """theta, theta', v, v' at time ts of the step of a machine's coefficients
    (theta0, theta1, theta2, v0, v1, v2)."""
    th0, th1, th2, v0, v1, v2 = coef
    return th0 + ts * (th1 + ts * th2), th1 + 2.0 * th2 * ts, v0 + ts * (v1 + ts * v2), v1 + 2.0 * v2 * ts


def _inputs(coef: Any, mu: Any, kappa: Any, p: Any, delta: Any, omega: Any, ts: Any) -> Any:
    """The component input (9,) of a network interval starting at ts with state (delta, omega)."""
    th, th_rate, v, v_rate = _local(coef, ts)
    return jnp.stack([delta - th, omega - th_rate, coef[2], v, v_rate, coef[5], mu, kappa, p - kappa * th_rate])


def chain(component: Component, count: int, sub: Any, theta: Any, coef: Any, mu: Any, kappa: Any, p: Any,
           delta0: Any, omega0: Any) -> tuple[Any, Any]:
    """One machine: (starts (count + 1, 2): (delta, omega) at the interval edges, inputs (count, 9))."""
    sizes, domain, form = component.sizes, component.domain, component.form

    def step(state, i):
        ts = i * sub
        x = _inputs(coef, mu, kappa, p, state[0], state[1], ts)
        phi, rate = phi_rate(sizes, domain, form, theta, x, jnp.asarray(sub))
        th, th_rate, _, _ = _local(coef, ts)
        end = jnp.stack([th + th_rate * sub + phi, th_rate + rate])
        return end, (end, x)

    _, (ends, xs) = jax.lax.scan(step, jnp.stack([delta0, omega0]), jnp.arange(count, dtype=jnp.float64))
    return jnp.concatenate([jnp.stack([delta0, omega0])[None], ends]), xs


def _index(t: Any, length: Any, last: Any) -> Any:
    """The interval of length `length` that holds t, in [0, last] (int32): a time within 1e-9 of an
    edge belongs to the later interval (XLA's fused arithmetic rounds t / length either side of an
    integer otherwise, and the state on an edge is the same from both sides). A step of length 0 (a
    fault cleared at t_c = 0 has an empty fault-on phase) holds only its start."""
    return jnp.clip(jnp.floor(t / jnp.maximum(length, 1e-300) + 1e-9), 0, last).astype(jnp.int32)


def state_at(component: Component, sub: Any, theta: Any, coef: Any, mu: Any, kappa: Any, p: Any, starts: Any,
        t: Any) -> Any:
    """(delta, omega) of one machine at time t in [0, h] of the step from its interval starts."""
    i = _index(t, sub, starts.shape[0] - 2)
    ts = i * sub
    tau = jnp.maximum(t - ts, 0.0)
    start = starts[i]
    x = _inputs(coef, mu, kappa, p, start[0], start[1], ts)
    phi, rate = phi_rate(component.sizes, component.domain, component.form, theta, x, tau)
    th, th_rate, _, _ = _local(coef, ts)
    return jnp.stack([th + th_rate * tau + phi, th_rate + rate])


@functools.lru_cache(maxsize=8)
def simulate_function(component: Component, h: float, max_steps: int, collocation: int, max_newton: int,
                      newton_tol: float, newton: Newton = "dense", cg_tol: float = 1e-12, max_cg: int = 200,
                      cg_forcing: float = 1e-12, cg_dtype: CgDtype = "float64") -> Any:
    """Jitted (theta, machines, p (n_P, n), delta0 (n,), omega0 (n,), steps, lengths (n_P,
    max_steps) s, phase (max_steps,) int) -> per P1 and step of the first `steps` (<= max_steps;
    the rest zero): interval starts (n_P, max_steps, count + 1, n, 2), coefficients (n_P, max_steps,
    n, 6), Newton iterations and the last update's size (n_P, max_steps), and the largest excursion
    of the network inputs out of the domain, in units of the box's half-width (<= 0 inside), with
    its column of `INPUTS` (n_P, max_steps) each, then the step's CG iterations (summed over its
    Newton iterations) and its CG solves' largest normal residual over its tolerance (`cgls`; <= 1:
    met) (n_P, max_steps) each (0 for the dense Newton). Step k of a P1 lasts lengths[k] <= h (a
    step case: h every step; a fault case: `simulator_faults.schedule`) on the network Z[phase[k]],
    the same phases for every P1; a step starts from the network's voltage for its start angles, so
    at a switch of Z the state is continuous and the voltage jumps. newton, cg_tol, max_cg, cg_forcing, cg_dtype: the update's linear solve
    (`simulator_newton.gauss_newton_update`, its products by Z in `CG_DTYPES[cg_dtype]`).
    machines: a dict of mu, kappa (n,) s^2/rad, s/rad, w = y E (n,) and Z (n_phase, n, n) complex p.u."""
    count, _ = substeps(component, h)
    fractions = np.arange(1, collocation + 1) / collocation
    lo, hi = component.domain.bounds()
    mid, half = jnp.asarray((lo + hi) / 2.0), jnp.asarray((hi - lo) / 2.0)

    def one_p(theta, mach, p, delta0, omega0, steps, lengths, phase):
        mu, kappa, w, Zs = mach["mu"], mach["kappa"], mach["w"], mach["Z"]
        all_norms = jax.vmap(column_norms)(Zs)
        all_products = Zs.astype(CG_DTYPES[cg_dtype])

        def linearised(c4, base, delta_start, omega_start, Z, nodes, sub):
            """The residual (n, s) complex and the Jacobian's two block-diagonal factors (n, s, 4) in
            the coefficients c4 (n, 4), own and g (`simulator_newton`): one pass through each
            machine's networks, its sensitivities (s, 4) by 4 forward tangents."""
            def machine_nodes(c, b, mu_k, kappa_k, p_k, d0, w0):
                coef = jnp.concatenate([b[:1], c[:2], b[1:], c[2:]])
                starts, _ = chain(component, count, sub, theta, coef, mu_k, kappa_k, p_k, d0, w0)
                return jax.vmap(lambda t: state_at(component, sub, theta, coef, mu_k, kappa_k, p_k, starts, t)[0])(nodes)

            def own_nodes(c, *args):
                value, tangent = jax.linearize(lambda q: machine_nodes(q, *args), c)
                return value, jax.vmap(tangent, out_axes=-1)(jnp.eye(4))

            delta, sens = jax.vmap(own_nodes)(c4, base, mu, kappa, p, delta_start, omega_start)  # (n, s), (n, s, 4)
            th = base[:, :1] + nodes * (c4[:, :1] + nodes * c4[:, 1:2])
            v = base[:, 1:] + nodes * (c4[:, 2:3] + nodes * c4[:, 3:])
            e = jnp.exp(1j * th)
            source = w[:, None] * jnp.exp(1j * delta)  # (n, s)
            own = jnp.stack([1j * v * e * nodes, 1j * v * e * nodes ** 2, e * nodes, e * nodes ** 2], -1)
            # d (Z w e^{j delta})_k (t_j) / d c_l = Z_kl j w_l e^{j delta_l(t_j)} d delta_l(t_j) / d c_l
            return v * e - Z @ source, own, (1j * source)[..., None] * sens

        def step(k, carry):
            delta_start, omega_start, guess, out = carry
            length, Z, norms, products = lengths[k], Zs[phase[k]], all_norms[phase[k]], all_products[phase[k]]
            nodes, sub = length * fractions, length / count
            V0 = Z @ (w * jnp.exp(1j * delta_start))
            base = jnp.stack([jnp.angle(V0), jnp.abs(V0)], -1)  # (n, 2)

            def iterate(state):
                c4, i, _, cg, cg_residual = state
                r, own, g = linearised(c4, base, delta_start, omega_start, Z, nodes, sub)
                update, cg_i, cg_rel = gauss_newton_update(newton, own, g, Z, norms, r, cg_tol, max_cg, cg_forcing,
                                                            products)
                return c4 + update, i + 1, jnp.max(jnp.abs(update)), cg + cg_i, jnp.maximum(cg_residual, cg_rel)

            # a step of length 0 has nothing to solve (its state is its start)
            c4, iterations, size, cg, cg_residual = jax.lax.while_loop(
                lambda s: (s[1] < max_newton) & (s[2] > newton_tol), iterate,
                (guess, 0, jnp.where(length > 0.0, jnp.inf, 0.0), 0, 0.0))
            coef = jnp.concatenate([base[:, :1], c4[:, :2], base[:, 1:], c4[:, 2:]], -1)  # (n, 6)
            starts, xs = jax.vmap(lambda cf, m_k, k_k, p_k, d0, w0: chain(component, count, sub, theta, cf, m_k, k_k,
                                                                           p_k, d0, w0))(coef, mu, kappa, p,
                                                                                         delta_start, omega_start)
            excess = jnp.max((jnp.abs(xs[..., 1:] - mid[1:]) / half[1:] - 1.0).reshape(-1, 8), axis=0)
            nxt = jnp.stack([c4[:, 0] + 2.0 * c4[:, 1] * length, c4[:, 1], c4[:, 2] + 2.0 * c4[:, 3] * length, c4[:, 3]],
                            -1)
            values = (jnp.transpose(starts, (1, 0, 2)), coef, iterations, size, jnp.max(excess), jnp.argmax(excess) + 1,
                      cg, cg_residual)
            out = tuple(buffer.at[k].set(value) for buffer, value in zip(out, values))
            return starts[:, -1, 0], starts[:, -1, 1], nxt, out

        n = delta0.shape[0]
        first = jnp.stack([omega0, jnp.zeros_like(omega0), jnp.zeros_like(omega0), jnp.zeros_like(omega0)], -1)
        buffers = (jnp.zeros((max_steps, count + 1, n, 2)), jnp.zeros((max_steps, n, 6)),
                   jnp.zeros(max_steps, jnp.int64), jnp.zeros(max_steps), jnp.full(max_steps, -1.0),
                   jnp.zeros(max_steps, jnp.int64), jnp.zeros(max_steps, jnp.int64), jnp.zeros(max_steps))
        return jax.lax.fori_loop(0, steps, step, (delta0, omega0, first, buffers))[3]

    # Z unbatched (one phase sequence for every P1): a product by Z is one matrix product over every P1
    return jax.jit(jax.vmap(one_p, (None, None, 0, None, None, None, 0, None)))


@functools.lru_cache(maxsize=8)
def query_function(component: Component, h: float) -> Any:
    """Jitted (grid, points): grid (theta, machines, p (n_P, n), starts, coef, last, edges (n_P,
    max_steps + 1) s, t (n_t,)) -> (2, n_P, n_t, n), delta and omega at the times t (s) from the
    simulated steps 0..last, step k of a P1 on [edges[k], edges[k + 1]] (a time beyond them: the
    last step's networks); points (..., last, edges, which (n_s,) int, t (n_s,)) -> (2, n_s, n) at
    the pairs (P1 row which[i], t[i]). A time within 1e-9 h of a step's edge belongs to the later
    step (`_index`'s rule; a step of length 0 holds no time)."""
    count, _ = substeps(component, h)

    def one(theta, mu, kappa, p, starts, coef, last, edges, t):
        i = jnp.clip(jnp.searchsorted(edges[1:], t + 1e-9 * h, side="right"), 0, last)
        sub = (edges[i + 1] - edges[i]) / count
        local = t - edges[i]
        return jax.vmap(lambda m_k, k_k, p_k, s_k, c_k: state_at(component, sub, theta, c_k, m_k, k_k, p_k, s_k, local),
                        (0, 0, 0, 1, 0))(mu, kappa, p, starts[i], coef[i])  # (n, 2)

    def grid(theta, mach, p, starts, coef, last, edges, t):
        per_p = jax.vmap(lambda pp, st, cf, ed: jax.vmap(lambda s: one(theta, mach["mu"], mach["kappa"], pp, st, cf,
                                                                       last, ed, s))(t))
        out = per_p(p, starts, coef, edges)  # (n_P, n_t, n, 2)
        return jnp.moveaxis(out, -1, 0)

    def points(theta, mach, p, starts, coef, last, edges, which, t):
        return jnp.moveaxis(jax.vmap(lambda i, s: one(theta, mach["mu"], mach["kappa"], p[i], starts[i], coef[i], last,
                                                      edges[i], s))(which, t), -1, 0)  # (2, n_s, n)

    return jax.jit(grid), jax.jit(points)
