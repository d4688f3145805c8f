"""The C sparse LU (``pvgraph/solver/clu.c``) against LAPACK getrf / getrs and SuperLU.

Matrices: the iteration matrix J = dF/dy + cj dF/dy' of the PVG 32 rig test 2 (91 unknowns,
the dense LAPACK path of the solver) and of the machine cycle (184 unknowns, SuperLU in the
solver), each 20 ms into a run with cj = 1e4, and random sparse matrices (about 4 entries per
column plus the diagonal, values uniform in [-1, 1]) of 300 and 1000 unknowns.

Timings, medians over interleaved rounds:

* from C: a timing loop compiled here calls ``pv_lu_factor`` (a context factorising from
  scratch, ``reuse=False``, and one reusing the structure of its last factorisation, as in a
  simulation) / ``pv_lu_solve`` and scipy's own
  LAPACK ``dgetrf`` / ``dgetrs`` (the routines ``scipy.linalg.cython_lapack`` exports, which
  ``cstep.c`` calls) through function pointers. getrf overwrites its input, so its loop copies
  the matrix first (a ``memcpy`` of n x n doubles, timed alone too); the sparse LU reads the
  matrix and leaves it;
* end to end: PVG 32 rig test 2 with the Python step, ``LUSolver()`` against
  ``LUSolver(kind="c")`` (substituted for the solver's own ``LUSolver``);
* from Python: ``SparseLU.factor`` / ``solve`` and scipy's ``getrf`` / ``getrs`` wrappers (what
  ``LUSolver`` calls), SuperLU's ``splu`` / ``solve`` on the CSC matrix, and an empty ctypes
  call (the overhead in every Python-side figure of the kernel).

Fill: entries of L + U (unit diagonal of L not counted) for each column ordering, against
SuperLU's ``L.nnz + U.nnz - n`` with its default COLAMD order.

Usage: ``python benchmarks/bench_clu.py [--rounds 15]``
"""

from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import sys
import tempfile
import time
import warnings

import numpy as np
import scipy.sparse as sp
from scipy.linalg import get_lapack_funcs
from scipy.sparse.linalg import splu

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from _machine import machine  # noqa: E402

TIMERS = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <string.h>
#include <time.h>

typedef int64_t (*factor_fn)(void *, const double *);
typedef void (*solve_fn)(const void *, double *);
typedef void (*getrf_fn)(int *, int *, double *, int *, int *, int *);
typedef void (*getrs_fn)(char *, int *, int *, double *, int *, int *, double *, int *, int *);

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

double time_clu_factor(void *fn, void *ctx, const double *a, int64_t reps)
{
    double t0 = now();
    for (int64_t r = 0; r < reps; r++) ((factor_fn) fn)(ctx, a);
    return (now() - t0) / reps;
}

double time_clu_solve(void *fn, void *ctx, const double *b0, double *b, int64_t n, int64_t reps)
{
    double t0 = now();
    for (int64_t r = 0; r < reps; r++) {
        memcpy(b, b0, (size_t) n * sizeof(double));
        ((solve_fn) fn)(ctx, b);
    }
    return (now() - t0) / reps;
}

double time_getrf(void *fn, const double *a, double *work, int *ipiv, int64_t n, int64_t reps)
{
    int ni = (int) n, info = 0;
    double t0 = now();
    for (int64_t r = 0; r < reps; r++) {
        memcpy(work, a, (size_t) (n * n) * sizeof(double));
        ((getrf_fn) fn)(&ni, &ni, work, &ni, ipiv, &info);
    }
    return (now() - t0) / reps;
}

double time_copy(const double *a, double *work, int64_t n, int64_t reps)
{
    double t0 = now();
    for (int64_t r = 0; r < reps; r++) {
        memcpy(work, a, (size_t) (n * n) * sizeof(double));
        __asm__ volatile("" : : "r"(work) : "memory");
    }
    return (now() - t0) / reps;
}

double time_getrs(void *fn, double *lu, int *ipiv, const double *b0, double *b, int64_t n,
                  int64_t reps)
{
    int ni = (int) n, one = 1, info = 0;
    char trans = 'N';
    double t0 = now();
    for (int64_t r = 0; r < reps; r++) {
        memcpy(b, b0, (size_t) n * sizeof(double));
        ((getrs_fn) fn)(&trans, &ni, &one, lu, &ni, ipiv, b, &ni, &info);
    }
    return (now() - t0) / reps;
}

void nop(void) {}
"""


def timers():
    from pvgraph import cbackend
    cc = cbackend.c_compiler()
    if cc is None:
        sys.exit("bench_clu needs a C compiler")
    lib = ctypes.CDLL(str(cbackend.compiled(TIMERS, "the LU timing loops")))
    vp, i64 = ctypes.c_void_p, ctypes.c_int64
    for name, args in (("time_clu_factor", [vp, vp, vp, i64]),
                       ("time_clu_solve", [vp, vp, vp, vp, i64, i64]),
                       ("time_getrf", [vp, vp, vp, vp, i64, i64]),
                       ("time_copy", [vp, vp, i64, i64]),
                       ("time_getrs", [vp, vp, vp, vp, vp, i64, i64])):
        getattr(lib, name).argtypes = args
        getattr(lib, name).restype = ctypes.c_double
    lib.nop.argtypes = []
    lib.nop.restype = None
    return lib


def circuit_matrix(build, t_end):
    """J = dF/dy + 1e4 dF/dy' of a compiled circuit at t_end into a run."""
    from pvgraph.simulate import simulate
    s = build().compile()
    res = simulate(s, t_end, rtol=1e-6)
    return s.jacobian_dense(float(res.t[-1]), res.y[-1], res.yp[-1], 1e4), s.jac_sparsity


def rig():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    p = report_tuned()
    return build_rig(p, load=laminar_load(p, L1="small", L3="small", t_switch=0.01),
                     U_input=4.24)


def machine_circuit():
    from pvgraph.circuits.machine import build_machine
    return build_machine()


def random_matrix(n, per_column, seed):
    rng = np.random.default_rng(seed)
    a = sp.random(n, n, density=per_column / n, random_state=rng,
                  data_rvs=lambda k: rng.uniform(-1.0, 1.0, k)).toarray()
    a += np.diag(rng.uniform(1.0, 2.0, n))
    return a, sp.csc_matrix(a)


def python_time(fn, reps):
    t0 = time.perf_counter()
    for _ in range(reps):
        fn()
    return (time.perf_counter() - t0) / reps


def measure(label, a, pattern, lib, rounds):
    from pvgraph.solver import clu
    from pvgraph.solver.cstep import _scipy_lapack
    getrf_py, getrs_py = get_lapack_funcs(("getrf", "getrs"), (np.empty(1),))
    n = a.shape[0]
    a = np.asfortranarray(a, dtype=float)
    csc = sp.csc_matrix(a)
    fill = {}
    for ordering in clu.ORDERINGS:
        lu = clu.SparseLU(n, pattern, ordering=ordering)
        assert lu.factor(a) == 0
        fill[ordering] = lu.nnz
    ref = splu(csc)
    fill["SuperLU"] = ref.L.nnz + ref.U.nnz - n
    lu = clu.SparseLU(n, pattern)
    scratch = clu.SparseLU(n, perm_c=lu.perm_c, reuse=False)
    assert lu.factor(a) == 0 and scratch.factor(a) == 0
    b0 = np.random.default_rng(0).standard_normal(n)
    b = b0.copy()
    lf, piv, info = getrf_py(a)
    assert info == 0
    x = lu.solve(b0)
    x_ref, _ = getrs_py(lf, piv, b0)
    agree = np.linalg.norm(x - x_ref) / np.linalg.norm(x_ref)
    work = np.empty_like(a)
    ipiv = np.empty(n, dtype=np.int32)
    lu_f = np.asfortranarray(lf)
    piv1 = (piv + 1).astype(np.int32)
    dgetrf, dgetrs = _scipy_lapack("dgetrf"), _scipy_lapack("dgetrs")
    fa, sa = lu.factor_address, lu.solve_address
    big = n > 500
    rf, rs = (20, 400) if big else (300, 4000)
    cases = {
        "C clu factor": lambda: lib.time_clu_factor(fa, lu.ctx, a.ctypes.data, rf),
        "C clu factor, scratch": lambda: lib.time_clu_factor(fa, scratch.ctx, a.ctypes.data,
                                                             rf),
        "C getrf (copy + dgetrf)": lambda: lib.time_getrf(dgetrf, a.ctypes.data, work.ctypes.data,
                                                          ipiv.ctypes.data, n, max(rf // 10, 3)),
        "C copy n x n": lambda: lib.time_copy(a.ctypes.data, work.ctypes.data, n, rf),
        "C clu solve": lambda: lib.time_clu_solve(sa, lu.ctx, b0.ctypes.data, b.ctypes.data, n,
                                                  rs),
        "C getrs": lambda: lib.time_getrs(dgetrs, lu_f.ctypes.data, piv1.ctypes.data,
                                          b0.ctypes.data, b.ctypes.data, n, rs),
        "Py SparseLU.factor": lambda: python_time(lambda: lu.factor(a), rf),
        "Py getrf": lambda: python_time(lambda: getrf_py(a), max(rf // 10, 3)),
        "Py SparseLU.solve": lambda: python_time(lambda: lu.solve(b0), rs // 4),
        "Py getrs": lambda: python_time(lambda: getrs_py(lf, piv, b0), rs // 4),
        "Py splu": lambda: python_time(lambda: splu(csc), max(rf // 10, 3)),
        "Py splu solve": lambda: python_time(lambda: ref.solve(b0), rs // 4),
        "Py empty ctypes call": lambda: python_time(lib.nop, rs),
    }
    times = {k: [] for k in cases}
    for _ in range(rounds):
        for k, f in cases.items():
            times[k].append(f())
    med = {k: statistics.median(v) * 1e6 for k, v in times.items()}
    return {"label": label, "n": n, "nnz": int(np.count_nonzero(a)), "fill": fill,
            "agree": agree, "t": med}


def end_to_end(rounds):
    """PVG 32 rig test 2 (1.01 s from the settled state, rtol 1e-6) with the Python step,
    ``linear_solver="lapack"`` or ``"c"`` (the Python route): statistics and wall time."""
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig, laminar_load
    from pvgraph.simulate import simulate
    from pvgraph.solver import clu
    p = report_tuned()
    settle = build_rig(p, load=laminar_load(p, L1="small", L3="small"), U_input=4.24).compile()
    y0 = simulate(settle, 8.0, rtol=1e-6).y[-1]
    s = rig().compile()
    t_eval = np.linspace(0.0, 1.01, 102)
    made = []
    init = clu.SparseLU.__init__

    def remembered(self, *a, **k):      # the LU contexts the run makes
        init(self, *a, **k)
        made.append(self)

    out = {k: [] for k in ("lapack", "c")}
    stats = {}
    clu.SparseLU.__init__ = remembered
    try:
        for _ in range(rounds):
            for k in out:
                made.clear()
                t0 = time.perf_counter()
                res = simulate(s, 1.01, rtol=1e-6, y0=y0, t_eval=t_eval, c_step=False,
                               linear_solver=k)
                out[k].append(time.perf_counter() - t0)
                stats[k] = (res.stats, res.y, sum(lu.nreused for lu in made))
    finally:
        clu.SparseLU.__init__ = init
    (sa, ya, _), (sc, yc, reused) = stats["lapack"], stats["c"]
    diff = np.max(np.abs(ya - yc) / (1e-6 * np.abs(ya) + 1e-6 * s.nominal))
    sc = dict(sc, nreused=reused)
    return sa, sc, diff, {k: statistics.median(v) for k, v in out.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=15)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    os.environ.setdefault("PVGRAPH_CACHE_DIR", tempfile.mkdtemp(prefix="pv-clu-bench-"))
    print(machine())
    lib = timers()
    mats = [("PVG 32 rig test 2", *circuit_matrix(rig, 0.02)),
            ("machine cycle", *circuit_matrix(machine_circuit, 0.02)),
            ("random, 4 per column + diagonal", *random_matrix(300, 4, 1)),
            ("random, 4 per column + diagonal", *random_matrix(1000, 4, 2))]
    rows = [measure(label, a, pattern, lib, args.rounds) for label, a, pattern in mats]
    print("\nFill: entries of L + U (L's unit diagonal not counted)\n")
    print("| matrix | n | nnz(A) | COLAMD | MMD_ATA | MMD_AT_PLUS_A | NATURAL | SuperLU (COLAMD) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        f = r["fill"]
        print(f"| {r['label']} | {r['n']} | {r['nnz']} | {f['COLAMD']} | {f['MMD_ATA']} | "
              f"{f['MMD_AT_PLUS_A']} | {f['NATURAL']} | {f['SuperLU']} |")
    print("\nFactor [us], medians; ratio = getrf / clu (same structure)\n")
    print("| matrix | n | C: clu, from scratch | C: clu, same structure | C: copy + dgetrf | "
          "(copy alone) | ratio | Python: SparseLU | Python: getrf | ratio | Python: splu |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        t = r["t"]
        print(f"| {r['label']} | {r['n']} | {t['C clu factor, scratch']:.1f} | "
              f"{t['C clu factor']:.1f} | "
              f"{t['C getrf (copy + dgetrf)']:.1f} | {t['C copy n x n']:.1f} | "
              f"{t['C getrf (copy + dgetrf)'] / t['C clu factor']:.1f} | "
              f"{t['Py SparseLU.factor']:.1f} | {t['Py getrf']:.1f} | "
              f"{t['Py getrf'] / t['Py SparseLU.factor']:.1f} | {t['Py splu']:.1f} |")
    print("\nSolve [us], medians; ratio = getrs / clu\n")
    print("| matrix | n | C: clu | C: dgetrs | ratio | Python: SparseLU | Python: getrs | "
          "Python: SuperLU | empty ctypes call | relative difference to LAPACK |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        t = r["t"]
        print(f"| {r['label']} | {r['n']} | {t['C clu solve']:.2f} | {t['C getrs']:.2f} | "
              f"{t['C getrs'] / t['C clu solve']:.1f} | {t['Py SparseLU.solve']:.2f} | "
              f"{t['Py getrs']:.2f} | {t['Py splu solve']:.2f} | "
              f"{t['Py empty ctypes call']:.2f} | {r['agree']:.1e} |")
    sa, sc, diff, wall = end_to_end(max(3, args.rounds // 3))
    print("\nPVG 32 rig test 2, 1.01 s, rtol 1e-6, Python step (c_step=False), LUSolver kind:\n")
    print("| LU | steps | nlu | nni | wall [ms] |")
    print("|---|---:|---:|---:|---:|")
    for k, st in (("lapack", sa), ("c", sc)):
        print(f"| {k} | {st['nsteps']} | {st['nlu']} | {st['nni']} | {wall[k] * 1e3:.1f} |")
    print(f"\nratio lapack / c: {wall['lapack'] / wall['c']:.2f}; largest difference of the "
          f"outputs: {diff:.2g} error weights (rtol |y| + atol); factorisations done "
          f"entirely on the previous structure: {sc['nreused']} of {sc['nlu']}")


if __name__ == "__main__":
    main()
