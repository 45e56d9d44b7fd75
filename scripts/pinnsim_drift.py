"""pinnsim at rest: each case at its operating point (P1 = generator 1's own p_m, where the
reference stays at its equilibrium), the speed of the centre of inertia (rad/s) that pinnsim
simulates against the reference's, and the angles from the centre of inertia. A machine at rest
against a constant terminal voltage is an exact fixed point of the swing equation; the component
network's residual term need not vanish there, and the grid's common frequency integrates what it
leaves.

Per case and step h: the largest |COI speed| over [0, 20] s of pinnsim and of the reference, the
COI speed at 20 s, and the largest |error| of the angles from the centre of inertia (rad). Rows to
OUT/pinnsim_drift.csv, the command and each fit's message to OUT/pinnsim_drift.json.

    python scripts/pinnsim_drift.py --out results/pinnsim-drift [--case NAME ...] [--h H ...]
        [--option KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from harness.report.files import write_script_rows
from solvers import make_solver
from solvers.pinn.component_error import option_argument
from systems.cases import CASES
from systems.model import center_of_inertia, relative_angles
from systems.reference import reference

CASES_MEASURED = ("wscc9", "kundur4", "ieee39")
STEPS = (0.25, 0.05)


def measure(name: str, h: float, options: dict) -> tuple[dict, str]:
    """The row of case `name` at step h (s) (see the module docstring) of the network of pinnsim's
    `options` and the fit's message."""
    case = CASES[name]
    solver = make_solver("pinnsim", case, **options, h=h)
    report = solver.fit()
    t, P1 = np.linspace(0.0, 20.0, 201), np.array([float(case.p_m[0])])
    traj = solver.solve(t, P1)
    ref_delta, ref_omega = reference(case, t, P1)
    coi, coi_ref = center_of_inertia(case, traj.omega)[0], center_of_inertia(case, ref_omega)[0]
    angles = np.abs(relative_angles(case, traj.delta) - relative_angles(case, ref_delta)).max()
    return {"case": name, "h_s": h, "P1": float(P1[0]), "coi_speed_max_rad_s": float(np.abs(coi).max()),
            "coi_speed_20s_rad_s": float(coi[-1]), "reference_coi_speed_max_rad_s": float(np.abs(coi_ref).max()),
            "coi_angle_error_max_rad": float(angles)}, report.message


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--case", nargs="+", default=list(CASES_MEASURED))
    parser.add_argument("--h", nargs="+", type=float, default=list(STEPS))
    parser.add_argument("--option", type=option_argument, action="append", default=[], metavar="KEY=VALUE",
                        help="a pinnsim option of the network measured (repeatable), e.g. form=rest-exact")
    args = parser.parse_args(argv)
    options = dict(args.option)
    if "h" in options:
        parser.error("the step is --h, not --option h=...")
    rows, fits = [], {}
    for name in args.case:
        for h in args.h:
            row, fits[name] = measure(name, h, options)
            rows.append(row)
            print(row)
    command = " ".join(["python scripts/pinnsim_drift.py", *(argv if argv is not None else sys.argv[1:])])
    write_script_rows(args.out, "pinnsim_drift", rows, {"command": command, "options": options, "fits": fits})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
