"""Train one JAX fault PINN and print what the accuracy and cct suites would measure of it: the
COI rel. L2 over the standard grid's stable and unstable clearing times, the worst stable rows, the
share of clearing times classified as the reference CCT does, and the CCT of the cct suite's
surrogate search (10 ms grid, then bisection). A probe for choosing a configuration, not a run:
the project's figures are the harness's rows.

    python scripts/fault_split_probe.py wscc9-bus8-line8-9 '{"max_iterations": 150, "max_seconds": null}'

The second argument: options of `make_solver` as JSON (its "config" key the config, default
fault-split); threads 1 unless it says otherwise.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from harness.measure import metrics
from harness.suites.accuracy import stability_classes
from harness.suites.cct import grid_then_bisect
from solvers import make_solver
from systems.cases import CASES, standard_grid
from systems.model import relative_angles
from systems.reference import reference
from systems.stability import reference_cct


def main(case_name: str, options_json: str) -> None:
    case = CASES[case_name]
    options = {"threads": 1, **json.loads(options_json)}
    solver = make_solver("jax-pinn", case, options.pop("config", "fault-split"), **options)
    report = solver.fit()
    print(f"fit {report.seconds:.1f} s, {report.iterations} iterations: {report.message}")
    ref_cct = reference_cct(case)
    t, P1 = standard_grid(case)
    pred = relative_angles(case, solver.solve(t, P1).delta)
    ref = relative_angles(case, reference(case, t, P1)[0])
    stable = P1 < ref_cct
    rows = metrics.rel_l2_per_row(pred.reshape(P1.size, -1), ref.reshape(P1.size, -1))
    print(f"split at {getattr(solver, 'split_s', float('nan'))!r} s, reference CCT {ref_cct!r} s")
    print(f"COI rel. L2: stable {metrics.rel_l2(pred[stable], ref[stable]):.3g}, "
          f"unstable {metrics.rel_l2(pred[~stable], ref[~stable]):.3g}, all {metrics.rel_l2(pred, ref):.3g}")
    worst = np.argsort(rows[stable])[-5:]
    print("worst stable rows:", ", ".join(f"t_c {P1[stable][i]:.5f} s {rows[stable][i]:.2g}" for i in worst))
    print(f"unstable rows: median {np.median(rows[~stable]):.3g}, largest {rows[~stable].max():.3g}")
    classes = stability_classes(solver, case, P1, stable)
    print(f"classified {classes['classified_correct']:.4f} ({classes['misclassified']} wrong: "
          f"{classes['misclassified_t_c']})")
    search = grid_then_bisect(solver, 0.01)
    print(f"CCT {search.cct_s!r} s, error {1e3 * (search.cct_s - ref_cct):+.4f} ms {search.note}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
