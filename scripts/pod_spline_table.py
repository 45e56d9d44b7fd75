"""pod-spline's fit and accuracy against its settings: for each case and (n_snapshots, k), the fit
(s), the errors on the standard grid (100 P1 x 201 t, no P1 a node and no t a knot but 0 and
t_final) against the tight reference, measured as the accuracy suite measures them (COI rel. L2 of
the angles on a case without an infinite bus, rel. L2 of the speeds), and the median of warm
queries of that grid (ms), on the adapter's BLAS threads (`blas_threads`). With --rival, numba-rk's
default and tight configs on the same grid. Every fit after one that loads numba's kernels (compiled
or from its cache) for the case. Prints a markdown table.

    python scripts/pod_spline_table.py [--case NAME ...] [--rival]
"""

from __future__ import annotations

import argparse

from harness.measure import metrics
from harness.measure.timing import blas_threads, time_call
from solvers import make_solver
from systems.cases import CASES, standard_grid
from systems.model import relative_angles
from systems.reference import reference

# (n_snapshots, k) measured per case; k None: the energy rule
SETTINGS = {
    "wscc9": ((5, None), (9, None), (17, None)),
    "ieee39": ((5, None), (9, None), (17, None), (17, 6)),
    "case1354pegase": ((5, None), (9, None), (17, None), (9, 40), (9, 80), (17, 120)),
}


def row(solver, case, t, P1, ref_delta, ref_omega, fit_s: float) -> str:
    with blas_threads(solver.blas_threads):
        traj = solver.solve(t, P1)
        timing = time_call(lambda: solver.solve(t, P1), min_repeats=3, budget_s=1.0)
    coi = metrics.rel_l2(relative_angles(case, traj.delta), relative_angles(case, ref_delta))
    omega = metrics.rel_l2(traj.omega, ref_omega)
    return f"{fit_s:.2f} | {coi:.2e} | {omega:.2e} | {1e3 * timing.median_s:.3g} |"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--case", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--rival", action="store_true", help="numba-rk's default and tight configs too")
    args = parser.parse_args()
    print("| case | solver | n_snapshots | k (delta, omega) | fit (s) | COI rel. L2 delta | rel. L2 omega | grid query (ms) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.case:
        case = CASES[name]
        t, P1 = standard_grid(case)
        ref_delta, ref_omega = reference(case, t, P1)
        make_solver("pod-spline", case, n_snapshots=2, n_times=2).fit()  # numba's kernels loaded: fits alike
        for n_snapshots, k in SETTINGS[name]:
            solver = make_solver("pod-spline", case, n_snapshots=n_snapshots, k=k)
            with blas_threads(solver.blas_threads):
                report = solver.fit()
            kept = f"{solver._delta.basis_t.shape[0]}, {solver._omega.basis_t.shape[0]}"
            print(f"| {name} ({case.n}) | pod-spline | {n_snapshots} | {kept} | "
                  f"{row(solver, case, t, P1, ref_delta, ref_omega, report.seconds)}", flush=True)
        for config in ("default", "tight") if args.rival else ():
            solver = make_solver("numba-rk", case, config)
            report = solver.fit()
            print(f"| {name} ({case.n}) | numba-rk [{config}] | - | - | "
                  f"{row(solver, case, t, P1, ref_delta, ref_omega, report.seconds)}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
