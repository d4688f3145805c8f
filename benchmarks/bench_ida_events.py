"""The SUNDIALS IDA backend on a circuit with many events: N cylinders fed from one supply.

Each cylinder (with its mass) brings four event functions (end-stop overrun, cavitation), so
N = 100 gives 400. Simulation wall time of 1 s at rtol 1e-7 with ``solver="ida"`` for each N,
in a fresh process per run; ``--before TREE`` alternates runs with the pvgraph of another
checkout and prints the medians side by side with their ratio.

Run: ``python benchmarks/bench_ida_events.py [--before TREE] [--repeats 3] 50 100``
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
import json, sys, time
from pvgraph import Circuit
from pvgraph.simulate import simulate
from pvgraph.components import Cylinder, Mass, Orifice, PressureSource, Tank
n = int(sys.argv[1])
c = Circuit("many")
supply, drain = [c.add("sup", PressureSource(p0=100e5)).port], [c.add("tank", Tank()).port]
for i in range(n):
    o = c.add(f"o{i}", Orifice(A=(1.0 + 4.0 * i / max(n - 1, 1)) * 1e-6, dp_t=1e4))
    cyl = c.add(f"cyl{i}", Cylinder(A_A="20 cm^2", A_rod="10 cm^2", stroke="2 m",
                                    V_dead_A="0.1 L", V_dead_B="0.1 L"))
    m = c.add(f"m{i}", Mass(m=50.0, b=2e4 + 1e5 * ((i * 37) % n) / n, x0=0.5))
    c.connect(o.b, cyl.A)
    c.connect(cyl.flange, m.flange)
    supply.append(o.a)
    drain.append(cyl.B)
c.connect(*supply)
c.connect(*drain)
system = c.compile()
t0 = time.perf_counter()
sol = simulate(system, 1.0, rtol=1e-7, solver="ida")
wall = time.perf_counter() - t0
print(json.dumps({"wall": wall, "v0": float(sol.final("m0.v"))}))
"""


def run(tree: Path, n: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", _CHILD, str(n)], env=env, capture_output=True,
                         text=True, cwd=tree)
    if out.returncode != 0:
        raise RuntimeError(f"N = {n} on {tree}: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(before: Path | None, sizes: list[int], repeats: int) -> None:
    sys.path.insert(0, str(HERE))
    from _machine import machine
    after = HERE.parent
    print(f"machine: {machine()}; {repeats} runs per case\n")
    if before is None:
        print("| N | events | IDA wall [s] |\n|---|---|---|")
    else:
        print("| N | events | before [s] | after [s] | ratio |\n|---|---|---|---|---|")
    for n in sizes:
        old, new = [], []
        for _ in range(repeats):
            if before is not None:
                old.append(run(before, n))
            new.append(run(after, n))
        b = statistics.median(r["wall"] for r in new)
        if before is None:
            print(f"| {n} | {4 * n} | {b:.2f} |", flush=True)
        else:
            a = statistics.median(r["wall"] for r in old)
            same = max(abs(x["v0"] - y["v0"]) for x, y in zip(old, new))
            print(f"| {n} | {4 * n} | {a:.2f} | {b:.2f} | {a / b:.1f}x (final m0.v differs "
                  f"by {same:.1e} m/s) |", flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    before = None
    repeats = 3
    while args and args[0].startswith("--"):
        if args[0] == "--before":
            before, args = Path(args[1]).resolve(), args[2:]
        elif args[0] == "--repeats":
            repeats, args = int(args[1]), args[2:]
        else:
            sys.exit(__doc__)
    if not args:
        sys.exit(__doc__)
    main(before, [int(a) for a in args], repeats)
