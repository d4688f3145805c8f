"""The ``pvgraph`` command line: any circuit, from a Python file, a module, a model file or a
registered name.

::

    pvgraph simulate my_rig.py:build --t-end 2 --var node.port.p --csv out.csv
    pvgraph simulate mypackage.rigs:build_press --plot press.png
    pvgraph simulate press.toml                      # a saved model file
    pvgraph vars my_rig.py:build                     # every variable with unit and description
    pvgraph graph my_rig.py:build --out rig.svg      # a layered schematic (PNG, SVG or DOT)
    pvgraph sweep my_rig.py:build --param orifice.A=1e-6:4e-6:4 --var node.port.p --out study
    pvgraph sweep ... --resume --timeout 60          # keep what is done, skip a hanging case
    pvgraph linearize my_rig.py:build --input pump.Q --output node.port.p
    pvgraph export my_rig.py:build --out rig.toml    # save as a model file (TOML or JSON)
    pvgraph components                               # the component library
    pvgraph circuits                                 # the circuits applications registered

A target ``FILE.py:NAME`` or ``MODULE:NAME`` names a function returning a
:class:`~pvgraph.Circuit` (called with the ``--option KEY=VALUE`` given) or a Circuit itself;
``FILE.toml`` / ``FILE.json`` is a model file (:mod:`pvgraph.modelfile`); any other name is
looked up among the circuits applications registered (:mod:`pvgraph.registry`, e.g. the PVG 32
``rig`` and its lab scenarios ``test-1`` ...). Values are printed for people (bar, L/min, mm;
``--si`` prints SI); files are SI and say so in their headers.

Exit codes: 0 success, 1 a run failed (a simulation stopped, a sweep case failed, no steady
state to linearise at), 2 bad arguments (checked before anything runs), 130 interrupted.
"""

from __future__ import annotations

import argparse
import difflib
import functools
import importlib
import importlib.util
import inspect
import json
import math
import os
import re
import sys
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

from ._progress import ProgressBar
from .errors import InitializationError, ParameterError, PvgraphError, SolverError
from .registry import registry
from .units import declared_unit, format_value, to_unit

__all__ = ["main", "build_parser", "load_target", "Target"]

DEFAULT_T_END = 10.0  # [s]


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


def _display(value: float, unit: str, si: bool = False) -> str:
    return format_value(value, unit, si)


# --------------------------------------------------------------------------------------------
# targets: FILE.py:NAME, MODULE:NAME, FILE.toml / FILE.json, registered names

@dataclass
class Target:
    """A circuit the command line can build: ``build(**options)`` gives a fresh Circuit."""

    spec: str
    build: Callable[..., Any]
    variables: tuple[str, ...] = ()
    t_end: float | None = None
    options: dict = field(default_factory=dict)
    description: str = ""
    source: str | None = None     # the user's file the builder is in (errors name its line)

    def circuit(self):
        from .circuit import Circuit
        try:
            c = self.build(**self.options)
        except TypeError as exc:
            if "missing" in str(exc) and "required" in str(exc) and \
                    _raised_by_call(exc.__traceback__):
                missing = re.findall(r"'(\w+)'", str(exc).split(":", 1)[-1])
                example = " ".join(f"--option {m}=..." for m in missing) or "--option NAME=..."
                raise PvgraphError(f"{self.spec}: the builder needs {', '.join(missing)} "
                                   f"({exc}); give {example}") from None
            if self.options and "argument" in str(exc):
                raise PvgraphError(f"{self.spec}: the builder does not take the options "
                                   f"{sorted(self.options)}: {exc}") from None
            raise
        except PvgraphError as exc:
            where = _line_in(exc.__traceback__, self.source)
            if where is None:
                raise
            raise PvgraphError(f"{where}: {exc}") from None
        if not isinstance(c, Circuit):
            raise PvgraphError(f"{self.spec} returned {type(c).__name__}, not a pvgraph "
                               f"Circuit")
        return c


def _raised_by_call(tb) -> bool:
    """Whether a TypeError was raised by the builder's call itself (its arguments), not by
    code inside the builder."""
    depth = 0
    while tb is not None:
        depth += 1
        tb = tb.tb_next
    return depth == 1


def _line_in(tb, source: str | None) -> str | None:
    """``"FILE, line N (in FUNCTION)"``: the last line of ``source`` in a traceback."""
    if source is None:
        return None
    source = os.path.realpath(source)
    found = None
    while tb is not None:
        code = tb.tb_frame.f_code
        if os.path.realpath(code.co_filename) == source:
            found = f"{os.path.relpath(source)}, line {tb.tb_lineno} (in {code.co_name})"
        tb = tb.tb_next
    return found


def _import_module_here(name: str):
    """Import ``name``, also from the working directory: ``pvgraph simulate my_rig:build``
    finds ./my_rig.py as ``python -m pvgraph.cli`` does (the installed script's path has no
    working directory in it)."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        here = os.getcwd()
        if exc.name != name.split(".")[0] or here in sys.path or "" in sys.path:
            raise
        sys.path.insert(0, here)
        try:
            return importlib.import_module(name)
        except ModuleNotFoundError as again:
            if again.name == name.split(".")[0]:
                sys.path.remove(here)
            raise


def _import_file(path: str):
    if not os.path.isfile(path):
        raise PvgraphError(f"no such file {path!r}")
    name = "_pvgraph_target_" + "".join(ch if ch.isalnum() else "_"
                                        for ch in os.path.abspath(path))
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    folder = os.path.dirname(os.path.abspath(path))
    sys.path.insert(0, folder)      # the file's own imports of its neighbours
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        del sys.modules[name]
        where = f" (line {exc.lineno})" if isinstance(exc, SyntaxError) else ""
        raise PvgraphError(f"{path}{where}: importing it failed: {type(exc).__name__}: "
                           f"{exc}") from exc
    except BaseException:
        del sys.modules[name]
        raise
    finally:
        sys.path.remove(folder)
    return module


def _allowed_modules(names) -> tuple[str, ...]:
    """The ``--module`` names, each imported (also from the working directory) to check it."""
    for name in names:
        try:
            _import_module_here(name)
        except ImportError as exc:
            raise PvgraphError(f"--module {name}: cannot import it: {exc}") from None
    return tuple(names)


def load_target(spec: str, options: dict | None = None, modules=()) -> Target:
    """The :class:`Target` a command-line argument names (see the module docstring);
    ``modules`` are the modules whose component classes a model file may name."""
    options = dict(options or {})
    if spec.endswith((".toml", ".json")) and ":" not in spec:
        from .modelfile import load
        if not os.path.isfile(spec):
            raise PvgraphError(f"no such model file {spec!r}")
        allowed = _allowed_modules(modules)
        return Target(spec, lambda: load(spec, modules=allowed),
                      description=f"model file {spec}")
    if modules:
        raise PvgraphError(f"--module applies to a model file target (.toml, .json), not to "
                           f"{spec}")
    module_part, colon, attr = spec.rpartition(":")
    if colon and module_part and (module_part.endswith(".py") or "/" in module_part
                                  or os.sep in module_part):
        module = _import_file(module_part)
    elif colon and module_part and not (len(module_part) == 1 and os.sep == "\\"):
        try:
            module = _import_module_here(module_part)
        except ImportError as exc:
            raise PvgraphError(f"cannot import module {module_part!r} of target {spec!r}: "
                               f"{exc}") from None
    elif spec.endswith(".py"):
        module, attr = _import_file(spec), "build"
        if not hasattr(module, "build"):
            raise PvgraphError(f"{spec} has no function build(); name the function that "
                               f"returns the circuit: {spec}:NAME")
    else:
        entries = registry.load().circuits
        if spec in entries:
            e = entries[spec]
            return Target(spec, e.build, e.variables, e.t_end,
                          {k: v for k, v in options.items() if k in e.options}, e.description)
        close = difflib.get_close_matches(spec, list(entries), n=3)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        known = f" Registered circuits: {', '.join(entries)}." if entries else \
            " No application has registered circuits."
        raise PvgraphError(f"unknown circuit {spec!r}.{hint} Give FILE.py:FUNCTION, "
                           f"MODULE:FUNCTION, a model file (.toml, .json) or a registered "
                           f"name.{known}")
    if not hasattr(module, attr):
        found = [n for n, v in vars(module).items() if callable(v) and not n.startswith("_")]
        close = difflib.get_close_matches(attr, found, n=3)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        raise PvgraphError(f"{module_part or spec} has no {attr!r}.{hint}")
    obj = getattr(module, attr)
    from .circuit import Circuit
    if isinstance(obj, Circuit):
        return Target(spec, lambda: obj, description=obj.name)
    if not callable(obj):
        raise PvgraphError(f"{spec} is {type(obj).__name__}; it must be a Circuit or a function "
                           f"returning one")
    user = {k: v for k, v in options.items() if k in _accepted(obj, options)}
    return Target(spec, obj, tuple(getattr(obj, "variables", ())), getattr(obj, "t_end", None),
                  user, (inspect.getdoc(obj) or "").split("\n")[0],
                  getattr(module, "__file__", None))


def _accepted(func, options) -> set:
    try:
        sig = inspect.signature(func)
    except (TypeError, ValueError):
        return set(options)
    if any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values()):
        return set(options)
    return set(sig.parameters) & set(options)


def _parse_options(pairs) -> dict:
    out = {}
    for pair in pairs or []:
        key, eq, value = pair.partition("=")
        if not eq or not key.strip().isidentifier():
            raise PvgraphError(f"--option {pair!r}: write KEY=VALUE (KEY a keyword argument of "
                               f"the builder)")
        try:
            out[key.strip()] = json.loads(value)
        except ValueError:
            out[key.strip()] = value
    return out


def _target(args) -> Target:
    """The target of a command, with the builder options of ``--option`` and extensions."""
    options = {}
    if args.target in registry.load().circuits:     # application options for its own circuits
        for ext in registry.extensions.get(args.command, []):
            if ext.options is not None:
                options.update(ext.options(args))
    else:
        typed = getattr(args, "_argv", [])
        given = [flag for dest, (flag, default) in
                 getattr(args, "_application_options", {}).items()
                 if getattr(args, dest, default) != default
                 or any(t == flag or t.startswith(flag + "=") for t in typed)]
        if given:
            names = ", ".join(sorted(registry.load().circuits)[:4])
            raise PvgraphError(f"{', '.join(given)} applies to the registered circuits "
                               f"({names}, ...; pvgraph circuits lists them), not to "
                               f"{args.target}: give your builder's arguments with "
                               f"--option NAME=VALUE")
    generic = _parse_options(getattr(args, "option", None))
    target = load_target(args.target, {**options, **generic}, getattr(args, "module", None) or ())
    if generic:
        missing = set(generic) - set(target.options)
        if missing:
            raise PvgraphError(f"{args.target} does not take the option(s) {sorted(missing)}")
    return target


def check_names(system, names, what: str = "--var") -> list[str]:
    """The canonical names of ``names`` (:meth:`System.resolve_name`: exposed-port names
    resolve to the variable they stand for); an unknown name raises with close matches."""
    out = []
    for name in names:
        try:
            out.append(system.resolve_name(name))
        except KeyError:
            close = system.close_names(name)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else "."
            raise PvgraphError(f"{what} {name!r} is not a variable or output of "
                               f"{system.name!r}{hint} List them with pvgraph vars.") from None
    return out


# --------------------------------------------------------------------------------------------
# simulate, vars, graph, export, components, circuits

def _need_matplotlib(option: str) -> None:
    """A figure option without matplotlib installed is refused before anything runs."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise PvgraphError(f"{option} draws with matplotlib, which is not installed: pip "
                           f"install matplotlib") from None


def cmd_simulate(args) -> int:
    from .simulate import _solver_function, simulate
    if args.plot:
        _need_matplotlib("--plot")

    if args.solver != "pvgraph":
        try:
            _solver_function(args.solver)   # an optional backend: checked before compiling
        except PvgraphError as exc:
            raise PvgraphError(f"--solver {args.solver}: {exc}") from None
    target = _target(args)
    circuit = target.circuit()
    system = circuit.compile()
    shown = args.var or list(target.variables) or _default_variables(system)
    check_names(system, shown)       # fails before the run; results keep the names as given
    t_end = args.t_end if args.t_end is not None else (target.t_end or DEFAULT_T_END)
    if not (math.isfinite(t_end) and t_end > 0):
        raise PvgraphError(f"--t-end must be a finite time > 0 s, got {t_end}")
    try:
        sol = simulate(system, t_end, rtol=args.rtol, solver=args.solver)
    except PvgraphError as exc:
        print(f"pvgraph simulate: {target.spec}: {exc}", file=sys.stderr)
        return 1
    width = max(len(n) for n in shown)
    for n in shown:
        print(f"{n:{width}s}  final {_display(sol.final(n), sol.unit(n), args.si)}")
    if sol.stats.get("nsteps") is None:
        print("no unknown left to integrate: the equations fix every variable")
    else:
        print(f"steps {sol.stats.get('nsteps')}, residual evaluations {sol.stats.get('nre')}")
    if args.csv:
        sol.to_csv(args.csv, shown)
        print(f"wrote {args.csv} (SI units, named in its header)")
    if args.plot:
        from .plotting import plot_solution
        print(f"wrote {plot_solution(sol, shown, args.plot, si=args.si)}")
    return 0


def _default_variables(system, limit: int = 8) -> list[str]:
    """The states, pressures first, when neither the user nor the circuit names any."""
    states = [n for n, d in zip(system.names, system.differential) if d]
    states.sort(key=lambda n: (system.unit(n) != "Pa", n))
    # a circuit the equations fix entirely has no unknown: show what it fixes
    return (states or list(system.names) or sorted(system.aliases))[:limit]


def _port_description(circuit, name: str) -> str:
    """``"p at port a (inlet)"`` for a port variable of a leaf component, else ``""``."""
    from .circuit import Circuit
    path, _, var = name.rpartition(".")
    owner, _, port = path.rpartition(".")
    try:
        comp = circuit[owner] if owner else None
    except Exception:         # not a component path: a variable of another kind
        return ""
    spec = None if comp is None or isinstance(comp, Circuit) else comp.ports.get(port)
    if spec is None:
        return ""
    d = spec.domain
    what = f"{var} at port {port}" if var == d.across else \
        (f"{var} into port {port}" if var == d.through else "")
    return f"{what} ({spec.description})" if what and spec.description else what


def _alias_text(coef, target, off) -> str:
    """``"= target"``, ``"= -1 * target + 0.0001667"`` or ``"fixed 0"`` (SI)."""
    if target is None:
        return f"fixed {off:g}"
    text = f"= {target}" if coef == 1.0 else \
        (f"= -{target}" if coef == -1.0 else f"= {coef:g} * {target}")
    if off != 0.0:
        text += f" {'+' if off > 0 else '-'} {abs(off):g}"
    return text


def cmd_vars(args) -> int:
    target = _target(args)
    circuit = target.circuit()
    system = circuit.compile()
    rows = []
    for k, n in enumerate(system.names):
        kind = "state" if system.differential[k] else "algebraic"
        rows.append((n, system.units[k], kind, _port_description(circuit, n) or (
            system.descriptions[k] if system.descriptions else "")))
    exposed = system.exposed_names()
    for n, (coef, tgt, off) in sorted(system.aliases.items()):
        kind = _alias_text(coef, tgt, off)
        rows.append((n, system.unit(n), kind, _port_description(circuit, n)))
    for n, (unit, desc) in sorted((n, v[:2]) for n, v in system.observed.items()):
        rows.append((n, unit, "output", desc or ""))
    for alias, real in sorted(exposed.items()):
        rows.append((alias, system.unit(real), f"alias of {real} (exposed port)",
                     _port_description(circuit, real)))
    if args.grep:
        rows = [r for r in rows if args.grep.lower() in r[0].lower()]
    width = max((len(r[0]) for r in rows), default=10)
    print(f"{system.name}: {system.n} unknowns ({int(system.differential.sum())} states), "
          f"{len(system.aliases)} eliminated, {len(system.observed)} outputs, {len(exposed)} "
          f"exposed-port names; units SI")
    for name, unit, kind, desc in rows:
        print(f"{name:{width}s}  [{unit}]  {kind}{'  ' + desc if desc else ''}")
    return 0


def cmd_graph(args) -> int:
    from .plotting import draw_circuit
    if args.out is None:        # the default name follows the format asked for
        args.out = f"circuit.{args.format or 'png'}"
    suffix = os.path.splitext(args.out)[1].lstrip(".").lower()
    suffix = {"gv": "dot"}.get(suffix, suffix)      # Graphviz's own extension
    if args.format is None and suffix not in ("png", "svg", "dot"):
        raise PvgraphError(f"--out {args.out!r}: the format comes from the extension; name "
                           f"the file .png, .svg, .dot or .gv" + (
                               ", or give --format for a name without one" if not suffix
                               else ""))
    if args.format is not None and suffix and suffix != args.format:
        raise PvgraphError(f"--format {args.format} but --out {args.out!r} is named "
                           f".{suffix}; name it "
                           f"{os.path.splitext(args.out)[0] + '.' + args.format!r} or leave "
                           f"--format out")
    if (args.format or suffix) != "dot":
        _need_matplotlib(f"--format {args.format}" if args.format else
                         f"--out {args.out!r} (a .{suffix} drawing)")
    target = _target(args)
    out = draw_circuit(target.circuit(), args.out, fmt=args.format or suffix)
    print(f"wrote {out}")
    return 0


def cmd_export(args) -> int:
    fmu = args.out.lower().endswith(".fmu")
    if fmu:
        for names, option in ((args.var, "--var"), (args.input, "--input"),
                              (args.parameter, "--parameter")):
            _refuse_repeats(names, option)
        both = sorted(set(args.input or []) & set(args.parameter or []))
        if both:
            raise PvgraphError(f"{both[0]} is given as --input and as --parameter; give it "
                               f"as one of them")
    else:
        given = [o for o, v in (("--var", args.var), ("--input", args.input),
                                ("--parameter", args.parameter)) if v]
        if given:
            raise PvgraphError(f"{', '.join(given)} appl{'ies' if len(given) == 1 else 'y'} "
                               f"to an FMU (--out NAME.fmu), not to a model file")
    target = _target(args)
    circuit = target.circuit()
    if fmu:
        from .fmi import export_fmu
        if not (args.var or target.variables):
            raise PvgraphError(f"an FMU needs at least one output: give --var NAME (the names: "
                               f"pvgraph vars {args.target})")
        path = export_fmu(circuit, args.out, outputs=args.var or list(target.variables),
                          inputs=args.input or [], parameters=args.parameter or [])
    else:
        from .modelfile import foreign_modules, save
        path = save(circuit, args.out)
        foreign = foreign_modules(circuit)
        if foreign:
            print(f"pvgraph export: note: {path} names component types of "
                  f"{', '.join(foreign)}, outside the library; loading it needs "
                  f"{' '.join('--module ' + m for m in foreign)} (in Python: load(path, "
                  f"modules={foreign!r}))", file=sys.stderr)
    print(f"wrote {path}")
    return 0


def cmd_components(args) -> int:
    from .docgen import _component_section, _components_of, component_reference, library_modules
    modules = library_modules()
    if not args.names:
        print(component_reference(modules))
        return 0
    classes = {cls.__name__: cls for m in modules for cls in _components_of(m)}
    lower = {name.lower(): name for name in classes}
    for name in args.names:
        real = classes.get(name) and name or lower.get(name.lower())
        if real is None:
            close = difflib.get_close_matches(name, list(classes), n=3, cutoff=0.5)
            hint = f"; did you mean {', '.join(map(repr, close))}?" if close else "."
            raise PvgraphError(f"components: no component named {name!r}{hint} "
                               f"pvgraph components lists them all")
        print("\n".join(_component_section(classes[real])).rstrip() + "\n")
    return 0


def cmd_circuits(args) -> int:
    entries = registry.load().circuits
    if not entries:
        print("no registered circuits; give FILE.py:FUNCTION, MODULE:FUNCTION or a model file")
        return 0
    groups: dict[str, list] = {}
    for e in entries.values():
        groups.setdefault(e.group or "other", []).append(e)
    for group, members in groups.items():
        print(f"{group}:")
        for e in members:
            print(f"  {e.name:12s} {e.description}")
    return 0


# --------------------------------------------------------------------------------------------
# sweep

def _check_param_name(name: str, valid, option: str = "--param") -> None:
    if name in valid:
        return
    if any(v.startswith(name + ".") for v in valid):
        example = next(v for v in valid if v.startswith(name + "."))
        raise PvgraphError(f"{option} {name!r} is a group of parameters; name one of its "
                           f"fields, e.g. {example!r} (see pvgraph sweep TARGET --list-params)")
    close = difflib.get_close_matches(name, list(valid), n=3, cutoff=0.6)
    hint = f"; did you mean {', '.join(map(repr, close))}?" if close else "."
    raise PvgraphError(f"{option}: unknown parameter {name!r}{hint} The circuit's parameters "
                       f"are component.field names; list them with pvgraph sweep TARGET "
                       f"--list-params")


def _parse_number(text: str, name: str, unit: str | None = None) -> float:
    try:
        value = float(text)
    except ValueError:
        if unit is None:
            raise PvgraphError(f"--param {name}: {text!r} is not a number") from None
        try:
            value = float(to_unit(text.strip(), unit, name))
        except ParameterError as exc:
            raise PvgraphError(f"--param {name}: {exc}") from None
    if not math.isfinite(value):
        raise PvgraphError(f"--param {name}: {text!r} is not a finite number")
    return value


def _is_bare(text: str) -> bool:
    """Whether a value of a ``--param`` spec is a plain number (read as SI)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _check_units_not_mixed(name: str, values: list[str], spell, declared=None) -> None:
    """A spec whose values mix plain numbers (SI) with quantities (``1:2 mm^2:3``) is
    refused: the plain one would be read as SI, not in the other's unit. ``spell(values)``
    writes the spec back from its values (for the correct spellings in the message);
    ``declared`` is the parameter's SI unit."""
    # zero is zero in every unit (no unit of the library has an offset)
    bare = [v.strip() for v in values if _is_bare(v) and float(v) != 0.0]
    given = [v.strip() for v in values if not _is_bare(v)]
    if not bare or not given:
        return
    from .units import _NUMBER
    match = _NUMBER.match(given[0])
    unit = match.group(2) if match and match.group(2) else None
    if unit and declared:
        from .units import UnitError, parse_unit
        try:
            same = parse_unit(unit) == parse_unit(declared)
        except UnitError:
            same = False
        if same:        # the quantity's unit is the SI one the plain numbers are read in
            return
    if unit:
        typed = [f"{v.strip()} {unit}" if _is_bare(v) else v.strip() for v in values]
        hint = f"write '{name}={spell(typed)}'"
        try:       # both readings in SI: the plain numbers in the unit, or as SI
            in_unit = [f"{_parse_number(v, name, declared):.12g}" for v in typed]
            as_si = [v.strip() if _is_bare(v) else f"{_parse_number(v, name, declared):.12g}"
                     for v in values]
        except PvgraphError:
            in_unit = as_si = None
        if declared and in_unit:
            hint += (f" (in SI, '{name}={spell(in_unit)}') if {bare[0]!r} is in {unit}, or "
                     f"'{name}={spell(as_si)}' if it is SI")
        else:
            hint += ", or SI numbers for all"
    else:
        hint = "give every value with its unit, or SI numbers for all"
    raise PvgraphError(f"--param {name}: {bare[0]!r} has no unit but {given[0]!r} has one, "
                       f"and a plain number is read as SI, not in that unit: {hint}")


def _parse_param(spec: str, random_mode: bool, units: dict | None = None):
    """``NAME=SPEC`` -> (name, grid values or random-sample range); see ``--param`` help."""
    import numpy as np
    name, eq, body = spec.partition("=")
    name = name.strip()
    unit = (units or {}).get(name)
    if not eq or not name or not body.strip():
        raise PvgraphError(f"--param {spec!r}: write NAME=VALUE, NAME=LO:HI:N, NAME=V1,V2,... "
                           f"or (with --random) NAME=LO:HI")
    log = body.startswith("log:")
    parts = (body[4:] if log else body).split(":")
    if len(parts) == 1 and not log:
        values = [_parse_number(v, name, unit) for v in body.split(",")]
        _check_units_not_mixed(name, body.split(","), ",".join, unit)
        if random_mode and len(values) > 1:
            raise PvgraphError(f"--param {name}: with --random give a range LO:HI (or "
                               f"log:LO:HI) or one fixed value, not a list")
        return name, (values[0] if random_mode else values)
    if random_mode:
        if len(parts) != 2:
            raise PvgraphError(f"--param {name}: with --random give a range LO:HI or "
                               f"log:LO:HI, not {body!r}")
        lo, hi = (_parse_number(v, name, unit) for v in parts)
        _check_units_not_mixed(name, parts, lambda v: ("log:" if log else "") + ":".join(v),
                               unit)
        if not lo < hi:
            raise PvgraphError(f"--param {name}: a random range LO:HI needs LO < HI, got "
                               f"{body!r} ({lo:g} to {hi:g} SI)")
        if log and lo <= 0:
            raise PvgraphError(f"--param {name}: a log range needs positive bounds, got "
                               f"{body!r}")
        return name, (("log", lo, hi) if log else (lo, hi))
    if len(parts) != 3:
        raise PvgraphError(f"--param {name}: a grid range needs the number of points, "
                           f"{'log:' if log else ''}LO:HI:N (or use --random N to sample "
                           f"LO:HI); got {body!r}")
    lo, hi = (_parse_number(v, name, unit) for v in parts[:2])
    _check_units_not_mixed(name, parts[:2], lambda v: ("log:" if log else "") + ":".join(v)
                           + ":" + parts[2].strip(), unit)
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


def _sweep_cases(args, valid, prefix: dict | None = None) -> list[dict]:
    """Cases from ``--param`` (a grid, or ``--random N`` samples), crossed with ``prefix``."""
    from .analysis.sweep import grid, random_sample
    units = {name: declared_unit(desc) for name, (_, desc) in valid.items()}
    specs = {}
    for spec in args.param or []:
        given = spec.partition("=")[0].strip()
        if "=" in spec and given:
            _check_param_name(given, valid)     # the name before its values
        value = valid.get(given, (None,))[0]
        if isinstance(value, str) and not isinstance(value, bool):
            # a choice (a valve's centre, a friction law): the values as written
            name, values = given, [v.strip() for v in spec.partition("=")[2].split(",")]
            if args.random is not None and len(values) > 1:
                raise PvgraphError(f"--param {name}: a choice cannot be sampled; give one "
                                   f"value with --random")
            values = values[0] if args.random is not None else values
        else:
            name, values = _parse_param(spec, args.random is not None, units)
        _check_param_name(name, valid)
        if name in specs:
            raise PvgraphError(f"--param {name!r} is given twice")
        specs[name] = values
    if not specs and not prefix:
        raise PvgraphError("give at least one --param NAME=SPEC (list the names with "
                           "pvgraph sweep TARGET --list-params)")
    if args.random is not None:
        if args.random < 1:
            raise PvgraphError(f"--random N needs N >= 1, got {args.random}")
        if not any(isinstance(v, tuple) for v in specs.values()):
            raise PvgraphError("--random needs at least one --param NAME=LO:HI range")
        samples = random_sample(specs, args.random, seed=args.seed, method=args.method)
        outer = grid(prefix) if prefix else [{}]
        return [{**o, **c} for o in outer for c in samples]
    return grid({**(prefix or {}), **specs})


#: the sweep's Python arguments in messages, as the command line spells them
_SWEEP_SPELLING = {"resume=True": "--resume", "overwrite=True": "--overwrite", "out='": "--out '",
                   "out=": "--out"}


def _in_option_spelling(message: str) -> str:
    """A sweep message with its Python arguments (``resume=True``) as command-line options
    (``--resume``)."""
    for python, option in _SWEEP_SPELLING.items():
        message = re.sub(rf"(?<![\w.]){re.escape(python)}", option, message)
    return message


def run_sweep(args, run, cases, units, check):
    """Run a sweep with the command's backend options; ``(result, backend)``, or
    ``(None, backend)`` after Ctrl-C (what finished is kept in ``--out``)."""
    from .analysis.sweep import SweepError, SweepInterrupted, sweep
    if args.workers is not None and args.workers < 1:
        raise PvgraphError(f"--workers must be >= 1, got {args.workers}")
    if args.timeout is not None and not args.timeout > 0:
        raise PvgraphError(f"--timeout must be > 0 s, got {args.timeout}")
    backend = args.backend or ("dask" if args.scheduler else "process")
    if args.scheduler and backend != "dask":
        raise PvgraphError("--scheduler is the address of a Dask scheduler; it needs "
                           "--backend dask")
    try:
        result = sweep(run, cases, backend=backend, workers=args.workers, client=args.scheduler,
                       progress=True, units=units, out=args.out, resume=args.resume,
                       overwrite=args.overwrite, timeout=args.timeout, check=check)
    except SweepError as exc:
        raise PvgraphError(_in_option_spelling(str(exc))) from None
    except SweepInterrupted as exc:
        done = exc.result
        print(f"\ninterrupted: {len(done.records)} of {done.n_cases} cases finished and kept "
              f"in {args.out}; run the same command with --resume to finish", file=sys.stderr)
        return None, backend
    return result, backend


def _canonical_target(spec: str) -> str:
    """``spec`` with the file it names as its real path (``./my_rig.py:build``, its absolute
    path and the path from another folder are one target, for a sweep's record), else as
    it is (a registered circuit, a module)."""
    module_part, colon, attr = spec.rpartition(":")
    if colon and module_part.endswith(".py") and os.path.exists(module_part):
        return f"{os.path.realpath(module_part)}:{attr}"
    if spec.endswith((".py", ".toml", ".json")) and os.path.exists(spec):
        return os.path.realpath(spec)
    return spec


def _target_circuit(target: str, options: dict, modules=()):
    """The circuit of a command-line target (a picklable factory for the sweep's workers)."""
    return load_target(target, options, modules).circuit()


def _noted_case(run, **params) -> dict:
    """Run one sweep case; a compilation for a structural parameter is a one-line note on
    stderr (once per structure and worker), other warnings pass through."""
    import warnings

    from .system import RecompileWarning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RecompileWarning)
        out = run(**params)
    for w in caught:
        if issubclass(w.category, RecompileWarning):
            print(f"note: {w.message}", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return out


_PLAIN_NUMBER_HINT = re.compile(r': a plain number is in ([^;]+); give the unit with the '
                                r'number, e\.g\. (\w+)="(\S+) ([^"]+)"')


def _typed_params(args) -> dict:
    """``{name: spec}`` of the ``--param`` options as typed."""
    return {n.strip(): body.strip() for n, eq, body in
            (spec.partition("=") for spec in getattr(args, "param", None) or []) if eq}


def _in_cli_spelling(message: str, case: dict, typed: dict) -> str:
    """A parameter message's hint for a plain number in the spelling of ``--param``: the
    spec with the unit on every value (``--param 'pump.Q=5 L/min:20 L/min:4'``), or no hint
    where the spec gave units already (the case's number is their SI value)."""
    def replace(m):
        si, field, number, usual = m.groups()
        for name, value in case.items():
            if name.rpartition(".")[2] != field or name not in typed or \
                    not isinstance(value, float) or f"{value:g}" != number:
                continue
            spec = typed[name]
            log = spec.startswith("log:")
            parts = (spec[4:] if log else spec).split(",")
            if len(parts) == 1:
                parts = parts[0].split(":")
                count = parts.pop() if len(parts) == 3 else None
                sep = ":"
            else:
                count, sep = None, ","
            if not all(_is_bare(v) for v in parts):
                return ""      # given with units: the bound (in its unit) says it all
            written = sep.join(f"{v.strip()} {usual}" for v in parts)
            written = ("log:" if log else "") + written + (f":{count}" if count else "")
            return (f": a plain number is in {si}; give the unit with the numbers, e.g. "
                    f"--param '{name}={written}'")
        return m.group(0)
    return _PLAIN_NUMBER_HINT.sub(replace, message)


def _check_target_case(circuit, case: dict, typed: dict | None = None) -> None:
    try:
        circuit.check_parameters(case)
    except PvgraphError as exc:
        text = _in_cli_spelling(str(exc), case, typed or {})
        if text == str(exc):
            raise
        raise PvgraphError(text) from None


def cmd_sweep(args) -> int:
    if args.target is None:
        handler = [e.run for e in registry.load().extensions.get("sweep", []) if e.run]
        if not handler:
            raise PvgraphError("give a circuit: pvgraph sweep my_rig.py:build --param "
                               "orifice.A=1e-6:4e-6:4 --var node.port.p")
        return handler[0](args)
    target = _target(args)
    circuit = target.circuit()
    valid = circuit.parameters()
    if getattr(args, "list_params", False):
        for name, (value, desc) in valid.items():
            print(f"{name:40s} {value!r:>24}  {desc[:90]}")
        return 0
    system = circuit.compile()
    outputs = tuple(args.var or target.variables or _default_variables(system))
    resolved = check_names(system, outputs)
    t_end = args.t_end if args.t_end is not None else (target.t_end or DEFAULT_T_END)
    cases = _sweep_cases(args, valid)
    both = [n for n in outputs if n in cases[0]]
    if both:
        raise PvgraphError(f"--var {both[0]} is also a swept --param: its values are in the "
                           f"case's {both[0]} column already; leave it out of --var")
    # compiled once per worker; each case runs with its values as runtime parameters
    from .analysis.sweep import CompiledRun
    run = functools.partial(_noted_case, CompiledRun(
        functools.partial(_target_circuit, _canonical_target(args.target), target.options,
                          tuple(args.module or ())),
        outputs=dict(zip(outputs, resolved)), t_end=None if args.steady else t_end,
        rtol=args.rtol, steady=args.steady, warm=args.steady))
    units = {n: system.unit(r) for n, r in zip(outputs, resolved)}
    result, backend = run_sweep(args, run, cases, units,
                                functools.partial(_check_target_case, circuit,
                                                  typed=_typed_params(args)))
    if result is None:
        return 130
    what = "steady states" if args.steady else f"t_end {t_end:g} s"
    print(f"{target.spec}: {len(result)} case{'s' if len(result) != 1 else ''} on {backend}, {what}, "
          f"{result.wall_time:.1f} s wall\n")
    param_units = {n: declared_unit(desc) or "" for n, (_, desc) in valid.items()}
    print(_format_table(result, units, args.si, param_units))
    print(f"\n{len(result.ok)} ok, {len(result.failed)} not ok; wrote {result.files[0]} and "
          f"{result.files[1]} (SI)")
    for r in result.failed:
        print(f"case {r.index} {r.params} {r.status}: {r.error}", file=sys.stderr)
    return 1 if result.failed else 0


def _format_table(result, units, si, param_units=None) -> str:
    """The sweep's cases as a table: parameters and outputs in the units people read (bar,
    L/min, mm^2 ...; SI with ``si``), each column headed by its unit."""
    from .units import display
    param_units = param_units or {}

    def head(name, unit):
        shown = display(1.0, unit, si)[1] if unit else ""
        return f"{name} [{shown}]" if shown else name

    heads = [head(p, param_units.get(p, "")) for p in result.param_names] + \
        [head(n, units.get(n, "")) for n in result.output_names]
    widths = [max(len(h), 10) for h in heads]
    lines = ["case  " + "  ".join(f"{h:>{w}s}" for h, w in zip(heads, widths)) + "  status"]
    lines.append("-" * len(lines[0]))
    for r in result:
        cells = [f"{display(r.params[p], param_units.get(p, ''), si)[0]:>{w}.6g}"
                 if isinstance(r.params[p], float) else f"{str(r.params[p]):>{w}s}"
                 for p, w in zip(result.param_names, widths)]
        for n, w in zip(result.output_names, widths[len(result.param_names):]):
            v = r.outputs.get(n)
            cells.append(f"{display(v, units.get(n, ''), si)[0]:>{w}.6g}" if v is not None
                         else f"{'-':>{w}s}")
        status = r.status if r.ok else f"{r.status}: " + " ".join((r.error or "").split())[:80]
        warned = getattr(r, "warnings", ())
        if warned:
            status += f" ({len(warned)} warning{'s' if len(warned) > 1 else ''}, above)"
        lines.append(f"{r.index:>4d}  " + "  ".join(cells) + f"  {status}")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# linearize

def _check_outputs(system, names) -> None:
    """Every name is a variable or a derived output of the system: a linear model's output."""
    for name in names:
        try:
            system.resolve_name(name)
            continue
        except KeyError:
            pass
        close = system.close_names(name)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise PvgraphError(f"--output {name!r} is not a variable of the circuit{hint} (it has "
                           f"{system.n + len(system.aliases)} variables, e.g. "
                           f"{', '.join(system.names[:3])}, and {len(system.observed)} derived "
                           f"outputs)")


def _refuse_repeats(names, option: str) -> None:
    """A name given twice to a repeatable option is refused, naming it."""
    seen = set()
    for name in names or []:
        if name in seen:
            raise PvgraphError(f"{option} {name} is given twice; give each once")
        seen.add(name)


def _frequency_response(lm, freq_hz, output: int, input: int = 0):
    """G(j 2 pi f) of a linear model at the frequencies ``freq_hz`` [Hz]."""
    import numpy as np
    return lm.frequency_response(2.0 * math.pi * np.asarray(freq_hz, dtype=float), output,
                                 input)


def cmd_linearize(args) -> int:
    import numpy as np

    from .analysis import linearize_circuit, steady_state

    if args.target is None:
        handler = [e.run for e in registry.load().extensions.get("linearize", []) if e.run]
        if not handler:
            raise PvgraphError("give a circuit: pvgraph linearize my_rig.py:build --input "
                               "pump.Q --output node.port.p")
        return handler[0](args)
    _refuse_repeats(args.input, "--input")
    _refuse_repeats(args.output, "--output")
    if args.bode:
        _need_matplotlib("--bode")
    if args.json and args.bode and os.path.realpath(args.json) == os.path.realpath(args.bode):
        raise PvgraphError(f"--json and --bode name the same file {args.json!r}; give the "
                           f"JSON record its own name, e.g. "
                           f"{os.path.splitext(args.json)[0] + '.json'!r}")
    target = _target(args)
    circuit = target.circuit()
    if not args.input:
        raise PvgraphError("give at least one --input PARAMETER (component.field, e.g. a "
                           "source's value), the input of the linear model")
    valid = circuit.parameters()
    for name in args.input:
        _check_param_name(name, valid, "--input")
    u0 = {name: float(valid[name][0]) for name in args.input}
    system = circuit.compile()
    if not args.output:
        raise PvgraphError("give at least one --output VARIABLE (see pvgraph vars)")
    outputs = list(args.output)      # exposed-port names stay as given (System.resolve_name)
    check_names(system, outputs, "--output")
    _check_outputs(system, outputs)

    def build(u):
        c = target.circuit()
        c.set_parameters(u)
        return c
    try:
        op = steady_state(system)
        lm = linearize_circuit(build, u0, outputs, op=op)
    except (InitializationError, SolverError) as exc:
        print(f"pvgraph linearize: no operating point of {target.spec}: {exc}", file=sys.stderr)
        return 1
    poles = lm.poles()
    wns, zetas, _ = lm.damping()
    params = circuit.parameters()
    in_units = {u: (declared_unit(params[u][1]) if u in params else None) or "-"
                for u in args.input}
    print(f"{target.spec} linearised at {', '.join(f'{k} = {v:.6g}' for k, v in u0.items())} "
          f"(SI); operating point ({op.method}, {op.iterations} iterations):")
    for n in outputs:
        print(f"  {n:40s} {_display(op[n], system.unit(n), args.si)}")
    verdict, why = lm.stability()
    stable = verdict == "stable"
    print(f"{len(lm.state_names)} states, {verdict.replace('unstable', 'NOT stable')} ({why}); "
          f"poles:")
    # rounding of the eigenvalues (a real part of 1e-13 at a pole of 300 rad/s) shown as 0
    tiny = 1e-9 * max(1.0, float(np.abs(poles).max())) if poles.size else 0.0

    def clean(x):
        return 0.0 if abs(x) <= tiny else float(x)
    records = [{"real": clean(s.real), "imag": clean(s.imag), "natural_frequency": clean(wn),
                "damping_ratio": (0.0 if abs(s.real) <= tiny else float(z)) if wn > tiny
                else None}
               for s, wn, z in zip(poles, wns, zetas)]
    for r in records[:args.poles]:
        zeta = "-" if r["damping_ratio"] is None else f"{r['damping_ratio']:.3f}"
        print(f"  {r['real']:12.5g} {r['imag']:+12.5g}  wn {r['natural_frequency']:.5g} rad/s  "
              f"zeta {zeta}")
    try:
        gain = lm.dc_gain()
    except np.linalg.LinAlgError:
        gain = None
    if gain is not None:
        print("DC gain (SI):")
        for i, n in enumerate(outputs):
            for j, u in enumerate(args.input):
                print(f"  d {n} / d {u}: {gain[i, j]:.6g} {_per(system.unit(n), in_units[u])}")
    if args.json:
        _write_json_atomic(args.json, {
            "target": target.spec, "inputs": u0, "units": {n: system.unit(n) for n in outputs},
            "operating_point": {n: op[n] for n in outputs}, "n_states": len(lm.state_names),
            "stable": stable, "stability": verdict, "poles": records,
            "dc_gain": None if gain is None else {n: {u: float(gain[i, j])
                                                      for j, u in enumerate(args.input)}
                                                  for i, n in enumerate(outputs)}})
        print(f"wrote {args.json} (SI)")
    if args.bode:
        from .analysis.linearize import _frequency_grid
        from .plotting import plot_bode
        w = _frequency_grid(poles, 100)
        mags, phases, labels = [], [], []
        for i, n in enumerate(outputs):
            for j, u in enumerate(args.input):
                mag, phase = lm.bode(w, i, j)
                mags.append(mag)
                phases.append(phase)
                labels.append(f"{n} / {u} [{_per(system.unit(n), in_units[u])}]")
        path = plot_bode(w / (2.0 * np.pi), mags, phases, args.bode, labels=labels,
                         title=f"{target.spec}: linearised at "
                               f"{', '.join(f'{k} = {v:.4g}' for k, v in u0.items())}")
        print(f"wrote {path}")
    return 0


def _per(out_unit: str, in_unit: str) -> str:
    """The unit of d out / d in: ``"Pa/(m^3/s)"``."""
    out_unit = out_unit or "-"
    if in_unit in ("-", ""):
        return out_unit
    return f"{out_unit}/({in_unit})" if any(c in in_unit for c in " /*^") else \
        f"{out_unit}/{in_unit}"


# --------------------------------------------------------------------------------------------
def time_arg(text: str) -> float:
    """argparse type of a time option: seconds, as a number or with a unit ("2 s", "500 ms");
    its range is checked where it is used."""
    try:
        return float(text)
    except ValueError:
        pass
    try:
        return float(to_unit(text.strip(), "s", "time"))
    except ParameterError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a time: give seconds, e.g. 2 or "
                                         f"'500 ms'") from None


def _tolerance(text: str) -> float:
    """argparse type of --rtol: a number in (0, 1)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and 0.0 < value < 1.0):
        raise argparse.ArgumentTypeError(f"{text!r}: a relative tolerance is a number between "
                                         f"0 and 1, e.g. 1e-5")
    return value


#: the figure formats the plotting commands write (matplotlib's, by extension)
FIGURE_SUFFIXES = (".png", ".svg", ".pdf")


def _csv_path(text: str) -> str:
    """argparse type of --csv: a writable file named .csv (or .txt), checked before anything
    runs (a table written into "out.xlsx" opens as a broken workbook)."""
    path = _output_path(text)
    if os.path.splitext(text)[1].lower() not in (".csv", ".txt"):
        raise argparse.ArgumentTypeError(
            f"{text!r}: --csv writes comma-separated text; name the file .csv (or .txt)")
    return path


def json_path(text: str) -> str:
    """argparse type of --json: a writable file (an existing folder is refused with a .json
    name in it as the hint), checked before anything runs."""
    if text and os.path.isdir(os.path.abspath(text)):
        raise argparse.ArgumentTypeError(
            f"{text!r} is a directory; give a file name, e.g. "
            f"{os.path.join(text, 'result.json')!r}")
    return _output_path(text)


def _figure_path(text: str) -> str:
    """argparse type of --plot and --bode: a file name with a figure extension, checked
    before anything runs."""
    suffix = os.path.splitext(text)[1].lower()
    if suffix not in FIGURE_SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"{text!r}: the figure format comes from the extension; use one of "
            f"{', '.join(FIGURE_SUFFIXES)}")
    return _output_path(text)


def _output_path(text: str) -> str:
    """argparse type of an output file: a file name whose directory exists or can be made,
    checked before anything runs (missing directories are made when the file is written)."""
    path = os.path.abspath(text)
    if not text or os.path.isdir(path):
        raise argparse.ArgumentTypeError(f"{text!r} is a directory; give a file name")
    _can_make(text, os.path.dirname(path), "a directory")
    return text


def output_dir(text: str) -> str:
    """argparse type of an output folder: not a file, and where it can be made (a missing
    folder is made when the command writes into it), checked before anything runs."""
    path = os.path.abspath(text)
    if not text:
        raise argparse.ArgumentTypeError("give a folder name")
    if os.path.exists(path) and not os.path.isdir(path):
        raise argparse.ArgumentTypeError(f"{text!r} is a file; give a folder")
    _can_make(text, path, "a folder")
    return text


def _can_make(text: str, path: str, what: str) -> None:
    """The nearest existing ancestor of ``path`` (itself included) is a writable folder."""
    parent = path
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise argparse.ArgumentTypeError(
            f"{text!r}: cannot make {what} there, {parent!r} is a file")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text!r}: the directory {parent!r} is not writable")


def _add_target(p, help_text="circuit: FILE.py:FUNCTION, MODULE:FUNCTION, a model file or a "
                             "registered name (pvgraph circuits)", optional=False):
    p.add_argument("target", nargs="?" if optional else None, help=help_text)
    p.add_argument("--option", "-o", action="append", metavar="KEY=VALUE",
                   help="keyword argument for the circuit's builder (repeatable; JSON values)")
    p.add_argument("--module", action="append", metavar="MODULE",
                   help="a module whose component classes a model file target may name "
                        "(type = \"MODULE:Class\"; repeatable)")


def _add_sweep_backend(w) -> None:
    w.add_argument("--param", action="append", metavar="NAME=SPEC",
                   help="parameter to vary (component.field, e.g. orifice.A). SPEC: LO:HI:N "
                        "(N points), log:LO:HI:N (log-spaced), V1,V2,... or a fixed V; with "
                        "--random: LO:HI, log:LO:HI or a fixed V. SI numbers, or quantities "
                        "with the unit on every value (\"2 mm^2:4 mm^2:3\"). Repeatable: the "
                        "grid is the product")
    w.add_argument("--random", type=int, metavar="N",
                   help="draw N random cases from the LO:HI ranges instead of a grid")
    w.add_argument("--seed", type=int, default=None, help="random seed (with --random)")
    w.add_argument("--method", default="lhs", choices=["lhs", "uniform"],
                   help="random sampling: Latin hypercube or independent uniform "
                        "(default: %(default)s)")
    w.add_argument("--backend", choices=["process", "serial", "dask"],
                   help="process pool (default), serial, or Dask (default with --scheduler)")
    w.add_argument("--workers", type=int, default=None,
                   help="parallel processes (default: the available CPUs)")
    w.add_argument("--scheduler", metavar="ADDRESS",
                   help="Dask scheduler address, e.g. tcp://10.0.0.5:8786 (its workers need "
                        "pvgraph installed); without it --backend dask starts a local cluster")
    w.add_argument("--out", default="pvgraph-sweep", type=output_dir,
                   help="output folder: cases.jsonl (each case as it finishes), sweep.csv and "
                        "sweep.json (default: %(default)s)")
    w.add_argument("--resume", action="store_true",
                   help="keep the finished cases recorded in OUT/cases.jsonl and run the rest")
    w.add_argument("--overwrite", action="store_true",
                   help="replace the record of an earlier sweep in OUT (without --resume or "
                        "--overwrite such a folder is refused)")
    w.add_argument("--timeout", type=float, metavar="SECONDS",
                   help="stop a case after this wall time and record it as timed out. Dask: "
                        "on the local cluster the sweep starts, the worker running a late "
                        "case is restarted; on a --scheduler cluster the case is cancelled "
                        "but runs on in its worker until it returns (Dask cannot stop a "
                        "running task)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pvgraph", description="Acausal hydraulic circuit modelling: simulate, inspect, "
                                    "sweep and linearise any circuit.")
    parser.add_argument("--eval", choices=["python", "c", "auto"], default=None,
                        help="how compiled circuits evaluate their equations: the generated "
                             "Python code, the same code compiled by the machine's C compiler "
                             "(cached; same numbers, faster), or C where a compiler is found "
                             "(default: $PVGRAPH_BACKEND, else python). Goes before the command: "
                             "pvgraph --eval c validate")
    sub = parser.add_subparsers(dest="command", required=True)
    parsers = {}

    s = parsers["simulate"] = sub.add_parser(
        "simulate", help="simulate a circuit and print final values")
    _add_target(s)
    s.add_argument("--t-end", type=time_arg, default=None,
                   help=f"end time [s] (default: the circuit's, else {DEFAULT_T_END:g})")
    s.add_argument("--solver", default="pvgraph", choices=["pvgraph", "ida"],
                   help="the built-in IDA-style solver (default) or SUNDIALS IDA through "
                        "scikit-sundae (pip install \"pvgraph[sundials]\")")
    s.add_argument("--rtol", type=_tolerance, default=1e-6,
                   help="relative tolerance (default: %(default)s)")
    s.add_argument("--var", action="append", help="variable to report (repeatable; names: "
                                                  "pvgraph vars TARGET)")
    s.add_argument("--csv", type=_csv_path, help="write the variables over time to this CSV file (SI)")
    s.add_argument("--plot", type=_figure_path,
                   help="plot the variables to this PNG, SVG or PDF file")
    s.add_argument("--si", action="store_true", help="print SI units (default: bar, L/min, mm)")
    s.set_defaults(func=cmd_simulate)

    v = parsers["vars"] = sub.add_parser(
        "vars", help="list every variable and output of a circuit with unit and description")
    _add_target(v)
    v.add_argument("--grep", help="only names containing this text")
    v.set_defaults(func=cmd_vars)

    g = parsers["graph"] = sub.add_parser(
        "graph", help="draw a circuit as a layered schematic (PNG, SVG or Graphviz DOT)")
    _add_target(g)
    g.add_argument("--out", default=None, type=_output_path,
                   help="output file (default: circuit.png, or circuit.FORMAT with --format)")
    g.add_argument("--format", choices=["png", "svg", "dot"],
                   help="default: from the extension of --out (which must then agree)")
    g.set_defaults(func=cmd_graph)

    e = parsers["export"] = sub.add_parser(
        "export", help="save a circuit as a model file (.toml, .json) or an FMU (.fmu)")
    _add_target(e)
    e.add_argument("--out", required=True, type=_output_path, help="FILE.toml, FILE.json or FILE.fmu")
    e.add_argument("--var", action="append", help="FMU output variable (repeatable)")
    e.add_argument("--input", action="append", metavar="PARAM",
                   help="FMU input: a component.field parameter set between steps (repeatable)")
    e.add_argument("--parameter", action="append", metavar="PARAM",
                   help="FMU parameter: a component.field set before the run (repeatable)")
    e.set_defaults(func=cmd_export)

    w = parsers["sweep"] = sub.add_parser(
        "sweep", help="run a circuit for many parameter values (grid or random sample)",
        description="Simulate a circuit for many parameter values, in parallel, and record the "
                    "final value of each --var per case. Each case is appended to "
                    "OUT/cases.jsonl as it finishes; Ctrl-C stops cleanly and --resume runs "
                    "the rest. Invalid parameter values fail before any case runs (exit 2); "
                    "exit 1 when a case failed, timed out or gave a non-finite output.")
    _add_target(w, optional=True)
    w.add_argument("--var", action="append", help="output variable (repeatable)")
    w.add_argument("--t-end", type=time_arg, default=None, help="simulated time per case [s]")
    w.add_argument("--rtol", type=_tolerance, default=1e-6,
                   help="relative tolerance (default: %(default)s)")
    w.add_argument("--steady", action="store_true",
                   help="record each case's steady operating point instead of simulating "
                        "to --t-end (each case starts from the last steady state found)")
    w.add_argument("--si", action="store_true", help="print SI units in the table")
    w.add_argument("--list-params", action="store_true",
                   help="list the parameter names with their values and exit")
    _add_sweep_backend(w)
    w.set_defaults(func=cmd_sweep)

    lz = parsers["linearize"] = sub.add_parser(
        "linearize", help="linear model of a circuit at its steady operating point",
        description="Linearise a circuit at its steady state: inputs are parameters "
                    "(--input component.field), outputs variables (--output). Prints the "
                    "operating point, the dominant poles (natural frequency, damping ratio) "
                    "and the DC gains.")
    _add_target(lz, optional=True)
    lz.add_argument("--input", action="append", metavar="PARAM",
                    help="input parameter, component.field (repeatable)")
    lz.add_argument("--output", action="append", metavar="NAME",
                    help="output variable (repeatable)")
    lz.add_argument("--poles", type=int, default=6, help="dominant poles to print "
                                                         "(default: %(default)s)")
    lz.add_argument("--json", type=json_path, help="write operating point, poles and DC gains to this file")
    lz.add_argument("--bode", metavar="PNG", type=_figure_path, help="draw the Bode plot of every output to this "
                                                  "PNG file")
    lz.add_argument("--si", action="store_true", help="print SI units")
    lz.set_defaults(func=cmd_linearize)

    c = sub.add_parser("components", help="list the component library (or the named "
                                          "components: pvgraph components Orifice)")
    c.add_argument("names", nargs="*", help="components to show (default: all)")
    c.set_defaults(func=cmd_components)
    r = sub.add_parser("circuits", help="list the circuits applications registered")
    r.set_defaults(func=cmd_circuits)

    reg = registry.load()
    for name, ext_list in reg.extensions.items():
        if name in parsers:
            before = {a.dest for a in parsers[name]._actions}
            for ext in ext_list:
                ext.configure(parsers[name])
            # the options applications add for their own circuits, with their defaults: one
            # given for a user's circuit is told, not ignored (see _target)
            parsers[name].set_defaults(_application_options={
                a.dest: (a.option_strings[0], a.default) for a in parsers[name]._actions
                if a.dest not in before and a.option_strings})
    for name, entry in reg.commands.items():
        if name in parsers or name in ("components", "circuits"):
            continue
        p = sub.add_parser(name, help=entry.help, description=entry.description or None)
        entry.configure(p)
        p.set_defaults(func=entry.run)
    return parser


def _ours(filename) -> bool:
    """Whether a warning was issued from pvgraph's own code (its packages, the component
    library, the registered applications shipped with it): its source line means nothing to
    the command's user."""
    if not filename:
        return False
    where = os.path.realpath(filename)
    roots = [os.path.dirname(os.path.realpath(__file__))]
    for name in ("pvgraph.components", "pvgraph.circuits"):
        module = sys.modules.get(name)
        roots += [os.path.realpath(p) for p in getattr(module, "__path__", None) or []]
    return any(where.startswith(root + os.sep) for root in roots)


def _show_warning(command, message, category, filename, lineno, file=None, line=None):
    """pvgraph's own warnings as one plain line; other libraries' as Python prints them."""
    from .errors import PlausibilityWarning
    from .system import RecompileWarning
    if issubclass(category, (PlausibilityWarning, RecompileWarning)) or _ours(filename):
        print(f"pvgraph {command}: warning: {message}", file=file or sys.stderr)
    else:
        print(warnings.formatwarning(message, category, filename, lineno, line),
              file=file or sys.stderr, end="")


def main(argv=None) -> int:
    try:
        parser = build_parser()
    except PvgraphError as exc:
        print(f"pvgraph: error: {exc}", file=sys.stderr)
        return 2
    args = parser.parse_args(argv)
    args._argv = list(sys.argv[1:] if argv is None else argv)   # the options as typed
    before = os.environ.get("PVGRAPH_BACKEND")
    backend = args.eval
    if backend is None and before is not None:      # as compile() reads it: checked here
        backend = before.strip().lower()
        if backend not in ("", "python", "c", "auto"):
            if args.command in ("components", "circuits"):     # they compile nothing
                backend = before
            else:
                print(f"pvgraph {args.command}: error: PVGRAPH_BACKEND={before!r}: choose "
                      f"python, c or auto (or unset it; --eval overrides it)",
                      file=sys.stderr)
                return 2
    if backend is not None and backend != before:   # in the environment, so worker
        os.environ["PVGRAPH_BACKEND"] = backend     # processes see it too
    try:
        return _run(args, argv)
    finally:
        if backend != before and argv is not None:  # called in-process: as it was
            if before is None:
                os.environ.pop("PVGRAPH_BACKEND", None)
            else:
                os.environ["PVGRAPH_BACKEND"] = before


def _run(args, argv) -> int:
    try:
        with warnings.catch_warnings():
            if argv is None:    # the command's own process (a caller may record warnings)
                warnings.showwarning = functools.partial(_show_warning, args.command)
            return args.func(args)
    except PvgraphError as exc:
        print(f"pvgraph {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:          # the output went to a reader that stopped (| head)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:          # an output file that could not be written after all
        text = str(exc) if str(exc).startswith("cannot write") else exc.strerror or str(exc)
        name = getattr(exc, "filename", None)
        if name and str(name) not in text:
            text = f"cannot write {str(name)!r}: {text}"
        print(f"pvgraph {args.command}: error: {text}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"pvgraph {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    # run as pvgraph.cli, not __main__: the functions a sweep sends to its workers and names
    # in its record are then the same as under the pvgraph command
    from pvgraph.cli import main as _main
    sys.exit(_main())
