"""Work-precision of pvgraph's IDA-style solver against SUNDIALS IDA (scikit-sundae).

For the Bari IVP Test Set problems Chemical Akzo Nobel and Transistor Amplifier, at several
tolerances rtol = atol = tol, both solvers integrate the same residual (same Python
function, same analytic Jacobian unless ``--fd``) from the same consistent initial values
with output at every internal step, in one process. Reported per solver: the median wall
time over ``--repeats`` runs, residual evaluations (nre), steps, and the mixed significant
correct digits (mescd) at t_end; and the wall-time ratio pvgraph / IDA.

Both solvers run with the same error-test configuration (no algebraic variables are
suppressed, which is scikit-sundae's setting and pvgraph's default); rows ``Akzo supalg`` pass
the algebraic mask and ``suppress_alg=True``, so pvgraph leaves y6 out of its error test
(IDA's suppressalg) while scikit-sundae's IDA still includes it. Runs of the two solvers are interleaved.

Usage::

    python benchmarks/bench_solver.py [--repeats 5] [--fd] [--quick]
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
from pvgraph.solver import solve_dae, solve_dae_sundials
from pvgraph.solver.testset import AKZO, TRANSISTOR, mescd

CASES = [
    (AKZO, [1e-4, 1e-6, 1e-8, 1e-10]),
    (TRANSISTOR, [1e-4, 1e-5, 1e-6, 1e-7]),
]
QUICK_CASES = [(AKZO, [1e-4, 1e-6]), (TRANSISTOR, [1e-4])]


def run(solver, problem, tol, fd, suppressalg=False):
    """One timed solve; returns (seconds, result)."""
    kwargs = dict(rtol=tol, atol=tol, calc_initial=None, max_steps=10**6)
    if not fd:
        kwargs["jac"] = problem.jac
    if suppressalg:
        kwargs["algebraic"] = problem.algebraic
        if solver is solve_dae:
            kwargs["suppress_alg"] = True
    t = time.perf_counter()
    res = solver(problem.residual, problem.t_span, problem.y0, problem.yp0, **kwargs)
    return time.perf_counter() - t, res


def measure(problem, tol, repeats, fd, suppressalg=False):
    """Median wall times of both solvers, runs interleaved so machine load hits both alike."""
    t_pv, t_ida = [], []
    for _ in range(repeats):
        dt, r_pv = run(solve_dae, problem, tol, fd, suppressalg)
        t_pv.append(dt)
        dt, r_ida = run(solve_dae_sundials, problem, tol, fd, suppressalg)
        t_ida.append(dt)
    return statistics.median(t_pv), r_pv, statistics.median(t_ida), r_ida


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--fd", action="store_true", help="finite-difference Jacobians")
    parser.add_argument("--quick", action="store_true", help="fewer tolerances")
    args = parser.parse_args()
    print(machine())
    print(f"repeats={args.repeats}, Jacobian: {'finite differences' if args.fd else 'analytic'}")
    header = (f"| {'problem':<11} | {'tol':>7} | {'pvgraph s':>9} | {'nre':>6} | {'steps':>6} "
              f"| {'mescd':>5} | {'IDA s':>8} | {'nre':>6} | {'steps':>6} | {'mescd':>5} "
              f"| {'ratio':>5} |")
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")
    ratios = []
    for solver in (solve_dae, solve_dae_sundials):     # warm-up: imports, first-call caches
        run(solver, AKZO, 1e-4, args.fd)
    for problem, tols in (QUICK_CASES if args.quick else CASES):
        short = "Akzo" if "Akzo" in problem.name else "Transistor"
        variants = [(False, "")]
        if problem.algebraic:
            variants.append((True, "suppressalg"))
        for tol in tols:
            for suppress, tag in variants:
                t_pv, r_pv, t_ida, r_ida = measure(problem, tol, args.repeats, args.fd,
                                                   suppress)
                m_pv = mescd(r_pv.y[-1], problem.y_ref, tol, tol)
                m_ida = mescd(r_ida.y[-1], problem.y_ref, tol, tol)
                ratio = t_pv / t_ida
                if not suppress:
                    ratios.append(ratio)
                name = short if not suppress else "Akzo supalg"
                print(f"| {name:<11} | {tol:7.0e} | {t_pv:9.4f} | {r_pv.stats['nre']:6d} "
                      f"| {r_pv.stats['nsteps']:6d} | {m_pv:5.2f} | {t_ida:8.4f} "
                      f"| {r_ida.stats['nre']:6d} | {r_ida.stats['nsteps']:6d} | {m_ida:5.2f} "
                      f"| {ratio:5.2f} |")
    print(f"median wall-time ratio pvgraph/IDA (same configuration): "
          f"{statistics.median(ratios):.2f}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
