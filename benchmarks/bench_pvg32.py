"""PVG 32 rig speed: the whole validation, and solenoid-step test 2 over 1 s against SUNDIALS IDA.

- ``pvgraph validate`` equivalent: all 19 scenarios on 2 worker processes (median of 3 runs).
- Step test 2 (L2 opening at U = 4.24 V): start from the settled state (closed L2), switch L2 at
  t = 10 ms, run 1 s at rtol = 1e-6; pvgraph's solver and SUNDIALS IDA (scikit-sundae) on the
  same compiled System, median of 5 runs each, and the difference of their final load pressure.

Run: ``python benchmarks/bench_pvg32.py``
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from pvgraph.circuits.pvg32.parameters import report_tuned  # noqa: E402
from pvgraph.circuits.rig import build_rig, laminar_load  # noqa: E402
from pvgraph.circuits.validation import validate  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402


def timed(fn, repeats):
    samples, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples), out


def main():
    print(f"Machine: {machine()}\n")
    t_val, results = timed(lambda: validate(report_tuned(), workers=2), 3)
    failed = [r.name for r in results if r.error]
    print(f"validate, 19 scenarios, 2 workers: median {t_val:.2f} s wall "
          f"(failed: {failed or 'none'})\n")

    p = report_tuned()
    settle = build_rig(p, load=laminar_load(p, L1="small", L3="small"), U_input=4.24).compile()
    y_settled = simulate(settle, 8.0, rtol=1e-6).y[-1]
    step = build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                     U_input=4.24).compile()
    assert step.names == settle.names
    t_eval = np.linspace(0.0, 1.01, 102)
    rows = []
    finals = {}
    for solver in ("pvgraph", "ida"):
        wall, sol = timed(lambda: simulate(step, 1.01, rtol=1e-6, y0=y_settled, t_eval=t_eval,
                                           solver=solver), 5)
        finals[solver] = dict(zip(np.round(sol.t, 12), sol["load.f.port.p"]))
        rows.append((solver, wall, sol.stats.get("nsteps"), sol.stats.get("nre")))
    print("| solver | wall [s] | steps | residual evaluations | faster than real time |")
    print("|---|---:|---:|---:|---:|")
    for solver, wall, steps, nre in rows:
        print(f"| {solver} | {wall:.3f} | {steps} | {nre} | {1.0 / wall:.1f}x |")
    ratio = rows[0][1] / rows[1][1]
    # compare where both returned a point (the IDA backend skips an output time that coincides
    # with the switching event)
    common = sorted(set(finals["pvgraph"]) & set(finals["ida"]))
    diff = max(abs(finals["pvgraph"][t] - finals["ida"][t]) for t in common) / 1e5
    print(f"\nwall-time ratio pvgraph / IDA: {ratio:.2f}; largest difference of the load pressure "
          f"Pf over the run: {diff:.4f} bar")


if __name__ == "__main__":
    main()
