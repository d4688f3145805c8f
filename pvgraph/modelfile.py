"""Circuits as text files: TOML or JSON, read safely, with a schema.

A model file holds what a circuit is made of: its components with their types and parameters
(with units), start-value overrides, sub-circuits to any depth, connections and exposed ports.
It is data only: it is parsed with :mod:`tomllib` or :mod:`json` (no ``eval``, no pickle), and a
component type is looked up among the component classes of the library packages (or of the
modules the caller allows), never imported from a name the file chooses::

    # pvgraph model file, format 1. A number without a unit is SI.
    format = 1
    name = "demo"
    connections = [["pump.port", "node.port", "orifice.a"], ["orifice.b", "tank.port"]]

    [components.pump]
    type = "FlowSource"
    params = { Q = "10 L/min" }

    [components.node]
    type = "VolumeNode"
    params = { V = "0.5 L" }
    start = { "port.p" = 1e5 }

    [components.orifice]
    type = "Orifice"
    params = { A = "2 mm^2" }

    [components.tank]
    type = "Tank"

A sub-circuit is a component entry with ``type = "Circuit"`` and its own ``components``,
``connections`` and ``expose = { P = { port = "node.port", description = "" } }``. A circuit's
``fluid = { rho = 1000, beta = "22000 bar" }`` is :meth:`Circuit.use_fluid`: its parts, and
those of its sub-circuits, take the properties they were not given.
:func:`save` writes parameters as SI numbers with the unit each declares (``"0.0005 m^3"``), so
a saved circuit loads back to the same floats. :func:`schema` is the JSON schema of the format.
An error names the file and the line of the entry at fault; a file with several mistakes
in its components, connections or exposed ports has them all told at once, in file order.
"""

from __future__ import annotations

import functools
import importlib
import json
import math
import os
import re
import sys
import tomllib
from typing import Any, Iterable, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .circuit import Circuit
from .component import Component
from .errors import CircuitError, ParameterError, PvgraphError
from .units import declared_unit

__all__ = ["ModelFileError", "save", "load", "to_dict", "from_dict", "dumps", "loads",
           "schema", "FORMAT"]

FORMAT = 1
HEADER = "# pvgraph model file, format 1. A number without a unit is SI."


class ModelFileError(PvgraphError):
    """A model file cannot be read: syntax, an unknown component type, a bad entry (the
    message names the file and the line)."""


# --------------------------------------------------------------------------------------------
# the format, as pydantic models (the schema)

class ExposedEntry(BaseModel):
    """An exposed port: the inner port (``"component.port"``) and a description."""

    model_config = ConfigDict(extra="forbid")
    port: str
    description: str = ""


class ComponentEntry(BaseModel):
    """A component: its type (``"Orifice"`` or ``"package.module:Class"``), parameters (numbers
    in SI or strings with units) and start-value overrides."""

    model_config = ConfigDict(extra="forbid")
    type: str = Field(pattern=r"^[A-Za-z_][\w.]*(:[A-Za-z_]\w*)?$")
    params: dict[str, Any] = {}
    start: dict[str, float | str] = {}


class CircuitEntry(BaseModel):
    """A sub-circuit: components, connections between their ports, exposed ports."""

    model_config = ConfigDict(extra="forbid")
    type: Literal["Circuit"]
    components: dict[str, Union["CircuitEntry", ComponentEntry]] = {}
    connections: list[list[str]] = []
    expose: dict[str, ExposedEntry] = {}
    fluid: dict[str, Any] = {}


class ModelFile(BaseModel):
    """A pvgraph model file."""

    model_config = ConfigDict(extra="forbid")
    format: Literal[1] = FORMAT
    name: str = "circuit"
    components: dict[str, Union[CircuitEntry, ComponentEntry]] = {}
    connections: list[list[str]] = []
    expose: dict[str, ExposedEntry] = {}
    fluid: dict[str, Any] = {}


def schema() -> dict:
    """The JSON schema of the model-file format."""
    return ModelFile.model_json_schema()


# --------------------------------------------------------------------------------------------
# component types

def _library_classes(modules: Iterable[str] = ()) -> dict[str, type]:
    """``{"module:Class": class}`` of the Component subclasses in the allowed modules."""
    from .docgen import LIBRARY_MODULES, library_modules
    import pkgutil
    found = {}
    for pkg in library_modules(tuple(LIBRARY_MODULES) + tuple(modules)):
        mods = [pkg]
        for info in pkgutil.iter_modules(getattr(pkg, "__path__", []) or []):
            mods.append(importlib.import_module(f"{pkg.__name__}.{info.name}"))
        for mod in mods:
            for obj in vars(mod).values():
                if isinstance(obj, type) and issubclass(obj, Component) and \
                        obj is not Component and obj.__module__ == mod.__name__:
                    found[f"{obj.__module__}:{obj.__qualname__}"] = obj
    return found


def _type_name(cls: type, known: dict[str, type]) -> str:
    module = cls.__module__
    if module == "__main__" or module.startswith("_pvgraph_target_") or "<locals>" in \
            cls.__qualname__:
        where = getattr(sys.modules.get(module), "__file__", None) or module
        raise ModelFileError(
            f"{cls.__qualname__} is defined in {where}, not in a module a model file can name "
            f"(package.module:Class): a file written now could not be loaded again. Move "
            f"{cls.__qualname__} into an importable module and load the file with "
            f"load(path, modules=['that.module']) (--module that.module on the command "
            f"line).")
    full = f"{module}:{cls.__qualname__}"
    if known.get(full) is not cls:
        full = _library_alias(cls, known) or full
    short = [k for k, v in known.items() if k.endswith(":" + cls.__qualname__)]
    if short == [full]:
        return cls.__qualname__
    return full


#: the library's top-level name in a source checkout, where ``components/`` is importable both
#: as ``components`` and as ``pvgraph.components`` (pyproject's package-dir)
CHECKOUT_PREFIX, LIBRARY_PREFIX = "components.", "pvgraph.components."


def _module_file(module: str) -> str | None:
    path = getattr(sys.modules.get(module), "__file__", None)
    return os.path.realpath(path) if path else None


def _library_alias(cls: type, known: dict[str, type]) -> str | None:
    """The library's ``"module:Class"`` of ``cls`` when ``cls`` is a library class imported
    under another module name (the same file: ``components.hydraulic.sources`` of a source
    checkout), else None."""
    where = _module_file(cls.__module__)
    if where is None:
        return None
    for key, other in known.items():
        if other.__qualname__ == cls.__qualname__ and _module_file(other.__module__) == where:
            return key
    return None


def foreign_modules(circuit: Circuit) -> list[str]:
    """The modules outside the library whose component classes ``circuit`` uses: a model
    file of it loads with ``load(path, modules=[...])`` naming them."""
    known = _library_classes()
    classes = set(known.values())
    found = set()

    def walk(node):
        for child in node.components.values():
            if isinstance(child, Circuit):
                walk(child)
            elif type(child) not in classes and _library_alias(type(child), known) is None:
                found.add(type(child).__module__)
    walk(circuit)
    return sorted(found)


def _resolve_type(name: str, known: dict[str, type]) -> type:
    if ":" in name:
        if name in known:
            return known[name]
        library = LIBRARY_PREFIX + name[len(CHECKOUT_PREFIX):]
        if name.startswith(CHECKOUT_PREFIX) and library in known:
            return known[library]       # written from a source checkout's own import
        module = name.partition(":")[0]
        raise KeyError(f"component type {name!r} is not in the library or in the allowed "
                       f"modules; allow its module: --module {module} on the command line, "
                       f"load(..., modules=[{module!r}]) in Python")
    matches = [v for k, v in known.items() if k.endswith(":" + name)]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise KeyError(f"component type {name!r} is ambiguous; write module:Class, one of "
                       f"{sorted(k for k in known if k.endswith(':' + name))}")
    import difflib
    close = difflib.get_close_matches(name, sorted({k.split(":")[1] for k in known}), n=3)
    hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
    raise KeyError(f"unknown component type {name!r}{hint}")


# --------------------------------------------------------------------------------------------
# circuit -> dict

def _value(value, unit):
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float):
        if unit and unit not in ("-", "1"):
            return f"{value!r} {unit}"
        return value
    if isinstance(value, (tuple, list)):
        return [_value(v, None) for v in value]
    return value


def _relative(ref, node: Circuit) -> str:
    names = [ref.name]
    owner = ref.owner
    while owner is not node:
        names.append(owner._name)
        owner = owner._parent
    return ".".join(reversed(names))


def _node_dict(node: Circuit, known) -> dict:
    comps = {}
    for name, child in node._components.items():
        if isinstance(child, Circuit):
            comps[name] = {"type": "Circuit", **_node_dict(child, known)}
            continue
        fields = type(child.params).model_fields
        params = {}
        from_fluid = set(node._inherited_fluid() or ()) - child.params.model_fields_set
        for key, info in fields.items():
            if key in from_fluid:       # the circuit's fluid gives it (written once, there)
                continue
            value = getattr(child.params, key)
            if value is None and info.default is None:
                continue
            if value is None:
                raise ModelFileError(f"{child.path}.{key} is None, which a model file cannot "
                                     f"hold where the default is {info.default!r}")
            params[key] = _value(value, declared_unit(info.description))
        entry = {"type": _type_name(type(child), known), "params": params}
        if child._start:
            entry["start"] = {k: float(v) for k, v in child._start.items()}
        comps[name] = entry
    out = {"components": comps,
           "connections": [[_relative(r, node) for r in refs] for refs in node._connections]}
    if node._exposed:
        out["expose"] = {name: {"port": _relative(ref, node), "description": desc}
                         for name, (ref, desc) in node._exposed.items()}
    if node._fluid is not None:
        out["fluid"] = {k: v if isinstance(v, (str, bool)) else _value(float(v), None)
                        for k, v in node._fluid.items()}
    return out


def to_dict(circuit: Circuit) -> dict:
    """The model-file structure of ``circuit`` (plain dicts, lists, strings and numbers)."""
    known = _library_classes()
    return {"format": FORMAT, "name": circuit.name, **_node_dict(circuit, known)}


# --------------------------------------------------------------------------------------------
# TOML writer (the standard library reads TOML but does not write it)

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ModelFileError(f"a model file cannot hold the non-finite number {v!r}")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise ModelFileError(f"a model file cannot hold {type(v).__name__} {v!r}")


def _toml_node(lines: list, prefix: str, node: dict) -> None:
    for key in ("type", "format", "name", "fluid", "params", "start", "connections", "expose"):
        if key in node and key != "components":
            value = node[key]
            if key == "connections":
                if not value:
                    continue
                lines.append("connections = [")
                lines.extend(f"  {_toml_value(c)}," for c in value)
                lines.append("]")
            else:
                lines.append(f"{key} = {_toml_value(value)}")
    for name, child in node.get("components", {}).items():
        table = f"{prefix}components.{_key(name)}"
        lines.append("")
        lines.append(f"[{table}]")
        _toml_node(lines, table + ".", child)


def dumps(circuit: Circuit, fmt: str = "toml") -> str:
    """The model file of ``circuit`` as text, ``fmt`` "toml" or "json"."""
    if not circuit.components:
        raise ModelFileError(f"circuit {circuit.name!r} has no components: a model file of it "
                             f"could not be loaded")
    data = to_dict(circuit)
    if fmt == "json":
        return json.dumps(data, indent=1, allow_nan=False) + "\n"
    if fmt != "toml":
        raise ModelFileError(f"unknown model file format {fmt!r}; choose toml or json")
    lines = [HEADER]
    _toml_node(lines, "", data)
    return "\n".join(lines) + "\n"


def save(circuit: Circuit, path) -> str:
    """Write ``circuit`` to ``path`` (``.toml`` or ``.json``, atomically); returns the path."""
    from .simulate import _atomic_write
    path = os.fspath(path)
    fmt = os.path.splitext(path)[1].lstrip(".").lower()
    if fmt not in ("toml", "json"):
        raise ModelFileError(f"{path}: name a model file .toml or .json")
    text = dumps(circuit, fmt)
    _atomic_write(path, lambda f: f.write(text))
    return path


# --------------------------------------------------------------------------------------------
# dict -> circuit

def _line_of(text: str, loc) -> int | None:
    """The line where the entry at ``loc`` (a key path) is written, found key by key."""
    if not text:
        return None
    pos, line = 0, None
    for key in loc:
        if isinstance(key, int) or key in ("CircuitEntry", "ComponentEntry"):
            continue
        written = json.dumps(str(key))[1:-1]        # as a file writes it: "tank\\n"
        pattern = re.compile(r'(?<![\w"])"?' + re.escape(written) + r'"?(?=\s*[=:.\]])')
        m = pattern.search(text, pos)
        if m is None:       # a value, not a key: a port of a connection ("pump.port",)
            m = re.compile(r'"' + re.escape(written) + r'"').search(text, pos)
        if m is None:
            break
        pos = m.end()
        line = text.count("\n", 0, m.start()) + 1
    return line


class _Loader:
    """Builds the circuits of a validated model file, collecting every mistake it finds (a
    component that cannot be made is left out, and so are the connections and exposed ports
    that name it, so that one mistake is told once) rather than stopping at the first."""

    def __init__(self, text: str, source: str, modules):
        self.text = text
        self.source = source
        self.known = _library_classes(modules)
        self.errors: list[tuple[int, str]] = []     # (line or 0, message), in file order


    @staticmethod
    def _at_fault(cls, child) -> str:
        """``"start"`` when the parameters alone make the component (its start values are at
        fault), else ``"params"``: the key whose line an error names."""
        if not child.start:
            return "params"
        try:
            cls(**child.params)
        except (ParameterError, CircuitError):
            return "params"
        return "start"
    def fail(self, loc, message, find=None) -> None:
        line = _line_of(self.text, find or loc)
        where = f"{self.source}" + (f", line {line}" if line else "")
        path = ".".join(str(k) if str(k).isidentifier() or isinstance(k, int)
                        else json.dumps(str(k)) for k in loc)
        self.errors.append((line or 0, f"{where} ({path}): {message}"))

    def raise_errors(self) -> None:
        """Raise one ModelFileError telling every mistake found (by line)."""
        if not self.errors:
            return
        told = [m for _, m in sorted(self.errors, key=lambda e: e[0])]
        if len(told) == 1:
            raise ModelFileError(told[0])
        raise ModelFileError(f"{len(told)} mistakes in {self.source}:\n" +
                             "\n".join("  " + m.replace("\n", "\n    ") for m in told))

    def add(self, circuit, name, component, loc) -> bool:
        try:
            circuit.add(name, component)
        except ParameterError as exc:      # the circuit's fluid does not fit the part
            self.fail(getattr(self, "fluid_loc", loc), str(exc))
        except CircuitError as exc:        # a name that is not an identifier
            self.fail(loc, str(exc))
        else:
            return True
        return False

    def node(self, name: str, entry, loc) -> Circuit:
        c = Circuit(name)
        if entry.fluid:     # the circuit's fluid (Circuit.use_fluid), for the parts added next
            c._fluid = dict(entry.fluid)
            self.fluid_loc = loc + ("fluid",)
        missing = set()     # the components that could not be made
        for cname, child in entry.components.items():
            here = loc + ("components", cname)
            if isinstance(child, CircuitEntry):
                told = len(self.errors)
                sub = self.node(cname, child, here)
                if len(self.errors) > told or not self.add(c, cname, sub, here):
                    missing.add(cname)     # its ports may be the ones left out
                continue
            comp = None
            try:
                cls = _resolve_type(child.type, self.known)
            except KeyError as exc:
                self.fail(here + ("type",), exc.args[0])
            else:
                try:
                    comp = cls(**child.params, start=dict(child.start) or None)
                except ParameterError as exc:
                    self.fail(here + (self._at_fault(cls, child),), str(exc))
                except CircuitError as exc:
                    self.fail(here + ("start",), str(exc))
            if comp is None or not self.add(c, cname, comp, here):
                missing.add(cname)
        if entry.fluid:
            from .circuit import _FLUID_NAMES
            unknown = sorted(k for k in entry.fluid if k not in _FLUID_NAMES)
            if unknown:
                self.fail(loc + ("fluid",), f"{', '.join(map(repr, unknown))}: not a fluid "
                                            f"property; a fluid has "
                                            f"{', '.join(sorted(_FLUID_NAMES))}")
            else:       # each property checked as Circuit.use_fluid checks it
                from .circuit import _check_fluid_values
                try:
                    _check_fluid_values(c, dict(entry.fluid))
                except ParameterError as exc:
                    self.fail(loc + ("fluid",), str(exc))

        def names_missing(refs):
            return any(isinstance(r, str) and r.split(".")[0] in missing for r in refs)
        for k, refs in enumerate(entry.connections):
            if names_missing(refs):
                continue
            try:
                c.connect(*refs)
            except CircuitError as exc:
                self.fail(loc + ("connections", k), str(exc),
                          find=loc + ("connections",) + ((refs[0],) if refs else ()))
        for pname, exp in entry.expose.items():
            if names_missing([exp.port]):
                continue
            try:
                c.expose(pname, exp.port, exp.description)
            except CircuitError as exc:
                self.fail(loc + ("expose", pname), str(exc))
        return c


def from_dict(data: dict, *, modules: Iterable[str] = (), text: str = "",
              source: str = "<model>") -> Circuit:
    """The circuit a model-file structure describes (``text`` locates errors by line)."""
    try:
        model = ModelFile.model_validate(data)
    except ValidationError as exc:
        err = _relevant_error(exc.errors(), data)
        loc = tuple(k for k in err["loc"] if k not in ("CircuitEntry", "ComponentEntry"))
        # a key that is missing is told at its table, not at the next place its name occurs
        line = _line_of(text, loc[:-1] if err["type"] == "missing" else loc)
        where = source + (f", line {line}" if line else "")
        msg = err["msg"]
        if err["type"] == "missing" and loc[-1] == "type":
            msg = ("no type: give the component's class, e.g. type = \"Orifice\" (or "
                   "type = \"Circuit\" for a sub-circuit)")
        elif err["type"] == "missing":
            msg = f"{loc[-1]!r} is missing"
        elif loc and loc[0] == "expose":
            msg = (f"an exposed port is written {loc[1] if len(loc) > 1 else 'P'} = "
                   f"{{ port = \"component.port\" }} (and optionally description = "
                   f"\"...\")")
        elif err["type"] == "dict_type":
            msg = "expected a table of name = value pairs (TOML) or an object (JSON)"
        if err["type"] == "extra_forbidden":
            msg = (f"unknown key {loc[-1]!r}; a component holds type, params and start, a "
                   f"sub-circuit type = \"Circuit\", components, connections, expose and "
                   f"fluid, the file format, name, components, connections, expose and fluid")
        raise ModelFileError(f"{where} ({'.'.join(map(str, loc)) or 'top level'}): "
                             f"{msg}") from None
    if not model.components:
        raise ModelFileError(f"{source} (top level): the model file holds no components; a "
                             f"circuit is written as [components.NAME] tables (type = "
                             f"\"Orifice\", params = {{ ... }}) and connections")
    loader = _Loader(text, source, modules)
    root = CircuitEntry(type="Circuit", components=model.components,
                        connections=model.connections, expose=model.expose, fluid=model.fluid)
    circuit = loader.node(model.name, root, ())
    loader.raise_errors()
    circuit._origin = functools.partial(_where, text, source)   # for the compiler's messages
    return circuit


def _where(text: str, source: str, label: str) -> str:
    """``"FILE, line N (components.orifice)"``: where the component of the port ``label``
    (``"bench.orifice.b"``) is written."""
    path = label.split(".")[:-1]
    loc = tuple(k for name in path for k in ("components", name))
    line = _line_of(text, loc) if loc else None
    return source + (f", line {line}" if line else "") + (f" ({'.'.join(loc)})" if loc else "")


def _relevant_error(errors: list, data) -> dict:
    """The error of the union branch the entry meant (by its ``type``), shallowest first."""
    def keep(err):
        node = data
        for key in err["loc"]:
            if key in ("CircuitEntry", "ComponentEntry"):
                is_circuit = isinstance(node, dict) and node.get("type") == "Circuit"
                return (key == "CircuitEntry") == is_circuit
            node = node.get(key) if isinstance(node, dict) else \
                (node[key] if isinstance(node, list) and isinstance(key, int) and
                 key < len(node) else None)
        return True
    relevant = [e for e in errors if keep(e)] or errors
    return min(relevant, key=lambda e: len(e["loc"]))


class _DuplicateKey(Exception):
    """A key repeated in one JSON object."""


def _unique_keys(pairs):
    out = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def loads(text: str, fmt: str = "toml", *, modules: Iterable[str] = (),
          source: str = "<model>") -> Circuit:
    """The circuit of a model file's text (``fmt`` "toml" or "json")."""
    try:
        if fmt == "json":
            data = json.loads(text, object_pairs_hook=_unique_keys)
        elif fmt == "toml":
            data = tomllib.loads(text)
        else:
            raise ModelFileError(f"unknown model file format {fmt!r}; choose toml or json")
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"{source}, line {exc.lineno}: not valid JSON: {exc.msg}") from None
    except _DuplicateKey as exc:
        key = json.dumps(exc.args[0])
        hits = [m.start() for m in re.finditer(re.escape(key) + r"\s*:", text)]
        line = f", line {text.count(chr(10), 0, hits[1]) + 1}" if len(hits) > 1 else ""
        raise ModelFileError(f"{source}{line}: the key {key} is given twice in one object "
                             f"(JSON keeps the last silently; name each component and "
                             f"parameter once)") from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"\(at line (\d+)", str(exc))
        line = f", line {m.group(1)}" if m else ""
        raise ModelFileError(f"{source}{line}: not valid TOML: {exc}") from None
    if not isinstance(data, dict):
        raise ModelFileError(f"{source}: a model file holds a table (object) at the top level")
    return from_dict(data, modules=modules, text=text, source=source)


def load(path, *, modules: Iterable[str] = ()) -> Circuit:
    """Read a circuit from a ``.toml`` or ``.json`` model file.

    ``modules`` names further modules (``"mypackage.parts"``) whose Component classes the file
    may use besides the library's.
    """
    path = os.fspath(path)
    fmt = os.path.splitext(path)[1].lstrip(".").lower()
    if fmt not in ("toml", "json"):
        raise ModelFileError(f"{path}: a model file is .toml or .json")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as exc:
        raise ModelFileError(f"cannot read model file {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        with open(path, "rb") as f:
            head = f.read(exc.start)
        line = head.count(b"\n") + 1
        column = exc.start - (head.rfind(b"\n") + 1) + 1
        raise ModelFileError(
            f"{path}, line {line}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at "
            f"column {column}); save the model file as UTF-8") from None
    return loads(text, fmt, modules=modules, source=path)
