"""Accuracy on the paper's 100 x 201 grid against the tight reference and the paper's own data."""

from __future__ import annotations

import numpy as np

from harness.measure import metrics
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites.cct import criterion_times
from solvers.base import AbstractSolver
from systems.cases import Case, standard_grid
from systems.model import relative_angles
from systems.reference import (
    OFF_TRAINING,
    STABILITY_CLASSES,
    STABLE_CLEARING,
    UNSTABLE_CLEARING,
    reference,
    seed_reference,
)
from systems.stability import is_unstable, reference_cct

# The quantity of the angles relative to the centre of inertia (systems without an infinite bus); the
# verdicts of such a case compare at it (`harness.report.ladder.verdict_rows`).
COI_DELTA = "delta - delta_COI"


def _errors(quantity: str, against: str, unit: str, pred: np.ndarray, ref: np.ndarray,
            P1: np.ndarray | None = None) -> dict:
    """Errors of `pred` against `ref` (n_P1, n_t, n): over every machine, time and P1; a
    trajectory is one P1 (all its machines). With `P1`, also the best and worst trajectory
    themselves ((n_t, n) nested lists, for the paper's figure 3; the CSV leaves them out, rows.jsonl
    keeps them)."""
    n_p = pred.shape[0]
    per_trajectory = metrics.rel_l2_per_row(pred.reshape(n_p, -1), ref.reshape(n_p, -1))
    best, worst = int(per_trajectory.argmin()), int(per_trajectory.argmax())
    row = {
        "quantity": quantity, "against": against, "unit": unit,
        "rel_l2": metrics.rel_l2(pred, ref), "max_abs": metrics.max_abs(pred, ref),
        "best_trajectory_rel_l2": float(per_trajectory[best]),
        "worst_trajectory_rel_l2": float(per_trajectory[worst]),
    }
    if P1 is not None:
        row.update(best_P1=float(P1[best]), worst_P1=float(P1[worst]),
                   best_pred=pred[best].tolist(), best_ref=ref[best].tolist(),
                   worst_pred=pred[worst].tolist(), worst_ref=ref[worst].tolist())
    return row


def stability_classes(solver: AbstractSolver, case: Case, P1: np.ndarray, stable: np.ndarray) -> dict:
    """How often `solver` puts fault case `case`'s clearing times P1 (s) on the reference's side of
    the CCT (`stable`: P1 below it): the cct suite's criterion (`is_unstable`) on the adapter's
    trajectories at its times (`criterion_times`)."""
    wrong = is_unstable(case, solver.solve(criterion_times(case), P1).delta) == stable
    return {"quantity": "stability", "against": STABILITY_CLASSES, "unit": "fraction of clearing times",
            "classified_correct": float(1.0 - wrong.mean()), "misclassified": int(wrong.sum()),
            "clearing_times": int(P1.size), "misclassified_t_c": " ".join(f"{x:.6g}" for x in P1[wrong])}


def off_training_grid(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """A grid away from a PINN's training data, which lie on t = 0 and the P1 edges of the standard
    grid: the 200 midpoints between its times (0.05 ... 19.95 s) x the 99 midpoints between its P1
    values (neither edge). Returns (t, P1)."""
    t, P1 = standard_grid(case)
    return 0.5 * (t[1:] + t[:-1]), 0.5 * (P1[1:] + P1[:-1])


def accuracy(solver: AbstractSolver, case: Case, settings: Settings) -> list[dict]:
    """Relative L2 (whole grid and every machine, the paper's measure), max abs error, best and worst
    trajectory of delta (rad) and omega (rad/s) against DOP853 at 1e-12 on the standard grid
    (`against` "reference"); for a system without an infinite bus also of the angles relative to
    the centre of inertia (quantity `COI_DELTA`: absolute angles drift together, and their error
    hides or inflates the swings); the same on `off_training_grid` ("reference, off the training
    points"); on a fault case, the angles relative to the centre of inertia and the speeds also over
    the grid's clearing times below the reference CCT alone (`STABLE_CLEARING`: past it a machine
    slips poles, and its angle error, growing without bound, dominates the whole grid's) and over
    those at or above it (`UNSTABLE_CLEARING`), and the share of the grid's clearing times the
    adapter classifies as the reference CCT does (`stability_classes`, quantity "stability"); delta also
    against the paper's ode45 data when the case has them."""
    t, P1 = standard_grid(case)
    traj = solver.solve(t, P1)
    ref_delta, ref_omega = reference(case, t, P1)
    t_off, p_off = off_training_grid(case)
    off = solver.solve(t_off, p_off)
    off_delta, off_omega = reference(case, t_off, p_off)
    rows = [
        _errors("delta", "reference", "rad", traj.delta, ref_delta, P1),
        _errors("omega", "reference", "rad/s", traj.omega, ref_omega, P1),
        _errors("delta", OFF_TRAINING, "rad", off.delta, off_delta),
        _errors("omega", OFF_TRAINING, "rad/s", off.omega, off_omega),
    ]
    if not case.has_infinite_bus:
        rows += [
            _errors(COI_DELTA, "reference", "rad", relative_angles(case, traj.delta),
                    relative_angles(case, ref_delta), P1),
            _errors(COI_DELTA, OFF_TRAINING, "rad", relative_angles(case, off.delta),
                    relative_angles(case, off_delta)),
        ]
    if case.fault is not None:
        stable = P1 < reference_cct(case)
        rows += [
            _errors(COI_DELTA, STABLE_CLEARING, "rad", relative_angles(case, traj.delta[stable]),
                    relative_angles(case, ref_delta[stable])),
            _errors("omega", STABLE_CLEARING, "rad/s", traj.omega[stable], ref_omega[stable]),
        ]
        if not stable.all():
            rows += [
                _errors(COI_DELTA, UNSTABLE_CLEARING, "rad", relative_angles(case, traj.delta[~stable]),
                        relative_angles(case, ref_delta[~stable])),
                _errors("omega", UNSTABLE_CLEARING, "rad/s", traj.omega[~stable], ref_omega[~stable]),
            ]
        rows.append(stability_classes(solver, case, P1, stable))
    seed = seed_reference(case)
    if seed is not None:
        t_seed, p1_seed, delta_seed = seed
        pred = traj.delta if np.allclose(t_seed, t) and np.allclose(p1_seed, P1) else solver.solve(t_seed, p1_seed).delta
        rows.append(_errors("delta", "paper ode45 data", "rad", pred, delta_seed))
    return rows


SUITE = Suite("accuracy", accuracy, every_seed=True)
