"""The C route against the generated Python code, side by side on the same compiled systems.

For each circuit: the cost of building the C library (a cold cache: a fresh folder), the cost
of one residual and one Jacobian evaluation, and the wall time of a simulation with both routes
(interleaved repeats, medians; each route with its defaults, so the C route with the C step
and the C sparse LU), with a check that both take the same steps and give the same numbers
when the C route is given the Python route's LU (``linear_solver="lapack"``: they must, the C
route computes the Python code's numbers bit for bit).

Circuits: PVG 32 rig step test 2 (1.01 s at rtol 1e-6 from the settled state, as in
``bench_pvg32.py``), the machine cycle of ``examples/machine_cycle.py`` (10 s at rtol 1e-5) and,
with ``--big``, a chain of 500 volume + orifice pairs (1500 unknowns: the Python code evaluates
its repeated rows as arrays, C as straight-line code). ``--validate`` also times ``pvgraph
validate`` and ``pvgraph --eval c validate`` (warm cache) as subprocesses, alternating.

Usage: ``python benchmarks/bench_cbackend.py [--repeats 5] [--big] [--validate]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from _machine import machine  # noqa: E402


def rig_case():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    from pvgraph.simulate import simulate
    p = report_tuned()
    settle = build_rig(p, load=laminar_load(p, L1="small", L3="small"), U_input=4.24).compile()
    y0 = simulate(settle, 8.0, rtol=1e-6).y[-1]
    circuit = build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                        U_input=4.24)
    t_eval = np.linspace(0.0, 1.01, 102)
    return ("PVG 32 rig test 2, 1.01 s, rtol 1e-6", circuit,
            lambda s: simulate(s, 1.01, rtol=1e-6, y0=y0, t_eval=t_eval))


def machine_case():
    from pvgraph.circuits.machine import CYCLE, RTOL, build_machine
    from pvgraph.simulate import simulate
    t_end = CYCLE["t"][-1]
    t_eval = np.linspace(0.0, t_end, int(t_end * 200) + 1)
    return (f"machine cycle, {t_end:g} s, rtol {RTOL:g}", build_machine(),
            lambda s: simulate(s, t_end, rtol=RTOL, t_eval=t_eval))


def chain_case(n=500):
    from bench_scaling import chain
    from pvgraph.simulate import simulate
    return (f"chain of {n} volume + orifice pairs, 0.05 s", chain(n),
            lambda s: simulate(s, 0.05))


def lapack_lu(sim):
    """``sim`` with solve_dae's ``linear_solver="lapack"`` (the C route's default is the C
    sparse LU, whose rounding differs)."""
    import pvgraph.solver as solver
    orig = solver.solve_dae

    def run(s):
        def patched(*a, **k):
            return orig(*a, linear_solver="lapack", **k)
        solver.solve_dae = patched
        try:
            return sim(s)
        finally:
            solver.solve_dae = orig
    return run


def run_case(label, circuit, sim, repeats):
    cache = tempfile.mkdtemp(prefix="pv-c-bench-")
    os.environ["PVGRAPH_CACHE_DIR"] = cache
    t0 = time.perf_counter()
    py = circuit.compile()
    t_py = time.perf_counter() - t0
    t0 = time.perf_counter()
    cc = circuit.compile(backend="c")
    t_c = time.perf_counter() - t0
    ref = sim(py)
    got = lapack_lu(sim)(cc)      # the C route with the Python route's LU: the same numbers
    same = ref.stats == got.stats and np.array_equal(ref.y, got.y)
    y, yp = ref.y[-1], ref.yp[-1]
    t = float(ref.t[-1])
    n = 2000 if py.n < 200 else 200
    calls = {}
    for name, s in (("python", py), ("c", cc)):
        calls[name] = (
            min(timeit.repeat(lambda: s.residual(t, y, yp), number=n, repeat=3)) / n,
            min(timeit.repeat(lambda: s.jacobian_values(t, y, yp, 100.0), number=n,
                              repeat=3)) / n)
    walls = {"python": [], "c": []}
    for _ in range(repeats):
        for name, s in (("python", py), ("c", cc)):
            t0 = time.perf_counter()
            sim(s)
            walls[name].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in walls.items()}
    return {"case": label, "n": py.n, "steps": ref.stats["nsteps"], "nre": ref.stats["nre"],
            "same": same, "compile_py": t_py, "compile_c": t_c,
            "res_py": calls["python"][0], "res_c": calls["c"][0],
            "jac_py": calls["python"][1], "jac_c": calls["c"][1],
            "wall_py": med["python"], "wall_c": med["c"]}


def validate_times(repeats):
    out = {"python": [], "c": []}
    env = dict(os.environ)
    cmd = {"python": [sys.executable, "-m", "pvgraph.cli", "validate", "--out"],
           "c": [sys.executable, "-m", "pvgraph.cli", "--eval", "c", "validate", "--out"]}
    tmp = tempfile.mkdtemp(prefix="pv-validate-")
    subprocess.run(cmd["c"] + [tmp], env=env, capture_output=True, check=True)  # warm cache
    for _ in range(repeats):
        for name in ("python", "c"):
            t0 = time.perf_counter()
            subprocess.run(cmd[name] + [tmp], env=env, capture_output=True, check=True)
            out[name].append(time.perf_counter() - t0)
    return {k: statistics.median(v) for k, v in out.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--big", action="store_true")
    ap.add_argument("--validate", action="store_true")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print(machine())
    cases = [rig_case(), machine_case()] + ([chain_case()] if args.big else [])
    rows = [run_case(*c, args.repeats) for c in cases]
    print("\n| circuit | unknowns | steps | nre | same steps and y | compile Python [s] | "
          "compile + C build, cold cache [s] | residual Python / C [us] | Jacobian Python / C "
          "[us] | simulate Python / C [ms] | ratio |")
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['case']} | {r['n']} | {r['steps']} | {r['nre']} | "
              f"{'yes' if r['same'] else 'NO'} | {r['compile_py']:.2f} | {r['compile_c']:.2f} | "
              f"{r['res_py'] * 1e6:.1f} / {r['res_c'] * 1e6:.1f} | "
              f"{r['jac_py'] * 1e6:.1f} / {r['jac_c'] * 1e6:.1f} | "
              f"{r['wall_py'] * 1e3:.1f} / {r['wall_c'] * 1e3:.1f} | "
              f"{r['wall_py'] / r['wall_c']:.2f} |")
    if args.validate:
        v = validate_times(max(3, args.repeats // 2))
        print(f"\npvgraph validate: {v['python']:.2f} s, pvgraph --eval c validate (warm cache): "
              f"{v['c']:.2f} s, ratio {v['python'] / v['c']:.2f}")


if __name__ == "__main__":
    main()
