"""Compiler scaling: wide connection sets, long chains, and the cost of the generated code.

Cases (each compiled in a fresh subprocess, so that its peak memory is its own):

- ``wide M``: one volume node joining a pump and M turbulent orifices, whose other ends all join
  the tank: two connection sets of M + 1 ports;
- ``chain N``: a pump feeding N volume + orifice pairs in series, ending at the tank.

For each: compile time, peak resident memory of the process (``ru_maxrss``), the size of the
generated source, and one residual and one Jacobian evaluation (medians).

Run: ``python benchmarks/bench_scaling.py [wide:300,3000 chain:5000 ...]`` (Markdown table).
"""

from __future__ import annotations

import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

DEFAULT = ["wide:100", "wide:300", "wide:1000", "wide:3000", "wide:10000",
           "chain:1000", "chain:5000", "chain:20000"]


def wide(m: int):
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    from pvgraph import Circuit
    from pvgraph.units import litre, lpm, mm2
    c = Circuit(f"wide{m}")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    tank = c.add("tank", Tank())
    orifices = [c.add(f"o{k}", Orifice(A=mm2(1.0 + 0.001 * k))) for k in range(m)]
    c.connect(pump.port, node.port, *[o.a for o in orifices])
    c.connect(tank.port, *[o.b for o in orifices])
    return c


def chain(n: int):
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    from pvgraph import Circuit
    from pvgraph.units import litre, lpm, mm2
    c = Circuit(f"chain{n}")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    prev = pump.port
    for k in range(n):
        v = c.add(f"v{k}", VolumeNode(V=litre(0.01)))
        o = c.add(f"o{k}", Orifice(A=mm2(20.0)))
        c.connect(prev, v.port, o.a)
        prev = o.b
    tank = c.add("tank", Tank())
    c.connect(prev, tank.port)
    return c


def median_time(fn, repeats=5):
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def run_case(case: str) -> dict:
    kind, size = case.split(":")
    circuit = {"wide": wide, "chain": chain}[kind](int(size))
    t0, c0 = time.perf_counter(), time.process_time()
    system = circuit.compile()
    t_compile, c_compile = time.perf_counter() - t0, time.process_time() - c0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # MB (Linux: kB)
    y, yp = system.y0 + 1.0, np.zeros(system.n)
    t_res = median_time(lambda: system.residual(0.0, y, yp))
    t_jac = median_time(lambda: system.jacobian_values(0.0, y, yp, 10.0))
    return {"case": case, "n": system.n, "nnz": len(system._rows), "compile_s": t_compile, "compile_cpu_s": c_compile,
            "rss_mb": rss, "source_mb": len(system.source()) / 1e6, "residual_ms": 1e3 * t_res,
            "jacobian_ms": 1e3 * t_jac}


def main(cases):
    from _machine import machine
    rows = []
    for case in cases:
        out = subprocess.run([sys.executable, __file__, "--one", case], capture_output=True,
                             text=True)
        if out.returncode != 0:
            rows.append({"case": case, "error": out.stderr.strip().splitlines()[-1]})
            continue
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(f"machine: {machine()}\n")
    print("| case | unknowns | Jacobian nnz | compile wall [s] | compile CPU [s] | peak RSS [MB] "
          "| source [MB] | residual [ms] | Jacobian [ms] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "error" in r:
            print(f"| {r['case']} | failed: {r['error']} |")
            continue
        print(f"| {r['case']} | {r['n']} | {r['nnz']} | {r['compile_s']:.2f} | "
              f"{r.get('compile_cpu_s', float('nan')):.2f} | {r['rss_mb']:.0f} "
              f"| {r['source_mb']:.2f} | {r['residual_ms']:.2f} | {r['jacobian_ms']:.2f} |")
    by = {r["case"]: r for r in rows if "error" not in r}
    if "wide:3000" in by and "wide:300" in by:
        a, b = by["wide:3000"], by["wide:300"]
        print(f"\ncompile(M = 3000) / compile(M = 300) = {a['compile_s'] / b['compile_s']:.1f} "
              f"wall, {a.get('compile_cpu_s', 0) / max(b.get('compile_cpu_s', 1), 1e-9):.1f} CPU")


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--one":
        print(json.dumps(run_case(sys.argv[2])))
    else:
        main(sys.argv[1:] or DEFAULT)
