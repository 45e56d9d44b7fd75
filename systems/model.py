"""The swing equation in matrix form, written once for every backend (numpy, torch, JAX, CasADi).

For machine k of n (see `systems.cases.Case`):

    m_k delta_k'' + d_k delta_k' + P_e,k(delta) - P_k = 0,
    P_e,k = sum_j C_kj cos(delta_k - delta_j) + S_kj sin(delta_k - delta_j)
            + c_inf_k cos(delta_k) + s_inf_k sin(delta_k),

with C = E E^T * G, S = E E^T * B (elementwise) and c_inf = E V_inf g_inf, s_inf = E V_inf b_inf.
Expanding the differences (cos(a - b) = cos a cos b + sin a sin b, ...) gives, with c = cos(delta)
and s = sin(delta) (n trigonometric calls, not n^2),

    P_e = c * (C c - S s) + s * (C s + S c) + c_inf * c + s_inf * s,

two matrix products per evaluation and no loop over machines. The functions take the backend's
`sin`, `cos` and a `matvec(M, v)`; the default is numpy with machines on the last axis of v
(shape (..., n)), which serves torch and JAX arrays as well (C and S are symmetric, so v @ M is
M v for each row). For the SMIB (n = 1, C = S = 0, c_inf = 0) P_e is b sin(delta) to the bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from systems.cases import Case

__all__ = ["V_INF", "Coupling", "accelerations", "center_of_inertia", "coupling", "electrical_power",
           "relative_angles", "residual", "rhs"]

V_INF = 1.0  # p.u., the infinite bus voltage


def _rows(M: Any, v: Any) -> Any:
    return v @ M


class Coupling(NamedTuple):
    """The coefficients of P_e (p.u.): C, S (n, n) symmetric and c_inf, s_inf (n,), as arrays of
    one backend (numpy float64 from `coupling`; `map` converts them)."""

    C: Any
    S: Any
    c_inf: Any
    s_inf: Any

    def map(self, convert: Callable[[np.ndarray], Any]) -> Coupling:
        """The same coefficients through `convert` (e.g. `torch.as_tensor`, `jnp.asarray`)."""
        return Coupling(*(convert(x) for x in self))


def coupling(case: Case) -> Coupling:
    """The coefficients of `case`'s electrical power, numpy float64."""
    E = np.asarray(case.E)
    EE = np.outer(E, E)
    return Coupling(EE * np.asarray(case.G), EE * np.asarray(case.B), E * V_INF * np.asarray(case.g_inf),
                    E * V_INF * np.asarray(case.b_inf))


def electrical_power(k: Coupling, delta: Any, sin: Callable = np.sin, cos: Callable = np.cos,
                     matvec: Callable = _rows) -> Any:
    """P_e (p.u.) of every machine for angles `delta` (rad; (..., n) by default, whatever `matvec`
    takes otherwise), in the layout of `delta`."""
    c, s = cos(delta), sin(delta)
    return (c * (matvec(k.C, c) - matvec(k.S, s)) + s * (matvec(k.C, s) + matvec(k.S, c))
            + (k.c_inf * c + k.s_inf * s))


def accelerations(k: Coupling, m: Any, d: Any, delta: Any, omega: Any, P: Any, sin: Callable = np.sin,
                  cos: Callable = np.cos, matvec: Callable = _rows) -> Any:
    """omega' (rad/s^2) = (P - d omega - P_e(delta)) / m of every machine; m, d, P broadcast
    against delta and omega (m, d: (n,) p.u., or symbols and trainable tensors for identification)."""
    return (P - d * omega - electrical_power(k, delta, sin, cos, matvec)) / m


def residual(k: Coupling, m: Any, d: Any, delta: Any, delta_t: Any, delta_tt: Any, P: Any,
             sin: Callable = np.sin, cos: Callable = np.cos, matvec: Callable = _rows) -> Any:
    """The swing-equation residual m delta'' + d delta' + P_e(delta) - P of every machine (p.u.)."""
    return m * delta_tt + d * delta_t + electrical_power(k, delta, sin, cos, matvec) - P


def rhs(case: Case) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
    """f(t, y, P) -> dy/dt for one trajectory of `case` in numpy: y = [delta (n), omega (n)]
    (rad, rad/s), P (n,) p.u."""
    k, m, d, n = coupling(case), np.asarray(case.m), np.asarray(case.d), case.n

    def f(_t: float, y: np.ndarray, P: np.ndarray) -> np.ndarray:
        return np.concatenate([y[n:], accelerations(k, m, d, y[:n], y[n:], P)])

    return f


def center_of_inertia(case: Case, delta: np.ndarray) -> np.ndarray:
    """The inertia-weighted mean angle sum_k m_k delta_k / sum_k m_k (rad) of `delta` (..., n):
    shape (...)."""
    m = np.asarray(case.m)
    return np.asarray(delta) @ m / m.sum()


def relative_angles(case: Case, delta: np.ndarray) -> np.ndarray:
    """Angles (..., n) rad against the system's reference: the infinite bus (the angles as they
    are) when the case has one, else the centre of inertia (delta_k - delta_COI), since the
    absolute angles of a system without an infinite bus drift together."""
    delta = np.asarray(delta)
    if case.has_infinite_bus:
        return delta
    return delta - center_of_inertia(case, delta)[..., None]
