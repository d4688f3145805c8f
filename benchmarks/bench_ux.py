"""Cost of the unit-aware parameter validation and of the pressure-reference check.

Run from the repository root, ``python benchmarks/bench_ux.py [other checkout]``: times building
a component from plain SI floats and from strings with units, ``build_rig()`` and compiling the
rig, in this checkout and (given a path) in another one, side by side in one run.
"""

import os
import statistics
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import machine  # noqa: E402

CODE = r'''
import statistics, time, json
from pvgraph.components import Orifice
from pvgraph.circuits.rig import build_rig

def med(f, n, rep=7):
    out = []
    for _ in range(rep):
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        out.append((time.perf_counter() - t0) / n)
    return statistics.median(out)

res = {"Orifice(A=2e-6) [us]": 1e6 * med(lambda: Orifice(A=2e-6), 2000),
       "build_rig() [ms]": 1e3 * med(build_rig, 20),
       "build_rig().compile() [ms]": 1e3 * med(lambda: build_rig().compile(), 3, rep=5)}
try:
    res["Orifice(A='2 mm^2') [us]"] = 1e6 * med(lambda: Orifice(A="2 mm^2"), 2000)
except Exception:
    pass
print(json.dumps(res))
'''


def run(root):
    env = {**os.environ, "PYTHONPATH": root}
    out = subprocess.run([sys.executable, "-c", CODE], cwd=root, env=env, capture_output=True,
                         text=True, check=True).stdout
    import json
    return json.loads(out)


def _square(x):
    return {"y": x * x}


def sweep_record_overhead(n=400, rep=5):
    """Median wall time per case of a trivial serial sweep, without and with ``out=``."""
    import tempfile

    from pvgraph.analysis.sweep import grid, sweep
    cases = grid({"x": [float(i) for i in range(n)]})
    out = {}
    for label in ("no files", "cases.jsonl + csv + json"):
        times = []
        for _ in range(rep):
            with tempfile.TemporaryDirectory() as folder:
                t0 = time.perf_counter()
                sweep(_square, cases, backend="serial",
                      out=folder if label != "no files" else None)
                times.append((time.perf_counter() - t0) / n)
        out[label] = statistics.median(times) * 1e6
    return out


def main():
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    other = sys.argv[1] if len(sys.argv) > 1 else None
    print(machine())
    rows = {"this checkout": run(here)}
    if other:
        rows["other checkout"] = run(other)
    keys = list(rows["this checkout"])
    for k in keys:
        cells = [f"{rows[r].get(k, float('nan')):10.3f}" for r in rows]
        ratio = (f"  ratio {rows['this checkout'][k] / rows['other checkout'][k]:.2f}"
                 if other and k in rows["other checkout"] else "")
        print(f"{k:32s} " + " ".join(cells) + ratio)
    sys.path.insert(0, here)
    per_case = sweep_record_overhead()
    print("serial sweep of a trivial run(), per case [us]: " +
          ", ".join(f"{k} {v:.1f}" for k, v in per_case.items()))


if __name__ == "__main__":
    main()
