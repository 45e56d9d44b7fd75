"""The product pinnsim's matrix-free Newton repeats, the network's impedance seen from the machine
terminals times a block of columns (one column per P1 and collocation point), made three ways on
one case: by the dense Z (n x n) in complex128 and in complex64 (`solvers.pinn.simulator`, the
option cg_dtype), and by the SuperLU factors of the bus admittance Y_bb (the right-hand sides put
on the terminal buses, the solution read there: the network kept sparse).

Per way and number of columns: the median seconds of --repeats products (after one untimed), the
factors' or Z's stored numbers, and the largest difference from the dense complex128 product
relative to its largest entry. Rows to OUT/pinnsim_products.csv, the command to
OUT/pinnsim_products.json.

    python scripts/pinnsim_products.py --out results/pinnsim-products --case case9241pegase
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from harness.report.files import write_script_rows
from solvers.pinn.simulator import impedance
from systems.cases import CASES


def _median_seconds(product, repeats: int) -> float:
    product()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        product()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--case", required=True, choices=sorted(CASES), metavar="NAME")
    parser.add_argument("--columns", type=int, nargs="+", default=[4, 64, 448],
                        help="columns a product (4 collocation points x the P1 of a call, padded: 1, 16, 112)")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    import jax
    import jax.numpy as jnp
    from scipy.sparse.linalg import splu

    jax.config.update("jax_enable_x64", True)
    network = CASES[args.case].network
    at, n = np.asarray(network.at), np.asarray(network.at).size
    Z = impedance(network)
    lu = splu(network.Y_bb.tocsc())
    rng = np.random.default_rng(0)
    rows = []
    for cols in args.columns:
        x = rng.standard_normal((n, cols)) + 1j * rng.standard_normal((n, cols))
        rhs = np.zeros((network.n_buses, cols), complex)
        rhs[at] = x
        exact = Z @ x
        ways = {}
        for name, dtype in (("dense complex128", jnp.complex128), ("dense complex64", jnp.complex64)):
            Zd, xd = jnp.asarray(Z, dtype), jnp.asarray(x, dtype)
            product = jax.jit(lambda A, b: A @ b)
            ways[name] = (lambda Zd=Zd, xd=xd, product=product: np.asarray(product(Zd, xd).block_until_ready()),
                          n * n)
        ways["SuperLU of Y_bb"] = (lambda rhs=rhs: lu.solve(rhs)[at], lu.L.nnz + lu.U.nnz)
        for name, (product, stored) in ways.items():
            seconds = _median_seconds(product, args.repeats)
            error = float(np.abs(product() - exact).max() / np.abs(exact).max())
            rows.append({"case": args.case, "machines": n, "buses": network.n_buses, "columns": cols, "way": name,
                         "median_s": seconds, "stored_numbers": stored, "max_rel_difference": error})
            print(rows[-1], flush=True)
    command = " ".join(["python scripts/pinnsim_products.py", *(argv if argv is not None else sys.argv[1:])])
    write_script_rows(args.out, "pinnsim_products", rows, {"command": command})
    return 0


if __name__ == "__main__":
    sys.exit(main())
