"""A caller's sparse Jacobian without a pattern: kept sparse (SuperLU) against densified.

The heat equation by the method of lines (N = 400 points, u' = L u) with ``solve_dae``: finite
differences, ``jac`` returning scipy.sparse without ``jac_sparsity``, the same with
``jac_sparsity``, and a ``jac`` returning the dense matrix (what a sparse ``jac`` without a
pattern was factorised as before). Medians of ``--repeats`` runs, the four alternated.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_sparse_jac.py [--repeats 7]``
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from pvgraph.solver import solve_dae  # noqa: E402

N = 400


def main(repeats: int) -> None:
    h = 1.0 / (N + 1)
    x = np.linspace(h, 1 - h, N)
    lap = sp.diags([np.ones(N - 1), -2 * np.ones(N), np.ones(N - 1)], [-1, 0, 1],
                   format="csr") / h ** 2
    eye = sp.identity(N, format="csc")
    u0 = np.sin(np.pi * x)

    def fun(t, u, up):
        return up - lap @ u

    def jac_sparse(t, u, up, c):
        return (c * eye - lap).tocsc()

    def jac_dense(t, u, up, c):
        return (c * eye - lap).toarray()

    cases = {"finite differences": {}, "jac sparse, no pattern": {"jac": jac_sparse},
             "jac sparse + jac_sparsity": {"jac": jac_sparse, "jac_sparsity": (eye + lap) != 0},
             "jac dense": {"jac": jac_dense}}
    times = {k: [] for k in cases}
    exact = u0 * np.exp(-np.pi ** 2 * 0.1 * (np.sin(np.pi * h / 2) / (np.pi * h / 2)) ** 2)
    err = {}
    for _ in range(repeats):
        for label, kw in cases.items():
            t0 = time.perf_counter()
            r = solve_dae(fun, (0.0, 0.1), u0, lap @ u0, rtol=1e-8, atol=1e-11, t_eval=[0.1],
                          **kw)
            times[label].append(time.perf_counter() - t0)
            err[label] = float(np.max(np.abs(r.y[-1] - exact)))
    print(f"machine: {machine()}\n")
    base = statistics.median(times["jac sparse, no pattern"])
    print("| Jacobian | median [s] | / sparse without pattern | max error at t = 0.1 |")
    print("|---|---|---|---|")
    for label in cases:
        med = statistics.median(times[label])
        print(f"| {label} | {med:.4f} | {med / base:.2f} | {err[label]:.2e} |")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(int(args[1]) if args[:1] == ["--repeats"] else 7)
