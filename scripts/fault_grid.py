"""Time and accuracy of every classical adapter that handles faults on the (t_c, t) grid of a fault
case: 36 clearing times over [0.05, 0.40] s x 201 times over [0, 3] s, at each adapter's default and
tight configs, against the reference (`systems.reference`). Also the grid answered as 36 calls of
one t_c each (every call integrating its own fault-on phase), to show what integrating the fault-on
phase once per call saves. Prints a markdown table; times are the median of warm calls (s).

    python scripts/fault_grid.py [--case NAME ...] [--solver NAME ...] [--threads 1]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from solvers import SOLVERS, fault_adapters, make_solver
from systems.cases import CASES
from systems.model import relative_angles
from systems.reference import reference

CASES_MEASURED = ("wscc9-bus8-line8-9", "kundur4-bus7-line7-8a")
# options that pin an adapter to the given number of threads (its own thread option)
THREAD_OPTIONS = {"numba-rk": "threads", "trapezoid": "threads", "casadi-cvodes": "threads", "diffrax": "threads"}


def median_seconds(call, budget: float = 2.0, most: int = 15) -> tuple[float, int]:
    """The median wall time (s) of warm calls of `call`, repeated until `budget` s or `most` calls
    (at least 3); and how many."""
    times: list[float] = []
    while len(times) < 3 or (sum(times) < budget and len(times) < most):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times), len(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", action="append")
    parser.add_argument("--solver", action="append")
    parser.add_argument("--config", action="append")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    t, T_c = np.linspace(0.0, 3.0, 201), np.linspace(0.05, 0.40, 36)
    names = args.solver or [n for n in fault_adapters() if not SOLVERS[n].trains]
    print("| case | solver | config | grid s (calls) | 36 x one t_c s | max COI angle err rad | max omega err rad/s |")
    print("|---|---|---|---|---|---|---|")
    for case_name in args.case or CASES_MEASURED:
        case = CASES[case_name]
        ref_delta, ref_omega = reference(case, t, T_c)
        for name in names:
            for config in args.config or ("default", "tight"):
                option = THREAD_OPTIONS.get(name)
                solver = make_solver(name, case, config, **({option: args.threads} if option else {}))
                if hasattr(solver, "FIT_SHAPES"):  # diffrax: compile the two shapes measured here only
                    solver.FIT_SHAPES = ()
                solver.fit()
                traj = solver.solve(t, T_c)
                solver.solve(t, T_c[:1])
                angle = np.abs(relative_angles(case, traj.delta) - relative_angles(case, ref_delta)).max()
                speed = np.abs(traj.omega - ref_omega).max()
                grid, calls = median_seconds(lambda: solver.solve(t, T_c))  # noqa: B023 - called here
                loop, _ = median_seconds(lambda: [solver.solve(t, T_c[i:i + 1]) for i in range(T_c.size)])  # noqa: B023
                print(f"| {case_name} | {name} | {config} | {grid:.4g} ({calls}) | {loop:.4g} | {angle:.2e} | {speed:.2e} |",
                      flush=True)


if __name__ == "__main__":
    main()
