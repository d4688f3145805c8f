"""Compile once, run many times: the cost of a sweep case and of the rig calibration.

1. Sweep case on the PVG 32 rig (87 unknowns): a steady state at another pump flow and supply
   voltage, (a) building and compiling the rig for the case, (b) reusing one compiled system
   with :meth:`System.with_params` (values read from a rebuilt circuit with
   :meth:`System.params_from`, or set by name). Medians of several cases.
2. ``calibrate_rig()``: wall time, model evaluations and Jacobians, estimates and intervals.

Run: ``python benchmarks/bench_params.py`` (prints Markdown).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def sweep_case_costs(cases: int = 5) -> dict:
    from pvgraph.circuits.pvg32.parameters import report_tuned, with_values
    from pvgraph.circuits.rig import build_rig, laminar_load
    from pvgraph.analysis import steady_state
    from pvgraph.units import lpm

    base = report_tuned()

    def params(k):
        return with_values(base, {"rig.pump_flow": lpm(15.0 + 0.5 * k),
                                  "rig.supply_voltage": 11.0 + 0.2 * k})

    def rig(p):
        return build_rig(p, load=laminar_load(p, l2_open=True), U_input=4.24)

    compiled = rig(base).compile()
    warm = steady_state(compiled, tol=1e-10).y
    full, reuse, by_name, values = [], [], [], []
    for k in range(cases):
        p = params(k)
        t0 = time.perf_counter()
        op_a = steady_state(rig(p).compile(), y0=warm, tol=1e-10)
        full.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        system = compiled.with_params(compiled.params_from(rig(p)))
        op_b = steady_state(system, y0=warm, tol=1e-10)
        reuse.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        op_c = steady_state(compiled, params={"pump.Q0": p.rig.pump_flow}, y0=warm, tol=1e-10)
        by_name.append(time.perf_counter() - t0)
        values.append((op_a["load.f.port.p"], op_b["load.f.port.p"], op_c["load.f.port.p"]))
    worst = max(abs(a - b) for a, b, _ in values)
    return {"full": statistics.median(full), "reuse": statistics.median(reuse),
            "by_name": statistics.median(by_name), "worst_diff_Pa": worst}


def calibration() -> dict:
    from pvgraph.circuits.calibration import calibrate_rig
    t0 = time.perf_counter()
    result, _ = calibrate_rig()
    wall = time.perf_counter() - t0
    return {"wall": wall, "result": result}


def main():
    from _machine import machine
    print(f"machine: {machine()}\n")
    s = sweep_case_costs()
    print("| sweep case (rig steady state) | median [s] | share of build + compile |")
    print("|---|---|---|")
    print(f"| build + compile + steady state | {s['full']:.3f} | 100 % |")
    print(f"| rebuild, params_from, with_params + steady state | {s['reuse']:.3f} | "
          f"{100 * s['reuse'] / s['full']:.1f} % |")
    print(f"| with_params by name + steady state | {s['by_name']:.3f} | "
          f"{100 * s['by_name'] / s['full']:.1f} % |")
    print(f"\nlargest difference in Pf between compiled-per-case and reused: "
          f"{s['worst_diff_Pa']:.2e} Pa\n")
    c = calibration()
    r = c["result"]
    print(f"calibrate_rig(): {c['wall']:.1f} s wall, {r.nfev} model evaluations, "
          f"{r.njev} model Jacobians\n")
    print("```")
    print(r.table())
    print("```")


if __name__ == "__main__":
    main()
