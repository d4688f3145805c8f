"""Measure one route to compiled residuals: numba on pvgraph's generated Python.

The generated residual and Jacobian are straight-line Python over ``y``, ``yp``, ``d`` and the
parameter vector ``P``. For circuits without runtime tables (every entry of ``P`` a float),
the same source compiles unchanged with ``numba.njit`` when called with numpy arrays. This
script times, for the chain of ``bench_scaling.py`` and the branch circuit of
``bench_compiler.py``: the numba compile time of the residual, and one residual evaluation in
pure Python (lists, as the solver calls it) against the numba version (arrays).

Not a dependency of pvgraph: run only where numba is installed.
Run: ``python benchmarks/bench_numba.py``.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def numba_residual(system):
    import numba
    src = next(s for s in system._sources if s.startswith("def residual"))
    ns = {"_sqrt": math.sqrt, "_exp": math.exp, "_log": math.log, "_tanh": math.tanh,
          "_sin": math.sin, "_cos": math.cos, "_atan": math.atan, "_nan": math.nan,
          "_inf": math.inf}
    exec(compile(src.replace("return [", "return np.array(["). replace("\n    ]\n", "\n    ])\n"),
                 "<numba residual>", "exec"), {**ns, "np": np}, ns)
    return numba.njit(cache=False)(ns["residual"])


def median(fn, repeats=7, inner=200):
    out = []
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(inner):
            fn()
        out.append((time.process_time() - t0) / inner)
    return statistics.median(out)


def main():
    from _machine import machine
    from bench_compiler import build
    from bench_scaling import chain
    print(f"machine: {machine()}\n")
    print("| circuit | unknowns | numba compile [s] | Python residual [us] | numba residual [us] "
          "| speed-up |")
    print("|---|---|---|---|---|---|")
    for label, circuit in (("branch x 4", build(4)), ("branch x 16", build(16)),
                           ("chain 100", chain(100))):
        s = circuit.compile()
        if any(not isinstance(v, float) for v in s._P):
            print(f"| {label} | {s.n} | runtime tables: not supported by this route |")
            continue
        y, yp = s.y0 + s.nominal, np.zeros(s.n)
        P = np.array(s._P)
        d = np.array(s.modes, dtype=float) if s.modes else np.zeros(1)
        t0 = time.perf_counter()
        fn = numba_residual(s)
        r_nb = fn(0.0, y, yp, d, P)
        t_jit = time.perf_counter() - t0
        r_py = s.residual(0.0, y, yp)
        assert np.allclose(r_nb, r_py, rtol=1e-12, atol=0.0, equal_nan=True)
        t_py = median(lambda: s.residual(0.0, y, yp))
        t_nb = median(lambda: fn(0.0, y, yp, d, P))
        print(f"| {label} | {s.n} | {t_jit:.1f} | {1e6 * t_py:.1f} | {1e6 * t_nb:.2f} | "
              f"{t_py / t_nb:.0f}x |")


if __name__ == "__main__":
    main()
