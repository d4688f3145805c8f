"""Work-precision on the Bari IVP Test Set: pvgraph against SUNDIALS IDA and CasADi IDAS.

For every problem of ``pvgraph.solver.testset`` and rtol in 1e-4, 1e-6, 1e-8 (the Ring
Modulator 1e-4 and 1e-6 only) with the test set's atol, three solvers start from the same
consistent values and report, in one run:

* **pvgraph**: ``solve_dae`` with default options (the problem's algebraic list, analytic
  Jacobian, output at every step);
* **IDA**: SUNDIALS IDA through scikit-sundae's own ``solve`` (its C loop, Python residual
  and Jacobian callbacks, algebraic variables in the error test: IDA's defaults);
* **IDAS**: CasADi's IDAS on the same residual written in SX (``residual_lib``), exact AD
  Jacobians, compiled evaluation in CasADi's virtual machine. The Transistor Amplifier,
  whose mass matrix is not diagonal, has no semi-explicit form here and is left out.

Columns: steps, residual evaluations (nre), mescd at t_end, median wall time over
``--repeats`` runs (interleaved) and the ratios pvgraph / IDA and pvgraph / IDAS.
With ``--variants`` pvgraph is also run with ``suppress_alg`` and ``NO_GROWTH_AFTER_FAILURE``
switched (steps and mescd, to decide the defaults).

With ``--compiled`` a second table compares, on the same rows, pvgraph on the residual traced
from ``residual_lib`` and compiled to C (:func:`pvgraph.dae.compile_dae` with ``backend="c"``,
exact symbolic Jacobian, ``solve_dae``'s defaults for it: the step and the integration loop in
C and the C sparse LU; the counterpart of CasADi's compiled SX) with
IDAS, next to pvgraph on the Python residual. Times exclude the one-off compilations on both
sides (CasADi's integrator construction, pvgraph's tracing and C build).

With ``--spread`` each row also reports the median steps and mescd of pvgraph and IDA over
the tolerances tol (1 + d), d in 0, +-1e-4, +-2e-4, +-5e-4, +-1e-3, +-2e-3 (rtol and atol
scaled together). The step-size sequence of both solvers is chaotic in the last bit (HIRES at
1e-8: 934-1223 steps and mescd 6.9-7.8 for pvgraph, 941-1157 and 7.0-8.4 for IDA over these
11 tolerances), so a single tolerance can show differences of 2x in steps or 1.5 digits that
are not there on the medians.

Usage::

    python benchmarks/bench_testset.py [--repeats 3] [--variants] [--spread] [--compiled]
        [--problems hires,e5]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _machine import machine  # noqa: E402
from pvgraph.solver import ida as ida_module  # noqa: E402
from pvgraph.solver import solve_dae  # noqa: E402
from pvgraph.solver.testset import PROBLEMS, mescd  # noqa: E402

TOLS = (1e-4, 1e-6, 1e-8)
LONG_TOLS = (1e-4, 1e-6)
SPREAD = (0.0, -1e-4, 1e-4, -2e-4, 2e-4, -5e-4, 5e-4, -1e-3, 1e-3, -2e-3, 2e-3)


def run_pvgraph(p, tol, suppress_alg=None, no_growth=None, scale=1.0):
    """solve_dae with its defaults (the two options only when given); atol times ``scale``."""
    kw = {} if suppress_alg is None else {"suppress_alg": suppress_alg}
    if no_growth is not None:
        kw["no_growth_after_failure"] = no_growth
    t = time.perf_counter()
    res = solve_dae(p.residual, p.t_span, p.y0, p.yp0, rtol=tol * scale,
                    atol=p.atol(tol) * scale, jac=p.jac, algebraic=p.algebraic,
                    calc_initial=None, max_steps=10**7, **kw)
    return time.perf_counter() - t, res.stats["nsteps"], res.stats["nre"], res.y[-1]


def spread(p, tol):
    """Median (steps, mescd) of pvgraph and of IDA over the tolerances tol (1 + SPREAD)."""
    cells = []
    for label, run in (("pvgraph", lambda s: run_pvgraph(p, tol, scale=s)),
                       ("IDA", lambda s: make_ida(p, tol, scale=s)())):
        outs = [run(1.0 + d) for d in SPREAD]
        steps = statistics.median(o[1] for o in outs)
        digits = statistics.median(mescd(o[3], p.y_ref, p.atol(tol), tol) for o in outs)
        lo, hi = min(o[1] for o in outs), max(o[1] for o in outs)
        cells.append(f"{label} {steps:.0f} ({lo}-{hi}) {digits:.2f}")
    return "; ".join(cells)


def make_ida(p, tol, scale=1.0):
    import sksundae
    n = p.y0.size

    def resfn(t, y, yp, res):
        res[:] = p.residual(t, y, yp)

    def jacfn(t, y, yp, res, cj, jj):
        jj[:, :] = p.jac(t, y, yp, cj)

    solver = sksundae.ida.IDA(resfn, jacfn=jacfn, rtol=tol * scale,
                              atol=np.full(n, p.atol(tol) * scale), algebraic_idx=p.algebraic,
                              max_num_steps=10**7)

    def run():
        t = time.perf_counter()
        sol = solver.solve(np.array(p.t_span), p.y0, p.yp0)
        dt = time.perf_counter() - t
        if not sol.success:
            raise RuntimeError(sol.message)
        return dt, sol.t.size - 1, int(sol.nfev), sol.y[-1]
    return run


def make_idas(p, tol):
    """CasADi IDAS integrator for problems with M = diag(1 or 0) (None otherwise)."""
    import casadi as ca
    if p.residual_lib is None or p.name.startswith("Transistor"):
        return None
    n = p.y0.size
    alg = sorted(p.algebraic or [])
    dif = [i for i in range(n) if i not in alg]
    x = ca.SX.sym("x", len(dif))
    z = ca.SX.sym("z", len(alg))
    t = ca.SX.sym("t")
    y = [None] * n
    for k, i in enumerate(dif):
        y[i] = x[k]
    for k, i in enumerate(alg):
        y[i] = z[k]
    res = p.residual_lib(t, y, [0.0] * n, ca)
    dae = {"x": x, "t": t, "ode": -ca.vertcat(*[res[i] for i in dif])}
    if alg:
        dae.update(z=z, alg=ca.vertcat(*[res[i] for i in alg]))
    def integrator(calc_ic):
        # IDAS starts from y' = 0 unless IDACalcIC runs; that fails on Robertson, where the
        # start is consistent anyway (y'(0) = 0 for the algebraic part)
        return ca.integrator("F", "idas", dae, p.t_span[0], [p.t_span[1]],
                             {"abstol": p.atol(tol), "reltol": tol, "max_num_steps": 10**7,
                              "calc_ic": calc_ic})

    f = integrator(True)

    def run():
        nonlocal f
        t0 = time.perf_counter()
        try:
            out = f(x0=p.y0[dif], z0=p.y0[alg] if alg else [])
        except RuntimeError:
            f = integrator(False)
            t0 = time.perf_counter()
            out = f(x0=p.y0[dif], z0=p.y0[alg] if alg else [])
        dt = time.perf_counter() - t0
        yf = np.empty(n)
        yf[dif] = np.asarray(out["xf"]).ravel()
        if alg:
            yf[alg] = np.asarray(out["zf"]).ravel()
        st = f.stats()
        return dt, int(st["nsteps"]), int(st["nfevals"]), yf
    return run


def make_pvgraph_c(p, tol):
    """pvgraph on the traced, C-compiled residual of ``residual_lib`` (None without one)."""
    from pvgraph.dae import compile_dae
    if p.residual_lib is None:
        return None
    system = compile_dae(p.residual_lib, p.y0, p.yp0, names=p.var_names, backend="c")
    jac = system.solver_jacobian()

    def run():
        t = time.perf_counter()
        res = solve_dae(system.residual, p.t_span, p.y0, p.yp0, rtol=tol, atol=p.atol(tol),
                        jac=jac, algebraic=p.algebraic, calc_initial=None, max_steps=10**7)
        return time.perf_counter() - t, res.stats["nsteps"], res.stats["nre"], res.y[-1]
    return run


def compiled_table(problems, repeats):
    """pvgraph (Python residual), pvgraph (compiled C) and IDAS, row by row."""
    head = ("| problem | rtol | pvgraph Python: steps | mescd | ms | pvgraph C: steps | nre | "
            "mescd | ms | IDAS steps | nre | mescd | ms | Python/C | C/IDAS |")
    print("\n" + head)
    print("|" + "---|" * (head.count("|") - 1))
    ratios = []
    for key in problems:
        p = PROBLEMS[key]
        for tol in (LONG_TOLS if p.slow else TOLS):
            reps = 1 if p.slow else repeats
            m = lambda yf: mescd(yf, p.y_ref, p.atol(tol), tol)  # noqa: E731
            run_c = make_pvgraph_c(p, tol)
            if run_c is None:
                continue
            t_pv, (_, s_pv, _, y_pv) = median_run(lambda: run_pvgraph(p, tol), reps)
            run_c()      # once untimed on both sides: the C step's kernel loads on first use
            t_c, (_, s_c, n_c, y_c) = median_run(run_c, reps)
            row = (f"| {p.name} | {tol:.0e} | {s_pv} | {m(y_pv):.2f} | {t_pv * 1e3:.1f} | "
                   f"{s_c} | {n_c} | {m(y_c):.2f} | {t_c * 1e3:.2f} ")
            idas = run_idas(p, tol, reps, warm=True)
            if idas is not None:
                t_i, s_i, n_i, y_i = idas
                ratios.append(t_c / t_i)
                row += (f"| {s_i} | {n_i} | {m(y_i):.2f} | {t_i * 1e3:.2f} | {t_pv / t_c:.1f} "
                        f"| {t_c / t_i:.2f} |")
            else:
                row += f"| - | - | - | - | {t_pv / t_c:.1f} | - |"
            print(row, flush=True)
    print(f"median wall ratio pvgraph C / IDAS {statistics.median(ratios):.2f} "
          f"({len(ratios)} rows)")


def run_idas(p, tol, repeats, warm=False):
    """(median wall, steps, nre, y_end) of CasADi IDAS, or None where it has no form or fails.

    ``warm``: one untimed run first."""
    idas = make_idas(p, tol)
    if idas is None:
        return None
    try:
        if warm:
            idas()
        t, (_, steps, nre, y) = median_run(idas, repeats)
    except RuntimeError:
        return None
    return t, steps, nre, y


def median_run(run, repeats):
    outs = [run() for _ in range(repeats)]
    return statistics.median(o[0] for o in outs), outs[-1]


def variants(p, tol):
    """(steps, mescd) of pvgraph with suppress_alg x NO_GROWTH_AFTER_FAILURE switched."""
    cells = []
    for no_growth in (True, False):
        for supp in ((True, False) if p.algebraic else (False,)):
            _, steps, _, yf = run_pvgraph(p, tol, supp, no_growth)
            cells.append(f"{'S' if supp else 's'}{'G' if no_growth else 'g'} {steps} "
                         f"{mescd(yf, p.y_ref, p.atol(tol), tol):.2f}")
    return "; ".join(cells)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--variants", action="store_true")
    parser.add_argument("--spread", action="store_true",
                        help="medians over tolerances perturbed by up to 0.2 %%")
    parser.add_argument("--problems", default=",".join(PROBLEMS))
    parser.add_argument("--compiled", action="store_true",
                        help="only the table of pvgraph on traced, C-compiled residuals")
    args = parser.parse_args()
    print(machine())
    if args.compiled:
        compiled_table(args.problems.split(","), args.repeats)
        return
    print(f"repeats={args.repeats}; pvgraph NO_GROWTH_AFTER_FAILURE="
          f"{ida_module.NO_GROWTH_AFTER_FAILURE}")
    head = ("| problem | rtol | pvgraph steps | nre | mescd | ms | IDA steps | nre | mescd | ms "
            "| IDAS steps | nre | mescd | ms | pv/IDA | pv/IDAS |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    r_ida, r_idas = [], []
    for key in args.problems.split(","):
        p = PROBLEMS[key]
        for tol in (LONG_TOLS if p.slow else TOLS):
            reps = 1 if p.slow else args.repeats
            t_pv, (_, s_pv, n_pv, y_pv) = median_run(lambda: run_pvgraph(p, tol), reps)
            t_ida, (_, s_ida, n_ida, y_ida) = median_run(make_ida(p, tol), reps)
            m = lambda yf: mescd(yf, p.y_ref, p.atol(tol), tol)  # noqa: E731
            row = (f"| {p.name} | {tol:.0e} | {s_pv} | {n_pv} | {m(y_pv):.2f} | {t_pv * 1e3:.1f} "
                   f"| {s_ida} | {n_ida} | {m(y_ida):.2f} | {t_ida * 1e3:.1f} ")
            r_ida.append(t_pv / t_ida)
            idas = run_idas(p, tol, reps)
            if idas is not None:
                t_c, s_c, n_c, y_c = idas
                r_idas.append(t_pv / t_c)
                row += (f"| {s_c} | {n_c} | {m(y_c):.2f} | {t_c * 1e3:.1f} "
                        f"| {t_pv / t_ida:.2f} | {t_pv / t_c:.1f} |")
            else:
                row += f"| - | - | - | - | {t_pv / t_ida:.2f} | - |"
            print(row, flush=True)
            if args.variants:
                print(f"|   variants (S/s suppress_alg on/off, G/g no-growth on/off: steps "
                      f"mescd): {variants(p, tol)} |", flush=True)
            if args.spread:
                print(f"|   spread (median steps (range) and median mescd over "
                      f"{len(SPREAD)} tolerances): {spread(p, tol)} |", flush=True)
    print(f"median wall ratio pvgraph/IDA {statistics.median(r_ida):.2f}, "
          f"pvgraph/IDAS {statistics.median(r_idas):.1f}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
