"""The traced solve of `solvers.classical.diffrax_ode` on a fault case (`systems.cases.Fault`): the fault-on
network from the equilibrium to each clearing time t_c, the post-fault network from the state at
t_c, no step across the switch, all clearing times of a query in one compiled call.

The fault-on phase does not depend on t_c: one diffrax solve of it, to the largest t_c (its last
step ends there), saves the states at the query times before it and at every t_c. Each post-fault
trajectory then starts from its own state at its t_c, in the time since t_c (the system is
autonomous), with its own steps (jax.vmap over t_c). A query at t = t_c answers the state at t_c.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["switched"]


def switched(y0: np.ndarray, solve_on: Callable, solve_post: Callable) -> Callable:
    """values(m, d, p_m, rtol, atol, dt, t, T_c) -> (y (n_c, n_t, 2n), ok (n_c,)): the fault case's
    states [delta_1..n (rad), omega_1..n (rad/s)] at sorted times t (n_t,) s for each clearing time
    T_c (n_c,) s >= 0, and whether each trajectory succeeded with finite states; every machine at
    p_m (n,) p.u., inertia m and damping d (n,) p.u. `y0` (2n,) is the equilibrium the fault-on
    phase starts from; `solve_on`, `solve_post` each phase's `diffrax_ode.phase_solver`. Traceable
    (the caller jits it)."""

    def values(m, d, p_m, rtol, atol, dt, t, T_c):
        n_t = t.size
        # fault-on outputs: the query times (those past the last t_c clipped to it, then unused)
        # and every t_c, sorted for SaveAt, scattered back after
        times = jnp.concatenate([jnp.minimum(t, jnp.max(T_c)), T_c])
        order = jnp.argsort(times)
        ys, ok_on = solve_on(jnp.asarray(y0), m, d, rtol, atol, dt, times[order], p_m)
        ys = jnp.zeros_like(ys).at[order].set(ys)
        on, at_clearing = ys[:n_t], ys[n_t:]
        since = jnp.maximum(t[None, :] - T_c[:, None], 0.0)  # (n_c, n_t), each row sorted
        post, ok_post = jax.vmap(lambda y, s: solve_post(y, m, d, rtol, atol, dt, s, p_m))(at_clearing, since)
        y = jnp.where((t[None, :] < T_c[:, None])[..., None], on[None], post)
        return y, ok_on & ok_post & jnp.all(jnp.isfinite(y), axis=(1, 2))

    return values
