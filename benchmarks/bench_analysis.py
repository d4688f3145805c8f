"""Analysis speed: sweep backends, and the cost of the calibration model.

What is measured, and why
-------------------------
1. **Sweep backends** (``pvgraph.analysis.sweep``). The same cases of two realistic per-case
   jobs run on ``backend="serial"``, ``"process"`` (a process pool of 2 workers, started by
   each sweep) and ``"dask"`` (a ``LocalCluster`` of 2 worker processes with 1 thread each):

   - *steady*: the rig's steady state at a PVE voltage from a grid (build + compile the rig,
     ``steady_state``), about 0.14 s per case -- what a parameter study of operating points
     costs;
   - *scenario*: ``run_scenario`` of solenoid-step test 9 (8 s settle + 2 s after the step, as
     ``pvgraph validate`` / ``pvgraph sweep`` run it) at a voltage from a grid, about 0.2 s.

   The Dask cluster's start-up is timed apart from the sweeps. On each fresh cluster two sweeps
   run: the first ("cold") pays for the workers importing pvgraph and numpy/scipy and warming
   their caches, the second ("warm") is what every further sweep on a kept cluster costs.
   ``overhead per case`` is the worker time a case costs beyond its serial cost,
   ``(W * T_backend - T_serial) / n`` with W = 2 workers: 0 for a perfect 2x speed-up. It
   contains pool start-up, pickling and scheduling spread over the cases, and any slow-down of
   the case itself by the two processes competing for the 2 cores (the parent process that
   collects the results runs on them too). ``case in worker`` is the median time ``run``
   itself took where it ran (``CaseResult.wall_time``).
2. **Calibration model** (``circuits/calibration.py``). One evaluation of the 17 calibration
   scenarios' steady states through ``RigSteadyModel`` (13 distinct rig configurations, one
   steady solve each), cold (no previous solution) and warm (started from the previous
   evaluation's solutions, the parameters moved by the fit's finite-difference step), serial
   and on 2 worker processes; against obtaining the same values by simulating every scenario
   with ``run_scenario`` as ``pvgraph validate`` does, serially and on 2 workers. The agreement
   of the two (largest difference in bar and L/min) shows the steady solve gives the tabulated
   quantities; the times show why ``calibrate_rig`` uses it. One full ``calibrate_rig()``
   (default fit, two weighting passes, workers=2) is timed once, with its number of model
   evaluations.
3. **Peak memory.** Peak resident set size (VmHWM) of the *steady* sweep run in a fresh
   interpreter per backend: the parent process, and the largest of its worker processes (each
   case reports the peak of the process it ran in), beside an interpreter that only imports
   and builds the cases. Pool workers are forked, so their RSS includes the pages they share
   copy-on-write with the parent; Dask workers are fresh interpreters.

Times are medians over ``--repeats`` rounds (default 5); in each round the backends run one
after the other (interleaved), so slow drifts of the machine load hit all of them alike. Ratios
are from the same run. Other processes on a 2-core machine slow the parallel backends but not
the serial one, so the CPU that other processes used during the rounds is reported too.

Run: ``python benchmarks/bench_analysis.py`` (about 5 min on 2 cores);
``python benchmarks/bench_analysis.py --quick`` for a smoke run (4 cases, 1 round, no
``calibrate_rig`` and no memory probe).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _machine import machine  # noqa: E402
from pvgraph.circuits.pvg32.parameters import report_tuned  # noqa: E402
from pvgraph.circuits.rig import build_rig, laminar_load  # noqa: E402
from pvgraph.circuits.scenarios import Scenario, get_scenario  # noqa: E402
from pvgraph.circuits.validation import run_scenario, validate  # noqa: E402
from pvgraph.analysis import steady_state  # noqa: E402
from pvgraph.analysis.sweep import sweep  # noqa: E402
from pvgraph.units import to_bar, to_lpm  # noqa: E402

WORKERS = 2
STEADY_TOL = 1e-10


# --------------------------------------------------------------------------------------------
# per-case jobs (module level: the process pool pickles them by reference, Dask by value)
def steady_job(U_input: float) -> dict:
    """The rig's steady state (voltage-sweep configuration: L3 large, L2 closed) at U_input."""
    p = report_tuned()
    system = build_rig(p, load=laminar_load(p, L1="small", L3="large", l2_open=False,
                                            t_switch=None), U_input=U_input).compile()
    op = steady_state(system, tol=STEADY_TOL)
    return {"Q_total": op["load.L2.q"] + op["load.L3.q"], "Pf": op["load.f.port.p"],
            "Pb": op["load.b.port.p"]}


def scenario_job(U_input: float) -> dict:
    """Solenoid-step test 9 (8 s settle, L2 closes, 2 s on) at U_input, as pvgraph sweep runs it."""
    s = Scenario.model_validate({**dict(get_scenario("test-9")), "U_input": U_input})
    r = run_scenario(s, report_tuned())
    return {**r.simulated, "steps": float(r.steps)}


JOBS = {"steady": (steady_job, (3.9, 5.5)), "scenario": (scenario_job, (4.2, 4.8))}


def cases_for(job: str, n: int) -> list[dict]:
    lo, hi = JOBS[job][1]
    return [{"U_input": float(u)} for u in np.linspace(lo, hi, n)]


def med(values) -> float:
    return statistics.median(values)


class OtherLoad:
    """CPU used by processes other than this one and its children while a block runs [cores].

    The machine's busy time (/proc/stat) minus this process tree's CPU time (``os.times``;
    worker processes count once they have been reaped, i.e. after their pool or cluster
    closed), over the wall time. Other jobs on a 2-core machine slow the parallel backends and
    not the serial one, so every round reports it. NaN where /proc/stat is unavailable.
    """

    def __init__(self):
        self.samples: list[float] = []

    @staticmethod
    def _busy() -> float:
        try:
            with open("/proc/stat") as f:
                v = [int(x) for x in f.readline().split()[1:]]
        except OSError:
            return float("nan")
        # user nice system idle iowait irq softirq steal ...
        return (v[0] + v[1] + v[2] + v[5] + v[6]) / os.sysconf("SC_CLK_TCK")

    def __enter__(self):
        self.t0, self.b0, self.c0 = time.perf_counter(), self._busy(), sum(os.times()[:4])
        return self

    def __exit__(self, *exc):
        wall = time.perf_counter() - self.t0
        own = sum(os.times()[:4]) - self.c0
        self.samples.append(max(0.0, (self._busy() - self.b0 - own) / wall))

    def summary(self) -> str:
        return (f"other processes' CPU load during the rounds: median {med(self.samples):.2f}, "
                f"max {max(self.samples):.2f} cores")


def vm_hwm_mb() -> float:
    """Peak resident set size of this process [MB] (VmHWM: reset at exec, unlike ru_maxrss)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def quiet_dask():
    # workers read this when they import distributed: no "failed heartbeat" traceback from a
    # worker racing the scheduler's shutdown (a failed case still fails check())
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")
    for name in ("distributed", "distributed.worker", "distributed.nanny", "distributed.scheduler",
                 "distributed.core", "distributed.http.proxy"):
        logging.getLogger(name).setLevel(logging.ERROR)


def start_cluster():
    import distributed
    cluster = distributed.LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
    client = distributed.Client(cluster, set_as_default=False)
    client.wait_for_workers(WORKERS)
    return cluster, client


def check(result, reference=None):
    if result.failed:
        raise RuntimeError(f"{len(result.failed)} cases failed: {result.failed[0].error}")
    if reference is not None:
        for name in reference.output_names:
            a, b = result.column(name), reference.column(name)
            if not np.allclose(a, b, rtol=1e-6, atol=1e-9 * max(1.0, np.max(np.abs(b)))):
                raise RuntimeError(f"{result.backend} differs from serial in {name}")


# --------------------------------------------------------------------------------------------
# 1. sweep backends
def bench_sweeps(job: str, n: int, repeats: int) -> dict:
    run = JOBS[job][0]
    cases = cases_for(job, n)
    t = {k: [] for k in ("serial", "process", "dask_start", "dask_cold", "dask_warm",
                         "dask_close", "dask_all")}
    inner = {k: [] for k in ("serial", "process", "dask_cold", "dask_warm")}
    load = OtherLoad()
    for _ in range(repeats):
        with load:
            ref = sweep(run, cases, backend="serial")
            check(ref)
            t["serial"].append(ref.wall_time)
            inner["serial"].append(med(ref.column("wall_time")))

            res = sweep(run, cases, backend="process", workers=WORKERS)
            check(res, ref)
            t["process"].append(res.wall_time)
            inner["process"].append(med(res.column("wall_time")))

            t0 = time.perf_counter()
            cluster, client = start_cluster()
            t["dask_start"].append(time.perf_counter() - t0)
            try:
                for key in ("dask_cold", "dask_warm"):
                    res = sweep(run, cases, backend="dask", client=client)
                    check(res, ref)
                    t[key].append(res.wall_time)
                    inner[key].append(med(res.column("wall_time")))
            finally:
                t0 = time.perf_counter()
                client.close()
                cluster.close()
                t["dask_close"].append(time.perf_counter() - t0)
            # what sweep(backend="dask", workers=2) without a client costs: start, one sweep, close
            t["dask_all"].append(t["dask_start"][-1] + t["dask_cold"][-1] + t["dask_close"][-1])
    return {"job": job, "n": n, "t": {k: med(v) for k, v in t.items()},
            "inner": {k: med(v) for k, v in inner.items()}, "load": load.summary()}


def sweep_table(results: list[dict]) -> str:
    rows = ["| job | cases | backend | wall [s] | per case [ms] | speed-up vs serial "
            "| overhead per case [ms] | case in worker [ms] |",
            "|---|---:|---|---:|---:|---:|---:|---:|"]
    labels = [("serial", "serial"), ("process", "process pool, 2 workers"),
              ("dask_cold", "Dask, first sweep on a fresh cluster"),
              ("dask_warm", "Dask, next sweep on the same cluster"),
              ("dask_all", "Dask incl. cluster start + close")]
    for r in results:
        ts, n = r["t"]["serial"], r["n"]
        for key, label in labels:
            wall = r["t"][key]
            w = 1 if key == "serial" else WORKERS
            over = (w * wall - ts) / n
            inner = r["inner"].get(key)
            rows.append(f"| {r['job']} | {n} | {label} | {wall:.2f} | {1e3 * wall / n:.0f} | "
                        f"{ts / wall:.2f} | {'-' if key == 'serial' else f'{1e3 * over:.0f}'} | "
                        f"{'-' if inner is None else f'{1e3 * inner:.0f}'} |")
    starts = ", ".join(f"{r['t']['dask_start']:.2f} s" for r in results)
    closes = ", ".join(f"{r['t']['dask_close']:.2f} s" for r in results)
    rows.append("")
    rows.append(f"Dask LocalCluster (2 processes x 1 thread) start-up, median: {starts}; "
                f"close: {closes} (per job, in the order above).")
    for r in results:
        rows.append(f"{r['job']} sweeps: {r['load']}.")
    return "\n".join(rows)


# --------------------------------------------------------------------------------------------
# 2. calibration model
def _get(p, path):
    for part in path.split("."):
        p = getattr(p, part)
    return p


def bench_calibration(repeats: int, full_fit: bool) -> str:
    from pvgraph.circuits.calibration import DEFAULT_FIT, RigSteadyModel, calibrate_rig, calibration_data
    from pvgraph.analysis.calibrate import DIFF_STEP

    base = report_tuned()
    data = calibration_data()
    names = sorted({d.scenario for d in data}, key=lambda s: (s.split("-")[0],
                                                             int(s.split("-")[1])))
    theta = {k: float(_get(base, k)) for k in DEFAULT_FIT}
    moved = dict(theta)
    moved["rig.supply_voltage"] *= 1.0 + DIFF_STEP      # one finite-difference step of the fit
    t = {k: [] for k in ("cold1", "warm1", "cold2", "warm2", "sim1", "sim2", "compile")}
    pred = sims = None
    n_configs = None
    for _ in range(repeats):
        for w in (1, 2):
            with RigSteadyModel(base, data, workers=w) as model:
                t0 = time.perf_counter()
                pred = model(theta)
                t[f"cold{w}"].append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                model(moved)
                t[f"warm{w}"].append(time.perf_counter() - t0)
                n_configs = len(model.configs)
                configs = model.configs
        # the compile part of an evaluation (the same 13 rigs built and compiled, no solve)
        t0 = time.perf_counter()
        for U, L1, L3, l2 in configs:
            build_rig(base, load=laminar_load(base, L1=L1, L3=L3, l2_open=l2, t_switch=None),
                      U_input=U).compile()
        t["compile"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        serial = {n: run_scenario(n, base) for n in names}
        t["sim1"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        results = validate(base, names, workers=2)
        t["sim2"].append(time.perf_counter() - t0)
        failed = [r.name for r in results if r.error]
        if failed:
            raise RuntimeError(f"scenarios failed: {failed}")
        sims = {r.name: r for r in results}
        for n in names:
            assert all(np.isclose(serial[n].simulated[q], v, rtol=1e-9, atol=1e-9)
                       for q, v in sims[n].simulated.items())
    m = {k: med(v) for k, v in t.items()}

    diff_bar, diff_lpm, worst = 0.0, 0.0, {}
    for d, value in zip(data, pred):
        sim = sims[d.scenario].simulated[d.quantity]
        sim = to_lpm(sim) if d.quantity.startswith("Q") else to_bar(sim)
        e = abs(value - sim)
        if d.quantity.startswith("Q"):
            if e > diff_lpm:
                diff_lpm, worst["lpm"] = e, d.label
        elif e > diff_bar:
            diff_bar, worst["bar"] = e, d.label

    out = [f"One evaluation of the calibration model: {len(names)} scenarios, {len(data)} data, "
           f"{n_configs} distinct rig configurations (one steady solve each).", "",
           "| how the 17 scenarios' steady values are obtained | 1 worker [s] | 2 workers [s] "
           "| / simulation, 1 worker | / simulation, 2 workers |", "|---|---:|---:|---:|---:|"]
    for key, how in (("cold", "steady states (RigSteadyModel), cold start"),
                     ("warm", "steady states, warm start (after a finite-difference step)"),
                     ("sim", "simulating each scenario, 8-10 s (run_scenario / validate)")):
        a, b = m[f"{key}1"], m[f"{key}2"]
        out.append(f"| {how} | {a:.2f} | {b:.2f} | {a / m['sim1']:.2f} | {b / m['sim2']:.2f} |")
    out.append("")
    out.append("2 workers: RigSteadyModel(workers=2) (its process pool started inside the cold "
               "evaluation) and validate(workers=2).")
    out.append("")
    out.append(f"Of a serial evaluation, building and compiling the {n_configs} rigs takes "
               f"{m['compile']:.2f} s (cold {100 * m['compile'] / m['cold1']:.0f} %, warm "
               f"{100 * m['compile'] / m['warm1']:.0f} %).")
    out.append(f"Agreement steady state vs simulation over the {len(data)} data: largest "
               f"difference {diff_bar:.4f} bar ({worst.get('bar')}), {diff_lpm:.4f} L/min "
               f"({worst.get('lpm')}).")
    if full_fit:
        t0 = time.perf_counter()
        result, _ = calibrate_rig(workers=2)
        wall = time.perf_counter() - t0
        out.append(f"calibrate_rig() (default fit: {len(result.names)} parameters, 2 passes, "
                   f"workers=2), once: {wall:.1f} s wall, {result.nfev} model evaluations "
                   f"({result.nfev * n_configs} steady solves, {wall / result.nfev:.2f} s per "
                   f"evaluation), success={result.success}; the same evaluations by simulation "
                   f"(validate, 2 workers) would take about {result.nfev * m['sim2']:.0f} s.")
    return "\n".join(out)


# --------------------------------------------------------------------------------------------
# 3. peak memory (each backend in a fresh interpreter)
def steady_job_mem(U_input: float) -> dict:
    """steady_job, and the peak RSS of the process it ran in."""
    return {**steady_job(U_input), "vm_hwm": vm_hwm_mb()}


def memory_probe(backend: str, n: int) -> None:
    cases = cases_for("steady", n)
    worker = float("nan")
    if backend != "none":
        if backend == "dask":
            quiet_dask()
        res = sweep(steady_job_mem, cases, backend=backend, workers=WORKERS)
        check(res)
        worker = float(np.max(res.column("vm_hwm")))
    print(json.dumps({"self": vm_hwm_mb(), "worker": worker}))


def bench_memory(n: int) -> str:
    rows = ["| steady sweep, fresh interpreter | parent peak RSS [MB] "
            "| largest worker peak RSS [MB] |", "|---|---:|---:|"]
    for backend, label in (("none", "imports and cases only, no sweep"), ("serial", "serial"),
                           ("process", "process pool, 2 workers"),
                           ("dask", "Dask LocalCluster, 2 workers")):
        out = subprocess.run([sys.executable, __file__, "--memory-probe", backend, "--cases",
                              str(n)], capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        child = "-" if backend in ("none", "serial") else f"{r['worker']:.0f}"
        rows.append(f"| {label} | {r['self']:.0f} | {child} |")
    return "\n".join(rows)


# --------------------------------------------------------------------------------------------
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run: 4 cases, 1 round, no "
                    "calibrate_rig, no memory probe")
    ap.add_argument("--repeats", type=int, default=5, help="rounds (default %(default)s)")
    ap.add_argument("--cases", type=int, default=16, help="cases per sweep (default %(default)s)")
    ap.add_argument("--parts", default="sweeps,calibration,memory",
                    help="comma-separated parts to run (default %(default)s)")
    ap.add_argument("--memory-probe", choices=("none", "serial", "process", "dask"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_probe:
        memory_probe(args.memory_probe, args.cases)
        return
    quiet_dask()
    repeats, n = (1, 4) if args.quick else (args.repeats, args.cases)
    print(f"Machine: {machine()}")
    import dask
    import distributed
    print(f"numpy {np.__version__}, dask {dask.__version__}, distributed "
          f"{distributed.__version__}; {repeats} round(s), {n} cases per sweep; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}\n")
    parts = set(args.parts.split(","))
    if "sweeps" in parts:
        results = []
        for job in JOBS:
            results.append(bench_sweeps(job, n, repeats))
            print(f"[{job} sweeps done]", file=sys.stderr, flush=True)
        print(sweep_table(results))
        print(flush=True)
    if "calibration" in parts:
        print(bench_calibration(repeats, full_fit=not args.quick))
        print(flush=True)
    if "memory" in parts and not args.quick:
        print(bench_memory(n))

if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore::DeprecationWarning")
    main()
