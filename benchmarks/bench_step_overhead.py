"""Per-step overhead of the built-in BDF solver: this tree against a git revision, side by side.

The solver modules ``pvgraph/solver/ida.py`` and ``solve.py`` of ``--base`` (default ``main``)
are loaded from ``git show`` into temporary modules; both versions integrate the same problems
in interleaved repeats. For each run: steps, residual evaluations (they must be equal: the
changes are meant to leave the step sequence untouched), the median wall time, and the solver's
own time per step, ``(wall - nre * t_res) / steps``, where ``t_res`` is the median cost of one
residual call measured on its own.

Problems: IVP Test Set HIRES, OREGO, E5, Akzo Nobel (rtol 1e-6), the Ring Modulator over
[0, 1e-4] (rtol 1e-6), a linear chain of 20 000 unknowns with a sparse
Jacobian and, with ``--rig``, PVG 32 rig step test 2 (1 s at rtol 1e-6, as in
``bench_pvg32.py``).

Usage::

    python benchmarks/bench_step_overhead.py [--repeats 5] [--base main] [--rig]
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from _machine import machine  # noqa: E402
import pvgraph.solver.solve as new_solve  # noqa: E402
from pvgraph.solver.testset import PROBLEMS  # noqa: E402


def load_base(rev):
    """solve_dae of revision ``rev``: its ida.py and solve.py as temporary modules."""
    tmp = tempfile.mkdtemp(prefix="pvgraph_base_")
    for name in ("ida", "solve"):
        src = subprocess.run(["git", "-C", ROOT, "show", f"{rev}:pvgraph/solver/{name}.py"],
                             check=True, capture_output=True, text=True).stdout
        src = src.replace("from pvgraph.solver.ida import", "from _base_ida import")
        with open(os.path.join(tmp, f"_base_{name}.py"), "w") as f:
            f.write(src)
    sys.path.insert(0, tmp)
    spec = importlib.util.spec_from_file_location("_base_solve", os.path.join(tmp, "_base_solve.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.solve_dae


def testset_case(key, tol, t_end=None):
    p = PROBLEMS[key]
    t_span = p.t_span if t_end is None else (p.t_span[0], t_end)

    def run(solve_dae):
        return solve_dae(p.residual, t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol), jac=p.jac,
                         algebraic=p.algebraic, calc_initial=None, max_steps=10**7)
    return f"{p.name} rtol {tol:g}" + ("" if t_end is None else f" to t = {t_end:g}"), run, \
        (p.residual, p.y0, p.yp0, p.t_span[0])


def chain_case(n=20_000):
    """Heat-conduction chain y' = K (y[i-1] - 2 y[i] + y[i+1]) + u(t) e_0, sparse Jacobian.

    The start profile is smooth and nowhere near zero, so that no entry of the history
    decays into subnormal numbers (which slow every vector operation a hundredfold).
    """
    import scipy.sparse as sp
    lap = sp.diags([np.ones(n - 1), -2.0 * np.ones(n), np.ones(n - 1)], [-1, 0, 1],
                   format="csr") * 50.0
    eye = sp.identity(n, format="csc")
    y0 = 1.0 + 0.5 * np.sin(0.01 * np.arange(n))
    yp0 = lap @ y0

    def residual(t, y, yp):
        r = yp - lap @ y
        r[0] -= math.sin(20.0 * t)
        return r

    def jac(t, y, yp, c):
        return (c * eye - lap).tocsc()

    def run(solve_dae):
        return solve_dae(residual, (0.0, 1.0), y0, yp0, rtol=1e-6, atol=1e-8, jac=jac,
                         jac_sparsity=(eye + lap), calc_initial=None)
    return f"chain n = {n}, rtol 1e-6", run, (residual, y0, yp0, 0.0)


def rig_case():
    """Rig step test 2 as in bench_pvg32.py, through solve_dae on the compiled System."""
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    import pvgraph.solver as solver_package
    from pvgraph.simulate import simulate

    p = report_tuned()
    settle = build_rig(p, load=laminar_load(p, L1="small", L3="small"), U_input=4.24).compile()
    y_settled = simulate(settle, 8.0, rtol=1e-6).y[-1]
    step = build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                     U_input=4.24).compile()
    t_eval = np.linspace(0.0, 1.01, 102)

    def run(solve_dae):
        import functools
        import inspect
        accepted = inspect.signature(solve_dae).parameters

        @functools.wraps(solve_dae)
        def known_options(*a, **kw):
            # an older solver lacks options simulate() sets now (newton_iterate_retry): drop
            # them for it; the comparison then shows whether the steps still agree
            return solve_dae(*a, **{k: v for k, v in kw.items() if k in accepted})
        saved = solver_package.solve_dae
        solver_package.solve_dae = known_options  # simulate() imports it at call time
        try:
            return simulate(step, 1.01, rtol=1e-6, y0=y_settled, t_eval=t_eval)
        finally:
            solver_package.solve_dae = saved
    sol = run(new_solve.solve_dae)
    return "PVG 32 rig test 2, 1 s, rtol 1e-6", run, (step.residual, sol.y[-1], sol.yp[-1], 0.5)


def residual_cost(fun, y, yp, t, calls=2000):
    samples = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(calls):
            fun(t, y, yp)
        samples.append((time.perf_counter() - t0) / calls)
    return statistics.median(samples)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--base", default="main")
    ap.add_argument("--rig", action="store_true")
    args = ap.parse_args()
    base_solve = load_base(args.base)
    cases = [testset_case("hires", 1e-6), testset_case("orego", 1e-6),
             testset_case("e5", 1e-6), testset_case("akzo", 1e-6),
             testset_case("ring", 1e-6, t_end=1e-4), chain_case()]
    if args.rig:
        cases.append(rig_case())
    print(f"Machine: {machine()}")
    print(f"base = {args.base}, this tree; median of {args.repeats} interleaved runs\n")
    print("| problem | steps | nre | same steps, nre, y | residual [us] | wall base [ms] | "
          "wall new [ms] | solver us/step base | solver us/step new | new / base |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|")
    for name, run, (fun, y, yp, t) in cases:
        walls = {"base": [], "new": []}
        out = {}
        for _ in range(args.repeats):
            for label, solver in (("base", base_solve), ("new", new_solve.solve_dae)):
                t0 = time.perf_counter()
                out[label] = run(solver)
                walls[label].append(time.perf_counter() - t0)
        sb, sn = out["base"].stats, out["new"].stats
        same = (sb["nsteps"] == sn["nsteps"] and sb["nre"] == sn["nre"]
                and np.array_equal(np.asarray(out["base"].y), np.asarray(out["new"].y)))
        t_res = residual_cost(fun, np.asarray(y, float), np.asarray(yp, float), t)
        wb, wn = statistics.median(walls["base"]), statistics.median(walls["new"])
        ob = (wb - sb["nre"] * t_res) / sb["nsteps"] * 1e6
        on = (wn - sn["nre"] * t_res) / sn["nsteps"] * 1e6
        print(f"| {name} | {sn['nsteps']} | {sn['nre']} | {'yes' if same else 'NO'} | "
              f"{t_res * 1e6:.1f} | {wb * 1e3:.1f} | {wn * 1e3:.1f} | {ob:.1f} | {on:.1f} | "
              f"{on / ob:.2f} |", flush=True)


if __name__ == "__main__":
    main()
