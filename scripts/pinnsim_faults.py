"""pinnsim (config "faults") on fault cases where the harness's accuracy suite cannot ask it: it
queries clearing times on both sides of the CCT in one call, and past the CCT a machine slips
poles, leaves any trained domain, and pinnsim refuses the whole call (SolveError). (The cct suite
asks a refused batch again one clearing time at a time, and judges a trajectory on the part that
held: `harness.suites.cct`.)

Per case, on the standard grid (`systems.cases.standard_grid`: 100 clearing times x 201 times):
the clearing times below the reference CCT (`systems.stability.reference_cct`) in one call (each
alone if that call is refused), its errors against the reference (`systems.reference`) of the
angles from the centre of inertia (rad) and the speeds (rad/s), as the accuracy suite's "reference,
stable clearing times" rows measure them; then each clearing time at or above the CCT alone: refused
(SolveError), or answered, and then judged by the cct suite's criterion (`is_unstable` at its
times); of the refused, those whose trajectory crossed the criterion before it stopped (as the cct
suite judges them unstable: `partial_labels`). Rows to OUT/pinnsim_faults.csv, the command and each
fit's message to OUT/pinnsim_faults.json.

    python scripts/pinnsim_faults.py --out results/pinnsim-faults [--case NAME ...] [--option KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from harness.measure import metrics
from harness.report.files import write_script_rows
from harness.suites.accuracy import COI_DELTA
from harness.suites.cct import criterion_times, partial_labels
from solvers import make_solver
from solvers.base import PartialSolveError, SolveError
from solvers.pinn.component_error import option_argument
from systems.cases import CASES, standard_grid
from systems.model import relative_angles
from systems.reference import STABLE_CLEARING, UNSTABLE_CLEARING, reference
from systems.stability import is_unstable, reference_cct

CASES_MEASURED = ("wscc9-bus8-line8-9", "kundur4-bus7-line7-8a")


def _answers(solver, t: np.ndarray, T_c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str],
                                                                np.ndarray]:
    """(delta, omega) (len(T_c), len(t), n) (NaN where refused), answered (len(T_c),) bool, the
    refusals' messages, and seen (len(T_c),) bool: refused, but past the cct suite's criterion before
    the trajectory stopped (`partial_labels`); one call for all, else one call each."""
    n = solver.case.n
    try:
        traj = solver.solve(t, T_c)
        return traj.delta, traj.omega, np.ones(T_c.size, bool), [], np.zeros(T_c.size, bool)
    except SolveError:
        pass
    delta, omega = np.full((2, T_c.size, t.size, n), np.nan)
    answered, seen, messages = np.zeros(T_c.size, bool), np.zeros(T_c.size, bool), []
    for i, t_c in enumerate(T_c):
        try:
            traj = solver.solve(t, float(t_c))
            delta[i], omega[i], answered[i] = traj.delta[0], traj.omega[0], True
        except PartialSolveError as exc:
            messages.append(str(exc))
            seen[i] = partial_labels(solver.case, exc)[0] == 1.0
        except SolveError as exc:
            messages.append(str(exc))
    return delta, omega, answered, messages, seen


def measure(name: str, options: dict) -> tuple[list[dict], str]:
    """The rows of case `name` (see the module docstring) and the fit's message."""
    case = CASES[name]
    solver = make_solver("pinnsim", case, "faults", **options)
    report = solver.fit()
    t, T_c = standard_grid(case)
    cct = reference_cct(case)
    stable = T_c < cct
    base = {"case": name, "reference_cct_s": cct, "fit_s": report.seconds}
    delta, omega, ok, messages, _ = _answers(solver, t, T_c[stable])
    ref_delta, ref_omega = reference(case, t, T_c[stable])
    rows = []
    for quantity, unit, pred, ref in ((COI_DELTA, "rad", relative_angles(case, delta[ok]),
                                       relative_angles(case, ref_delta[ok])),
                                      ("omega", "rad/s", omega[ok], ref_omega[ok])):
        rows.append({**base, "quantity": quantity, "against": STABLE_CLEARING, "unit": unit,
                     "rel_l2": metrics.rel_l2(pred, ref) if ok.any() else float("nan"),
                     "max_abs": metrics.max_abs(pred, ref) if ok.any() else float("nan"),
                     "clearing_times": int(stable.sum()), "answered": int(ok.sum()),
                     "judged_unstable": int(is_unstable(case, delta[ok]).sum()) if ok.any() else 0,
                     "first_refusal": messages[0] if messages else ""})
    tc = criterion_times(case)
    none = (None, None, np.zeros(0, bool), [], np.zeros(0, bool))
    answers = _answers(solver, tc, T_c[~stable]) if (~stable).any() else none
    judged = is_unstable(case, answers[0][answers[2]]) if answers[2].any() else np.zeros(0, bool)
    rows.append({**base, "quantity": "stability", "against": UNSTABLE_CLEARING, "unit": "clearing times",
                 "clearing_times": int((~stable).sum()), "answered": int(answers[2].sum()),
                 "judged_unstable": int(judged.sum()), "seen_unstable_before_refusal": int(answers[4].sum()),
                 "first_refusal": answers[3][0] if answers[3] else ""})
    return rows, report.message


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--case", nargs="+", default=list(CASES_MEASURED))
    parser.add_argument("--option", type=option_argument, action="append", default=[], metavar="KEY=VALUE",
                        help="a pinnsim option (repeatable), e.g. max_iterations=1500")
    args = parser.parse_args(argv)
    rows, fits = [], {}
    for name in args.case:
        case_rows, fits[name] = measure(name, dict(args.option))
        rows += case_rows
        for row in case_rows:
            print(row)
    command = " ".join(["python scripts/pinnsim_faults.py", *(argv if argv is not None else sys.argv[1:])])
    write_script_rows(args.out, "pinnsim_faults", rows, {"command": command, "fits": fits})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
