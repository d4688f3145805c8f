"""Compile CPU of two pvgraph checkouts, alternating, in fresh processes: medians and ratios.

Each run builds one case of ``bench_scaling.py`` (``chain:N`` or ``wide:M``) with the pvgraph of
one tree and times ``circuit.compile()`` (process CPU time; the modules a compile imports are
imported first, as in a session that has compiled before) and the peak resident memory of the
process. Runs alternate between the trees (before, after, before, ...), so that load changes of
a shared machine hit both alike; the table gives the medians, the ratio of the medians and the
range of the ratios of the pairs.

Run: ``python benchmarks/bench_compile_ab.py --before TREE [--repeats 5] chain:20000 wide:10000``
with ``TREE`` an exported older commit (``git archive <commit> | tar -x -C TREE``).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

_CHILD = r"""
import json, resource, sys, time
sys.path.insert(0, sys.argv[2])
from bench_scaling import chain, wide
kind, size = sys.argv[1].split(":")
circuit = {"wide": wide, "chain": chain}[kind](int(size))
# the modules a compile imports, imported before timing as in a session that has compiled
# before (their one-time cost, 0.4 s, does not grow with the circuit)
import pvgraph.compiler, pvgraph.index_reduction, pvgraph.system, pvgraph.codegen  # noqa
c0 = time.process_time()
circuit.compile()
cpu = time.process_time() - c0
print(json.dumps({"cpu": cpu, "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def run(tree: Path, case: str) -> dict:
    """Compile CPU [s] and peak RSS [MB] of ``case`` with the pvgraph of ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree), PVGRAPH_BENCH_TREE=str(tree))
    out = subprocess.run([sys.executable, "-c", _CHILD, case, str(HERE)], env=env,
                         capture_output=True, text=True, cwd=tree)
    if out.returncode != 0:
        raise RuntimeError(f"{case} on {tree}: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(before: Path, cases: list[str], repeats: int) -> None:
    from _machine import machine
    after = HERE.parent
    print(f"machine: {machine()}\n\nbefore: pvgraph of {before}; after: pvgraph of {after}; "
          f"{repeats} pairs per case\n")
    print("| case | compile CPU before [s] | after [s] | ratio (range over the pairs) "
          "| peak RSS before [MB] | after [MB] |")
    print("|---|---|---|---|---|---|")
    for case in cases:
        old, new = [], []
        for _ in range(repeats):
            old.append(run(before, case))
            new.append(run(after, case))
        a = statistics.median(r["cpu"] for r in old)
        b = statistics.median(r["cpu"] for r in new)
        ratios = [x["cpu"] / y["cpu"] for x, y in zip(old, new)]
        print(f"| {case} | {a:.2f} | {b:.2f} | {a / b:.2f}x ({min(ratios):.2f}-"
              f"{max(ratios):.2f}) | {max(r['rss'] for r in old):.0f} | "
              f"{max(r['rss'] for r in new):.0f} |", flush=True)


if __name__ == "__main__":
    sys.path.insert(0, str(HERE))
    args = sys.argv[1:]
    if len(args) < 3 or args[0] != "--before":
        sys.exit(__doc__)
    tree, args = Path(args[1]).resolve(), args[2:]
    repeats = 5
    if args[:1] == ["--repeats"]:
        repeats, args = int(args[1]), args[2:]
    main(tree, args, repeats)
