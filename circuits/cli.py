"""The PVG 32 on the command line: ``pvgraph validate`` and the lab scenarios.

This module registers the PVG 32 with pvgraph (:func:`register`, the ``pvgraph.circuits``
entry point): the circuits ``rig``, ``pvg32``, ``pvp``, ``pvb``, ``pve`` and one per lab
scenario (``test-1`` ... ``test-12``, ``sweep-1`` ... ``sweep-7``) for ``pvgraph simulate``,
``graph``, ``vars`` and ``sweep``; the ``validate`` command; the options ``--preset`` and
``--law`` of ``simulate``; and the scenario forms of ``sweep`` and ``linearize``::

    pvgraph validate                 # the PVG 32 rig validation against the lab data
    pvgraph validate --calibrate     # fit the uncertain rig parameters first, then validate
    pvgraph validate --cross-validate  # also: refit leaving one group out, held-out errors
    pvgraph simulate test-2 --t-end 2 --csv out.csv --plot out.png
    pvgraph sweep --scenario test-9 --param U_input=4.2:4.6:5 --settle 2 --out sweep-out
    pvgraph sweep --list-params      # the parameter names a scenario sweep can vary
    pvgraph linearize --scenario test-9 --json lin.json --bode bode.png
"""

from __future__ import annotations

import functools
import math
import os
import sys
import time

from pvgraph.cli import (_check_outputs, _display, _frequency_response, _noted_case, _progress,
                         _refuse_repeats, _sweep_cases, _write_json_atomic, json_path,
                         output_dir, run_sweep, time_arg)
from pvgraph.errors import InitializationError, ParameterError, PvgraphError, SolverError
from pvgraph.units import to_bar, to_lpm, to_mm

__all__ = ["register"]


def _preset(name: str):
    from pvgraph.circuits.pvg32.parameters import report_initial, report_tuned
    presets = {"tuned": report_tuned, "initial": report_initial}
    if name not in presets:
        raise PvgraphError(f"unknown preset {name!r}; choose one of {sorted(presets)}")
    return presets[name]()




def cmd_validate(args) -> int:
    from pvgraph.circuits import validation as V
    from pvgraph.circuits.scenarios import scenario_names

    names = args.scenario or scenario_names()
    unknown = [n for n in names if n not in scenario_names()]
    if unknown:
        raise PvgraphError(f"unknown scenario(s) {unknown}; valid: {', '.join(scenario_names())}")
    _refuse_repeats(args.scenario, "--scenario")
    _check_cross_validation_options(args)
    _check_json_beside_out(args)
    params = _preset(args.preset)
    _check_calibration_options(args, params)
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
    from .crossval import SETTLED_STEP, held_out_target
    for label, (ok, total, rows) in V.targets(results, roles).items():
        # the step tests' settling allows one miss; the others are judged on every point here,
        # fitted ones included
        need = held_out_target(label, total) if label == SETTLED_STEP else total
        aim = "" if need == total else f"; target >= {need} of {total}, aim {total}"
        print(f"  {'PASS' if ok >= need else 'miss'}  {label}: {ok}/{total} "
              f"({V.role_breakdown(rows)}{aim})")
    print(f"  {V.margin_statement(params)}")
    json_path = args.json or os.path.join(args.out, "validation.json")
    _write_json_atomic(json_path, V.comparison_records(results, roles))
    print(f"\nwrote {json_path}")
    targets_path = os.path.join(args.out, "validation_targets.json")
    _write_json_atomic(targets_path, V.targets_record(results, roles))
    print(f"wrote {targets_path}")
    if not args.no_plots:
        from .plotting import plot_flow_vs_voltage, plot_step_traces
        # the figure's legend knows fit, held-out and trivial; a repeat of a fit is a fit
        shown = {k: "fit" if v == "repeat" else v for k, v in roles.items()}
        for path in (plot_flow_vs_voltage(results, os.path.join(args.out, "flow_vs_voltage.png"),
                                          roles=shown),
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


def _out_files(args) -> list:
    """The files this ``pvgraph validate`` writes into its --out folder (besides the default
    --json), by its options."""
    files = ["validation_targets.json"]
    if not args.no_plots:
        files += ["flow_vs_voltage.png", "step_dp_L3.png"]
    if args.calibrate:
        files.append("calibration.json")
    if args.cross_validate:
        files.append("cross_validation.json")
        if not args.no_plots:
            files.append("cross_validation.png")
    return files


def _check_json_beside_out(args) -> None:
    """--json is a file that is neither the --out folder, nor a folder above it, nor one of
    the files written into it: checked before any run."""
    if not args.json:
        return
    json_path = os.path.realpath(args.json)
    out = os.path.realpath(args.out)
    if json_path == out or out.startswith(json_path.rstrip(os.sep) + os.sep):
        where = "is the --out folder" if json_path == out else \
            f"is a folder above --out {args.out!r}"
        raise PvgraphError(f"--json {args.json!r} {where}; give a file name, e.g. "
                           f"{os.path.join(args.out, 'validation.json')!r}")
    clash = [name for name in _out_files(args) if json_path == os.path.join(out, name)]
    if clash:
        raise PvgraphError(f"--json {args.json!r} is the file {clash[0]} the command writes "
                           f"into --out; give another name, e.g. "
                           f"{os.path.join(args.out, 'validation.json')!r}")


def _check_calibration_options(args, params) -> None:
    """--fit goes with --calibrate, names fittable parameters once each, and the fit needs the
    laminar load: checked before any run (and before --out is made)."""
    if args.fit and not args.calibrate:
        raise PvgraphError("--fit only applies with --calibrate")
    if not args.calibrate:
        return
    if args.law != "laminar":
        raise PvgraphError("--calibrate fits the laminar load constants; use --law laminar")
    _refuse_repeats(args.fit, "--fit")
    from pvgraph.circuits import calibration as C
    for path in args.fit or []:
        try:
            C.fit_parameter(path, params)      # unknown names fail here, before any solving
        except PvgraphError as exc:
            raise PvgraphError(f"--fit {path}: {exc}") from None


def _check_cross_validation_options(args) -> None:
    """--fold and --meter-out go with --cross-validate, and fold names exist: checked before
    any run."""
    given = [opt for opt, value in (("--fold", args.fold), ("--meter-out", args.meter_out))
             if value]
    if given and not args.cross_validate:
        raise PvgraphError(f"{' and '.join(given)} only appl{'y' if len(given) > 1 else 'ies'} "
                           f"with --cross-validate")
    _refuse_repeats(args.fold, "--fold")
    if args.fold:
        from pvgraph.circuits.crossval import fold_keys
        keys = fold_keys()
        unknown = [f for f in args.fold if f not in keys]
        if unknown:
            import difflib
            close = difflib.get_close_matches(unknown[0], keys, n=2, cutoff=0.5)
            hint = f"; did you mean {' or '.join(map(repr, close))}?" if close else ""
            raise PvgraphError(f"--fold {unknown}: no such fold{hint} The folds are "
                               f"{', '.join(repr(k) for k in keys)}")


def _positive_time(text: str) -> float:
    """argparse type of --after and --t-switch: a finite time > 0 s."""
    import argparse
    value = time_arg(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite time > 0 s, got {text}")
    return value


def _positive_int(text: str) -> int:
    """argparse type of --workers: a whole number >= 1."""
    import argparse
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: give 1 or more processes")
    return value


def _validation_roles(args, names):
    """Roles of the compared values: the tuned preset's, or all fitted after --calibrate."""
    from pvgraph.circuits.crossval import role, tuned_roles
    from pvgraph.circuits.scenarios import get_scenario
    roles = tuned_roles()
    if args.calibrate:
        from pvgraph.circuits.calibration import EXCLUDED, QUANTITIES
        fitted = {(n, q) for (n, _) in roles if n not in EXCLUDED for q in QUANTITIES}
        roles = {k: role(get_scenario(k[0]), k[1], fitted) for k in roles}
    return roles


def _cross_validate(args) -> None:
    """Leave-one-group-out identification and held-out prediction (circuits.crossval)."""
    from pvgraph.circuits import crossval as X
    print("\nCross-validation: every data-derived parameter (load laws, supply voltage, A_H "
          "shape, return line, pump flow) re-identified without the held-out group\n")
    folds = getattr(args, "fold", None)
    cv = X.cross_validate(workers=args.workers or 2, folds=folds,
                          meter_out=getattr(args, "meter_out", None),
                          progress=_progress(len(folds) if folds else 14, "cross-validating"))
    if not cv.folds:
        raise PvgraphError(f"--fold {folds}: no such fold; folds are named like 'U = 4.6 V', "
                           f"'L1 small, L3 small', 'sweep (L3 large, L2 closed)'")
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
    from pvgraph.circuits import calibration as C
    from pvgraph.circuits.pvg32.parameters import with_values

    if args.law != "laminar":
        raise PvgraphError("--calibrate fits the laminar load constants; use --law laminar")
    fit = args.fit or list(C.DEFAULT_FIT)
    for path in fit:
        C.fit_parameter(path, start)          # unknown names fail here, before any solving
    if args.preset == "tuned":
        # start the fitted rig quantities from the report's untuned table 4.9, so the estimates
        # are compared with the hand-tuned table 4.14 from an independent start
        from pvgraph.circuits.pvg32.parameters import report_initial
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
    print(C.report_table(result))
    print()
    print(C.residual_summary(result))
    print()
    path = os.path.join(args.out, "calibration.json")
    _write_json_atomic(path, result.to_dict())
    print(f"wrote {path}\n")
    return fitted


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
    from pvgraph.circuits.pvg32.parameters import parameter_field, parameter_paths
    out = {name: (None, desc) for name, desc in SCENARIO_PARAMS.items()}
    for path in parameter_paths(params):
        out[path] = parameter_field(params, path)
    return out


def _rig_case(**kwargs) -> dict:
    """One sweep case (see :func:`_scenario_case`) on the compiled rig of this process.

    The rig of a case is built with its values; a rig built like one compiled before (the
    swept names are runtime parameters of its components, e.g. ``rig.pump_flow`` the pump's
    ``Q0``, ``rig.return_line_K`` the return line's ``K``) runs on that compiled system with
    the new values. A value that changes the structure (``rig.return_line_K`` None or not, a
    structural component field) compiles, with a one-line note.
    """
    from pvgraph.circuit import reuse_compiled
    with reuse_compiled():
        return _noted_case(_scenario_case, **kwargs)


def _scenario_case(*, scenario: str, preset: str, law: str, settle: float, after: float,
                   **params) -> dict:
    """One sweep case: a lab scenario on the rig with some parameters changed (SI outputs)."""
    from pydantic import ValidationError

    from pvgraph.circuits import validation as V
    from pvgraph.circuits.pvg32.parameters import with_values
    from pvgraph.circuits.scenarios import Scenario, get_scenario

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
    out = {**r.simulated, **r.margins, "settled": float(r.settled),
           "settle_deviation": r.settle_deviation, "steps": float(r.steps)}
    if not math.isfinite(r.settle_deviation):   # a run too short to judge: no deviation, not
        del out["settle_deviation"]             # a non-finite result
    return out


def _format_sweep_table(result, si: bool = False) -> str:
    params = result.param_names
    heads = [f"{RIG_OUTPUTS[n][3]} [{RIG_OUTPUTS[n][0 if si else 1]}]" for n in TABLE_OUTPUTS]
    widths = [max(len(p), 10) for p in params] + [max(len(h), 9) for h in heads]
    head = f"{'case':>4s}  " + "  ".join(f"{h:>{w}s}" for h, w in zip(params + heads, widths)) \
        + "  settled"
    lines = [head, "-" * len(head)]
    for r in result:
        cells = [f"{r.params[p]:>{w}.6g}" if isinstance(r.params[p], float) else
                 f"{str(r.params[p]):>{w}s}" for p, w in zip(params, widths)]
        if r.ok:
            spec = "4g" if si else "3f"
            cells += [f"{(float if si else RIG_OUTPUTS[n][2])(r.outputs[n]):>{w}.{spec}}"
                      for n, w in zip(TABLE_OUTPUTS, widths[len(params):])]
            tail = "yes" if r.outputs.get("settled") else "NO"
        else:
            tail = "FAILED: " + " ".join(r.error.split())[:100]
        lines.append(f"{r.index:>4d}  " + "  ".join(cells) + f"  {tail}")
    return "\n".join(lines)



def _check_rig_case(preset: str, case: dict) -> None:
    """Raise ParameterError if a case's values are invalid (before any case runs)."""
    from pydantic import ValidationError

    from pvgraph.circuits.pvg32.parameters import with_values
    from pvgraph.circuits.scenarios import Scenario, get_scenario

    params = dict(case)
    s = get_scenario(params.pop("scenario", "sweep-4"))
    if "U_input" in params:
        u = params.pop("U_input")
        try:
            Scenario.model_validate({**dict(s), "U_input": u})
        except ValidationError as exc:
            raise ParameterError(f"U_input = {u!r}: {exc.errors()[0]['msg']}") from None
    with_values(_preset(preset), params)


def sweep_scenarios(args) -> int:
    """``pvgraph sweep`` without a circuit target: rig parameters over lab scenarios."""
    from pvgraph.circuits.scenarios import scenario_names

    params = _preset(args.preset)
    valid = _sweepable(params)
    if args.list_params:
        for name, (value, desc) in valid.items():
            shown = "(scenario)" if name in SCENARIO_PARAMS else f"{value!r}"
            print(f"{name:45s} {shown:>24s}  {desc.split('. ')[0][:90]}")
        return 0
    if not args.scenario:
        raise PvgraphError("give a circuit (pvgraph sweep my_rig.py:build --param ...) or at "
                           "least one --scenario (e.g. --scenario test-9); valid: "
                           f"{', '.join(scenario_names())}")
    unknown = [n for n in args.scenario if n not in scenario_names()]
    if unknown:
        raise PvgraphError(f"unknown scenario(s) {unknown}; valid: {', '.join(scenario_names())}")
    settle = args.settle if args.settle is not None else (args.t_end or 8.0)
    if not (math.isfinite(settle) and settle > 0):
        option = "--settle" if args.settle is not None else "--t-end"
        raise PvgraphError(f"{option} must be a finite time > 0 s, got {settle}")
    cases = _sweep_cases(args, valid, {"scenario": list(args.scenario)})
    if len(args.scenario) == 1:
        for c in cases:
            del c["scenario"]
    run = functools.partial(_rig_case, scenario=args.scenario[0], preset=args.preset,
                            law=args.law, settle=settle, after=args.after)
    check = functools.partial(_check_rig_case, args.preset)
    units = {n: u[0] for n, u in RIG_OUTPUTS.items()}
    result, backend = run_sweep(args, run, cases, units, check)
    if result is None:
        return 130
    print(f"PVG 32 rig sweep: {', '.join(args.scenario)}, preset '{args.preset}', {args.law} "
          f"load, settle {settle:g} s; {len(result)} case{'s' if len(result) != 1 else ''} on {backend}, "
          f"{result.wall_time:.1f} s wall\n")
    print(_format_sweep_table(result, si=args.si))
    print(f"\n{len(result.ok)} ok, {len(result.failed)} failed; wrote {result.files[0]} and "
          f"{result.files[1]}")
    if result.failed:
        for r in result.failed:
            print(f"case {r.index} {r.params} failed: {r.error}", file=sys.stderr)
        return 1
    return 0


def _configure_sweep(parser) -> None:
    g = parser.add_argument_group("PVG 32 lab scenarios (without a circuit target)")
    g.add_argument("--scenario", action="append",
                   help="lab scenario (test-1 ... test-12, sweep-1 ... sweep-7); repeat to sweep "
                        "over several. --param then names U_input or a dotted PVG32Params "
                        "field (rig.return_line_K, pve.input_gain)")
    g.add_argument("--settle", type=time_arg, default=None,
                   help="simulated time to the steady state (before the solenoid step of "
                        "step tests) [s] (default: --t-end, else 8 s as pvgraph validate)")
    g.add_argument("--after", type=_positive_time, default=2.0,
                   help="simulated time after the solenoid step of step tests [s] "
                        "(default: %(default)s)")


def _configure_rig_options(parser) -> None:
    g = parser.add_argument_group("PVG 32 rig")
    g.add_argument("--preset", default="tuned", help="PVG 32 parameter preset: tuned (report "
                                                     "table 4.14) or initial (table 4.9)")
    g.add_argument("--law", default="laminar", choices=["laminar", "turbulent"],
                   help="rig load orifice law (report 4.7.2 concludes laminar)")


def _rig_options(args) -> dict:
    return {"preset": args.preset, "law": args.law}



#: SI unit -> (converter, display unit) for the Bode plot's axes
_DISPLAY = {"Pa": (to_bar, "bar"), "m^3/s": (to_lpm, "L/min"), "m": (to_mm, "mm")}
LINEARIZE_OUTPUTS = ["pvg.pvb.main_spool.flange.x", "load.f.port.p"]
#: [V] without --scenario: test 9's input voltage on the default rig load (small L1/L3, L2
#: closed), not test 9's load (large L1/L3: ``--scenario test-9``)
DEFAULT_VOLTAGE = 4.29


def linearize_rig(args) -> int:
    """``pvgraph linearize`` without a circuit target: the rig at a scenario or a voltage."""
    import numpy as np
    from pvgraph.circuits.rig import build_rig, laminar_load, turbulent_load
    from pvgraph.circuits.scenarios import get_scenario, scenario_names
    from pvgraph.analysis import linearize_circuit, steady_state

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
        print(f"  {n:40s} {_display(op[n], units[n], args.si)}")
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
            print(f"  {n:40s} {_display(float(g), units[n], args.si)}/V")

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
        from pvgraph.plotting import plot_bode
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




# --------------------------------------------------------------------------------------------
# registration

RIG_VARIABLES = ("load.f.port.p", "load.m.port.p", "load.b.port.p", "load.L2.q", "load.L3.q",
                 "pvg.pvb.main_spool.flange.x")


def _rig(preset: str = "tuned", law: str = "laminar"):
    from pvgraph.circuits.rig import build_rig, laminar_load, turbulent_load
    p = _preset(preset)
    return build_rig(p, load=(laminar_load if law == "laminar" else turbulent_load)(p))


def _module(name: str):
    def build(preset: str = "tuned"):
        from pvgraph.circuits.pvg32 import modules
        return getattr(modules, f"build_{name}")(_preset(preset))
    build.__name__ = f"build_{name}"
    return build


def _scenario_rig(name: str, preset: str = "tuned", law: str = "laminar",
                  t_switch: float = 8.0):
    """The rig set up for one lab scenario (L2 switching at ``t_switch`` in step tests)."""
    from pvgraph.circuits import validation as V
    s = V.get_scenario(name)
    step = s.solenoid_event in ("opening", "closing")
    return V._build(s, _preset(preset), law, t_switch if step else None)


def _configure_validate(v) -> None:
    v.add_argument("--out", default="pvgraph-report", type=output_dir,
                   help="output folder (default: %(default)s)")
    v.add_argument("--json", type=json_path,
                   help="write the comparison records here (default: OUT/validation.json; "
                        "the targets go to OUT/validation_targets.json)")
    v.add_argument("--preset", default="tuned", help="parameter preset: tuned (report table 4.14) "
                                                     "or initial (table 4.9)")
    v.add_argument("--law", default="laminar", choices=["laminar", "turbulent"],
                   help="load orifice law (report 4.7.2 concludes laminar)")
    v.add_argument("--scenario", action="append", help="run only this scenario (repeatable)")
    v.add_argument("--workers", type=_positive_int, default=None,
                   help="parallel processes (default 2)")
    v.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    v.add_argument("--calibrate", action="store_true",
                   help="first fit the uncertain rig parameters to the lab's steady data "
                        "(least squares with 95 %% intervals, about 10 s), then validate "
                        "with the estimates; writes OUT/calibration.json")
    v.add_argument("--fit", action="append", metavar="PARAM",
                   help="parameter to calibrate (repeatable; default: supply voltage, pump "
                        "flow, return line and the four load constants)")
    v.add_argument("--cross-validate", action="store_true",
                   help="also refit every data-derived parameter leaving out one group of "
                        "scenarios at a time (by input voltage, by load configuration) and "
                        "report the held-out errors (steady states; a few minutes on 2 "
                        "cores); writes OUT/cross_validation.json")
    v.add_argument("--fold", action="append", metavar="KEY",
                   help="with --cross-validate: run only this fold (repeatable), e.g. "
                        "'U = 4.6 V' or 'L1 large, L3 large' (a quick look at one group)")
    v.add_argument("--meter-out", choices=("overlap", "ratio"), default=None,
                   help="with --cross-validate: also identify return edges of their own "
                        "(A->T, B->T) with the return line from Pb: an extra overlap or "
                        "A_out = A_H (r0 + r1 u) (docs/pvg32_model.md 8b; default: the "
                        "report's one A_H)")


def _configure_simulate(parser) -> None:
    parser.add_argument("--t-switch", type=_positive_time, default=8.0,
                        help="PVG 32 scenarios: solenoid L2 switching time of step tests [s]")


def _simulate_options(args) -> dict:
    return {**_rig_options(args), "t_switch": args.t_switch}


def _configure_linearize(parser) -> None:
    g = parser.add_argument_group("PVG 32 rig (without a circuit target)")
    g.add_argument("--scenario", help="take the load and the voltage of this lab scenario "
                                      "(L2 in its final state)")
    g.add_argument("--voltage", type=float,
                   help=f"PVE input voltage U [V] (default: the scenario's, else "
                        f"{DEFAULT_VOLTAGE})")


def register(registry) -> None:
    """Register the PVG 32 circuits, scenarios, commands and plots with pvgraph."""
    from pvgraph.circuits.plotting import plot_flow_vs_voltage, plot_step_traces
    from pvgraph.circuits.scenarios import all_scenarios

    group = "PVG 32 (circuits/)"
    registry.circuit("rig", _rig, description="the PVG 32 on its lab rig (laminar load, "
                     "small orifices, L2 closed)", variables=RIG_VARIABLES, t_end=10.0,
                     options=("preset", "law"), group=group)
    for name, what in (("pvg32", "the PVG 32 valve: PVP, PVB and PVE"),
                       ("pvp", "the PVP pump-side module"), ("pvb", "the PVB module"),
                       ("pve", "the PVE actuator")):
        registry.circuit(name, _module(name), description=what, options=("preset",),
                         group=group)
    for s in all_scenarios():
        registry.circuit(s.name, functools.partial(_scenario_rig, s.name),
                         description=f"lab scenario {s.name} on the rig ({s.kind}, "
                                     f"U = {s.U_input} V)",
                         variables=RIG_VARIABLES, t_end=10.0,
                         options=("preset", "law", "t_switch"), group="PVG 32 lab scenarios")
    registry.command("validate", _configure_validate, cmd_validate,
                     help="simulate the 19 PVG 32 lab scenarios and compare with the data")
    registry.extension("simulate", _configure_rig_options, options=_rig_options)
    registry.extension("simulate", _configure_simulate, options=_simulate_options)
    for command in ("graph", "vars", "export", "sweep", "linearize"):
        registry.extension(command, _configure_rig_options, options=_rig_options)
    registry.extension("sweep", _configure_sweep, run=sweep_scenarios)
    registry.extension("linearize", _configure_linearize, run=linearize_rig)
    registry.plot("pvg32.flow_vs_voltage", plot_flow_vs_voltage)
    registry.plot("pvg32.step_traces", plot_step_traces)
