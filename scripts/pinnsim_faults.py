"""pinnsim (config "faults") on fault cases, each side of the CCT apart: past the CCT a machine
slips poles, leaves any trained domain, and pinnsim refuses those clearing times (SolveError). The
accuracy suite asks such a grid again one clearing time at a time and measures what was answered
(`harness.suites.accuracy.answers`); this script adds, of the refused clearing times past the CCT,
how many crossed the cct suite's criterion before they stopped (`harness.suites.cct`).

Per case, on the standard grid (`systems.cases.standard_grid`: 100 clearing times x 201 times):
the clearing times below the reference CCT (`systems.stability.reference_cct`) in one call (each
alone if that call is refused), its errors against the reference (`systems.reference`) of the
angles from the centre of inertia (rad) and the speeds (rad/s), as the accuracy suite's "reference,
stable clearing times" rows measure them; then the clearing times at or above the CCT likewise:
refused (SolveError), or answered, and then judged by the cct suite's criterion (`is_unstable` at
its times); of the refused, those whose trajectory crossed the criterion before it stopped (as the
cct suite judges them unstable: `stability_labels`). Rows to OUT/pinnsim_faults.csv, the command and each
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
from harness.suites.accuracy import COI_DELTA, answers
from harness.suites.cct import criterion_times, stability_labels
from solvers import make_solver
from solvers.pinn.component_error import option_argument
from systems.cases import CASES, standard_grid
from systems.model import relative_angles
from systems.reference import STABLE_CLEARING, UNSTABLE_CLEARING, reference
from systems.stability import is_unstable, reference_cct

CASES_MEASURED = ("wscc9-bus8-line8-9", "kundur4-bus7-line7-8a")


def _answers(solver, t: np.ndarray, T_c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str],
                                                                np.ndarray]:
    """(delta, omega) (len(T_c), len(t), n) (NaN where refused), answered (len(T_c),) bool, the
    refusals' messages (the accuracy suite's `answers`: one call for all, else one call each), and
    seen (len(T_c),) bool: refused, but past the cct suite's criterion before the trajectory
    stopped (`stability_labels`)."""
    got = answers(solver, t, T_c)
    seen = np.zeros(T_c.size, bool)
    if not got.answered.all():
        seen[~got.answered] = stability_labels(solver, T_c[~got.answered]) == 1.0
    return got.delta, got.omega, got.answered, got.refusals, seen


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
    past = _answers(solver, tc, T_c[~stable]) if (~stable).any() else none
    judged = is_unstable(case, past[0][past[2]]) if past[2].any() else np.zeros(0, bool)
    rows.append({**base, "quantity": "stability", "against": UNSTABLE_CLEARING, "unit": "clearing times",
                 "clearing_times": int((~stable).sum()), "answered": int(past[2].sum()),
                 "judged_unstable": int(judged.sum()), "seen_unstable_before_refusal": int(past[4].sum()),
                 "first_refusal": past[3][0] if past[3] else ""})
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
