"""Solver time of PVG 32 rig test 2 and the machine cycle on the C route, step by step.

The same compiled C-route system run four ways, side by side:

- ``python``: the Python BDF step with LAPACK's dense LU (``c_step=False,
  linear_solver="lapack"``);
- ``c-step``: the C step with LAPACK, the integration loop in Python (one call into C per
  step; ``CStepIntegrator.c_loop`` off) -- the C route before the loop moved into C;
- ``c-loop``: the C step with LAPACK and the integration loop in C (``pv_advance``);
- ``c-lu``: as ``c-loop`` with the sparse LU of ``pvgraph/solver/clu.c`` (the C route's
  default).

The first three must give the same numbers bit for bit (checked: steps, t, y, y'); the
fourth pivots as LAPACK but rounds differently, so its accuracy is checked instead: the
largest error at the outputs against a run with 1000 times tighter rtol and atol, in units of
rtol times (|value| + the variable's range), beside the Python step's (``simulate`` leaves
algebraic variables out of the error test, so theirs dominate). Times: medians of interleaved repeats of ``simulate`` (wall) and
of the time spent inside ``solve_dae`` (the solver), per run.

Usage: ``python benchmarks/bench_rig_solver.py [--repeats 21]``
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

VARIANTS = {
    "python": dict(c_step=False, linear_solver="lapack"),
    "c-step": dict(c_step=True, linear_solver="lapack", c_loop=False),
    "c-loop": dict(c_step=True, linear_solver="lapack"),
    "c-lu": dict(c_step=True, linear_solver="c"),
}


def variant(sim, c_step, linear_solver, c_loop=True):
    """``sim`` with solve_dae's options and the C loop switch; returns (result, solver s)."""
    import pvgraph.solver as solver
    from pvgraph.solver.cstep import CStepIntegrator
    orig = solver.solve_dae

    def run(s, **extra):
        spent = [0.0]

        def patched(*a, **k):
            k.update(c_step=c_step, linear_solver=linear_solver)
            k.update(extra)
            t0 = time.perf_counter()
            try:
                return orig(*a, **k)
            finally:
                spent[0] += time.perf_counter() - t0
        solver.solve_dae = patched
        CStepIntegrator.c_loop = c_loop
        try:
            return sim(s), spent[0]
        finally:
            solver.solve_dae = orig
            CStepIntegrator.c_loop = True
    return run


def error_units(res, ref, rtol):
    scale = rtol * (np.abs(ref.y) + np.abs(ref.y).max(axis=0)) + 1e-12
    return float(np.max(np.abs(res.y - ref.y) / scale))


def run_case(label, circuit, sim, rtol, repeats):
    s = circuit.compile(backend="c")
    runs = {k: variant(sim, **v) for k, v in VARIANTS.items()}
    res = {k: run(s)[0] for k, run in runs.items()}
    ref = res["python"]
    same = all(ref.stats == res[k].stats and np.array_equal(ref.t, res[k].t)
               and np.array_equal(ref.y, res[k].y) and np.array_equal(ref.yp, res[k].yp)
               for k in ("c-step", "c-loop"))
    tight = variant(sim, False, "lapack")(s, rtol=rtol * 1e-3, atol=rtol * 1e-3 * s.nominal)[0]
    errors = {k: error_units(res[k], tight, rtol) for k in ("python", "c-lu")}
    walls = {k: [] for k in runs}
    solver_s = {k: [] for k in runs}
    for _ in range(repeats):
        for k, run in runs.items():
            t0 = time.perf_counter()
            _, inside = run(s)
            walls[k].append(time.perf_counter() - t0)
            solver_s[k].append(inside)
    return {"case": label, "n": s.n, "same": same, "errors": errors,
            "steps": {k: r.stats["nsteps"] for k, r in res.items()},
            "nlu": {k: r.stats["nlu"] for k, r in res.items()},
            "wall": {k: statistics.median(v) for k, v in walls.items()},
            "solver": {k: statistics.median(v) for k, v in solver_s.items()}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    ap.add_argument("--skip-machine", action="store_true")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print(machine())
    from pvgraph.solver import clu, cstep
    if cstep.kernel() is None or not clu.available():
        sys.exit(f"the C step or the C LU is not available: {cstep.kernel_error()} "
                 f"{clu.load_error()}")
    from pvgraph.circuits.machine import RTOL
    cases = [(rig_case, 1e-6)] + ([] if args.skip_machine else [(machine_case, RTOL)])
    rows = [run_case(*case(), rtol, args.repeats) for case, rtol in cases]
    names = list(VARIANTS)
    print(f"\nmedians of {args.repeats} interleaved runs; variants: " + ", ".join(names))
    print("\n| circuit | unknowns | steps (python / c-lu) | LU factorisations | python = c-step "
          "= c-loop bit for bit | error [rtol units] python / c-lu | simulate [ms] "
          + " / ".join(names) + " | solve_dae [ms] " + " / ".join(names)
          + " | python / c-lu |")
    print("|---|---:|---:|---:|---|---:|---:|---:|---:|")
    for r in rows:
        w, sv = r["wall"], r["solver"]
        print(f"| {r['case']} | {r['n']} | {r['steps']['python']} / {r['steps']['c-lu']} | "
              f"{r['nlu']['python']} / {r['nlu']['c-lu']} | {'yes' if r['same'] else 'NO'} | "
              f"{r['errors']['python']:.0f} / {r['errors']['c-lu']:.0f} | "
              + " / ".join(f"{w[k] * 1e3:.1f}" for k in names) + " | "
              + " / ".join(f"{sv[k] * 1e3:.2f}" for k in names)
              + f" | {w['python'] / w['c-lu']:.1f}x |")


if __name__ == "__main__":
    main()
