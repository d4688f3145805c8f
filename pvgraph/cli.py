"""The ``pvgraph`` command line.

::

    pvgraph validate                 # the PVG 32 rig validation against the lab data
    pvgraph simulate test-2 --t-end 2 --csv out.csv --plot out.png
    pvgraph components               # the component library with ports and parameters
    pvgraph graph rig --out rig.png  # draw a circuit

Exit codes: 0 success, 1 a run failed (a scenario did not simulate), 2 bad arguments.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from .errors import PvgraphError

__all__ = ["main"]


def _progress(total: int, label: str):
    """A one-line progress bar on stderr (silent when stderr is not a terminal)."""
    done = [0]
    tty = sys.stderr.isatty()

    def tick(name):
        done[0] += 1
        if tty:
            bar = "#" * int(30 * done[0] / total)
            sys.stderr.write(f"\r{label} [{bar:30s}] {done[0]}/{total} {name:10s}")
            if done[0] == total:
                sys.stderr.write("\n")
            sys.stderr.flush()
    return tick


def _write_json_atomic(path: str, data) -> None:
    from .simulate import _atomic_write
    _atomic_write(path, lambda f: json.dump(data, f, indent=1))


def _preset(name: str):
    from circuits.pvg32.parameters import report_initial, report_tuned
    presets = {"tuned": report_tuned, "initial": report_initial}
    if name not in presets:
        raise PvgraphError(f"unknown preset {name!r}; choose one of {sorted(presets)}")
    return presets[name]()


def cmd_validate(args) -> int:
    from circuits import validation as V
    from circuits.scenarios import scenario_names

    names = args.scenario or scenario_names()
    unknown = [n for n in names if n not in scenario_names()]
    if unknown:
        raise PvgraphError(f"unknown scenario(s) {unknown}; valid: {', '.join(scenario_names())}")
    params = _preset(args.preset)
    t0 = time.perf_counter()
    results = V.validate(params, names, law=args.law, workers=args.workers,
                         progress=_progress(len(names), "simulating"))
    wall = time.perf_counter() - t0
    print(f"PVG 32 on the lab rig: {len(results)} scenarios, preset '{args.preset}', "
          f"{args.law} load, {wall:.1f} s wall\n")
    print(V.format_table(results))
    print()
    for label, (ok, total, _) in V.targets(results).items():
        print(f"  {'PASS' if ok == total else 'miss'}  {label}: {ok}/{total}")
    os.makedirs(args.out, exist_ok=True)
    json_path = args.json or os.path.join(args.out, "validation.json")
    _write_json_atomic(json_path, V.comparison_records(results))
    print(f"\nwrote {json_path}")
    if not args.no_plots:
        from .plotting import plot_flow_vs_voltage, plot_step_traces
        for path in (plot_flow_vs_voltage(results, os.path.join(args.out, "flow_vs_voltage.png")),
                     plot_step_traces(results, os.path.join(args.out, "step_dp_L3.png"))):
            print(f"wrote {path}")
    failed = [r.name for r in results if r.error]
    if failed:
        print(f"\n{len(failed)} scenario(s) failed to simulate: {', '.join(failed)}",
              file=sys.stderr)
        return 1
    return 0


def cmd_simulate(args) -> int:
    from circuits.scenarios import scenario_names
    from circuits import validation as V
    from .simulate import simulate

    if args.target not in scenario_names():
        raise PvgraphError(f"unknown scenario {args.target!r}; valid: "
                           f"{', '.join(scenario_names())}")
    scenario = V.get_scenario(args.target)
    params = _preset(args.preset)
    step = scenario.solenoid_event in ("opening", "closing")
    t_switch = args.t_switch if step else None
    system = V._build(scenario, params, args.law, t_switch).compile()
    sol = simulate(system, args.t_end, rtol=args.rtol, solver=args.solver)
    names = args.var or ["load.f.port.p", "load.m.port.p", "load.b.port.p", "load.L2.q",
                         "load.L3.q", "pvg.pvb.main_spool.flange.x"]
    for n in names:
        print(f"{n:40s} final {sol.final(n): .6g} {sol.unit(n)}")
    print(f"steps {sol.stats.get('nsteps')}, residual evaluations {sol.stats.get('nre')}")
    if args.csv:
        sol.to_csv(args.csv, names)
        print(f"wrote {args.csv}")
    if args.plot:
        from .plotting import plot_solution
        print(f"wrote {plot_solution(sol, names, args.plot)}")
    return 0


def cmd_components(args) -> int:
    from .docgen import component_reference, library_modules
    print(component_reference(library_modules()))
    return 0


def cmd_graph(args) -> int:
    from .plotting import draw_circuit
    from circuits.rig import build_rig
    from circuits.pvg32.modules import build_pve, build_pvb, build_pvg32, build_pvp
    builders = {"rig": build_rig, "pvg32": build_pvg32, "pvp": build_pvp, "pvb": build_pvb,
                "pve": build_pve}
    if args.circuit not in builders:
        raise PvgraphError(f"unknown circuit {args.circuit!r}; choose one of {sorted(builders)}")
    circuit = builders[args.circuit]()
    out = draw_circuit(circuit, args.out, fmt=args.format)
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pvgraph", description="Acausal hydraulic circuit modelling; the PVG 32 valve.")
    sub = parser.add_subparsers(dest="command", required=True)

    v = sub.add_parser("validate", help="simulate the 19 lab scenarios and compare with the data")
    v.add_argument("--out", default="pvgraph-report", help="output folder (default: %(default)s)")
    v.add_argument("--json", help="write the comparison records here (default: OUT/validation.json)")
    v.add_argument("--preset", default="tuned", help="parameter preset: tuned (report table 4.14) "
                                                     "or initial (table 4.9)")
    v.add_argument("--law", default="laminar", choices=["laminar", "turbulent"],
                   help="load orifice law (report 4.7.2 concludes laminar)")
    v.add_argument("--scenario", action="append", help="run only this scenario (repeatable)")
    v.add_argument("--workers", type=int, default=None, help="parallel processes (default 2)")
    v.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    v.set_defaults(func=cmd_validate)

    s = sub.add_parser("simulate", help="simulate one scenario (test-1 ... test-12, sweep-1 ...)")
    s.add_argument("target", help="scenario name")
    s.add_argument("--t-end", type=float, default=10.0, help="end time [s]")
    s.add_argument("--t-switch", type=float, default=8.0, help="solenoid switching time [s]")
    s.add_argument("--solver", default="pvgraph", choices=["pvgraph", "ida"])
    s.add_argument("--rtol", type=float, default=1e-5)
    s.add_argument("--preset", default="tuned")
    s.add_argument("--law", default="laminar", choices=["laminar", "turbulent"])
    s.add_argument("--var", action="append", help="variable to report (repeatable)")
    s.add_argument("--csv", help="write the variables over time to this CSV file")
    s.add_argument("--plot", help="plot the variables to this PNG file")
    s.set_defaults(func=cmd_simulate)

    c = sub.add_parser("components", help="list the component library")
    c.set_defaults(func=cmd_components)

    g = sub.add_parser("graph", help="draw a circuit (PNG via matplotlib, or Graphviz DOT)")
    g.add_argument("circuit", help="rig, pvg32, pvp, pvb or pve")
    g.add_argument("--out", default="circuit.png")
    g.add_argument("--format", default="png", choices=["png", "dot"])
    g.set_defaults(func=cmd_graph)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except PvgraphError as exc:
        print(f"pvgraph {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
