"""The BDF step in C against the Python step, both on the C route, side by side.

For PVG 32 rig test 2 (1.01 s at rtol 1e-6 from the settled state, 91 unknowns, dense LU)
and the machine cycle (7.5 s at rtol 1e-5, 184 unknowns, SuperLU solves called back from C),
``simulate`` on the same compiled C-route system with the Python step (``c_step=False``),
the C step with the iteration matrix (Jacobian evaluation and LU factorisation), the event
functions after each step and the interpolation (outputs, event location) left to the Python
code (C0: ``CStepIntegrator.dense_setup``, ``step_events`` and ``c_interpolate`` off), and the
C step as it runs by default (C1: a dense compiled Jacobian evaluated and factorised in C,
compiled events evaluated after the step and the interpolant in C): a check that
all three take the same steps and give the same outputs (``np.array_equal``), interleaved
repeats of the wall time (medians), and, from instrumented runs (the fastest of 3), the time
inside ``step()`` per step and, from the median wall time, the time per step outside it
(event handling, outputs, the integration loop).

Usage: ``python benchmarks/bench_cstep.py [--repeats 7]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from _machine import machine  # noqa: E402
from bench_cbackend import machine_case, rig_case  # noqa: E402


def with_c_step(sim, c_step, in_c=True):
    """``sim`` with ``c_step`` passed on to solve_dae; ``in_c=False``: the C step with the
    iteration matrix, the events after each step and the interpolation by the Python code."""
    import pvgraph.solver as solver
    from pvgraph.solver.cstep import CStepIntegrator
    orig = solver.solve_dae

    def run(s):
        def patched(*a, **k):
            return orig(*a, c_step=c_step, **k)
        solver.solve_dae = patched
        CStepIntegrator.dense_setup = CStepIntegrator.step_events = in_c
        CStepIntegrator.c_interpolate = in_c
        try:
            return sim(s)
        finally:
            solver.solve_dae = orig
            CStepIntegrator.dense_setup = CStepIntegrator.step_events = True
            CStepIntegrator.c_interpolate = True
    return run


def instrumented(run, s):
    """(result, seconds in step(), seconds in iteration matrices + LU) of one run."""
    from pvgraph.solver import ida, cstep
    from pvgraph.solver.linalg import JacobianEvaluator, LUSolver
    spent = {"step": 0.0, "setup": 0.0}
    saved = {}

    def timed(cls, name, key):
        fn = getattr(cls, name)
        saved[(cls, name)] = fn

        def wrapper(*a, **k):
            t0 = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[key] += time.perf_counter() - t0
        setattr(cls, name, wrapper)

    timed(ida.IDAIntegrator, "step", "step")
    timed(cstep.CStepIntegrator, "step", "step")
    timed(JacobianEvaluator, "iteration_matrix", "setup")
    timed(LUSolver, "factor", "setup")
    try:
        res = run(s)
    finally:
        for (cls, name), fn in saved.items():
            setattr(cls, name, fn)
    return res, spent["step"], spent["setup"]


def run_case(label, circuit, sim, repeats):
    s = circuit.compile(backend="c")
    runs = {"python": with_c_step(sim, False), "c0": with_c_step(sim, None, False),
            "c": with_c_step(sim, None)}
    ref = runs["python"](s)
    same = True
    for name in ("c0", "c"):
        got = runs[name](s)
        same &= (ref.stats == got.stats and np.array_equal(ref.t, got.t)
                 and np.array_equal(ref.y, got.y) and np.array_equal(ref.yp, got.yp))
    walls = {k: [] for k in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            t0 = time.perf_counter()
            run(s)
            walls[name].append(time.perf_counter() - t0)
    inner = {}
    for name, run in runs.items():
        if name == "python":
            continue
        best = None
        for _ in range(3):
            _, t_step, t_setup = instrumented(run, s)
            if best is None or t_step < best[0]:
                best = (t_step, t_setup)
        inner[name] = best
    steps = ref.stats["nsteps"]
    return {"case": label, "n": s.n, "steps": steps, "nre": ref.stats["nre"],
            "nsetups": ref.stats["nlu"], "same": same,
            "wall": {k: statistics.median(v) for k, v in walls.items()},
            "step": {k: v[0] / steps for k, v in inner.items()},
            "own": {k: (v[0] - v[1]) / steps for k, v in inner.items()}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print(machine())
    from pvgraph.solver import cstep
    if cstep.kernel() is None:
        sys.exit(f"the C step is not available: {cstep.kernel_error()}")
    rows = [run_case(*case(), args.repeats) for case in (rig_case, machine_case)]
    print("\nsimulate with the Python step / the C step with J + LU, events and interpolation "
          "by the Python code (C0) / the C step with a dense J + LU, events and interpolation "
          "in C (C1)")
    print("\n| circuit | unknowns | steps | nre | same steps and outputs | simulate Python / "
          "C0 / C1 [ms] | C0 / C1 | in step() per step, C0 / C1 [us] | outside step() per "
          "step, C0 / C1 [us] |")
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|")
    for r in rows:
        w, st = r["wall"], r["step"]
        out = {k: w[k] / r["steps"] - st[k] for k in ("c0", "c")}
        print(f"| {r['case']} | {r['n']} | {r['steps']} | {r['nre']} | "
              f"{'yes' if r['same'] else 'NO'} | {w['python'] * 1e3:.1f} / "
              f"{w['c0'] * 1e3:.1f} / {w['c'] * 1e3:.1f} | {w['c0'] / w['c']:.2f} | "
              f"{st['c0'] * 1e6:.1f} / {st['c'] * 1e6:.1f} | "
              f"{out['c0'] * 1e6:.1f} / {out['c'] * 1e6:.1f} |")


if __name__ == "__main__":
    main()
