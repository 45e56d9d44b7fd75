"""What the matrix-free Newton's options cost and change on one case: pinnsim simulated with each
set of options in turn, on the same P1 and times, alone in one process.

Per variant (a comma-separated list of KEY=VALUE pinnsim options on top of newton=matrix-free; ""
is the defaults): the wall seconds of one `solve` of --p1 P1 values (spread over the standard
grid's) on the standard grid's times up to --horizon s (the shape compiled before, untimed), the
Newton iterations and CG iterations a step (mean and max over P1 and steps, `PinnSim.stats`), the
COI rel. L2 of the angles against the reference, and the largest difference of the angles from
the first variant's (rad). Timings are one call each, in the order given: compare them within one
run of the script. Rows to OUT/pinnsim_newton_cost.csv, the command and each fit's message to
OUT/pinnsim_newton_cost.json.

    python scripts/pinnsim_newton_cost.py --out results/pinnsim-newton-cost --case case1354pegase
        --p1 16 --variant "" "cg_forcing=1e-3" "cg_forcing=1e-3,cg_dtype=float32,cg_tol=1e-5"
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from harness.measure import metrics
from harness.report.files import write_script_rows
from solvers import make_solver
from solvers.pinn.component_error import option_argument
from systems.cases import CASES, standard_grid
from systems.model import relative_angles
from systems.reference import reference


def variant_options(spec: str) -> dict:
    """The pinnsim options of a variant "KEY=VALUE,KEY=VALUE" (values read as JSON where they are)."""
    return dict(option_argument(item) for item in spec.split(",") if item)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--case", required=True, choices=sorted(CASES), metavar="NAME")
    parser.add_argument("--p1", type=int, default=16, help="how many P1 of the standard grid's (spread evenly)")
    parser.add_argument("--horizon", type=float, default=None, help="the last time (s; default the grid's)")
    parser.add_argument("--variant", nargs="+", required=True, metavar="OPTIONS",
                        help='comma-separated KEY=VALUE pinnsim options on top of newton=matrix-free ("": none)')
    args = parser.parse_args(argv)
    try:
        variants = [variant_options(spec) for spec in args.variant]
    except ValueError as err:
        parser.error(str(err))
    case = CASES[args.case]
    t, grid_p1 = standard_grid(case)
    t = t if args.horizon is None else t[t <= args.horizon]
    P1 = grid_p1[np.linspace(0, grid_p1.size - 1, args.p1).round().astype(int)]
    ref_delta, _ = reference(case, t, P1)
    rows, fits, first = [], {}, None
    for spec, options in zip(args.variant, variants):
        solver = make_solver("pinnsim", case, **{"newton": "matrix-free", **options})
        fits[spec] = solver.fit().message
        solver.solve(t[:2], P1)  # compiles the shape (every number of steps shares it)
        start = time.perf_counter()
        traj = solver.solve(t, P1)
        wall = time.perf_counter() - start
        first = traj.delta if first is None else first
        stats = solver.stats
        rows.append({"case": args.case, "variant": spec, "p1": P1.size, "horizon_s": float(t[-1]),
                     "wall_s": wall, "steps": stats["steps"], "newton_mean": stats["newton_mean"],
                     "newton_max": stats["newton_max"], "cg_mean": stats["cg_mean"], "cg_max": stats["cg_max"],
                     "coi_rel_l2": metrics.rel_l2(relative_angles(case, traj.delta), relative_angles(case, ref_delta)),
                     "delta_from_first_max_rad": float(np.abs(traj.delta - first).max())})
        print(rows[-1], flush=True)
    command = " ".join(["python scripts/pinnsim_newton_cost.py", *(argv if argv is not None else sys.argv[1:])])
    write_script_rows(args.out, "pinnsim_newton_cost", rows, {"command": command, "fits": fits})
    return 0


if __name__ == "__main__":
    sys.exit(main())
