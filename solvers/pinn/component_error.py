"""The component PINN's one-step error against the exact machine response, over a held-out test set.

A test input is a step's start (phi0 over the full circle, slip, the voltage polynomial's theta2,
v0, v1, v2) and a machine (mu, kappa, p), drawn uniformly from the network's `Domain` box with
|v1| <= v1 - 2 v2_max h (so that the re-centred v1 of every network interval stays inside); theta0
and theta1 are 0 without loss (the invariances of `solvers.pinn.component`). The PINN answers as
the simulator does, composing ceil(h / net_h) network intervals (`solvers.pinn.simulator`); the
truth is scipy's DOP853 at rtol = atol = 1e-12 of the single machine with that voltage. An input
whose exact trajectory takes an interval's inputs out of the box (a slip beyond its range) is
outside the step's domain: counted, not measured.

    python -m solvers.pinn.component_error --out results/pinnsim-component [--samples 400] [--seed 7]
        [--config faults] [--option KEY=VALUE ...]

writes one row per time bin (`component_error.csv`) of the `pinnsim` network of the default options
(or of the config's, e.g. "faults" on the default case's fault case, or of those `--option` sets,
e.g. `--option rate_weight=0.2`), loaded or trained as `fit` does.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from scipy.integrate import solve_ivp

from solvers.pinn.component import INPUTS, KAPPA, MU, PHI0, SLIP, THETA2, V0, V1, V2, Component, P
from solvers.pinn.simulator import chain, state_at, substeps

__all__ = ["one_step_error", "option_argument", "test_inputs"]


def test_inputs(component: Component, h: float, samples: int, seed: int) -> np.ndarray:
    """`samples` step inputs (samples, 9) from `seed`, the test set of the module docstring."""
    domain = component.domain
    x = domain.sample(samples, np.random.default_rng(np.random.SeedSequence([seed, 0x7E57])))
    x[:, V1] *= max(domain.v1 - 2.0 * domain.v2 * h, 0.0) / domain.v1
    return x


def _exact(x: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(phi, phi') (2, len(times)) of one input, DOP853 at 1e-12."""
    def rhs(t, y):
        v = x[V0] + t * (x[V1] + t * x[V2])
        return [y[1], (x[P] - x[KAPPA] * y[1] - v * np.sin(y[0] - x[THETA2] * t * t)) / x[MU]]

    sol = solve_ivp(rhs, (0.0, times[-1]), [x[PHI0], x[SLIP]], method="DOP853", t_eval=times, rtol=1e-12, atol=1e-12)
    return sol.y


def _row(t_from: float, t_to: float, worst: np.ndarray) -> dict:
    """Median, 99th percentile and max over the inputs of their largest errors (inputs, 2) in a bin."""
    out: dict = {"t_from_s": float(t_from), "t_to_s": float(t_to)}
    for k, (name, unit) in enumerate((("delta", "rad"), ("omega", "rad_s"))):
        out.update({f"{name}_median_{unit}": float(np.median(worst[:, k])),
                    f"{name}_p99_{unit}": float(np.quantile(worst[:, k], 0.99)), f"{name}_max_{unit}": float(worst[:, k].max())})
    return out


def one_step_error(component: Component, h: float, samples: int, seed: int, n_t: int = 50) -> dict:
    """Errors of delta (rad) and omega (rad/s) at n_t times of (0, h], per input the largest in each
    of five equal bins of t, and over the inputs of the step's domain their median, 99th percentile and max."""
    count, sub = substeps(component, h)
    x = test_inputs(component, h, samples, seed)
    times = h * np.arange(1, n_t + 1) / n_t
    ts = sub * np.arange(count)  # the network intervals' starts
    grid = np.union1d(times, ts[1:])
    start = time.perf_counter()
    path = np.array([_exact(row, grid) for row in x])  # (samples, 2, len(grid))
    exact_s = time.perf_counter() - start
    exact = path[:, :, np.searchsorted(grid, times)]
    # inside: every interval's slip and effective power within the box along the exact path
    rate = np.concatenate([x[:, SLIP, None], path[:, 1, np.searchsorted(grid, ts[1:])]], axis=1)
    slip = rate - 2.0 * x[:, THETA2, None] * ts
    effective = x[:, P, None] - x[:, KAPPA, None] * 2.0 * x[:, THETA2, None] * ts
    voltage = x[:, V0, None] + ts * (x[:, V1, None] + ts * x[:, V2, None])
    lo, hi = component.domain.bounds()
    leaves = {"slip": ~(np.abs(slip) <= hi[SLIP]).all(1), "p": ~((effective >= lo[P]) & (effective <= hi[P])).all(1),
              "v0": ~((voltage >= lo[V0]) & (voltage <= hi[V0])).all(1)}
    inside = ~(leaves["slip"] | leaves["p"] | leaves["v0"])

    def pinn(theta, row):
        coef = jnp.stack([0.0, 0.0, row[THETA2], row[V0], row[V1], row[V2]])
        starts, _ = chain(component, count, sub, theta, coef, row[MU], row[KAPPA], row[P], row[PHI0], row[SLIP])
        return jax.vmap(lambda t: state_at(component, sub, theta, coef, row[MU], row[KAPPA], row[P], starts, t))(times)

    with jax.enable_x64(True):
        both = np.asarray(jax.jit(jax.vmap(pinn, (None, 0)))(jnp.asarray(component.theta), jnp.asarray(x)))
    error = np.abs(np.transpose(both, (0, 2, 1)) - exact)[inside]  # (kept, 2, n_t)
    rows = []
    edges = np.linspace(0.0, h, 6)
    for lo_t, hi_t in itertools.pairwise(edges):
        sel = (times > lo_t + 1e-12) & (times <= hi_t + 1e-12)
        worst = error[:, :, sel].max(-1)  # (kept, 2)
        rows.append(_row(lo_t, hi_t, worst))
    rows.append(_row(0.0, h, error.max(-1)))
    return {"rows": rows, "samples": samples, "measured": int(inside.sum()), "outside": int((~inside).sum()),
            "outside_by_input": {name: int(mask.sum()) for name, mask in leaves.items()},
            "exact_seconds": exact_s, "intervals": count, "inputs": list(INPUTS)}


def option_argument(text: str) -> tuple[str, object]:
    """"KEY=VALUE" -> (KEY, VALUE), VALUE read as JSON where it is JSON, as text otherwise."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"an option is KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="The pinnsim component PINN's one-step error (rows to --out).")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=400)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--h", type=float, default=0.25)
    parser.add_argument("--case", default=None, help="any case the config takes (the network does not depend "
                        "on it; default wscc9, or its fault case for a config made for fault cases)")
    parser.add_argument("--config", default="default", help="a pinnsim config (its domain and options)")
    parser.add_argument("--option", type=option_argument, action="append", default=[], metavar="KEY=VALUE",
                        help="a pinnsim option of the network measured (repeatable), e.g. rate_weight=0.2")
    args = parser.parse_args(argv)
    from solvers import make_solver
    from solvers.pinn.pinnsim import PinnSim
    from systems.cases import FAULT_SCENARIO, STEP_SCENARIO
    from systems.faults import FAULT_CASES

    options = dict(args.option)
    if "h" in options:
        parser.error("the step is --h, not --option h=...")
    try:
        scenario = FAULT_SCENARIO if PinnSim.CASE_SCENARIOS.get(args.config) == {FAULT_SCENARIO} else STEP_SCENARIO
        case = args.case or ("wscc9" if scenario == STEP_SCENARIO else FAULT_CASES["wscc9"][0])
        solver = make_solver("pinnsim", case, args.config, **options, h=args.h)
    except (ValueError, RuntimeError) as exc:  # RuntimeError: JAX not installed (SolverUnavailable)
        parser.error(str(exc))
    assert isinstance(solver, PinnSim)
    report = solver.fit()
    result = one_step_error(solver.component, args.h, args.samples, args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "component_error.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(result["rows"][0]))
        writer.writeheader()
        writer.writerows(result["rows"])
    info = {key: value for key, value in result.items() if key != "rows"}
    info.update({"command": " ".join(["python -m solvers.pinn.component_error", *(argv or sys.argv[1:])]),
                 "fit_message": report.message, "component_record": solver.component.record,
                 "config": args.config, "options": {k: v for k, v in solver.options.items()}})
    (args.out / "component_error.json").write_text(json.dumps(info, indent=1, default=str) + "\n")
    for row in result["rows"]:
        print(row)
    print({k: v for k, v in info.items() if k in ("samples", "measured", "outside", "outside_by_input")})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
