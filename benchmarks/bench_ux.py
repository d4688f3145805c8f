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
from components import Orifice
from circuits.rig import build_rig

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


if __name__ == "__main__":
    main()
