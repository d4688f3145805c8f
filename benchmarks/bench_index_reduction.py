"""Cost of index reduction in the compiler.

1. **Circuits that need no reduction.** The synthetic hydraulic circuit of
   ``bench_compiler.py`` (N copies of a ten-component branch): compile time with the index
   detection (one extra maximum bipartite matching) against the same compile with
   ``reduce_index`` replaced by a pass-through, interleaved in each round.
2. **Circuits that do.** N copies of a rigidly joined pair of masses on a spring to ground,
   pushed by a force (each pair is index two): compile time and the share of it spent in
   ``reduce_index`` (Pantelides, dummy derivatives, first-order form).

Times are medians over ``--repeats`` rounds (default 5). Run:
``python benchmarks/bench_index_reduction.py``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from bench_compiler import build  # noqa: E402
from pvgraph.components.mechanical import ForceInput, LinearSpring, SpoolMass  # noqa: E402
from pvgraph.components.signal import Constant  # noqa: E402
from pvgraph import Circuit  # noqa: E402
import pvgraph.index_reduction as ir  # noqa: E402


def joined_pairs(copies: int) -> Circuit:
    top = Circuit(f"pairs{copies}")
    for k in range(copies):
        a = top.add(f"a{k}", SpoolMass(m=1.0))
        b = top.add(f"b{k}", SpoolMass(m=2.0))
        s = top.add(f"s{k}", LinearSpring(k=1e3))
        f = top.add(f"f{k}", ForceInput())
        u = top.add(f"u{k}", Constant(k=1.0))
        top.connect(a.flange, b.flange, s.flange, f.flange)
        top.connect(u.y, f.u)
    return top


def timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    real = ir.reduce_index

    def passthrough(equations, infos, subs, events, observed, given=None):
        return equations, events, observed, ir.IndexReduction()

    spent = []

    def measured(*a, **k):
        t0 = time.perf_counter()
        out = real(*a, **k)
        spent.append(time.perf_counter() - t0)
        return out

    print(f"Machine: {machine()}\n")
    print("| copies | unknowns | compile, detection on [ms] | detection off [ms] | ratio |")
    print("|---:|---:|---:|---:|---:|")
    for n in (4, 16, 64):
        on, off = [], []
        for _ in range(args.repeats):
            ir.reduce_index = real
            on.append(timed(lambda: build(n).compile()))
            ir.reduce_index = passthrough
            off.append(timed(lambda: build(n).compile()))
        ir.reduce_index = real
        size = build(n).compile().n
        a, b = statistics.median(on), statistics.median(off)
        print(f"| {n} | {size} | {a * 1e3:.1f} | {b * 1e3:.1f} | {a / b:.3f} |")

    print("\n| joined pairs | unknowns | compile [ms] | in reduce_index [ms] | per pair [ms] |")
    print("|---:|---:|---:|---:|---:|")
    ir.reduce_index = measured
    for n in (4, 16, 64):
        total, inner = [], []
        for _ in range(args.repeats):
            spent.clear()
            total.append(timed(lambda: joined_pairs(n).compile()))
            inner.append(spent[-1])
        size = joined_pairs(n).compile().n
        a, b = statistics.median(total), statistics.median(inner)
        print(f"| {n} | {size} | {a * 1e3:.1f} | {b * 1e3:.1f} | {a / n * 1e3:.2f} |")
    ir.reduce_index = real


if __name__ == "__main__":
    main()
