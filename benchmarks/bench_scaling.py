"""Compiler scaling: wide connection sets, long chains, and the cost of the generated code.

Cases (each compiled in a fresh subprocess, so that its peak memory is its own):

- ``wide M``: one volume node joining a pump and M turbulent orifices, whose other ends all join
  the tank: two connection sets of M + 1 ports;
- ``chain N``: a pump feeding N volume + orifice pairs in series, ending at the tank.

For each: compile time, peak resident memory of the process (``ru_maxrss``), the size of the
generated source, and one residual and one Jacobian evaluation (medians).

Run: ``python benchmarks/bench_scaling.py [wide:300 wide:3000 chain:5000 ...]`` (Markdown table).
``--before TREE`` also runs every case on the pvgraph of another checkout (``TREE``, e.g. an
exported older commit), alternating with this one, and prints both side by side with ratios.
``--eval chain:5000`` compiles one case twice in one process, with rows of one shape evaluated
as arrays (the default for big systems) and as straight-line code (``array_rows=False``), and
compares the cost of a residual, a Jacobian and a short simulation.
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

import os

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, os.environ.get("PVGRAPH_BENCH_TREE", str(HERE.parent)))

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


def _run(case, tree=None):
    env = dict(os.environ)
    if tree is not None:
        env["PVGRAPH_BENCH_TREE"] = str(Path(tree).resolve())
        env["PYTHONPATH"] = env["PVGRAPH_BENCH_TREE"]
    out = subprocess.run([sys.executable, __file__, "--one", case], capture_output=True,
                         text=True, env=env)
    if out.returncode != 0:
        lines = out.stderr.strip().splitlines() or ["(no output)"]
        return {"case": case, "error": lines[-1]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _row(r):
    if "error" in r:
        return f"| {r['case']} | failed: {r['error']} |"
    return (f"| {r['case']} | {r['n']} | {r['nnz']} | {r['compile_s']:.2f} | "
            f"{r.get('compile_cpu_s', float('nan')):.2f} | {r['rss_mb']:.0f} "
            f"| {r['source_mb']:.2f} | {r['residual_ms']:.2f} | {r['jacobian_ms']:.2f} |")


def main(cases, before=None):
    from _machine import machine
    rows, old = [], []
    for case in cases:
        if before is not None:
            old.append(_run(case, before))
        rows.append(_run(case))
    print(f"machine: {machine()}\n")
    if before is not None:
        print(f"before: pvgraph of {before}; after: pvgraph of {HERE.parent}\n")
        print("| case | unknowns | compile CPU before [s] | after [s] | ratio | peak RSS before "
              "[MB] | after [MB] | residual before [ms] | after [ms] | Jacobian before [ms] "
              "| after [ms] |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for a, b in zip(old, rows):
            if "error" in a or "error" in b:
                print(f"| {b['case']} | {a.get('error', '')} {b.get('error', '')} |")
                continue
            print(f"| {b['case']} | {b['n']} | {a['compile_cpu_s']:.2f} | {b['compile_cpu_s']:.2f}"
                  f" | {a['compile_cpu_s'] / b['compile_cpu_s']:.1f}x | {a['rss_mb']:.0f} | "
                  f"{b['rss_mb']:.0f} | {a['residual_ms']:.2f} | {b['residual_ms']:.2f} | "
                  f"{a['jacobian_ms']:.2f} | {b['jacobian_ms']:.2f} |")
        print()
    print("| case | unknowns | Jacobian nnz | compile wall [s] | compile CPU [s] | peak RSS [MB] "
          "| source [MB] | residual [ms] | Jacobian [ms] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(_row(r))
    by = {r["case"]: r for r in rows if "error" not in r}
    if "wide:3000" in by and "wide:300" in by:
        a, b = by["wide:3000"], by["wide:300"]
        print(f"\ncompile(M = 3000) / compile(M = 300) = {a['compile_s'] / b['compile_s']:.1f} "
              f"wall, {a.get('compile_cpu_s', 0) / max(b.get('compile_cpu_s', 1), 1e-9):.1f} CPU")


def compare_eval(case: str, repeats: int = 7, t_end: float = 0.05):
    """Residual, Jacobian and a short simulation: array rows against straight-line code."""
    from _machine import machine
    from pvgraph.simulate import simulate
    kind, size = case.split(":")
    circuit = {"wide": wide, "chain": chain}[kind](int(size))
    systems = {"straight-line": circuit.compile(array_rows=False),
               "array rows": circuit.compile()}
    y = systems["array rows"].y0 + 1.0
    yp = np.zeros(len(y))
    res = {k: [] for k in systems}
    jac = {k: [] for k in systems}
    for _ in range(repeats):   # alternating, so that load changes hit both alike
        for k, s in systems.items():
            t0 = time.perf_counter()
            s.residual(0.0, y, yp)
            res[k].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            s.jacobian_values(0.0, y, yp, 10.0)
            jac[k].append(time.perf_counter() - t0)
    sims = {}
    for k, s in systems.items():
        t0 = time.process_time()
        sol = simulate(s, t_end)
        sims[k] = (time.process_time() - t0, sol.stats["nre"], sol.stats["nsteps"],
                   sol[f"o{int(size) - 1}.q"][-1])
    print(f"machine: {machine()}\n")
    print(f"{case}: {systems['array rows'].n} unknowns, simulate(system, {t_end}) with the "
          f"default solver\n")
    print("| evaluation | residual [ms] | Jacobian [ms] | simulation CPU [s] | residual calls "
          "| steps | last orifice flow [m^3/s] |")
    print("|---|---|---|---|---|---|---|")
    for k in systems:
        cpu, nres, npts, q = sims[k]
        print(f"| {k} | {1e3 * statistics.median(res[k]):.2f} | "
              f"{1e3 * statistics.median(jac[k]):.2f} | {cpu:.2f} | {nres} | {npts} | {q:.9e} |")
    a, b = "straight-line", "array rows"
    print(f"\nstraight-line / array rows: residual "
          f"{statistics.median(res[a]) / statistics.median(res[b]):.1f}x, Jacobian "
          f"{statistics.median(jac[a]) / statistics.median(jac[b]):.1f}x, simulation "
          f"{sims[a][0] / sims[b][0]:.1f}x")


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) > 1 and args[0] == "--one":
        print(json.dumps(run_case(args[1])))
    elif len(args) > 1 and args[0] == "--eval":
        compare_eval(args[1])
    else:
        tree = None
        if len(args) > 1 and args[0] == "--before":
            tree, args = args[1], args[2:]
        main(args or DEFAULT, tree)
