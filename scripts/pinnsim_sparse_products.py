"""pinnsim's network products, dense against sparse: the matrix-free Gauss-Newton multiplies by
Z = (Y_bb^-1)[at, at] (n, n), kept dense (`solvers.pinn.simulator.impedance`); the same product by
the SuperLU factors of Y_bb (scatter to the machine buses, solve, gather) never forms Z.

Per case and number of right-hand-side columns (a step's collocation points times the P1 of a
query), the best of `--repeats` timings of each (s), alone on the machine, and the largest
difference between the two (p.u.). Rows to OUT/sparse_products.csv, the command to
OUT/sparse_products.json.

    python scripts/pinnsim_sparse_products.py --out results/pinnsim-sparse-products [--case NAME ...]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import splu

from solvers.pinn.simulator import impedance
from systems.cases import CASES

COLUMNS = (4, 16, 64, 448)  # one P1 at s = 4 collocation points, then 4, 16, 112 P1 (the grid's padded count)


def _best(f, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return min(times)


def measure(name: str, repeats: int) -> list[dict]:
    """The rows of case `name` (see the module docstring)."""
    network = CASES[name].network
    Z, lu = impedance(network), splu(network.Y_bb.tocsc())
    at, nb = np.asarray(network.at), network.n_buses
    rng, rows = np.random.default_rng(0), []
    for cols in COLUMNS:
        X = rng.normal(size=(at.size, cols)) + 1j * rng.normal(size=(at.size, cols))

        def dense(X=X):
            return Z @ X

        def sparse(X=X, cols=cols):
            rhs = np.zeros((nb, cols), complex)
            rhs[at] = X
            return lu.solve(rhs)[at]

        rows.append({"case": name, "machines": int(at.size), "buses": int(nb), "nnz_lu": int(lu.L.nnz + lu.U.nnz),
                     "columns": cols, "dense_s": _best(dense, repeats), "sparse_s": _best(sparse, repeats),
                     "max_difference": float(np.abs(dense() - sparse()).max())})
        print(rows[-1])
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--case", nargs="+", default=["case1354pegase", "case9241pegase"])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    rows = [row for name in args.case for row in measure(name, args.repeats)]
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "sparse_products.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    command = " ".join(["python scripts/pinnsim_sparse_products.py", *(argv if argv is not None else sys.argv[1:])])
    (args.out / "sparse_products.json").write_text(json.dumps({"command": command}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
