"""The accuracy reference: DOP853 at rtol = atol = 1e-12, one trajectory at a time, cached.

A fault case's trajectory is integrated in its two phases with the switch exact: the fault-on
network from the equilibrium to t_c, then the post-fault one from the state at t_c (no step across
the switch)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from systems.cases import CASES, Case, check_array
from systems.model import rhs

__all__ = ["OFF_TRAINING", "PAPER_DATA", "REFERENCE_DATA", "REFERENCE_TOL", "SEED_DIR", "Event", "load_seed_reference",
           "reference", "seed_reference", "switched"]

REFERENCE_TOL = 1e-12
# A terminal event of the reference integrator: g(t, y, P) whose sign change stops the integration
# (scipy's `solve_ivp` events; marked terminal by `switched`).
Event = Callable[[float, np.ndarray, np.ndarray], float]
# Names of the two data sources of delta in the rows: this module's `reference`, and the paper's
# published MATLAB ode45 trajectories (`seed_reference`, ~1.2e-3 rad of their own error).
REFERENCE_DATA = "reference"
PAPER_DATA = "paper ode45"
# The accuracy suite's name (column `against`) of the reference on the grid away from a PINN's
# training points (`harness.suites.accuracy.off_training_grid`).
OFF_TRAINING = "reference, off the training points"
# ... and of the reference on the clearing times of the standard grid below a fault case's reference
# CCT (`systems.stability.reference_cct`): the stable trajectories, where an engineer reads them.
STABLE_CLEARING = "reference, stable clearing times"
# ... at or above it: the unstable trajectories, where a machine slips poles ...
UNSTABLE_CLEARING = "reference, unstable clearing times"
# ... and the stable / unstable classes of those clearing times (below the reference CCT / not).
STABILITY_CLASSES = "reference CCT's classes"


def reference(case: Case, t, P1) -> tuple[np.ndarray, np.ndarray]:
    """delta (rad) and omega (rad/s) of every machine of `case`, shape (len(P1), len(t), n), for
    1-D t (s, any order, >= 0) and P1 (the scenario parameter, `Case.scenario`: p.u., or a fault
    case's clearing times, s): DOP853 at rtol = atol = 1e-12, one trajectory per P1 (max error on
    the SMIB standard grid ~1e-11 rad). At t = t_c a fault case's state is the post-fault phase's
    start, which is the fault-on phase's end. Results are cached per (case, t, P1); the
    returned arrays are read-only."""
    t = check_array("t", t, nonnegative=True)
    P1 = check_array("P1", P1, promote=True)
    return _reference(case, t.tobytes(), P1.tobytes())


@lru_cache(maxsize=64)
def _reference(case: Case, t_bytes: bytes, p1_bytes: bytes) -> tuple[np.ndarray, np.ndarray]:
    t, P1 = np.frombuffer(t_bytes), np.frombuffer(p1_bytes)
    times, order = np.unique(t, return_inverse=True)
    n = case.n
    f, powers = rhs(case), case.powers(P1)
    y0 = np.array(case.delta0 + case.omega0)
    delta = np.empty((P1.size, times.size, n))
    omega = np.empty_like(delta)
    for i, p1 in enumerate(P1):
        if case.fault is None:
            y = _integrate(f, 0.0, y0, times, powers[i], p1)[0]
        else:
            y = switched(case, float(p1), times)[0]
        delta[i], omega[i] = y[:n].T, y[n:].T
    delta, omega = delta[:, order], omega[:, order]
    delta.flags.writeable = omega.flags.writeable = False
    return delta, omega


def _integrate(f, t0: float, y0: np.ndarray, times: np.ndarray, P: np.ndarray, p1: float,
               event: Event | None = None) -> tuple[np.ndarray, float | None]:
    """y (2n, k) of dy/dt = f(t, y, P) from y(t0) = y0 at `times` (sorted, >= t0; k = len(times),
    fewer when `event` stopped the integration first) and the time (s) the event stopped it, or
    None."""
    if times.size == 0:
        return np.empty((y0.size, 0)), None
    if times[-1] <= t0:  # every time is the start: nothing to integrate (a span of zero length)
        return np.repeat(y0[:, None], times.size, axis=1), None
    events: Any = None  # scipy's stubs type an event without the `args` that solve_ivp passes it
    if event is not None:
        def events(t: float, y: np.ndarray, P: np.ndarray) -> float:
            return event(t, y, P)
        events.terminal = True
    sol = solve_ivp(f, (t0, times[-1]), y0, method="DOP853", t_eval=times,
                    rtol=REFERENCE_TOL, atol=REFERENCE_TOL, args=(P,), events=events)
    if not sol.success:
        raise RuntimeError(f"reference failed at P1={p1!r}: {sol.message}")
    stopped = float(sol.t_events[0][0]) if sol.status == 1 and sol.t_events is not None else None
    return np.asarray(sol.y, np.float64).reshape(y0.size, -1), stopped  # stopped before any time: y is []


def switched(case: Case, t_c: float, times: np.ndarray, event: Event | None = None
             ) -> tuple[np.ndarray, float | None]:
    """The reference trajectory of fault case `case` cleared at t_c s: y = [delta, omega] (2n, k)
    (rad, rad/s) at the sorted `times` (s, >= 0), the fault-on phase on [0, t_c) (and to t_c
    itself), the post-fault phase from the state at t_c, no step across the switch; with a
    terminal `event` g(t, y, P) (P the mechanical powers (n,) p.u.), the integration stops where g
    changes sign: k < len(times) then, and the second item is that time (s), else None."""
    y0 = np.array(case.delta0 + case.omega0)
    P = case.powers(np.array([t_c]))[0]
    split = int(np.searchsorted(times, t_c))
    on, stopped = _integrate(rhs(case.phase("on")), 0.0, y0, np.append(times[:split], t_c), P, t_c, event)
    if stopped is not None:
        return on[:, :split], stopped
    post, stopped = _integrate(rhs(case.phase("post")), t_c, on[:, -1], times[split:], P, t_c, event)
    return np.concatenate([on[:, :-1], post], axis=1), stopped


def load_seed_reference(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's MATLAB ode45 data (a .mat with keys t, x, usol): t (201,) s, P1 (100,) p.u.,
    delta (100, 201, 1) rad (one machine)."""
    from scipy.io import loadmat

    data = loadmat(path)
    return data["t"].ravel(), data["x"].ravel(), data["usol"][:, :, None]


SEED_DIR = Path(__file__).resolve().parents[1] / "data" / "seed-reference"
SEED_FILES = {"smib-inference": "swingEquation_inference.mat",
              "smib-identification": "swingEquation_identification.mat"}


def seed_reference(case: Case) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The paper's ode45 data for `case` (t, P1, delta; see `load_seed_reference`), or None when
    the paper published none for it (compared by case parameters, not by name)."""
    for name, filename in SEED_FILES.items():
        paper_case = CASES[name]
        same = dataclasses.replace(case, name=paper_case.name, source=paper_case.source) == paper_case
        if same and (SEED_DIR / filename).exists():
            return load_seed_reference(SEED_DIR / filename)
    return None
