"""Circuits: named components, connections and exposed ports, nestable to any depth.

::

    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    orf = c.add("orifice", Orifice(A=mm2(2)))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    system = c.compile()

A circuit exposes inner ports with ``expose("P", inner_port)``; it can then be added to a bigger
circuit and connected like any component (``rig > pvg > pvb > compensator``).
"""

from __future__ import annotations

import contextlib
import difflib
import gc
import os
import re
import warnings
from collections import OrderedDict
from collections.abc import Mapping

from pydantic import BaseModel

from .component import Component, Port, PortRef
from .errors import (CircuitError, ConnectionError_, ParameterError, PlausibilityWarning,
                     PvgraphError, StructureError, outside_stacklevel)

__all__ = ["Circuit", "reuse_compiled"]

#: compiled systems kept for :func:`reuse_compiled`, per circuit structure, most recent last
_COMPILED: OrderedDict = OrderedDict()
_REUSE = {"depth": 0, "max": 16, "hits": 0, "compilations": 0}


@contextlib.contextmanager
def reuse_compiled(max_structures: int = 16):
    """Inside this block, ``Circuit.compile()`` of a circuit built like one compiled before
    returns that system with the new circuit's runtime parameter values, without compiling.

    "Built like" means the same components (paths and types), connections, exposed ports,
    compile options, start values and structural parameter values
    (:meth:`~pvgraph.system.System.params_from` decides); anything else compiles. The compiled
    systems stay in this process across blocks (the ``max_structures`` most recent ones), so
    code that builds and compiles a circuit per call, such as a sweep case run in a worker
    process, compiles each structure once per process::

        with reuse_compiled():
            result = run_scenario(...)          # builds and compiles inside
    """
    _REUSE["depth"] += 1
    _REUSE["max"] = int(max_structures)
    try:
        yield _REUSE
    finally:
        _REUSE["depth"] -= 1


def _structure_key(circuit, options) -> tuple:
    """Components (path, type), connections and exposed ports, to any depth, and options."""
    from .compiler import _rel_path
    parts = [circuit.name, tuple(sorted((k, repr(v)) for k, v in options.items()))]

    def walk(node, prefix):
        for name, child in node._components.items():
            parts.append((prefix + name, type(child).__qualname__))
            if isinstance(child, Circuit):
                walk(child, f"{prefix}{name}.")
        parts.append(tuple(tuple((prefix + _rel_path(node, r.owner), r.name) for r in refs)
                           for refs in node._connections))
        parts.append(tuple((n, _rel_path(node, r.owner), r.name, v)
                           for n, (r, v) in node._exposed.items()))

    walk(circuit, "")
    return tuple(parts)


def _reused(circuit, options):
    """A compiled system of ``circuit``'s structure carrying its values, or None."""
    key = _structure_key(circuit, options)
    why = None
    for compiled in _COMPILED.get(key, ()):
        try:
            values = compiled.params_from(circuit)
        except ParameterError as exc:
            why = str(exc)                    # another structural value
            continue
        _COMPILED.move_to_end(key)
        _REUSE["hits"] += 1
        return key, compiled.with_params(values, recompile=False)
    if why is not None:
        from .system import RecompileWarning
        warnings.warn(RecompileWarning(f"compiling again: {why.split('. Compile it')[0]}"),
                      stacklevel=3)
    return key, None


def _keep(key, system) -> None:
    _COMPILED.setdefault(key, []).append(system)
    _COMPILED.move_to_end(key)
    _REUSE["compilations"] += 1
    while sum(len(v) for v in _COMPILED.values()) > max(_REUSE["max"], 1):
        first = next(iter(_COMPILED))
        _COMPILED[first].pop(0)
        if not _COMPILED[first]:
            del _COMPILED[first]

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


#: components that join two domains, for the message on a node that mixes them
_CONVERTERS = {
    frozenset({"hydraulic", "mechanical"}): "a component that converts (e.g. PistonChamber or "
                                            "Cylinder)",
    frozenset({"hydraulic", "rotational"}): "a pump or a motor (e.g. FixedDisplacementPump, "
                                            "HydraulicMotor)",
    frozenset({"hydraulic", "signal"}): "a sensor or a signal-driven source (PressureSensor, "
                                        "FlowSensor; PressureInput, FlowInput)",
    frozenset({"mechanical", "signal"}): "a sensor or a signal-driven source (PositionSensor, "
                                         "VelocitySensor, ForceSensor; ForceInput, PositionInput)",
    frozenset({"rotational", "signal"}): "a sensor or a signal-driven source (SpeedSensor, "
                                         "AngleSensor, TorqueSensor; TorqueInput, SpeedInput)",
    frozenset({"mechanical", "rotational"}): "a transmission (e.g. RackPinion)",
}


class Circuit:
    """A named collection of components and connections; itself usable as a component."""

    def __init__(self, name: str = "circuit"):
        self.name = name
        self._components: dict[str, Component | Circuit] = {}
        self._connections: list[tuple[PortRef, ...]] = []
        self._exposed: dict[str, tuple[PortRef, str]] = {}
        self._name: str | None = None
        self._parent: Circuit | None = None
        self._fluid: dict | None = None

    # building ----------------------------------------------------------------------------------
    def use_fluid(self, fluid, *, override: bool = False) -> "Circuit":
        """Give every part of this circuit (and of its sub-circuits, now and added later) the
        properties of ``fluid`` it takes and was not given (a Simscape fluid block):
        ``c.use_fluid(Fluid(rho=1000, nu="1 cSt", beta="22000 bar"))``.

        ``fluid`` is a parameter model (``pvgraph.components.Fluid``) or a mapping of field
        names to values; a part takes the fields its parameter model declares under those
        names (``rho``, ``nu``, ``beta``, ``air``, ...). A value given to the part itself wins
        (parts built by a function that passes its own values, the PVG 32's, keep them), unless
        ``override``: then the fluid replaces those too. A sub-circuit's own fluid wins over
        its parent's for the properties it gives; the others it takes from its parent's, now
        and when the parent's changes. A mapping adds to the circuit's fluid so far; a name
        that is not a fluid
        property (``rho``, ``nu``, ``beta``, ``air``, ``kappa``, ``p_vap``, ``p_atm``,
        ``dp_cav``, ``p_min_abs``), or a value a part declaring it would refuse, is refused
        before anything changes. Returns the circuit.
        """
        if isinstance(fluid, BaseModel):
            values = {k: getattr(fluid, k) for k in type(fluid).model_fields}
        elif isinstance(fluid, Mapping):
            values = {**(self._fluid or {}), **fluid}
        else:
            raise CircuitError(f"circuit {self.path!r}: use_fluid takes a fluid (Fluid(...)) or "
                               f"a mapping of its properties, got {type(fluid).__name__}")
        unknown = sorted(k for k in values if k not in _FLUID_NAMES)
        if unknown:
            raise CircuitError(f"circuit {self.path!r}: {', '.join(map(repr, unknown))} "
                               f"{'is not a fluid property' if len(unknown) == 1 else 'are not fluid properties'}"
                               f"; a fluid has {', '.join(sorted(_FLUID_NAMES))}")
        _check_fluid_values(self, values)
        if not isinstance(override, bool):
            raise CircuitError(f"circuit {self.path!r}: use_fluid(override=...) takes True or "
                               f"False, got {override!r}")
        parent = self._parent._inherited_fluid() if self._parent is not None else None
        # all checked before any is set
        updates = self._fluid_updates({**(parent or {}), **values}, bool(override))
        for comp, params in updates:
            comp.params = params
        self._fluid = values
        return self

    def _fluid_updates(self, values, override=False) -> list:
        """``[(component, new parameter model)]`` of the parts taking ``values`` (see
        :func:`_fluid_into`), raising before anything is changed."""
        out = []
        for name, child in self._components.items():
            if isinstance(child, Circuit):    # its own fluid's properties win
                out.extend(child._fluid_updates({**values, **(child._fluid or {})}, override))
            else:
                new = _fluid_into(child, values, f"{self.path}.{name}" if self._parent else name,
                                  override)
                if new is not None:
                    out.append((child, new))
        return out

    def _inherited_fluid(self):
        """The fluid of this circuit: its own properties over those of the circuits around
        it, or None where none has one."""
        out = None
        node = self
        while node is not None:
            if node._fluid is not None:
                out = {**node._fluid, **(out or {})}
            node = node._parent
        return out

    def add(self, name: str, component):
        """Add ``component`` under ``name`` and return it."""
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise CircuitError(f"circuit {self.path!r}: component name {name!r} is not a valid "
                               f"identifier (letters, digits, underscore; not starting with a "
                               f"digit)")
        if name in self._components:
            raise CircuitError(f"circuit {self.path!r} already has a component named {name!r}")
        if name in self._exposed:
            raise CircuitError(f"circuit {self.path!r}: {name!r} is already an exposed port")
        if not isinstance(component, (Component, Circuit)):
            raise CircuitError(f"circuit {self.path!r}: {name!r} must be a Component or Circuit, "
                               f"got {type(component).__name__}")
        node = self
        while node is not None:       # a circuit inside itself would recurse without end
            if node is component:
                what = "itself" if component is self else f"its enclosing circuit {node.path!r}"
                raise CircuitError(f"circuit {self.path!r} cannot contain {what} (as {name!r})")
            node = node._parent
        if component._parent is not None:
            raise CircuitError(f"{type(component).__name__} {component.path!r} is already part of "
                               f"a circuit; create a new instance for {name!r}")
        fluid = self._inherited_fluid()
        updates = []        # the circuit's fluid for the new part(s), checked before adding
        if fluid is not None:
            if isinstance(component, Circuit):   # its own fluid's properties win
                updates = component._fluid_updates({**fluid, **(component._fluid or {})})
            else:
                new = _fluid_into(component, fluid, name)
                updates = [(component, new)] if new is not None else []
        for comp, params in updates:
            comp.params = params
        component._name = name
        component._parent = self
        self._components[name] = component
        return component

    def connect(self, *ports) -> None:
        """Join two or more ports into one connection set (a node)."""
        if len(ports) == 1 and isinstance(ports[0], (list, tuple)):
            ports = tuple(ports[0])         # connect([a, b, c]) as connect(a, b, c)
        if len(ports) < 2:
            raise CircuitError(f"circuit {self.path!r}: connect() needs at least two ports, "
                               f"got {len(ports)}")
        refs = tuple(self._resolve(p) for p in ports)
        paths = [r.path() for r in refs]
        twice = sorted({q for q in paths if paths.count(q) > 1})
        if twice:
            raise CircuitError(f"circuit {self.path!r}: connect() joins port {twice[0]!r} to "
                               f"itself; a connection joins two or more different ports")
        domains = {r.port.domain.name for r in refs}
        if len(domains) > 1:
            desc = ", ".join(f"{r.path()} ({r.port.domain.name})" for r in refs)
            via = _CONVERTERS.get(frozenset(domains) if len(domains) == 2 else None,
                                  "a component that converts between them")
            raise ConnectionError_(
                f"circuit {self.path!r}: incompatible domains joined in one node: {desc}. A node "
                f"joins ports of one domain only; {' and '.join(sorted(domains))} ports meet "
                f"through {via}.")
        self._connections.append(refs)

    def expose(self, name: str, inner, description: str = "") -> PortRef:
        """Make the inner port ``inner`` a port of this circuit called ``name``."""
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise CircuitError(f"circuit {self.path!r}: port name {name!r} is not an identifier")
        if name in self._exposed or name in self._components:
            raise CircuitError(f"circuit {self.path!r} already has a port or component {name!r}")
        ref = self._resolve(inner)
        self._exposed[name] = (ref, description)
        return PortRef(self, name)

    # access ------------------------------------------------------------------------------------
    @property
    def path(self) -> str:
        if self._parent is None:
            return self.name
        parent = self._parent.path if self._parent._parent is not None else None
        return f"{parent}.{self._name}" if parent else self._name

    @property
    def components(self) -> dict:
        """The direct subcomponents by name."""
        return dict(self._components)

    @property
    def ports(self) -> dict[str, Port]:
        """The exposed ports and their declarations."""
        return {name: ref.port for name, (ref, _) in self._exposed.items()}

    def __getitem__(self, path: str):
        import difflib
        node = self
        for part in path.split("."):
            if not isinstance(node, Circuit) or part not in node._components:
                pool = sorted(node._components) if isinstance(node, Circuit) else []
                close = difflib.get_close_matches(part, pool, n=1)
                hint = f" Did you mean {close[0]!r}?" if close else ""
                raise KeyError(f"circuit {self.path!r} has no component {path!r} ({part!r} is "
                               f"not in {node.path!r}, whose components are {pool}).{hint}")
            node = node._components[part]
        return node

    def __contains__(self, path: str) -> bool:
        try:
            self[path]
        except KeyError:
            return False
        return True

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        exposed = self.__dict__.get("_exposed", {})
        if name in exposed:
            return PortRef(self, name)
        comps = self.__dict__.get("_components", {})
        hint = (f" {name!r} is a component: use circuit[{name!r}]." if name in comps else "")
        if not hint:
            close = difflib.get_close_matches(name, list(comps), n=3, cutoff=0.6)
            if close:
                hint = (f" Did you mean the component {close[0]!r}? Components are read as "
                        f"circuit[{close[0]!r}] (or the object add() returned).")
        raise AttributeError(f"circuit {self.__dict__.get('name')!r} has no port {name!r}; its "
                             f"ports are {sorted(exposed)}.{hint}")

    def _port_spec(self, name: str) -> Port:
        if name not in self._exposed:
            raise CircuitError(f"circuit {self.path!r} has no port {name!r}; its ports are "
                               f"{sorted(self._exposed)}")
        return self._exposed[name][0].port

    def _resolve(self, port) -> PortRef:
        """A PortRef from a PortRef or a dotted string ``"component.port"`` within this circuit."""
        if isinstance(port, str):
            comp_path, _, port_name = port.rpartition(".")
            if not comp_path:
                return PortRef(self, port_name) if port_name in self._exposed else \
                    self._fail_port(port)
            try:
                owner = self[comp_path]
            except KeyError as exc:
                raise CircuitError(str(exc.args[0])) from None
            owner._port_spec(port_name)
            return PortRef(owner, port_name)
        if not isinstance(port, PortRef):
            raise CircuitError(f"circuit {self.path!r}: connect() takes ports (component.port or "
                               f"'component.port' strings), got {type(port).__name__} "
                               f"{port!r}")
        port.port  # validates the port name
        if not self._owns(port.owner):
            raise CircuitError(f"port {port.path()!r} does not belong to circuit {self.path!r}; "
                               f"add its component to this circuit first")
        return port

    def _fail_port(self, text):
        raise CircuitError(f"circuit {self.path!r}: {text!r} does not name a port; write "
                           f"'component.port'")

    def _owns(self, owner) -> bool:
        node = owner
        while node is not None:
            if node is self:
                return True
            node = node._parent
        return False

    # compiling ---------------------------------------------------------------------------------
    def compile(self, **options):
        """Compile to a :class:`~pvgraph.system.System` (see :func:`pvgraph.compiler.compile`).

        A hydraulic network with no pressure reference (no tank or pressure source) is named:
        an error when the compiler finds it singular, a :class:`PlausibilityWarning` when its
        volumes let it compile (the pressure level of two or more volumes then floats on their
        start values).

        ``backend``: how the residual, Jacobian and events are evaluated: ``"python"`` (the
        generated Python code), ``"c"`` (the same code compiled by the machine's C compiler,
        cached; an error without a compiler) or ``"auto"`` (C where a compiler is found and the
        system is small enough for straight-line code, below
        :data:`pvgraph.system.ARRAY_MIN_ROWS` rows; bigger ones keep their rows evaluated as
        arrays). The default is the environment variable ``PVGRAPH_BACKEND``, else
        ``"python"``. See :meth:`pvgraph.system.System.use_backend`.
        """
        from .compiler import compile_circuit
        backend = options.pop("backend", None) or os.environ.get("PVGRAPH_BACKEND") or "python"
        if backend not in ("python", "c", "auto"):
            raise ValueError(f"compile(backend={backend!r}): choose 'python', 'c' or 'auto' "
                             f"(also the values of PVGRAPH_BACKEND)")
        if backend == "c" and options.get("array_rows") is None:
            options["array_rows"] = False      # C evaluates every row as straight-line code
        try:
            system = self._compile(compile_circuit, options)
        except CircuitError as exc:
            origin = getattr(self, "_origin", None)     # a circuit read from a model file
            port = re.search(r"port '([^']+)'", str(exc))
            if origin is None or port is None:
                raise
            raise type(exc)(f"{origin(port.group(1))}: {exc}") from None
        return system.use_backend(backend) if system.backend != backend else system

    def _compile(self, compile_circuit, options):
        key = None
        if _REUSE["depth"]:
            key, system = _reused(self, options)
            if system is not None:
                return system
        try:
            system = compile_circuit(self, **options)
            known = system.__dict__.pop("_known_roles", None)
        except StructureError as exc:
            loose = [i for i in _pressure_islands(self) if not i["volumes"]]
            if loose:
                found = str(exc)
                if "contradicts the others" in found:   # the flows contradict: the cause
                    names = ", ".join(sorted({c for i in loose for c in i["components"]})[:6])
                    raise StructureError(
                        f"circuit {self.name!r}: {found}\n(The network of {names} has no "
                        f"pressure of its own either: flow sources with nothing between them, "
                        f"or a flow source into a closed end, fix flows, not a pressure. Put a "
                        f"VolumeNode and a relief valve between them, or remove one source.)"
                    ) from None
                if "repeats the others" in found:   # the loop's missing reference, not 2 sources
                    found = found.split(" This happens when")[0]
                raise StructureError(f"{_no_reference_message(self, loose)}\n(The structural "
                                     f"check of the compiler: {found})") from None
            raise
        floating = [i for i in _pressure_islands(self, known) if len(i["volumes"]) > 1]
        if floating:
            names = "; ".join(", ".join(sorted(i["components"])[:4]) for i in floating)
            warnings.warn(PlausibilityWarning(
                f"circuit {self.name!r}: the hydraulic network of {names} has no pressure "
                f"reference (no Tank or pressure source): its pressures float on the start "
                f"values of its volumes. Connect a Tank (or a PressureSource) to it."),
                stacklevel=outside_stacklevel())
        if key is not None:
            _keep(key, system)
        return system

    # parameters --------------------------------------------------------------------------------
    def parameters(self) -> dict[str, tuple]:
        """``{"component.field": (value, description)}`` of every leaf component, to any depth."""
        out = {}
        for path, comp in _leaves(self):
            for field, info in type(comp.params).model_fields.items():
                out[f"{path}.{field}"] = (getattr(comp.params, field), info.description or "")
        return out

    def _parameter_owner(self, path: str):
        comp_path, _, field = path.rpartition(".")
        pool = self.parameters()
        if comp_path and comp_path in self and not isinstance(self[comp_path], Circuit) and \
                field in type(self[comp_path].params).model_fields:
            return self[comp_path], field
        close = difflib.get_close_matches(path, list(pool), n=3, cutoff=0.6)
        hint = f" Did you mean {', '.join(map(repr, close))}?" if close else ""
        raise ParameterError(f"circuit {self.name!r} has no parameter {path!r} (write "
                             f"component.field, e.g. {next(iter(pool), 'pump.Q')!r}).{hint}")

    def _validated(self, values: dict) -> list:
        from pydantic import ValidationError

        from .component import _describe_validation
        updates: dict = {}
        for path, value in values.items():
            comp, field = self._parameter_owner(path)
            updates.setdefault(id(comp), (comp, {}))[1][field] = value
        out = []
        for comp, fields in updates.values():
            try:
                params = type(comp.params)(**{**dict(comp.params), **fields})
            except ValidationError as exc:
                msg = _describe_validation(f"{type(comp).__name__} {comp.path!r}", exc,
                                           list(type(comp.params).model_fields), fields,
                                           type(comp.params))
                raise ParameterError(msg) from None
            out.append((comp, params))
        return out

    def check_parameters(self, values: dict) -> None:
        """Raise :class:`ParameterError` if ``{"component.field": value}`` would be invalid."""
        self._validated(parameter_values(values, f"{self.path}.check_parameters: values"))

    def set_parameters(self, values: dict) -> None:
        """Set parameters by dotted path, ``{"orifice.A": "2 mm^2", "pump.Q": 1e-4}`` (or a
        list of ``(name, value)`` pairs, as :meth:`System.with_params` takes)."""
        values = parameter_values(values, f"{self.path}.set_parameters: values")
        for comp, params in self._validated(values):
            comp.params = params

    def port_aliases(self) -> dict[str, str]:
        """Names through exposed ports: ``{"valve.P.p": "valve.spool.P.p", ...}``.

        Every variable of an exposed port of a sub-circuit is also reachable by the name of
        the exposing circuit's port; the values are the names the compiled system uses.
        """
        out = {}

        def walk(node, prefix):
            for name, child in node._components.items():
                if isinstance(child, Circuit):
                    walk(child, f"{prefix}{name}.")
            if node is self:
                return
            for port, (ref, _) in node._exposed.items():
                owner, inner = _leaf_port(ref)
                spec = owner._port_spec(inner)
                rel = owner.path[len(self.path) + 1:] if self._parent is not None else owner.path
                for var in filter(None, (spec.domain.across, spec.domain.through)):
                    target = f"{rel}.{inner}" if spec.domain.name == "signal" else \
                        f"{rel}.{inner}.{var}"
                    alias = f"{prefix}{port}" if spec.domain.name == "signal" else \
                        f"{prefix}{port}.{var}"
                    out[alias] = target
                    if spec.domain.name == "signal":
                        break
        walk(self, "")
        return out

    def __repr__(self):
        return f"<Circuit {self.path} with {len(self._components)} components>"


def parameter_values(values, where: str) -> dict:
    """``{name: value}`` from a mapping or from ``(name, value)`` pairs; anything else (one
    name, a list of names, None) raises :class:`ParameterError` naming ``where``."""
    expected = ("a mapping {'component.field': value} or a list of (name, value) pairs, "
                "e.g. {'orifice.A': '2 mm^2'}")
    if isinstance(values, Mapping):
        pairs = list(values.items())
    elif isinstance(values, (str, bytes)) or values is None:
        raise ParameterError(f"{where} must be {expected}; got {values!r}")
    else:
        try:
            pairs = [tuple(item) if not isinstance(item, (str, bytes)) else (item,)
                     for item in values]
        except TypeError:
            raise ParameterError(f"{where} must be {expected}; got {values!r}") from None
        bad = [item for item in pairs if len(item) != 2]
        if bad:
            raise ParameterError(f"{where} must be {expected}; got {values!r}")
    names = [k for k, _ in pairs if not isinstance(k, str)]
    if names:
        raise ParameterError(f"{where}: parameter names are strings ('component.field'), "
                             f"got {names[0]!r}")
    seen: set = set()
    twice = sorted({k for k, _ in pairs if k in seen or seen.add(k)})
    if twice:       # a generated list (a sweep table, merged settings) would drop one silently
        raise ParameterError(f"{where}: parameters given twice: {twice}; give each once")
    return dict(pairs)


def _leaves(circuit: Circuit) -> list:
    """``(dotted path, component)`` of every leaf component below ``circuit``."""
    out = []

    def walk(node, prefix):
        for name, child in node._components.items():
            if isinstance(child, Circuit):
                walk(child, f"{prefix}{name}.")
            else:
                out.append((f"{prefix}{name}", child))
    walk(circuit, "")
    return out


def boundary_flows(root: Circuit) -> dict[str, tuple[list[str], str, str]]:
    """The flows through the exposed ports of ``root``'s sub-circuits that join several
    inner ports: ``{"bench.P.q": (["bench.node.port.q", "bench.orifice.a.q"], unit, text)}``.

    The flow into a sub-circuit through its port is the sum of the flows into the parts its
    inner node joins (as the flow of a Modelica connector on a model's boundary), not the flow
    of the one inner port it was exposed from. A port exposed from a node of one inner port
    is that port's variable under a second name (:meth:`Circuit.port_aliases`).
    """
    out = {}

    def rel(owner) -> str:
        parts, node = [], owner
        while node is not None and node is not root:
            parts.append(node._name)
            node = node._parent
        return ".".join(reversed(parts))

    def walk(node: Circuit):
        for child in node._components.values():
            if isinstance(child, Circuit):
                walk(child)
        if node is root or not node._exposed:
            return
        parent: dict = {}

        def find(k):
            parent.setdefault(k, k)
            while parent[k] != k:
                parent[k] = parent[parent[k]]
                k = parent[k]
            return k

        def key(ref):
            return (id(ref.owner), ref.name)

        leaf_ports: dict = {}

        def visit(sub: Circuit):
            for refs in sub._connections:
                for r in refs:
                    if not isinstance(r.owner, Circuit):
                        leaf_ports[key(r)] = r
                for a, b in zip(refs, refs[1:]):
                    parent[find(key(a))] = find(key(b))
            for name, (ref, _) in sub._exposed.items():
                if not isinstance(ref.owner, Circuit):
                    leaf_ports[key(ref)] = ref
                parent[find((id(sub), name))] = find(key(ref))
            for child in sub._components.values():
                if isinstance(child, Circuit):
                    visit(child)

        visit(node)
        for port, (ref, _) in node._exposed.items():
            domain = ref.port.domain
            if domain.through is None:
                continue
            root_key = find((id(node), port))
            inner = sorted(f"{rel(r.owner)}.{r.name}.{domain.through}"
                           for k, r in leaf_ports.items() if find(k) == root_key)
            if len(inner) > 1:
                out[f"{rel(node)}.{port}.{domain.through}"] = (
                    inner, domain.through_unit or "",
                    f"{domain.through} into {rel(node)} through its port {port} (the sum over "
                    f"the {len(inner)} ports its node joins inside)")

    walk(root)
    return out


def _leaf_port(ref: PortRef):
    """The leaf (component, port name) an exposed port stands for."""
    owner, name = ref.owner, ref.name
    while isinstance(owner, Circuit):
        inner = owner._exposed[name][0]
        owner, name = inner.owner, inner.name
    return owner, name


def _pressure_islands(circuit: Circuit, known: dict | None = None) -> list[dict]:
    """Hydraulic networks without a pressure reference: ``{"components", "volumes"}`` each.

    Ports joined by a connection are one network; so are two ports of one component when an
    equation holds both their flows (a flow path: an orifice, a valve edge). A port fixes the
    pressure level when its component's equations use its pressure but never its flow (a
    Tank, a pressure source), and so does a load: a port whose pressure acts on a mechanical
    port of its component (a piston, a motor) where that component's other such ports lie in
    other networks (a motor whose two ports share one closed loop feels their difference
    only); a volume is a port whose pressure's time derivative appears.
    ``known``: the port roles of components by path, where the compiler read them from its
    templates (:func:`pvgraph._roles.template_roles`); the others are traced here.
    """
    # the traced graphs are acyclic and freed by reference counting (as in the compiler)
    enabled = gc.isenabled()
    gc.disable()
    try:
        return _islands(circuit, known or {})
    finally:
        if enabled:
            from .compiler import resume_gc
            resume_gc()


def _islands(circuit: Circuit, known: dict) -> list[dict]:
    import numpy as np
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from .component import HYDRAULIC

    leaves = _leaves(circuit)
    # hydraulic ports numbered in the order of the leaves, each leaf's consecutively; the
    # networks are the connected components of the graph of connections and flow paths
    index: dict[tuple, int] = {}
    ports: list[tuple] = []     # (path, port name)
    hyd_of: dict = {}           # class -> its hydraulic ports
    local: dict = {}            # (class, id(roles)) -> roles as offsets (see below)
    kinds: list = []            # per leaf with hydraulic ports: its local roles ...
    bases: list = []            # ... and the number of its first port
    seen: dict = {}   # (class, parameter values) -> the ports' roles, for instances alike
    shared: dict = {}  # class -> [instances traced, instances that took another's roles]
    hyd_leaves: list = []   # (path, component) of each leaf with hydraulic ports
    for path, comp in leaves:
        cls = type(comp)
        hyd = hyd_of.get(cls)
        if hyd is None:
            hyd = hyd_of[cls] = [n for n, pt in comp.ports.items() if pt.domain is HYDRAULIC]
        if not hyd:
            continue
        cid, base = id(comp), len(ports)
        for pname in hyd:
            index[(cid, pname)] = len(ports)
            ports.append((path, pname))
        roles = known.get(path)
        if roles is None:
            roles = _shared_roles(comp, path, hyd, seen, shared)
        key = (cls, id(roles))
        got = local.get(key)
        if got is None:
            at = {n: k for k, n in enumerate(hyd)}
            paths, fixing, vols, coupled = roles
            pairs = [(at[a], at[b]) for flows in paths for a, b in zip(flows, flows[1:])]
            got = local[key] = (len(local), roles, pairs, [at[n] for n in fixing],
                                [at[n] for n in vols], [at[n] for n in coupled])
        kinds.append(got[0])
        bases.append(base)
        hyd_leaves.append((path, comp))
    ea, eb = [], []

    def walk(node):
        for refs in node._connections:
            ends = []
            for r in refs:
                owner, pname = _leaf_port(r)
                k = index.get((id(owner), pname))
                if k is not None:       # a hydraulic port
                    ends.append(k)
            ea.extend(ends[:-1])
            eb.extend(ends[1:])
        for child in node._components.values():
            if isinstance(child, Circuit):
                walk(child)
    walk(circuit)
    n = len(ports)
    kinds_a = np.asarray(kinds, dtype=np.int64)
    bases_a = np.asarray(bases, dtype=np.int64)
    ref = np.zeros(n, dtype=bool)
    vol = np.zeros(n, dtype=bool)
    rows, cols = [np.asarray(ea, dtype=np.int64)], [np.asarray(eb, dtype=np.int64)]
    for k, _, pairs, fixing, vols, _ in local.values():
        at = bases_a[kinds_a == k]
        for a, b in pairs:
            rows.append(at + a)
            cols.append(at + b)
        for a in fixing:
            ref[at + a] = True
        for a in vols:
            vol[at + a] = True
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # the networks in the order of their first port; those with a reference dropped
    _, first = np.unique(label, return_index=True)
    has_ref = np.zeros(len(first), dtype=bool)
    has_ref[label[ref]] = True
    for k, _, _, _, _, coupled in local.values():
        if not coupled:
            continue
        nets = label[bases_a[kinds_a == k][:, None] + np.asarray(coupled)[None, :]]
        # a load holds the level of a network where it meets one coupled port of a component
        # whose others lie elsewhere (or that has only one)
        apart = np.ones(len(nets), dtype=bool) if nets.shape[1] == 1 else \
            np.any(nets != nets[:, :1], axis=1)
        has_ref[nets[apart].ravel()] = True
        # all in one network: the load feels the common pressure where the areas differ
        # (a differential cylinder in regeneration), not where they cancel (a motor's loop)
        if not apart.all():
            which = np.flatnonzero(kinds_a == k)
            names = [hyd_of[type(hyd_leaves[which[0]][1])][c] for c in coupled]
            for r in np.flatnonzero(~apart):
                path, comp = hyd_leaves[which[r]]
                if _feels_level(comp, path, names):
                    has_ref[nets[r]] = True
    loose = np.flatnonzero(~has_ref[label])         # the ports of those networks
    loose = loose[np.argsort(label[loose], kind="stable")]
    cuts = np.flatnonzero(np.diff(label[loose])) + 1
    out = []
    for members in sorted(np.split(loose, cuts) if len(loose) else [],
                          key=lambda m: first[label[m[0]]]):
        out.append({"components": {ports[k][0] for k in members},
                    "volumes": {ports[k] for k in members if vol[k]}, "ref": False})
    return out


def _feels_level(comp, path, ports) -> bool:
    """True if the equations of ``comp`` that read a mechanical port change with the common
    pressure of its hydraulic ``ports`` (every other variable at 0): the areas on a piston
    differ. False where they cancel, or where that cannot be told."""
    import numpy as np

    from . import expr as E
    from ._templates import _value
    from .component import HYDRAULIC, SIGNAL
    try:
        residuals, _ = comp.trace(path)
    except Exception:
        return False
    mech = tuple(f"{path}.{n}." for n, pt in comp.ports.items()
                 if pt.domain is not HYDRAULIC and pt.domain is not SIGNAL)
    rows = [r for r in residuals if any(nm.startswith(mech) for _, nm in _symbols_read(r))]
    pressures = {f"{path}.{n}.p" for n in ports}
    head = len(path) + 1

    class Values:
        def __init__(self, level):
            self.level = level

        def __getitem__(self, name):
            return float(_value(comp.params, name[head:]))

        def leaf(self, node):
            return self.level if node.value in pressures else 0.0
    try:
        low = np.array([E.evaluate(r, Values(1e5)) for r in rows], dtype=float)
        high = np.array([E.evaluate(r, Values(2e5)) for r in rows], dtype=float)
    except Exception:
        return False
    change = np.abs(high - low)
    return bool(np.all(np.isfinite(change)) and np.any(change > 1e-9 * (np.abs(low) + 1e5)))


def _shared_roles(comp, path, hyd, seen, shared):
    """:func:`_port_roles` of ``comp``, or those of an instance traced before whose class and
    parameter values are its own (``seen``: by that key; ``shared``: per class, instances
    traced and instances that took another's roles)."""
    count = shared.setdefault(type(comp), [0, 0])
    # a class whose instances all differ so far is not keyed any more (keying costs)
    key = _alike(comp) if count[1] or count[0] < _KEYED_UNSHARED else None
    roles = seen.get(key) if key is not None else None
    if roles is None:
        roles = _port_roles(comp, path, hyd)
        count[0] += 1
        if key is not None:
            seen[key] = roles
    else:
        count[1] += 1
    return roles


_KEYED_UNSHARED = 32
_PLAIN_STATE = frozenset(("params", "_start", "_name", "_parent"))


def _alike(comp):
    """A key equal for instances whose equations trace alike: their class and parameter
    values (None where that cannot be told: state of their own, values of other types)."""
    if not _PLAIN_STATE.issuperset(vars(comp)):
        return None
    frozen = _frozen(comp.params)
    return None if frozen is None else (type(comp), frozen)


_MODEL_FIELDS: dict = {}   # parameter model class -> its field names


def _frozen(value):
    if isinstance(value, BaseModel):
        cls = type(value)
        names = _MODEL_FIELDS.get(cls)
        if names is None:
            names = _MODEL_FIELDS[cls] = tuple(cls.model_fields)
        out = [cls]
        for name in names:
            item = getattr(value, name)
            # a float by its value; a zero by its repr (tells -0.0 from 0.0; a NaN, equal to
            # nothing, only misses)
            item = (float, item if item else repr(item)) if type(item) is float else \
                _frozen(item)
            if item is None:
                return None
            out.append((name, item))
        return tuple(out)
    if isinstance(value, (tuple, list)):
        items = tuple(_frozen(x) for x in value)
        return None if any(x is None for x in items) else (type(value), items)
    if isinstance(value, float):
        return (float, value if value else repr(value))   # tells -0.0 from 0.0
    if value is None or isinstance(value, (bool, int, str)):
        return (type(value), value)
    return None


def _port_roles(comp, path, hyd):
    """``(flow paths, reference ports, volume ports)`` of one component, by port name."""
    try:
        residuals, _ = comp.trace(path)
    except Exception:           # the compiler reports a component that cannot trace
        return [], list(hyd), [], []
    return _roles_of(residuals, comp, path, hyd)


def _hydraulic_ports(comp) -> list:
    from .component import HYDRAULIC
    return [n for n, pt in comp.ports.items() if pt.domain is HYDRAULIC]


def _roles_of(residuals, comp, path, hyd=None):
    """:func:`_port_roles` read from ``residuals`` (traced for ``comp`` at ``path``); None
    for a component without hydraulic ports."""
    if hyd is None:
        hyd = _hydraulic_ports(comp)
        if not hyd:
            return None
    used = set()
    paths = []
    # an internal flow (a line's q) carries flow between the ports whose equations hold it
    carriers = [v for v, var in getattr(comp, "variables", {}).items() if var.unit == "m^3/s"]
    held: dict[str, str] = {}
    reads = []
    for r in residuals:
        leaves_r = _symbols_read(r)
        reads.append(leaves_r)
        used |= leaves_r
        flows = [n for n in hyd if ("sym", f"{path}.{n}.q") in leaves_r]
        if len(flows) > 1:
            paths.append(flows)
        for v in carriers:
            if flows and (("sym", f"{path}.{v}") in leaves_r or
                          ("der", f"{path}.{v}") in leaves_r):
                if v in held and held[v] != flows[0]:
                    paths.append([held[v], flows[0]])
                held[v] = flows[0]
    fixing = [n for n in hyd if ("sym", f"{path}.{n}.p") in used and
              ("sym", f"{path}.{n}.q") not in used]
    vols = [n for n in hyd if ("der", f"{path}.{n}.p") in used]
    # ports whose pressure acts on a mechanical port (a piston's force, a motor's torque): the
    # load holds the pressure level of their network unless all of them share that network
    # (a motor in a closed loop feels only the difference)
    from .component import HYDRAULIC, SIGNAL
    mech = tuple(f"{path}.{n}." for n, pt in comp.ports.items()
                 if pt.domain is not HYDRAULIC and pt.domain is not SIGNAL)
    coupled = set()
    if mech:
        for leaves_r in reads:
            if any(nm.startswith(mech) for _, nm in leaves_r):
                coupled.update(n for n in hyd if ("sym", f"{path}.{n}.p") in leaves_r)
    return paths, fixing, vols, [n for n in hyd if n in coupled]


def _symbols_read(root) -> set:
    """The ``(op, name)`` of the variable (``sym``) and derivative (``der``) leaves of an
    expression graph (each node visited once)."""
    found = set()
    seen = {id(root)}
    stack = [root]
    pop, push, add = stack.pop, stack.append, seen.add
    while stack:
        node = pop()
        args = node.args
        if args:
            for a in args:
                if id(a) not in seen:
                    add(id(a))
                    push(a)
        elif node.op == "sym" or node.op == "der":
            found.add((node.op, node.value))
    return found


#: the names of the fluid properties the parts of the library take (use_fluid takes these)
_FLUID_NAMES = frozenset(("rho", "nu", "beta", "air", "kappa", "p_vap", "p_atm", "dp_cav",
                          "p_min_abs"))


_FLUID_MODELS: list = []     # the fluid parameter models a component library registers


def register_fluid_model(model) -> None:
    """Register ``model`` (a pydantic model with fields named as fluid properties, its own
    message on a bad value) to check the properties of a circuit's fluid that none of its
    parts declares (the component library registers its ``Fluid``)."""
    if model not in _FLUID_MODELS:
        _FLUID_MODELS.append(model)


def _check_fluid_values(circuit, values) -> None:
    """Each fluid property checked by the parameter model of a part that declares it (a part
    given its own value, too), so that a value no part could take is refused now rather than
    where a part is added or ``override`` is asked later; the others by a registered fluid
    model (see :func:`register_fluid_model`), so that nothing wrong is kept (and saved)
    where no part takes it yet."""
    done = set()
    for path, comp in _leaves(circuit):
        for k in values.keys() & type(comp.params).model_fields.keys() - done:
            _fluid_into(comp, {k: values[k]}, path, override=True)    # raises, changes nothing
            done.add(k)
    for model in _FLUID_MODELS:
        rest = {k: v for k, v in values.items()
                if k not in done and k in getattr(model, "model_fields", {})}
        if not rest:
            continue
        try:
            model(**rest)
        except PvgraphError as exc:
            raise ParameterError(f"circuit {circuit.path!r}: its fluid: {exc}") from None
        except ValueError as exc:       # a pydantic ValidationError
            raise ParameterError(f"circuit {circuit.path!r}: its fluid: {exc}") from None
        done.update(rest)


def _fluid_into(comp, values, where, override=False):
    """The parameter model of ``comp`` with the fluid properties of ``values`` its model takes
    and its builder did not give (``model_fields_set``; all with ``override``), validated by
    the model (the fields stay "not given", so another fluid replaces them), or None where
    nothing changes."""
    p = comp.params
    fields = type(p).model_fields
    given = p.model_fields_set - (set(values) if override else set())
    update = {k: v for k, v in values.items() if k in fields and k not in given}
    if not update:
        return None
    from pydantic import ValidationError

    from .component import _describe_validation
    try:
        new = type(p)(**{k: getattr(p, k) for k in given}, **update)
    except ValidationError as exc:
        raise ParameterError(f"{where}: the circuit's fluid does not fit: " + _describe_validation(
            type(comp).__name__, exc, list(fields), update, type(p))) from None
    object.__setattr__(new, "__pydantic_fields_set__", set(given))
    return new


def _no_reference_message(circuit: Circuit, islands: list[dict]) -> str:
    parts = []
    for i in islands:
        names = ", ".join(sorted(i["components"])[:6])
        parts.append(f"the hydraulic network of {names} has no pressure reference: nothing "
                     f"fixes its pressure level, so every pressure in it is undetermined. "
                     f"Connect a Tank (or a PressureSource) to one of its nodes; where it lies "
                     f"between pumps or flow sources (which fix flows, not a pressure), give it "
                     f"a VolumeNode and a relief valve to tank instead.")
    return f"circuit {circuit.name!r}: " + " ".join(parts)
