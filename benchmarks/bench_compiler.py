"""Compiler and generated-code speed: compile time, residual and Jacobian evaluation time.

Builds a synthetic circuit of N copies of a ten-component hydraulic sub-circuit (a pump branch
with volume nodes, turbulent and laminar orifices, a pressure-relief-like restriction and a
tank), so that N = 4 is about 40 components, and measures for N = 1, 4, 16, 64:

- compile time (flatten, connection sets, alias elimination, checks, code generation),
- one residual evaluation and one Jacobian evaluation (medians of many repeats),
- the ratio Jacobian / residual.

Run: ``python benchmarks/bench_compiler.py`` (prints a Markdown table).
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from pvgraph.components import FlowSource, LaminarOrifice, Orifice, Tank, VolumeNode  # noqa: E402
from pvgraph import Circuit  # noqa: E402
from pvgraph.units import litre, lpm, lpm_per_bar, mm2  # noqa: E402


def branch(name: str) -> Circuit:
    """Ten components: a source, three volumes, five restrictions and a tank."""
    c = Circuit(name)
    src = c.add("pump", FlowSource(Q=lpm(10)))
    v1 = c.add("v1", VolumeNode(V=litre(0.5)))
    v2 = c.add("v2", VolumeNode(V=litre(0.05)))
    v3 = c.add("v3", VolumeNode(V=litre(0.05)))
    o1 = c.add("o1", Orifice(A=mm2(3)))
    o2 = c.add("o2", Orifice(A=mm2(2)))
    o3 = c.add("o3", LaminarOrifice(K=lpm_per_bar(0.3)))
    o4 = c.add("o4", Orifice(A=mm2(1)))
    o5 = c.add("o5", Orifice(A=mm2(4)))
    tank = c.add("tank", Tank())
    c.connect(src.port, v1.port, o1.a, o4.a)
    c.connect(o1.b, v2.port, o2.a, o3.a)
    c.connect(o2.b, o3.b, v3.port, o5.a)
    c.connect(o4.b, o5.b, tank.port)
    return c


def build(copies: int) -> Circuit:
    top = Circuit(f"bench{copies}")
    for k in range(copies):
        top.add(f"b{k}", branch(f"b{k}"))
    return top


def median_time(fn, repeats: int, inner: int) -> float:
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        samples.append((time.perf_counter() - t0) / inner)
    return statistics.median(samples)


def main():
    print(f"Machine: {machine()}\n")
    print("| copies | components | unknowns | Jacobian nnz | compile [ms] | residual [us] "
          "| Jacobian [us] | Jacobian / residual | residual per unknown [us] |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    rng = np.random.default_rng(0)
    for copies in (1, 4, 16, 64):
        compile_times = []
        for _ in range(5):
            circuit = build(copies)
            t0 = time.perf_counter()
            system = circuit.compile()
            compile_times.append(time.perf_counter() - t0)
        y = system.nominal * rng.uniform(0.5, 1.5, system.n)
        yp = system.nominal * rng.normal(size=system.n)
        inner = max(10, 2000 // copies)
        t_res = median_time(lambda: system.residual(0.0, y, yp), 7, inner)
        jac = system.solver_jacobian()
        t_jac = median_time(lambda: jac(0.0, y, yp, 1e3), 7, inner)
        print(f"| {copies} | {10 * copies} | {system.n} | {len(system._rows)} | "
              f"{1e3 * statistics.median(compile_times):.1f} | {1e6 * t_res:.1f} | "
              f"{1e6 * t_jac:.1f} | {t_jac / t_res:.2f} | {1e6 * t_res / system.n:.3f} |")


if __name__ == "__main__":
    main()
