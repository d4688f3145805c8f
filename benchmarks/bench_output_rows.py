"""What solving the algebraic variables at output times costs, and what it buys.

``simulate`` leaves the algebraic variables out of the error test; between steps (rows at
``t_eval``, event conditions) it solves them from the equations at the interpolated states
(``pvgraph.solver.solve._consistent_interpolant``) instead of interpolating them. This runs
PVG 32 rig test 2 for 1 s (Python-evaluated residual, the default) with 101, 1001 and 10001
output times, with the rows solved (the default) and interpolated (the interpolant put back),
interleaved, and reports the median wall time of ``simulate``, the residual evaluations, and
the error of the algebraic variables at the rows against a run at rtol 1e-10 (largest, and
the 99th percentile over rows and variables, in tolerance units ``rtol (|y| + nominal)``).

Usage: ``python benchmarks/bench_output_rows.py [--repeats 5]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import machine  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    import pvgraph.solver.solve as S
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    from pvgraph.simulate import simulate
    p = report_tuned()
    system = build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                       U_input=4.24).compile()
    solved = S._consistent_interpolant

    def interpolated(integ, *rest):
        return integ.interpolate

    alg = np.asarray(system.algebraic, dtype=bool)
    print(f"rig test 2, 1 s, rtol 1e-6, on {machine()}; medians of {args.repeats} "
          f"interleaved runs")
    print(f"{'rows':>6} {'how':>12} {'wall [ms]':>10} {'residuals':>10} "
          f"{'alg. error max / p99 [tol]':>28}")
    for n_rows in (101, 1001, 10001):
        t = np.linspace(0.0, 1.0, n_rows)
        ref = simulate(system, 1.0, t_eval=t, rtol=1e-10)
        times = {"solved": [], "interpolated": []}
        last = {}
        for _ in range(args.repeats):
            for how, fn in (("solved", solved), ("interpolated", interpolated)):
                S._consistent_interpolant = fn
                t0 = time.perf_counter()
                sol = simulate(system, 1.0, t_eval=t)
                times[how].append(time.perf_counter() - t0)
                last[how] = sol
        S._consistent_interpolant = solved
        scale = 1e-6 * (np.abs(ref.y) + system.nominal)
        for how in ("solved", "interpolated"):
            sol = last[how]
            err = (np.abs(sol.y - ref.y) / scale)[:, alg]
            print(f"{n_rows:>6} {how:>12} {statistics.median(times[how]) * 1e3:>10.1f} "
                  f"{sol.stats['nre']:>10} {err.max():>14.3g} / {np.percentile(err, 99):<10.3g}")


if __name__ == "__main__":
    main()
