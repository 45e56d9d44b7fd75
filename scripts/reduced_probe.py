"""Train one reduced-output PINN (`reduced-pinn`) and print what its fit cost, where the seconds
went, and what the scaling suite would measure of it: the COI rel. L2 of the angles on the scaling
grid (held-out P1 between the snapshot nodes), the floor the basis sets (the reference projected
onto it), and the error of each window's span of time. A probe for choosing a configuration, not
a run: the project's figures are the harness's rows.

    python scripts/reduced_probe.py case1354pegase '{"max_iterations": 60}'

The second argument: options of `make_solver` as JSON (its "config" key the config, default
default); threads 2 unless it says otherwise. The reference is cached under .cache/reference, as
the scaling suite caches it.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

import solvers.pinn.jax_reduced as adapter
from harness.measure import metrics
from harness.settings import DEFAULT
from harness.suites.scaling import cached_reference, scaling_grid
from solvers import make_solver
from systems.cases import CASES
from systems.model import relative_angles


def _instrument(log: dict) -> None:
    """Wrap the adapter's window functions and optimiser so that each window's seconds of
    residuals, Gauss-Newton products (the first call of each includes its compilation) and LM are logged."""
    window_functions, lm = adapter.window_functions, adapter.levenberg_marquardt

    def timed(fn, key):
        def run(*args):
            start = time.perf_counter()
            out = fn(*args)
            log[key].append(time.perf_counter() - start)
            return out
        return run

    def functions(*args, **kwargs):
        residuals, jacobian, normal_equations = window_functions(*args, **kwargs)
        return timed(residuals, "residual_s"), jacobian, timed(normal_equations, "jacobian_s")

    def optimise(residuals, jacobian, theta, **kwargs):
        losses = []
        start = time.perf_counter()
        result = lm(residuals, jacobian, theta, progress=lambda i, loss: losses.append(loss), **kwargs)
        log["windows"].append({"lm_s": time.perf_counter() - start, "iterations": result.iterations,
                               "loss": [losses[i] for i in (0, len(losses) // 2, -1)] if losses else [],
                               "stop": result.message})
        return result

    adapter.window_functions, adapter.levenberg_marquardt = functions, optimise


def main(case_name: str, options_json: str) -> None:
    case = CASES[case_name]
    options = {"threads": 2, **json.loads(options_json)}
    log: dict = {"residual_s": [], "jacobian_s": [], "windows": []}
    _instrument(log)
    solver = make_solver("reduced-pinn", case, options.pop("config", "default"), **options)
    report = solver.fit()
    print(f"fit {report.seconds:.1f} s: {report.message}")
    lm_s = sum(w["lm_s"] for w in log["windows"])
    log["jacobian_s"] = log["jacobian_s"] or [np.nan]  # the dense path (k <= width) is not timed apart
    print(f"LM {lm_s:.1f} s; residuals {len(log['residual_s'])} calls {sum(log['residual_s']):.1f} s "
          f"(first {log['residual_s'][0]:.2f} s); J^T J and J^T r {len(log['jacobian_s'])} calls "
          f"{sum(log['jacobian_s']):.1f} s (first {log['jacobian_s'][0]:.2f} s, median "
          f"{np.median(log['jacobian_s']):.3f} s); linear algebra and the rest of LM "
          f"{lm_s - sum(log['residual_s']) - sum(log['jacobian_s']):.1f} s")
    for w, window in enumerate(log["windows"]):
        print(f"  window {w + 1}: {window['iterations']} it {window['lm_s']:.1f} s, loss first/middle/last "
              f"{' '.join(f'{x:.3g}' for x in window['loss'])} ({window['stop']})")
    t, P1 = scaling_grid(case, DEFAULT)
    ref_delta = cached_reference(case, t, P1, Path(".cache/reference"))[0]
    delta = solver.solve(t, P1).delta
    U, delta0 = np.asarray(solver._args[1]), np.asarray(case.delta0)
    projected = delta0 + (ref_delta - delta0) @ U @ U.T
    ref = relative_angles(case, ref_delta)
    pred, floor = relative_angles(case, delta), relative_angles(case, projected)
    per_window = [metrics.rel_l2(pred[:, (t >= s) & (t <= s + 1)], ref[:, (t >= s) & (t <= s + 1)])
                  for s in range(int(np.ceil(case.t_final)))]
    per_p1 = [metrics.rel_l2(pred[i], ref[i]) for i in range(P1.size)]
    print(f"COI rel. L2 {metrics.rel_l2(pred, ref):.3g} (basis floor {metrics.rel_l2(floor, ref):.3g}); "
          f"per second of t: {' '.join(f'{x:.2g}' for x in per_window)}; per P1: "
          f"{' '.join(f'{x:.2g}' for x in per_p1)}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
