"""Simulation cost of a K-section PVG 32 stack: is it linear in K?

Builds the stack of ``examples/pvg32_stack.py`` with K PVB sections (each with its PVE, its
laminar rig load, its input voltage and its LS shuttle), compiles it once, and simulates
``T_END`` seconds at ``rtol = 1e-4`` from rest. Reported per K: unknowns, events, compile time,
simulation wall and CPU time, steps, residual evaluations, time per step, and the share of the
simulation spent evaluating event functions (cProfile, second run).

Run: ``python benchmarks/bench_stack.py [K ...]`` (default 8 64; prints a Markdown table).
"""

from __future__ import annotations

import cProfile
import pstats
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "examples"))

T_END = 0.05
RTOL = 1e-4


def voltages(k: int) -> dict:
    """Inputs spread over 4.4-5.2 V (all sections feed port B, at different flows)."""
    return {f"s{i}": 4.4 + 0.8 * i / max(k - 1, 1) for i in range(k)}


def run(k: int) -> dict:
    from pvg32_stack import build_stack
    from pvgraph.simulate import simulate
    circuit = build_stack(voltages=voltages(k))
    t0 = time.perf_counter()
    system = circuit.compile()
    t_compile = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    sol = simulate(system, T_END, rtol=RTOL)
    t_sim, c_sim = time.perf_counter() - t0, time.process_time() - c0
    prof = cProfile.Profile()
    prof.enable()
    simulate(system, T_END, rtol=RTOL)
    prof.disable()
    st = pstats.Stats(prof)
    total = sum(v[3] for k_, v in st.stats.items() if k_[2] == "simulate")
    events = sum(v[3] for k_, v in st.stats.items()
                 if k_[0].endswith("events.py") and k_[2] in ("evaluate", "crossings"))
    steps = sol.stats.get("nsteps", sol.stats.get("steps", len(sol.t)))
    return {"K": k, "n": system.n, "events": len(system.event_specs), "compile": t_compile,
            "sim": t_sim, "cpu": c_sim, "steps": steps, "nres": sol.stats.get("nre"),
            "event_share": events / total if total else float("nan")}


def main(ks):
    from _machine import machine
    rows = [run(k) for k in ks]
    print(f"machine: {machine()}\n")
    print(f"T_END = {T_END} s, rtol = {RTOL}\n")
    print("| K | unknowns | events | compile [s] | simulate wall [s] | simulate CPU [s] | steps | "
          "residuals | per step [ms] | events share |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['K']} | {r['n']} | {r['events']} | {r['compile']:.1f} | {r['sim']:.2f} | "
              f"{r['cpu']:.2f} | "
              f"{r['steps']} | {r['nres']} | {1e3 * r['sim'] / max(r['steps'], 1):.2f} | "
              f"{100 * r['event_share']:.0f} % |")
    if len(rows) >= 2:
        a, b = rows[0], rows[-1]
        print(f"\ntime(K = {b['K']}) / time(K = {a['K']}) = {b['sim'] / a['sim']:.1f} wall, "
              f"{b['cpu'] / a['cpu']:.1f} CPU (K ratio {b['K'] / a['K']:.0f}; CPU per step "
              f"{b['cpu'] / b['steps'] / (a['cpu'] / a['steps']):.1f})")


if __name__ == "__main__":
    main([int(x) for x in sys.argv[1:]] or [8, 64])
