"""Accuracy on the paper's 100 x 201 grid against the tight reference and the paper's own data."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from harness.measure import metrics
from harness.settings import Settings
from harness.suites._base import Suite
from harness.suites.cct import stability_labels
from solvers.base import AbstractSolver, SolveError
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
from systems.stability import reference_cct

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


class Answers(NamedTuple):
    """An adapter's trajectories where it answered: `delta` (rad) and `omega` (rad/s) (len(P1),
    len(t), n), NaN where it refused; `answered` (len(P1),) bool; the refusals' messages in P1 order."""

    delta: np.ndarray
    omega: np.ndarray
    answered: np.ndarray
    refusals: list[str]


def answers(solver: AbstractSolver, t: np.ndarray, P1: np.ndarray, one_at_a_time: bool = True) -> Answers:
    """`solver`'s trajectories at the times t (s) for P1: one call for all; where the adapter refuses
    that call (`SolveError`: pinnsim, when a machine slips poles and leaves its trained domain), one
    call per P1, and a P1 refused alone is NaN (with `one_at_a_time` False, the refusal is raised)."""
    try:
        traj = solver.solve(t, P1)
        return Answers(traj.delta, traj.omega, np.ones(P1.size, bool), [])
    except SolveError:
        if not one_at_a_time:
            raise
    delta, omega = np.full((2, P1.size, t.size, solver.case.n), np.nan)
    answered, refusals = np.zeros(P1.size, bool), []
    for i, p1 in enumerate(P1):
        try:
            traj = solver.solve(t, float(p1))
        except SolveError as error:
            refusals.append(str(error))
            continue
        delta[i], omega[i], answered[i] = traj.delta[0], traj.omega[0], True
    return Answers(delta, omega, answered, refusals)


def stability_classes(solver: AbstractSolver, case: Case, P1: np.ndarray, stable: np.ndarray) -> dict:
    """How often `solver` puts fault case `case`'s clearing times P1 (s) on the reference's side of
    the CCT (`stable`: P1 below it), judged as the cct suite judges them (`stability_labels`): a
    clearing time the adapter refuses (`refused`, listed in `refused_t_c`) is on neither side, so
    not classified correctly, and not counted `misclassified` either."""
    labels = stability_labels(solver, P1)
    refused = np.isnan(labels)
    wrong = ~refused & ((labels == 1.0) == stable)
    return {"quantity": "stability", "against": STABILITY_CLASSES, "unit": "fraction of clearing times",
            "classified_correct": float((~refused & ~wrong).mean()), "misclassified": int(wrong.sum()),
            "clearing_times": int(P1.size), "misclassified_t_c": " ".join(f"{x:.6g}" for x in P1[wrong]),
            "refused": int(refused.sum()), "refused_t_c": " ".join(f"{x:.6g}" for x in P1[refused])}


def off_training_grid(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """A grid away from a PINN's training data, which lie on t = 0 and the P1 edges of the standard
    grid: the 200 midpoints between its times (0.05 ... 19.95 s) x the 99 midpoints between its P1
    values (neither edge). Returns (t, P1)."""
    t, P1 = standard_grid(case)
    return 0.5 * (t[1:] + t[:-1]), 0.5 * (P1[1:] + P1[:-1])


def _answered_errors(quantity: str, against: str, unit: str, pred: np.ndarray, ref: np.ndarray,
                     got: Answers, where: np.ndarray | None = None, P1: np.ndarray | None = None) -> dict:
    """`_errors` over the trajectories the adapter answered (`got.answered`, within the selection
    `where` of them when given; `pred` and `ref` already selected), with how many there were
    (`trajectories`) and answered (`answered`), and the first refusal's message (`first_refusal`);
    NaN errors where it answered none."""
    ok = got.answered if where is None else got.answered[where]
    counts = {"trajectories": int(ok.size), "answered": int(ok.sum()),
              "first_refusal": got.refusals[0] if got.refusals else ""}
    if not ok.any():
        return {"quantity": quantity, "against": against, "unit": unit, "rel_l2": np.nan, "max_abs": np.nan, **counts}
    return {**_errors(quantity, against, unit, pred[ok], ref[ok], None if P1 is None else P1[ok]), **counts}


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
    against the paper's ode45 data when the case has them.

    On a fault case an adapter may refuse clearing times (pinnsim does where a machine slips poles
    and leaves its trained domain): a refused grid is asked again one clearing time at a time
    (`answers`), errors are over the trajectories it answered, and every error row says how many
    (`answered` of `trajectories`); one that answers none fails the unit. Elsewhere a refusal
    fails the unit."""
    t, P1 = standard_grid(case)
    fault = case.fault is not None  # a refusal is expected there past the CCT; elsewhere it fails the unit
    traj = answers(solver, t, P1, one_at_a_time=fault)
    if not traj.answered.any():
        raise SolveError(f"{solver.name} refused every clearing time of {case.name}'s grid; the first: {traj.refusals[0]}")
    ref_delta, ref_omega = reference(case, t, P1)
    t_off, p_off = off_training_grid(case)
    off = answers(solver, t_off, p_off, one_at_a_time=fault)
    off_delta, off_omega = reference(case, t_off, p_off)
    rows = [
        _answered_errors("delta", "reference", "rad", traj.delta, ref_delta, traj, P1=P1),
        _answered_errors("omega", "reference", "rad/s", traj.omega, ref_omega, traj, P1=P1),
        _answered_errors("delta", OFF_TRAINING, "rad", off.delta, off_delta, off),
        _answered_errors("omega", OFF_TRAINING, "rad/s", off.omega, off_omega, off),
    ]
    if not case.has_infinite_bus:
        rows += [
            _answered_errors(COI_DELTA, "reference", "rad", relative_angles(case, traj.delta),
                             relative_angles(case, ref_delta), traj, P1=P1),
            _answered_errors(COI_DELTA, OFF_TRAINING, "rad", relative_angles(case, off.delta),
                             relative_angles(case, off_delta), off),
        ]
    if fault:
        stable = P1 < reference_cct(case)
        for side, against in ((stable, STABLE_CLEARING), (~stable, UNSTABLE_CLEARING)):
            if side.any():
                rows += [
                    _answered_errors(COI_DELTA, against, "rad", relative_angles(case, traj.delta[side]),
                                     relative_angles(case, ref_delta[side]), traj, side),
                    _answered_errors("omega", against, "rad/s", traj.omega[side], ref_omega[side], traj, side),
                ]
        rows.append(stability_classes(solver, case, P1, stable))
    seed = seed_reference(case)
    if seed is not None:
        t_seed, p1_seed, delta_seed = seed
        pred = traj.delta if np.allclose(t_seed, t) and np.allclose(p1_seed, P1) else solver.solve(t_seed, p1_seed).delta
        rows.append(_errors("delta", "paper ode45 data", "rad", pred, delta_seed))
    return rows


SUITE = Suite("accuracy", accuracy, every_seed=True)
