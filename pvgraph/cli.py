"""The ``pvgraph`` command line.

::

    pvgraph validate                 # the PVG 32 rig validation against the lab data
    pvgraph validate --calibrate     # fit the uncertain rig parameters first, then validate
    pvgraph validate --cross-validate  # also: refit leaving one group out, held-out errors
    pvgraph simulate test-2 --t-end 2 --csv out.csv --plot out.png
    pvgraph components               # the component library with ports and parameters
    pvgraph graph rig --out rig.png  # draw a circuit
    pvgraph sweep --scenario test-9 --param U_input=4.2:4.6:5 --settle 2 --out sweep-out
    pvgraph sweep --scenario sweep-4 --param rig.return_line_K=log:2e-9:2e-8 --random 20
    pvgraph sweep --list-params      # the parameter names a sweep can vary
    pvgraph linearize --scenario test-9 --json lin.json --bode bode.png

Exit codes: 0 success, 1 a run failed (a scenario did not simulate, a sweep case failed, no
steady state to linearise at), 2 bad arguments.
"""

from __future__ import annotations

import argparse
import difflib
import functools
import json
import math
import os
import sys
import time

from ._progress import ProgressBar
from .errors import InitializationError, ParameterError, PvgraphError, SolverError
from .units import to_bar, to_lpm, to_mm

__all__ = ["main"]


def _progress(total: int, label: str):
    """``tick(name)`` advancing a one-line progress bar on stderr (silent unless a terminal)."""
    bar = ProgressBar(total, label)
    done = [0]

    def tick(name):
        done[0] += 1
        bar.update(done[0], name)
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
    label = f"preset '{args.preset}'"
    os.makedirs(args.out, exist_ok=True)
    if args.calibrate:
        params = _calibrate(args, params)
        label = "calibrated parameters"
    t0 = time.perf_counter()
    results = V.validate(params, names, law=args.law, workers=args.workers,
                         progress=_progress(len(names), "simulating"))
    wall = time.perf_counter() - t0
    print(f"PVG 32 on the lab rig: {len(results)} scenarios, {label}, "
          f"{args.law} load, {wall:.1f} s wall\n")
    roles = _validation_roles(args, names)
    print(V.format_table(results, roles))
    print()
    for label, (ok, total, rows) in V.targets(results, roles).items():
        print(f"  {'PASS' if ok == total else 'miss'}  {label}: {ok}/{total} "
              f"({V.role_breakdown(rows)})")
    print(f"  {V.margin_statement(params)}")
    json_path = args.json or os.path.join(args.out, "validation.json")
    _write_json_atomic(json_path, V.comparison_records(results, roles))
    print(f"\nwrote {json_path}")
    if not args.no_plots:
        from .plotting import plot_flow_vs_voltage, plot_step_traces
        for path in (plot_flow_vs_voltage(results, os.path.join(args.out, "flow_vs_voltage.png"),
                                          roles=roles),
                     plot_step_traces(results, os.path.join(args.out, "step_dp_L3.png"))):
            print(f"wrote {path}")
    if args.cross_validate:
        _cross_validate(args)
    failed = [r.name for r in results if r.error]
    if failed:
        print(f"\n{len(failed)} scenario(s) failed to simulate: {', '.join(failed)}",
              file=sys.stderr)
        return 1
    return 0


def _validation_roles(args, names):
    """Roles of the compared values: the tuned preset's, or all fitted after --calibrate."""
    from circuits.crossval import role, tuned_roles
    from circuits.scenarios import get_scenario
    roles = tuned_roles()
    if args.calibrate:
        from circuits.calibration import EXCLUDED, QUANTITIES
        fitted = {(n, q) for (n, _) in roles if n not in EXCLUDED for q in QUANTITIES}
        roles = {k: role(get_scenario(k[0]), k[1], fitted) for k in roles}
    return roles


def _cross_validate(args) -> None:
    """Leave-one-group-out identification and held-out prediction (circuits.crossval)."""
    from circuits import crossval as X
    print("\nCross-validation: every data-derived parameter (load laws, supply voltage, A_H "
          "shape, return line, pump flow) re-identified without the held-out group\n")
    cv = X.cross_validate(workers=args.workers or 2,
                          progress=_progress(14, "cross-validating"))
    print(X.format_cross_validation(cv))
    path = os.path.join(args.out, "cross_validation.json")
    summary = {g: {label: {"passed": ok, "total": total}
                   for label, (ok, total, _) in X.judge(cv.records, g).items()}
               for g in dict.fromkeys(r["grouping"] for r in cv.records)}
    _write_json_atomic(path, {"records": cv.records, "folds": cv.folds, "targets": summary,
                              "wall_time_s": round(cv.wall_time, 2), "workers": cv.workers})
    print(f"wrote {path}")
    if not args.no_plots:
        from .plotting import plot_cross_validation
        png = os.path.join(args.out, "cross_validation.png")
        print(f"wrote {plot_cross_validation(cv.records, png)}")


def _calibrate(args, start):
    """Fit ``args.fit`` to the lab's steady data; print and save the estimates; return them."""
    from circuits import calibration as C
    from circuits.pvg32.parameters import with_values

    if args.law != "laminar":
        raise PvgraphError("--calibrate fits the laminar load constants; use --law laminar")
    fit = args.fit or list(C.DEFAULT_FIT)
    for path in fit:
        C.fit_parameter(path, start)          # unknown names fail here, before any solving
    if args.preset == "tuned":
        # start the fitted rig quantities from the report's untuned table 4.9, so the estimates
        # are compared with the hand-tuned table 4.14 from an independent start
        from circuits.pvg32.parameters import report_initial
        initial = report_initial()
        start = with_values(start, {k: v for k, v in (
            ("rig.supply_voltage", initial.rig.supply_voltage),
            ("rig.pump_flow", initial.rig.pump_flow)) if k in fit})
    if "rig.supply_voltage" in fit:
        start = C.opening_follows_supply(start)

    def progress(nfev, cost):
        if sys.stderr.isatty():
            sys.stderr.write(f"\rcalibrating: {nfev} model evaluations, cost {cost:.4g}   ")
            sys.stderr.flush()

    t0 = time.perf_counter()
    result, fitted = C.calibrate_rig(fit, start=start, workers=args.workers or 2,
                                     progress=progress)
    if sys.stderr.isatty():
        sys.stderr.write("\n")
    print(f"Calibration against the lab's steady states ({len(result.measured)} values, "
          f"{time.perf_counter() - t0:.0f} s wall); the report's hand tuning beside it\n")
    print(result.table(C.TABLE_4_14, "table 4.14"))
    print()
    print(C.residual_summary(result))
    print()
    path = os.path.join(args.out, "calibration.json")
    _write_json_atomic(path, result.to_dict())
    print(f"wrote {path}\n")
    return fitted


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


# --------------------------------------------------------------------------------------------
# pvgraph sweep: rig parameters over a scenario

#: the scenario-level parameter a sweep can vary besides the dotted PVG32Params paths
SCENARIO_PARAMS = {"U_input": "PVE control voltage U_in [V] (overrides the scenario's)"}
#: rig outputs of one sweep case: name -> (SI unit, table unit, converter from SI, heading)
RIG_OUTPUTS = {
    "Q_total": ("m^3/s", "L/min", to_lpm, "Q_total"),
    "Q_branch": ("m^3/s", "L/min", to_lpm, "Q_branch"),
    "Pf": ("Pa", "bar", to_bar, "Pf"),
    "Pm": ("Pa", "bar", to_bar, "Pm"),
    "Pb": ("Pa", "bar", to_bar, "Pb"),
    "pump_margin": ("Pa", "bar", to_bar, "pump margin"),
    "main_spool_drop": ("Pa", "bar", to_bar, "spool drop"),
    "main_spool_x": ("m", "mm", to_mm, "x_main"),
    "pump_relief_flow": ("m^3/s", "L/min", to_lpm, "Q_relief"),
    "settled": ("-", "", float, "settled"),
    "settle_deviation": ("Pa", "bar", to_bar, "settle dev"),
    "steps": ("-", "", float, "steps"),
}
TABLE_OUTPUTS = ("Q_total", "Pf", "Pm", "Pb", "pump_margin", "main_spool_x")


def _sweepable(params) -> dict:
    """``{name: (preset value or None, description)}`` of every parameter a sweep can vary."""
    from circuits.pvg32.parameters import parameter_field, parameter_paths
    out = {name: (None, desc) for name, desc in SCENARIO_PARAMS.items()}
    for path in parameter_paths(params):
        out[path] = parameter_field(params, path)
    return out


def _check_param_name(name: str, valid) -> None:
    if name in valid:
        return
    if any(v.startswith(name + ".") for v in valid):
        example = next(v for v in valid if v.startswith(name + "."))
        raise PvgraphError(f"--param {name!r} is a group of parameters; name one of its "
                           f"fields, e.g. {example!r} (see pvgraph sweep --list-params)")
    close = difflib.get_close_matches(name, list(valid), n=3, cutoff=0.6)
    hint = f"; did you mean {', '.join(map(repr, close))}?" if close else "."
    raise PvgraphError(f"unknown parameter {name!r}{hint} Valid names are U_input and the "
                       f"dotted PVG32Params fields; list them with pvgraph sweep --list-params")


def _rig_case(*, scenario: str, preset: str, law: str, settle: float, after: float,
              **params) -> dict:
    """One sweep case: a lab scenario on the rig with some parameters changed (SI outputs)."""
    from pydantic import ValidationError

    from circuits import validation as V
    from circuits.pvg32.parameters import with_values
    from circuits.scenarios import Scenario, get_scenario

    params = dict(params)
    s = get_scenario(params.pop("scenario", scenario))
    if "U_input" in params:
        u = params.pop("U_input")
        try:
            s = Scenario.model_validate({**dict(s), "U_input": u})
        except ValidationError as exc:
            raise ParameterError(f"U_input = {u!r}: {exc.errors()[0]['msg']}") from None
    p = with_values(_preset(preset), params)
    r = V.run_scenario(s, p, law=law, settle=settle, after=after)
    return {**r.simulated, **r.margins, "settled": float(r.settled),
            "settle_deviation": r.settle_deviation, "steps": float(r.steps)}


def _parse_number(text: str, name: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise PvgraphError(f"--param {name}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise PvgraphError(f"--param {name}: {text!r} is not a finite number")
    return value


def _parse_param(spec: str, random_mode: bool):
    """``NAME=SPEC`` -> (name, grid values or random-sample range); see ``--param`` help."""
    import numpy as np
    name, eq, body = spec.partition("=")
    name = name.strip()
    if not eq or not name or not body.strip():
        raise PvgraphError(f"--param {spec!r}: write NAME=VALUE, NAME=LO:HI:N, NAME=V1,V2,... "
                           f"or (with --random) NAME=LO:HI")
    log = body.startswith("log:")
    parts = (body[4:] if log else body).split(":")
    if len(parts) == 1 and not log:
        values = [_parse_number(v, name) for v in body.split(",")]
        if random_mode and len(values) > 1:
            raise PvgraphError(f"--param {name}: with --random give a range LO:HI (or "
                               f"log:LO:HI) or one fixed value, not a list")
        return name, (values[0] if random_mode else values)
    if random_mode:
        if len(parts) != 2:
            raise PvgraphError(f"--param {name}: with --random give a range LO:HI or "
                               f"log:LO:HI, not {body!r}")
        lo, hi = (_parse_number(v, name) for v in parts)
        return name, (("log", lo, hi) if log else (lo, hi))
    if len(parts) != 3:
        raise PvgraphError(f"--param {name}: a grid range needs the number of points, "
                           f"{'log:' if log else ''}LO:HI:N (or use --random N to sample "
                           f"LO:HI); got {body!r}")
    lo, hi = (_parse_number(v, name) for v in parts[:2])
    try:
        n = int(parts[2])
    except ValueError:
        n = 0
    if n < 1:
        raise PvgraphError(f"--param {name}: the number of points N in LO:HI:N must be a "
                           f"positive integer, got {parts[2]!r}")
    if log and (lo <= 0 or hi <= 0):
        raise PvgraphError(f"--param {name}: a log range needs positive bounds, got {body!r}")
    values = np.geomspace(lo, hi, n) if log else np.linspace(lo, hi, n)
    return name, [float(v) for v in values]


def _sweep_cases(args, valid) -> list[dict]:
    from .analysis.sweep import grid, random_sample
    specs = {}
    for spec in args.param or []:
        name, values = _parse_param(spec, args.random is not None)
        _check_param_name(name, valid)
        if name in specs:
            raise PvgraphError(f"--param {name!r} is given twice")
        specs[name] = values
    if args.random is not None:
        if args.random < 1:
            raise PvgraphError(f"--random N needs N >= 1, got {args.random}")
        if not any(isinstance(v, tuple) for v in specs.values()):
            raise PvgraphError("--random needs at least one --param NAME=LO:HI range")
        samples = random_sample(specs, args.random, seed=args.seed, method=args.method)
        cases = [{"scenario": s, **c} for s in args.scenario for c in samples]
    else:
        cases = grid({"scenario": args.scenario, **specs})
    if len(args.scenario) == 1:
        for c in cases:
            del c["scenario"]
    return cases


def _format_sweep_table(result) -> str:
    params = result.param_names
    heads = [f"{RIG_OUTPUTS[n][3]} [{RIG_OUTPUTS[n][1]}]" for n in TABLE_OUTPUTS]
    widths = [max(len(p), 10) for p in params] + [max(len(h), 9) for h in heads]
    head = f"{'case':>4s}  " + "  ".join(f"{h:>{w}s}" for h, w in zip(params + heads, widths)) \
        + "  settled"
    lines = [head, "-" * len(head)]
    for r in result:
        cells = [f"{r.params[p]:>{w}.6g}" if isinstance(r.params[p], float) else
                 f"{str(r.params[p]):>{w}s}" for p, w in zip(params, widths)]
        if r.ok:
            cells += [f"{RIG_OUTPUTS[n][2](r.outputs[n]):>{w}.3f}"
                      for n, w in zip(TABLE_OUTPUTS, widths[len(params):])]
            tail = "yes" if r.outputs.get("settled") else "NO"
        else:
            tail = "FAILED: " + " ".join(r.error.split())[:100]
        lines.append(f"{r.index:>4d}  " + "  ".join(cells) + f"  {tail}")
    return "\n".join(lines)


def cmd_sweep(args) -> int:
    from circuits.scenarios import scenario_names
    from .analysis.sweep import sweep

    params = _preset(args.preset)
    valid = _sweepable(params)
    if args.list_params:
        for name, (value, desc) in valid.items():
            shown = "(scenario)" if name in SCENARIO_PARAMS else f"{value!r}"
            print(f"{name:45s} {shown:>24s}  {desc.split('. ')[0][:90]}")
        return 0
    if not args.scenario:
        raise PvgraphError("give at least one --scenario (e.g. --scenario test-9); valid: "
                           f"{', '.join(scenario_names())}")
    unknown = [n for n in args.scenario if n not in scenario_names()]
    if unknown:
        raise PvgraphError(f"unknown scenario(s) {unknown}; valid: {', '.join(scenario_names())}")
    if args.settle <= 0:
        raise PvgraphError(f"--settle must be > 0 s, got {args.settle}")
    if args.workers is not None and args.workers < 1:
        raise PvgraphError(f"--workers must be >= 1, got {args.workers}")
    backend = args.backend or ("dask" if args.scheduler else "process")
    if args.scheduler and backend != "dask":
        raise PvgraphError("--scheduler is the address of a Dask scheduler; it needs "
                           "--backend dask")
    cases = _sweep_cases(args, valid)
    run = functools.partial(_rig_case, scenario=args.scenario[0], preset=args.preset,
                            law=args.law, settle=args.settle, after=args.after)
    units = {n: u[0] for n, u in RIG_OUTPUTS.items()}
    result = sweep(run, cases, backend=backend, workers=args.workers, client=args.scheduler,
                   progress=True, units=units)
    csv_path, json_path = result.save(args.out)
    print(f"PVG 32 rig sweep: {', '.join(args.scenario)}, preset '{args.preset}', {args.law} "
          f"load, settle {args.settle:g} s; {len(result)} cases on {backend}, "
          f"{result.wall_time:.1f} s wall\n")
    print(_format_sweep_table(result))
    print(f"\n{len(result.ok)} ok, {len(result.failed)} failed; wrote {csv_path} and {json_path}")
    if result.failed:
        for r in result.failed:
            print(f"case {r.index} {r.params} failed: {r.error}", file=sys.stderr)
        return 1
    return 0


# --------------------------------------------------------------------------------------------
# pvgraph linearize: the rig's linear model at an operating point

LINEARIZE_OUTPUTS = ["pvg.pvb.main_spool.flange.x", "load.f.port.p"]
DEFAULT_VOLTAGE = 4.29  # [V] the test-9 operating point of examples/linearize_pvg32.py
#: SI unit -> (converter, display unit) for the printed values
_DISPLAY = {"Pa": (to_bar, "bar"), "m^3/s": (to_lpm, "L/min"), "m": (to_mm, "mm")}


def _display(value: float, unit: str) -> str:
    convert, shown = _DISPLAY.get(unit, (float, unit))
    return f"{convert(value):.6g} {shown}"


def _check_outputs(system, names) -> None:
    linear = list(system.index) + list(system.aliases)
    for name in names:
        if name in system.index or name in system.aliases:
            continue
        if name in system.observed:
            raise PvgraphError(f"--output {name!r} is a derived output (computed after the "
                               f"solve); linearise one of the variables it is computed from, "
                               f"e.g. a port pressure or flow")
        close = difflib.get_close_matches(name, linear, n=3, cutoff=0.6)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise PvgraphError(f"--output {name!r} is not a variable of the rig{hint} (the rig has "
                           f"{len(linear)} variables, e.g. {', '.join(linear[:3])})")


def _frequency_response(lm, freq_hz, output: int, input: int = 0):
    import numpy as np
    A, B, C, D = lm.A, lm.B[:, input], lm.C[output], lm.D[output, input]
    eye = np.eye(A.shape[0])
    return np.array([C @ np.linalg.solve(2j * np.pi * f * eye - A, B) + D for f in freq_hz])


def cmd_linearize(args) -> int:
    import numpy as np
    from circuits.rig import build_rig, laminar_load, turbulent_load
    from circuits.scenarios import get_scenario, scenario_names
    from .analysis import linearize_circuit, steady_state

    p = _preset(args.preset)
    outputs = args.output or list(LINEARIZE_OUTPUTS)
    make = laminar_load if args.law == "laminar" else turbulent_load
    if args.scenario is not None:
        if args.scenario not in scenario_names():
            raise PvgraphError(f"unknown scenario {args.scenario!r}; valid: "
                               f"{', '.join(scenario_names())}")
        s = get_scenario(args.scenario)
        load_kw = dict(L1=s.orifice_L1 or "small", L3=s.orifice_L3, l2_open=s.l2_open_finally)
        U0 = args.voltage if args.voltage is not None else s.U_input
        where = f"scenario {s.name} (L2 {'open' if s.l2_open_finally else 'closed'})"
    else:
        load_kw = {}
        U0 = args.voltage if args.voltage is not None else DEFAULT_VOLTAGE
        where = "the default rig load (small L1/L3, L2 closed)"
    if not (math.isfinite(U0) and 0.0 <= U0 <= p.rig.supply_voltage):
        raise PvgraphError(f"--voltage {U0!r} V is outside 0 .. {p.rig.supply_voltage} V (the "
                           f"PVE supply voltage of preset '{args.preset}')")

    def build(u):  # a fresh load each time: a circuit instance joins one rig only
        return build_rig(p, load=make(p, **load_kw), U_input=u["U"])

    system = build({"U": U0}).compile()
    _check_outputs(system, outputs)
    try:
        op = steady_state(system)
        lm = linearize_circuit(build, {"U": U0}, outputs, op=op)
    except (InitializationError, SolverError) as exc:
        print(f"pvgraph linearize: no operating point at U = {U0} V: {exc}", file=sys.stderr)
        return 1
    poles = lm.poles()
    try:
        gain = lm.dc_gain()[:, 0]
    except np.linalg.LinAlgError:
        gain = None
    units = {n: system.unit(n) for n in outputs}
    n_shown = min(args.poles, len(poles))

    print(f"PVG 32 rig linearised at U = {U0:g} V on {where}, preset '{args.preset}', "
          f"{args.law} load")
    print(f"operating point ({op.method}, {op.iterations} iterations, scaled residual "
          f"{op.residual_norm:.2g}):")
    for n in outputs:
        print(f"  {n:40s} {_display(op[n], units[n])}")
    stable = bool(np.all(poles.real < 0))
    print(f"{len(lm.state_names)} states, {'stable' if stable else 'NOT stable'}; "
          f"{n_shown} dominant poles:")
    print(f"  {'real [1/s]':>12s} {'imag [1/s]':>12s} {'wn [rad/s]':>11s} {'fn [Hz]':>9s} "
          f"{'zeta':>7s}")
    wns, zetas, _ = lm.damping()
    records = [{"real": float(s_.real), "imag": float(s_.imag), "natural_frequency": float(wn),
                # a pole at the origin: an integrator, reported as critically damped
                "damping_ratio": float(zeta) if wn > 0 else 1.0}
               for s_, wn, zeta in zip(poles, wns, zetas)]
    for r in records[:n_shown]:
        print(f"  {r['real']:12.5g} {r['imag']:+12.5g} {r['natural_frequency']:11.5g} "
              f"{r['natural_frequency'] / (2 * math.pi):9.4g} {r['damping_ratio']:7.3f}")
    if gain is None:
        print("DC gain: not defined (A is singular: the linear model has a pure integrator)")
    else:
        print("DC gain per volt of U:")
        for n, g in zip(outputs, gain):
            print(f"  {n:40s} {_display(float(g), units[n])}/V")

    if args.json:
        data = {"U": U0, "scenario": args.scenario, "preset": args.preset, "law": args.law,
                "operating_point": {"method": op.method, "iterations": op.iterations,
                                    "residual_norm": float(op.residual_norm),
                                    "values": {n: op[n] for n in outputs}},
                "units": units, "n_states": len(lm.state_names),
                "state_names": list(lm.state_names), "stable": stable, "poles": records,
                "dominant_poles": records[:n_shown],
                "dc_gain": None if gain is None else {n: float(g) for n, g in zip(outputs, gain)},
                "dc_gain_units": {n: f"{units[n]}/V" for n in outputs}}
        _write_json_atomic(args.json, data)
        print(f"wrote {args.json}")
    if args.bode:
        from .plotting import plot_bode
        freq = np.logspace(-1, 3, 300)
        mags, phases, labels = [], [], []
        for k, n in enumerate(outputs):
            convert, shown = _DISPLAY.get(units[n], (lambda v: v, units[n]))
            h = convert(_frequency_response(lm, freq, k))
            mags.append(20 * np.log10(np.maximum(np.abs(h), 1e-300)))
            phases.append(np.degrees(np.unwrap(np.angle(h))))
            labels.append(f"{n} [{shown}/V]")
        path = plot_bode(freq, mags, phases, args.bode, labels=labels,
                         title=f"PVG 32 rig: response per volt of U at U = {U0:g} V")
        print(f"wrote {path}")
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
    v.add_argument("--calibrate", action="store_true",
                   help="first fit the uncertain rig parameters to the lab's steady data "
                        "(least squares with 95 %% intervals, about a minute), then validate "
                        "with the estimates; writes OUT/calibration.json")
    v.add_argument("--fit", action="append", metavar="PARAM",
                   help="parameter to calibrate (repeatable; default: supply voltage, pump "
                        "flow, return line and the four load constants)")
    v.add_argument("--cross-validate", action="store_true",
                   help="also refit every data-derived parameter leaving out one group of "
                        "scenarios at a time (by input voltage, by load configuration) and "
                        "report the held-out errors (steady states, about 30 s on 2 cores); "
                        "writes OUT/cross_validation.json")
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

    w = sub.add_parser(
        "sweep", help="sweep rig parameters over lab scenarios (grid or random sample)",
        description="Run lab scenarios of the PVG 32 rig for many parameter values, in "
                    "parallel. Each case reports the steady simulated Q_total, Q_branch, Pf, "
                    "Pm, Pb, the pump margin, main spool drop and position (SI in the files). "
                    "Values are SI, as the parameter models define them. Exit code 1 when any "
                    "case failed (the others are still written).")
    w.add_argument("--scenario", action="append",
                   help="lab scenario (test-1 ... test-12, sweep-1 ... sweep-7); repeat to sweep "
                        "over several")
    w.add_argument("--param", action="append", metavar="NAME=SPEC",
                   help="parameter to vary: U_input or a dotted PVG32Params field (e.g. "
                        "rig.return_line_K, pve.input_gain). SPEC: LO:HI:N (N points), "
                        "log:LO:HI:N (log-spaced), V1,V2,... or a fixed V; with --random: "
                        "LO:HI, log:LO:HI or a fixed V. Repeatable: the grid is the product")
    w.add_argument("--random", type=int, metavar="N",
                   help="draw N random cases from the LO:HI ranges instead of a grid")
    w.add_argument("--seed", type=int, default=None, help="random seed (with --random)")
    w.add_argument("--method", default="lhs", choices=["lhs", "uniform"],
                   help="random sampling: Latin hypercube or independent uniform "
                        "(default: %(default)s)")
    w.add_argument("--settle", "--t-end", dest="settle", type=float, default=8.0,
                   help="simulated time to the steady state (before the solenoid step of "
                        "step tests) [s] (default: %(default)s, as pvgraph validate)")
    w.add_argument("--after", type=float, default=2.0,
                   help="simulated time after the solenoid step of step tests [s] "
                        "(default: %(default)s)")
    w.add_argument("--preset", default="tuned", help="parameter preset: tuned or initial")
    w.add_argument("--law", default="laminar", choices=["laminar", "turbulent"],
                   help="load orifice law")
    w.add_argument("--backend", choices=["process", "serial", "dask"],
                   help="process pool (default), serial, or Dask (default with --scheduler)")
    w.add_argument("--workers", type=int, default=None,
                   help="parallel processes (default: the available CPUs)")
    w.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler address, e.g. tcp://10.0.0.5:8786 (its workers need "
                        "pvgraph installed); without it --backend dask starts a local cluster")
    w.add_argument("--out", default="pvgraph-sweep",
                   help="output folder for sweep.csv and sweep.json (default: %(default)s)")
    w.add_argument("--list-params", action="store_true",
                   help="list the parameter names with their preset values and exit")
    w.set_defaults(func=cmd_sweep)

    lz = sub.add_parser(
        "linearize", help="linear model of the rig at a steady operating point",
        description="Linearise the PVG 32 rig at the steady state of a scenario or a PVE "
                    "input voltage: input U (the PVE control voltage), outputs by default the "
                    "main spool position and the load pressure. Prints the operating point, "
                    "the dominant poles (natural frequency, damping ratio) and the DC gains.")
    lz.add_argument("--scenario", help="take the load and the voltage of this lab scenario "
                                       "(L2 in its final state)")
    lz.add_argument("--voltage", type=float,
                    help=f"PVE input voltage U [V] (default: the scenario's, else "
                         f"{DEFAULT_VOLTAGE})")
    lz.add_argument("--output", action="append", metavar="NAME",
                    help=f"output variable (repeatable; default: {', '.join(LINEARIZE_OUTPUTS)})")
    lz.add_argument("--preset", default="tuned", help="parameter preset: tuned or initial")
    lz.add_argument("--law", default="laminar", choices=["laminar", "turbulent"],
                    help="load orifice law")
    lz.add_argument("--poles", type=int, default=6, help="dominant poles to print "
                                                         "(default: %(default)s)")
    lz.add_argument("--json", help="write operating point, poles and DC gains to this file")
    lz.add_argument("--bode", metavar="PNG", help="draw the Bode plot of every output to this "
                                                  "PNG file")
    lz.set_defaults(func=cmd_linearize)
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
