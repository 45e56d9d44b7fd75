"""The swing equation, written once for every backend (numpy, CasADi, torch, JAX).

For generator k of n, against an infinite bus at angle 0:

    m_k delta_k'' + d_k delta_k' + sum_j B_kj sin(delta_k - delta_j) + Binf_k sin(delta_k) - P_k = 0

with B_kj = B_kj V_k V_j (p.u.). SMIB is n = 1, B = [[0]], Binf = [b]. The functions take the
elementwise `sin` of the backend, so the same lines build a CasADi expression, a torch residual
or a numpy right-hand side; a multi-machine system is a change of data, not of code.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from harness.cases import Case

__all__ = ["SwingSystem", "accelerations", "residual", "smib_system"]


@dataclass(frozen=True)
class SwingSystem:
    """n machines: inertia m (n,), damping d (n,), coupling B (n, n) with zero diagonal,
    coupling to the infinite bus b_inf (n,), all p.u.; initial delta0 (n,) rad, omega0 (n,) rad/s."""

    m: tuple[float, ...]
    d: tuple[float, ...]
    B: tuple[tuple[float, ...], ...]
    b_inf: tuple[float, ...]
    delta0: tuple[float, ...]
    omega0: tuple[float, ...]

    @property
    def n(self) -> int:
        return len(self.m)


def smib_system(case: Case) -> SwingSystem:
    """The one-machine system of a `Case`."""
    return SwingSystem(
        m=(case.m,), d=(case.d,), B=((0.0,),), b_inf=(case.b,),
        delta0=(case.delta0,), omega0=(case.omega0,),
    )


def _electrical_power(system: SwingSystem, delta: Sequence[Any], sin: Callable) -> list[Any]:
    """Electrical power out of each machine, sum_j B_kj sin(d_k - d_j) + Binf_k sin(d_k)."""
    out = []
    for k in range(system.n):
        pe = system.b_inf[k] * sin(delta[k])
        for j in range(system.n):
            if system.B[k][j] != 0.0:
                pe = pe + system.B[k][j] * sin(delta[k] - delta[j])
        out.append(pe)
    return out


def accelerations(
    system: SwingSystem, delta: Sequence[Any], omega: Sequence[Any], P: Sequence[Any],
    sin: Callable = np.sin, m: Sequence[Any] | None = None, d: Sequence[Any] | None = None,
) -> list[Any]:
    """omega_k' (rad/s^2) of each machine; `m`, `d` override the system's (for identification,
    where they are symbols or trainable tensors). Entries may be scalars or arrays of a batch."""
    m = system.m if m is None else m
    d = system.d if d is None else d
    pe = _electrical_power(system, delta, sin)
    return [(P[k] - d[k] * omega[k] - pe[k]) / m[k] for k in range(system.n)]


def residual(
    system: SwingSystem, delta: Sequence[Any], delta_t: Sequence[Any], delta_tt: Sequence[Any],
    P: Sequence[Any], sin: Callable = np.sin, m: Sequence[Any] | None = None,
    d: Sequence[Any] | None = None,
) -> list[Any]:
    """The swing-equation residual m delta'' + d delta' + Pe(delta) - P of each machine (p.u.)."""
    m = system.m if m is None else m
    d = system.d if d is None else d
    pe = _electrical_power(system, delta, sin)
    return [m[k] * delta_tt[k] + d[k] * delta_t[k] + pe[k] - P[k] for k in range(system.n)]
