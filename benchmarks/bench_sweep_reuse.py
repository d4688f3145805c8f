"""Sweep cases on one compiled system against cases that build and compile.

Per-case wall time, medians over the cases, the two ways measured side by side (alternating
case by case in one process):

1. A small circuit (flow source -> volume -> orifice -> tank, 1 unknown): steady state, and a
   transient of 50 ms. Rebuild: build, set the case's parameters, compile, solve. Reuse:
   :class:`pvgraph.analysis.CompiledRun` by parameter name (``orifice.A``, ``pump.Q``) and by
   builder argument (``build=``).
2. The PVG 32 rig (87 unknowns) steady state at test-9's voltage with L2 open, over
   ``rig.pump_flow`` and ``rig.return_line_K``: rebuild, ``CompiledRun(build=...)`` (the rig
   built from the PVG32Params of the case, values read into the compiled system), and
   ``CompiledRun`` by the component parameter names (``pump.Q0``, ``return_line.K``).
3. A ``pvgraph sweep --scenario sweep-4`` case (2 s settling simulation of the rig): the case
   of ``circuits/cli.py`` with and without :func:`pvgraph.circuit.reuse_compiled`.

Every reused case is checked against its rebuilt twin (largest relative difference printed).
The one compilation of the reuse runs is made before timing (it is paid once per worker).

Run: ``python benchmarks/bench_sweep_reuse.py [--cases N]`` (prints Markdown).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

RHO, CD = 870.0, 0.6


def orifice_bench(Q=1e-4, A=2e-6):
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    from pvgraph import Circuit
    c = Circuit("orifice_bench")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V=1e-4))
    orf = c.add("orifice", Orifice(A=A, Cd=CD, rho=RHO))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    return c


def _rebuilt_small(steady, t_end, **case):
    from pvgraph.analysis import steady_state
    from pvgraph.simulate import simulate
    c = orifice_bench()
    c.set_parameters(case)
    system = c.compile()
    if steady:
        return {"p": steady_state(system, tol=1e-10)["node.port.p"]}
    return {"p": simulate(system, t_end, rtol=1e-6).final("node.port.p")}


def _rig(p):
    from pvgraph.circuits.rig import build_rig, laminar_load
    return build_rig(p, load=laminar_load(p, l2_open=True), U_input=4.24)


def _rig_from(**case):
    from pvgraph.circuits.pvg32.parameters import report_tuned, with_values
    return _rig(with_values(report_tuned(), case))


def _rebuilt_rig(**case):
    from pvgraph.analysis import steady_state
    return {"Pf": steady_state(_rig_from(**case).compile(), tol=1e-10)["load.f.port.p"]}


_LAST = {}


def _rebuilt_rig_warm(**case):
    """Build and compile, the steady state started from the previous case's."""
    from pvgraph.analysis import steady_state
    op = steady_state(_rig_from(**case).compile(), tol=1e-10, y0=_LAST.get("y"))
    _LAST["y"] = op.y
    return {"Pf": op["load.f.port.p"]}


def _side_by_side(pairs, cases):
    """Median per-case time of each run, alternating; outputs of run 0 as the reference."""
    times = [[] for _ in pairs]
    worst = [0.0 for _ in pairs]
    for case in cases:
        ref = None
        for k, (run, to_args) in enumerate(pairs):
            args = to_args(case)
            t0 = time.perf_counter()
            out = run(**args)
            times[k].append(time.perf_counter() - t0)
            if ref is None:
                ref = out
            else:
                worst[k] = max(worst[k], max(abs(out[n] - ref[n]) / abs(ref[n]) for n in ref))
    return [statistics.median(t) for t in times], worst


def small(n_cases):
    from functools import partial

    from pvgraph.analysis import CompiledRun
    As = [1e-6 * (1 + 3 * k / max(n_cases - 1, 1)) for k in range(n_cases)]
    cases = [{"orifice.A": a, "pump.Q": 1e-4 * (1 + 0.1 * (k % 3))} for k, a in enumerate(As)]
    rows = []
    for label, steady, t_end in (("steady state", True, None), ("transient 50 ms", False, 0.05)):
        kw = dict(steady=True, tol=1e-10) if steady else dict(t_end=t_end, rtol=1e-6)
        by_name = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, **kw)
        by_build = CompiledRun(build=orifice_bench, outputs={"p": "node.port.p"}, **kw)
        first = {"orifice.A": 2e-6, "pump.Q": 1e-4}
        by_name(**first), by_build(A=2e-6, Q=1e-4)          # the one compilation per worker
        med, worst = _side_by_side(
            [(partial(_rebuilt_small, steady, t_end), dict),
             (by_name, dict),
             (by_build, lambda c: {"A": c["orifice.A"], "Q": c["pump.Q"]})], cases)
        rows.append((f"small circuit, {label}", med, worst))
    return rows


def rig(n_cases):
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.analysis import CompiledRun
    base = report_tuned()
    cases = [{"rig.pump_flow": base.rig.pump_flow * (0.9 + 0.2 * k / max(n_cases - 1, 1)),
              "rig.return_line_K": base.rig.return_line_K * (0.8 + 0.4 * ((3 * k) % n_cases)
                                                             / max(n_cases - 1, 1))}
             for k in range(n_cases)]
    by_build = CompiledRun(build=_rig_from, outputs={"Pf": "load.f.port.p"}, steady=True,
                           tol=1e-10)
    by_name = CompiledRun(_rig(base), outputs={"Pf": "load.f.port.p"}, steady=True, tol=1e-10)
    by_build(**cases[0]), by_name(**{"pump.Q0": base.rig.pump_flow})
    med, worst = _side_by_side(
        [(_rebuilt_rig, dict), (by_build, dict),
         (by_name, lambda c: {"pump.Q0": c["rig.pump_flow"],
                              "return_line.K": c["rig.return_line_K"]})], cases)
    rows = [("PVG 32 rig, steady state from the start values", med, worst)]
    warm_build = CompiledRun(build=_rig_from, outputs={"Pf": "load.f.port.p"}, steady=True,
                             tol=1e-10, warm=True)
    warm_name = CompiledRun(_rig(base), outputs={"Pf": "load.f.port.p"}, steady=True,
                            tol=1e-10, warm=True)
    warm_build(**cases[0]), warm_name(**{"pump.Q0": base.rig.pump_flow})
    _rebuilt_rig_warm(**cases[0])
    med, worst = _side_by_side(
        [(_rebuilt_rig_warm, dict), (warm_build, dict),
         (warm_name, lambda c: {"pump.Q0": c["rig.pump_flow"],
                                "return_line.K": c["rig.return_line_K"]})], cases)
    rows.append(("PVG 32 rig, steady state from the previous case's (`warm=True`)", med,
                 worst))
    return rows


def scenario(n_cases):
    from pvgraph.circuits.cli import _rig_case, _scenario_case
    from pvgraph.circuits.pvg32.parameters import report_tuned
    base = report_tuned()
    kw = dict(scenario="sweep-4", preset="tuned", law="laminar", settle=2.0, after=2.0)
    cases = [{"rig.pump_flow": base.rig.pump_flow * (0.9 + 0.2 * k / max(n_cases - 1, 1))}
             for k in range(n_cases)]
    _rig_case(**kw, **cases[0])
    med, worst = _side_by_side([(lambda **c: _scenario_case(**kw, **c), dict),
                                (lambda **c: _rig_case(**kw, **c), dict)], cases)
    return [("PVG 32 `sweep --scenario sweep-4` case (2 s simulation)", med + [None],
             worst + [None])]


def main():
    from _machine import machine
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=9)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print(f"machine: {machine()}\n")
    rows = small(args.cases) + rig(args.cases) + scenario(max(args.cases // 2, 3))
    print("| case (median of the cases) | build + compile [ms] | reuse, by builder "
          "[ms] | reuse, by parameter name [ms] | reuse / rebuild | largest rel. diff |")
    print("|---|---|---|---|---|---|")
    for label, med, worst in rows:
        if label.startswith("PVG 32 `sweep"):
            full, build = med[0], med[1]
            print(f"| {label} | {1e3 * full:.1f} | {1e3 * build:.1f} | - | "
                  f"{100 * build / full:.1f} % | {worst[1]:.1e} |")
            continue
        full, name, build = med[0], med[1], med[2]
        if label.startswith("PVG 32"):
            build, name = med[1], med[2]
        print(f"| {label} | {1e3 * full:.1f} | {1e3 * build:.1f} | {1e3 * name:.1f} | "
              f"{100 * build / full:.1f} % / {100 * name / full:.1f} % | "
              f"{max(w for w in worst if w is not None):.1e} |")


if __name__ == "__main__":
    main()
