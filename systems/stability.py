"""The stability criterion of a fault case, stated once and applied alike to every method, and the
reference critical clearing time (CCT).

Criterion (`is_unstable`): a trajectory is unstable when, within the horizon [0, t_final], some
machine's angle from the centre of inertia exceeds pi rad in magnitude,

    max_t max_k |delta_k(t) - delta_COI(t)| > pi,   delta_COI = sum_k m_k delta_k / sum_k m_k,

the rotor-angle criterion of time-domain transient-stability assessment in the centre-of-inertia
frame (the COI frame: M. A. Pai, *Energy Function Analysis for Power System Stability*, Kluwer
1989, ch. 2; the 180-degree limit is the one issue 23 states; DSATools TSAT's transient stability
index uses the kindred limit of 360 degrees between two machines). A case with an infinite bus
measures the angles from the bus instead (`systems.model.relative_angles`). A machine that stays in
synchronism swings back before its angle from the COI reaches pi; one that loses synchronism
passes pi and keeps going.

The reference CCT (`reference_cct`) is the clearing time at which the reference integrator
(`systems.reference.switched`: DOP853 at rtol = atol = 1e-12, the switch exact) changes from
stable to unstable, by bisection to a bracket of `tol` s; each simulation stops at the first
crossing of the criterion (a terminal event), so an unstable one costs only its first swing.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from systems.cases import Case, check_number
from systems.model import relative_angles
from systems.reference import switched

__all__ = ["ANGLE_LIMIT", "is_unstable", "max_coi_angle", "reference_cct", "reference_unstable"]

ANGLE_LIMIT = math.pi  # rad: the largest angle from the centre of inertia of a stable trajectory


def max_coi_angle(case: Case, delta: np.ndarray) -> np.ndarray:
    """The largest |delta_k - delta_COI| (rad) over the machines k and the times of `delta`
    (..., n_t, n) rad, a trajectory of `case` (its angles from the infinite bus when it has one):
    shape (...)."""
    delta = np.asarray(delta, np.float64)
    if delta.ndim < 2 or delta.shape[-1] != case.n:
        raise ValueError(f"delta must be (..., n_t, {case.n}) for case {case.name!r}, got shape {delta.shape}")
    return np.abs(relative_angles(case, delta)).max(axis=(-2, -1))


def is_unstable(case: Case, delta: np.ndarray) -> np.ndarray:
    """Whether each trajectory of `delta` (..., n_t, n) rad of `case` is unstable by the criterion
    (`max_coi_angle` > `ANGLE_LIMIT`), judged at its n_t times: bool, shape (...). The times must
    cover the horizon finely enough to see the crossing (the cct suite: every 10 ms)."""
    return max_coi_angle(case, delta) > ANGLE_LIMIT


def _event(case: Case):
    """g(t, y, P) = ANGLE_LIMIT - max_k |delta_k - delta_COI| of y = [delta, omega]: negative once
    the criterion is crossed."""
    n = case.n

    def g(_t: float, y: np.ndarray, _P: np.ndarray) -> float:
        return ANGLE_LIMIT - float(np.abs(relative_angles(case, y[:n])).max())

    return g


def reference_unstable(case: Case, t_c: float) -> bool:
    """Whether fault case `case` cleared at t_c s is unstable on the reference integrator, the
    integration stopped at the first crossing of the criterion."""
    _fault_case(case)
    t_c = check_number("t_c", t_c)
    if not 0 < t_c < case.t_final:
        raise ValueError(f"t_c must lie in (0, t_final = {case.t_final}) s, got {t_c!r}")
    return switched(case, t_c, np.array([case.t_final]), _event(case))[1] is not None


def _fault_case(case: Case) -> None:
    if not isinstance(case, Case) or case.fault is None:
        name = case.name if isinstance(case, Case) else type(case).__name__
        raise ValueError(f"case {name!r} is no fault case: it has no clearing time, hence no CCT")


def reference_cct(case: Case, tol: float = 1e-6) -> float:
    """The reference CCT (s) of fault case `case`: the midpoint of a bracket [stable, unstable] of
    clearing times no wider than `tol` s, found by bisection from the case's range [p1_min,
    p1_max] (`reference_unstable` at each point). Cached per (case, tol). A ValueError when the
    case is no fault case, `tol` is not positive, or the CCT is not inside the range (the case
    stable at p1_max, or unstable at p1_min: the message says which)."""
    _fault_case(case)
    tol = check_number("tol", tol)
    if not tol > 0:
        raise ValueError(f"tol must be > 0 s, got {tol!r}")
    return _reference_cct(case, tol)


@functools.lru_cache(maxsize=64)
def _reference_cct(case: Case, tol: float) -> float:
    lo, hi = case.p1_min, case.p1_max
    if reference_unstable(case, lo):
        raise ValueError(f"case {case.name!r}: unstable at the shortest clearing time p1_min = {lo} s, "
                         "so its CCT lies below the range")
    if not reference_unstable(case, hi):
        raise ValueError(f"case {case.name!r}: stable at the longest clearing time p1_max = {hi} s, "
                         "so its CCT lies above the range")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if reference_unstable(case, mid):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)
