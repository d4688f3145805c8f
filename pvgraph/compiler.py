"""The graph compiler: circuit -> DAE system F(t, y, y') = 0.

Pipeline
--------
1. Flatten the hierarchy; every variable gets its dotted name (``pvg.pvb.main_spool.flange.x``).
2. Join the ports connection by connection (union-find); each group is a connection set. Per
   set: across variables equal, through variables sum to zero; signals have exactly one driver.
3. Trace every component's equations once into expression graphs (exact incidence). Numeric
   parameters are traced as parameter symbols (runtime values of the compiled system); those
   the equations turn into plain numbers are recorded as structural.
4. Alias elimination: equations of the form ``a*u + b*v + c = 0`` or ``a*u + c = 0`` in plain
   variables remove one unknown each (connection equalities, two-port flow balances, fixed
   pressures); ``b`` and ``c`` may depend on parameters, the eliminated unknown's ``a`` is a
   constant. Every eliminated name stays addressable in results.
5. Checks: equations equal unknowns; a maximum bipartite matching proves the pencil
   dF/dy + c dF/dy' structurally regular; a second matching on (derivatives of differential
   variables, algebraic variables) proves index <= 1. Failures name equations and variables.
6. Differentiate each residual row in one reverse pass (all its partial derivatives at once),
   move the parametric subexpressions into a ``derive`` function evaluated once per parameter
   set, and emit the residual, the Jacobian values on a fixed sparse pattern, all event
   functions as one function, and (when first needed) the derived outputs and dF/dp as
   generated Python (:mod:`pvgraph.codegen`). In big systems, rows of one shape (the same
   equation of many instances of a component class) are differentiated and generated once and
   evaluated over arrays of their instances (``array_rows``). Every stage costs time linear in
   the size of the circuit, connection sets of any width included.

Parallel volumes on one node need no special treatment: the node's pressure is one unknown after
alias elimination, each volume contributes its own flow unknown, and the DAE stays index one.
"""

from __future__ import annotations

import gc
import itertools
import operator
import warnings
import zlib
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from . import codegen
from . import expr as E
from ._roles import template_roles
from ._templates import Templates, read_sets
from .circuit import Circuit, _hydraulic_ports, _port_roles, _roles_of
from .component import SIGNAL, Component
from .errors import (CircuitError, ConnectionError_, PlausibilityWarning, StructureError,
                     outside_stacklevel)

__all__ = ["compile_circuit", "VarInfo"]

MAX_AFFINE_NODES = 40  # larger expressions are not tested for the affine alias form
MAX_BUILDER_NODES = 400  # rows substituted by a generated builder have at most these nodes
_PARAMETRIC = object()   # a provenance key whose rows' affine forms depend on parameters
NAMES_IN_MESSAGES = 12


@dataclass
class VarInfo:
    """Metadata of one variable (unknown or eliminated)."""

    name: str
    unit: str
    start: float
    nominal: float
    description: str
    owner: str
    start_priority: int = 0  # 0 class default, 1 from parameters, 2 set by the user
    # not a field (set on the few instances it applies to): 0 a default start value, 1 from a
    # parameter given a non-default value, 2 set by ``start=``
    given = 0


@dataclass
class _Equation:
    expr: E.Expr
    origin: str      # component path or "node ..." for connection equations
    label: str       # human-readable description


#: What closes an unconnected port of each domain.
_CLOSURE = {"hydraulic": "a Plug (no flow) or a Tank",
            "mechanical": "a Fixed (no motion) or a Free (no force)",
            "rotational": "a RotationalFixed (no rotation) or a RotationalFree (no torque)"}

def compile_circuit(circuit: Circuit, *, eliminate_aliases: bool = True,
                    array_rows: bool | None = None, choice_point: dict | None = None):
    """Compile ``circuit`` to a :class:`~pvgraph.system.System`.

    ``array_rows``: how rows of one shape (the same equation of many instances of a component
    class) are evaluated: None (default) as arrays over their instances in big systems, True
    as arrays whenever a shape repeats, False always as straight-line code (see
    :func:`pvgraph.system.build_system`).

    Raises
    ------
    CircuitError, ConnectionError_
        Unconnected ports, incompatible domains, undriven or multiply driven signals.
    StructureError
        Unbalanced, structurally singular or higher-index systems, with names.
    """
    if not isinstance(circuit, Circuit):
        raise CircuitError(f"compile() takes a Circuit, got {type(circuit).__name__}")
    # Expression graphs are acyclic and freed by reference counting; the cyclic collector would
    # rescan every node of a large circuit again and again while the graphs are built
    enabled = gc.isenabled()
    gc.disable()
    try:
        return _compile(circuit, eliminate_aliases, array_rows, choice_point)
    finally:
        if enabled:
            resume_gc()


def resume_gc():
    """Enable the cyclic collector again after a stretch of building acyclic graphs.

    The objects made meanwhile (a compiled system keeps its expression graphs, about 50 per
    component) are first moved to the oldest generation (``gc.freeze`` then ``gc.unfreeze``,
    a splice of lists), so the next young collections do not walk all of them again, one
    generation after the other; a full collection still visits them (skipped where the
    program has frozen objects of its own, which unfreezing would release).
    """
    if gc.get_freeze_count() == 0:
        gc.freeze()
        gc.unfreeze()
    gc.enable()


def _compile(circuit, eliminate_aliases, array_rows=None, choice_point=None):
    leaves = _flatten(circuit)
    if not leaves:
        raise CircuitError(f"circuit {circuit.name!r} has no components")
    infos: dict[str, VarInfo] = {}
    equations: list[_Equation] = []
    observed: dict[str, tuple] = {}
    events = []
    mode_names: list[str] = []
    mode_start: list[float] = []

    registry: dict = {}   # parameter name -> ParameterInfo, in the order first read
    trace = E.ParameterTrace({})
    templates = Templates()
    found = []
    # rows built from a template: id -> (row, key, names); rows of one key are one graph with
    # their names exchanged (see _Provenance)
    prov = _Provenance()
    var_specs: dict = {}   # component class -> its variables (see _declare_variables)
    given: dict = {}       # start values the user gave, by full name
    of_template: dict = {}   # template -> [(path, component) built from it]
    balance: dict = {}       # component class -> the equations it owes (_local_balance)
    unbalanced: list = []    # components returning another number of equations
    # the parameter trace is active over the whole loop (the start values read numbers only);
    # the math functions of the vocabulary stay symbolic throughout
    with trace:
        for path, comp in leaves:
            _declare_variables(path, comp, infos, registry, var_specs, given)
            trace.where = f"{type(comp).__name__}.equations of {path!r}"
            residuals, v, leaves_read = templates.trace(comp, path, registry, trace)
            found.extend(leaves_read)
            want = balance.get(type(comp))
            if want is None:
                want = balance[type(comp)] = _local_balance(type(comp))
            if len(residuals) != want[0]:
                unbalanced.append((path, type(comp).__name__, len(residuals), want))
            if templates.last is not None:
                tpl, at = templates.last
                built = of_template.get(tpl)
                if built is None:
                    built = of_template[tpl] = []
                built.append((path, comp))
                rows = list(residuals) + [ev.condition for ev in v.events]
                nodes = tpl.last_nodes or ()
                prov.add_rows(rows, prov.template_keys(tpl, len(rows)), tpl.row_names(at),
                              nodes)
            for k, r in enumerate(residuals):
                equations.append(_Equation(r, path, f"{path} equation {k + 1} "
                                                    f"({type(comp).__name__})"))
            for name, obs in v.observed.items():
                observed[f"{path}.{name}"] = (obs.expr, obs.unit, obs.description)
            for ev in v.events:
                events.append((path, ev))
            for mname, mstart in type(comp).modes.items():
                mode_names.append(f"{path}.#{mname}")
                mode_start.append(float(mstart))

    del templates
    roles = template_roles(of_template, registry, _roles_of, _traced_roles)
    del of_template
    from .circuit import boundary_flows
    for name, (inner, unit, text) in boundary_flows(circuit).items():
        total = E.Expr("sym", (), inner[0])
        for other in inner[1:]:
            total = total + E.Expr("sym", (), other)
        observed[name] = (total, unit, text)
    n_component = len(equations)
    keys: list = []
    equations.extend(_connection_equations(circuit, leaves, infos, keys))
    for eq, got in zip(equations[n_component:], keys):
        if got is not None:
            prov.add(eq.expr, *got)
            found.append((set(got[1]), set()))   # ``a - b`` or ``q1 + ... + qn``
        else:
            found.append(read_sets(eq.expr))
    _check_symbols(equations, found, infos, set(mode_names))

    # every parameter has its value (those read as leaves have theirs) and, where the
    # equations made it a number, the reason (the others keep the default "")
    values = trace.values
    for name in registry.keys() - values.keys():
        values[name] = registry[name].value
    for name in trace.structural.keys() & registry.keys():
        registry[name].structural = trace.structural[name]

    subs: dict[str, tuple] = {}
    why: dict[str, tuple] = {}
    held: dict[str, tuple] = {}
    incidence = None
    if eliminate_aliases:
        incidence = []
        try:
            equations = _eliminate_aliases(equations, infos, subs, trace.values, found,
                                           incidence, prov, why, held)
        except StructureError as exc:
            if unbalanced:    # the cause: it leads
                raise StructureError(f"{_unbalanced_text(unbalanced)}\nWhat the structural "
                                     f"check then finds: {exc}") from None
            raise
    del found

    from .index_reduction import reduce_index
    from .system import build_system
    try:
        equations, events, observed, reduction = reduce_index(equations, infos, subs, events,
                                                              observed, given,
                                                              incidence, params=values,
                                                              choice_point=choice_point)
        del incidence
        system = build_system(circuit.name, equations, infos, subs, observed, events,
                              mode_names, mode_start, parameters=registry,
                              tables=trace.tables, array_rows=array_rows, provenance=prov)
    except StructureError as exc:
        told = _fixed_elsewhere(exc, equations, infos, subs, why)
        if unbalanced:    # the cause: it leads
            raise StructureError(f"{_unbalanced_text(unbalanced)}\nWhat the structural check "
                                 f"then finds: {exc}" + (f"\n{told}" if told else "")) from None
        if told:
            raise StructureError(f"{exc}\n{told}") from None
        raise
    system._circuit = circuit
    system._known_roles = roles     # for the no-reference check (Circuit.compile takes them)
    system.held_rates = held
    system._components = dict(leaves)
    system._models = {path: comp.params for path, comp in leaves}
    return reduction.attach(system)


def _local_balance(cls) -> tuple[int, str]:
    """The number of equations a component of class ``cls`` gives in a balanced model, and
    what they are for: one per own variable, one per port's through variable (flow, force,
    torque), one per signal output (Modelica's local balance)."""
    own = list(cls.variables)
    flows = [f"{pn}.{pt.domain.through}" for pn, pt in cls.ports.items()
             if pt.domain is not SIGNAL and pt.domain.through]
    outs = [pn for pn, pt in cls.ports.items()
            if pt.domain is SIGNAL and pt.causality == "output"]
    parts = []
    for what, names in (("own variable", own), ("port through variable", flows),
                        ("signal output", outs)):
        if names:
            parts.append(f"{len(names)} {what}{'s' if len(names) > 1 else ''} "
                         f"({', '.join(names)})")
    return len(own) + len(flows) + len(outs), ", ".join(parts) or "nothing"


def _unbalanced_text(unbalanced) -> str:
    """The components whose equations do not match their own unknowns, for a structural
    error's message."""
    lines = ["Components giving another number of equations than they own unknowns (one per "
             "own variable, port flow or force, and signal output):"]
    for path, cls_name, got, (want, what) in unbalanced[:6]:
        lines.append(f"  {path!r} ({cls_name}): {got} equation{'s' if got != 1 else ''} for "
                     f"{what}: {abs(want - got)} {'missing' if got < want else 'too many'}")
    if len(unbalanced) > 6:
        lines.append(f"  ... and {len(unbalanced) - 6} more")
    return "\n".join(lines)


def _traced_roles(comp, path):
    """The port roles of ``comp`` traced with numbers (see :mod:`pvgraph._roles`)."""
    return _port_roles(comp, path, _hydraulic_ports(comp))


# 1. flatten ---------------------------------------------------------------------------------

def _flatten(circuit: Circuit) -> list[tuple[str, Component]]:
    out = []

    def walk(node: Circuit, prefix: str):
        for name, child in node._components.items():
            path = f"{prefix}{name}"
            if isinstance(child, Circuit):
                walk(child, path + ".")
            else:
                out.append((path, child))

    walk(circuit, "")
    return out


def _rel_path(root: Circuit, owner) -> str:
    parts = []
    node = owner
    while node is not None and node is not root:
        parts.append(node._name)
        node = node._parent
    return ".".join(reversed(parts))


# 2. connection sets -------------------------------------------------------------------------

def _declare_variables(path, comp, infos, registry, specs=None, given=None):
    """Enter the variables of ``comp`` (ports' across and through variables, then its own) in
    ``infos`` with their start values. ``specs``: a dict kept over one compilation, holding
    each class's list of variables (see :func:`_variable_specs`) and, for a class whose start
    values read no parameters, those of the class. ``given``, a dict, receives the start values
    the user gave (by full name): ``start=`` entries and parameter-derived ones that differ
    from what the class's parameter defaults give.

    Priorities: 2 set by ``start=``, 1 derived from a parameter given a non-default value (or
    from a parameter without a default), 0 the class default. A given start thus wins over a
    default one on the same node (see :func:`_set_start`)."""
    cls = type(comp)
    got = None if specs is None else specs.get(cls)
    if got is None:
        got = (_variable_specs(cls), _class_starts(cls), _start_defaults(cls))
        if specs is not None:
            specs[cls] = got
    spec, fixed, defaults = got
    explicit_user = comp._start
    if fixed is not None:   # as start_values_traced gives them, no parameter read
        starts = {**fixed, **explicit_user} if explicit_user else fixed
    else:
        starts = comp.start_values_traced(path, registry)
    for suffix, unit, key, nominal, desc, how in spec:
        name = path + suffix
        if how == 1:      # a through variable: starts at zero, never given
            infos[name] = VarInfo(name, unit, 0.0, nominal, desc, path, 0)
            continue
        start = float(starts.get(key, 0.0)) if how == 0 else float(starts[key])
        # ``prio`` ranks the variables alias elimination keeps; ``told`` says whether the
        # start value was given (it wins over a default one on the same node)
        if key in explicit_user:
            prio = told = 2
        elif fixed is None and key in defaults:
            default = defaults[key]
            prio = 1 if key in defaults[_FROM_STARTS] else 0
            if default is _NO_DEFAULT:   # reads a parameter without a default: given
                told = 1 if prio or start != 0.0 else 0
            else:
                told = 1 if start != default else 0
        else:
            prio = told = 0
        if told and given is not None and (told == 2 or start != 0.0 or
                                           defaults.get(key) is not _NO_DEFAULT):
            given[name] = start
        info = infos[name] = VarInfo(name, unit, start, nominal, desc, path, prio)
        if told:
            info.given = told


_NO_DEFAULT = object()
_FROM_STARTS = object()     # key of the set of keys ``starts`` returns
_START_DEFAULTS: dict = {}


class _NoDefault(Exception):
    pass


class _DefaultView:
    """A parameter model's fields at their declared defaults (raising for a required one)."""

    __slots__ = ("_model",)

    def __init__(self, model):
        self._model = model

    def __getattr__(self, name):
        field = self._model.model_fields.get(name)
        if field is None:
            attr = getattr(self._model, name, None)
            if isinstance(attr, property):
                return attr.fget(self)
            raise _NoDefault(name)
        if field.is_required():
            raise _NoDefault(name)
        return field.get_default(call_default_factory=True)


def _start_defaults(cls):
    """``{key: start value with every parameter at its default}`` of the parameter-derived start
    values of ``cls`` (``starts`` and callable variable starts), ``_NO_DEFAULT`` where that
    value reads a parameter without a default; under ``_FROM_STARTS`` the keys ``starts``
    returns. Computed once per class."""
    got = _START_DEFAULTS.get(cls)
    if got is not None:
        return got
    out: dict = {}
    view = _DefaultView(cls.Params)
    keys = ()
    if cls.starts is not Component.starts:
        try:
            values = cls.starts(None, view)
            keys = tuple(values)
            for key, value in values.items():
                out[key] = float(value)
        except Exception:   # a parameter without a default, or a start not computable so
            try:
                keys = tuple(_keys_of_starts(cls))
            except Exception:
                keys = ()
            for key in keys:
                out[key] = _NO_DEFAULT
    out[_FROM_STARTS] = frozenset(keys)
    for name, var in cls.variables.items():
        if callable(var.start) and name not in out:
            try:
                out[name] = float(var.start(view))
            except Exception:
                out[name] = _NO_DEFAULT
    _START_DEFAULTS[cls] = out
    return out


def _keys_of_starts(cls):
    """The keys ``cls.starts`` returns, read from a view giving every parameter as 0."""
    class _Zeros:
        def __getattr__(self, name):
            attr = getattr(cls.Params, name, None)
            if isinstance(attr, property):
                return attr.fget(self)
            return 0.0
    return cls.starts(None, _Zeros())


def _class_starts(cls):
    """The start values of every instance of ``cls`` before the user's, where they read no
    parameters (no parameter-derived ``starts``, constant variable starts), else None."""
    if cls.starts is not Component.starts or \
            cls.start_values_traced is not Component.start_values_traced or \
            any(callable(var.start) for var in cls.variables.values()):
        return None
    return {name: var.start for name, var in cls.variables.items()}


def _variable_specs(cls) -> list:
    """``(".name" suffix, unit, start key, nominal, description, how)`` of each variable of a
    component class, in the order declared; ``how``: 0 a port's across variable or a signal
    (start value 0 unless given), 1 a through variable, 2 a variable of the class's own."""
    out = []
    for pname, port in cls.ports.items():
        d = port.domain
        if d is SIGNAL:
            out.append((f".{pname}", port.across_unit, pname, port.across_nominal,
                        port.description or f"signal {pname}", 0))
            continue
        key = f"{pname}.{d.across}"
        out.append((f".{key}", d.across_unit, key, d.across_nominal,
                    f"{d.across} at port {pname}", 0))
        out.append((f".{pname}.{d.through}", d.through_unit, None, d.through_nominal,
                    f"{d.through} into port {pname}", 1))
    for vname, var in cls.variables.items():
        out.append((f".{vname}", var.unit, vname, var.nominal, var.description, 2))
    return out


def _connection_equations(root, leaves, infos, keys=None) -> list[_Equation]:
    """The equations of the connection sets. ``keys``, a list, receives each equation's
    provenance (as :func:`_connection_key` reads it off the equation)."""
    # ports numbered in the order met; connection sets by union-find over those numbers,
    # listed in the order of their first port (as a graph's connected components are)
    index: dict[tuple, int] = {}
    attrs: list[tuple] = []     # (label, comp, port name, leaf)
    for path, comp in leaves:
        cid = id(comp)
        for pname in type(comp).ports:
            index[(cid, pname)] = len(attrs)
            attrs.append((f"{path}.{pname}", comp, pname, True))
    leaf_ids = {id(c) for _, c in leaves}
    parent: list[int] = list(range(len(attrs)))

    def node_of(ref):
        key = (id(ref.owner), ref.name)
        k = index.get(key)
        if k is None:
            k = index[key] = len(attrs)
            attrs.append(((_rel_path(root, ref.owner) + "." + ref.name).lstrip("."),
                          ref.owner, ref.name, id(ref.owner) in leaf_ids))
            parent.append(k)
        return k

    def find(a):
        root_ = a
        while parent[root_] != root_:
            root_ = parent[root_]
        while parent[a] != root_:
            parent[a], a = root_, parent[a]
        return root_

    def join(a, b):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[rb] = ra

    def walk(node: Circuit):
        for refs in node._connections:
            keys = [node_of(r) for r in refs]
            for a, b in zip(keys, keys[1:]):
                join(a, b)
        for name, (ref, _) in node._exposed.items():
            join(node_of(_PortKey(node, name)), node_of(ref))
        for child in node._components.values():
            if isinstance(child, Circuit):
                walk(child)

    walk(root)
    members: dict[int, list[int]] = {}
    for k in range(len(attrs)):
        members.setdefault(find(k), []).append(k)
    groups = sorted(members.values(), key=lambda g: g[0])
    equations = []
    shorted = []    # (component path, its ports on one node)
    for group in groups:
        ports = [attrs[k] for k in group if attrs[k][3]]
        ports.sort(key=operator.itemgetter(0))
        if len(ports) > 1:
            _note_shorted(ports, shorted)
        labels = [a[0] for a in ports]
        exposed = sorted(attrs[k][0] for k in group if not attrs[k][3])
        specs = [type(a[1]).ports[a[2]] for a in ports]
        domains = {s.domain.name for s in specs}
        if len(domains) > 1:
            desc = ", ".join(f"{lab} ({s.domain.name})" for lab, s in zip(labels, specs))
            raise ConnectionError_(f"incompatible domains joined in one node: {desc}. A node "
                                   f"joins ports of one domain only.")
        domain = specs[0].domain
        if domain is SIGNAL:
            signal = _signal_set(labels, specs, exposed)
            equations.extend(signal)
            if keys is not None:
                keys.extend(_connection_key(eq.expr) for eq in signal)
            continue
        if len(ports) == 1:
            comp = ports[0][1]
            alone = [pn for pn in type(comp).ports
                     if sum(attrs[j][3] for j in members[find(index[(id(comp), pn)])]) == 1]
            if not exposed and len(alone) == len(type(comp).ports) and \
                    type(comp).__name__ in _CLOSURE.get(domain.name, "").split():
                # a closure itself (a Tank, a Plug) left over: closing it is no advice
                path = labels[0].rsplit(".", 1)[0]
                raise CircuitError(
                    f"component {path!r} ({type(comp).__name__}) is connected to nothing: "
                    f"connect port{'s' if len(alone) > 1 else ''} "
                    f"{', '.join(repr(f'{path}.{pn}') for pn in alone)} or remove the "
                    f"component from the circuit.")
            via = f" (exposed as {', '.join(exposed)}, but not connected outside)" if exposed \
                else ""
            raise CircuitError(
                f"port {labels[0]!r} ({domain.name}) is not connected{via}. Connect it to "
                f"another port, or close it explicitly with "
                f"{_CLOSURE.get(domain.name, 'a component that fixes it')}.")
        node_label = _node_label(labels)
        # the rows are built as ``a - first`` and ``q1 + q2 + ...`` would fold them: leaves of
        # distinct names fold nothing
        suffix = "." + domain.across
        first = E.Expr("sym", (), labels[0] + suffix)
        for lab in labels[1:]:
            a = E.Expr("sym", (), lab + suffix)
            row = E.Expr("sub", (a, first))
            equations.append(_Equation(row, node_label,
                                       f"{node_label}: {domain.across} equal at {lab}"))
            if keys is not None:    # ``a - b`` of two distinct names
                keys.append((("connection", "sub"), (a.value, first.value), [a, first, row]))
        suffix = "." + domain.through
        through = [E.Expr("sym", (), lab + suffix) for lab in labels]
        total = through[0]
        nodes = [total]
        for q in through[1:]:
            total = E.Expr("add", (total, q))
            nodes += (q, total)
        equations.append(_Equation(total, node_label,
                                   f"{node_label}: sum of {domain.through} is zero"))
        if keys is not None:    # ``q1 + q2 + ... + qn`` summed from the left
            keys.append((("connection", "sum", len(through)),
                         tuple(q.value for q in through), nodes))
    if shorted:
        told = "; ".join(f"{path!r} ({', '.join(names)})" for path, names in shorted[:5])
        more = f" and {len(shorted) - 5} more" if len(shorted) > 5 else ""
        warnings.warn(PlausibilityWarning(
            f"component{'s' if len(shorted) > 1 else ''} with two ports on one node: "
            f"{told}{more}. The node joins them, so the component sees no difference across "
            f"them (a short circuit: an orifice passes no flow, a spring holds no force). "
            f"Check the connections: a port may have been connected twice."),
            stacklevel=outside_stacklevel())
    return equations


def _note_shorted(ports, shorted):
    """Add to ``shorted`` each component with two or more (non-signal) ports among the
    ``(label, component, port, leaf)`` of one connection set."""
    if len({id(a[1]) for a in ports}) == len(ports):     # the common case: all distinct
        return
    seen: dict[int, tuple] = {}
    for label, comp, pname, _ in ports:
        if type(comp).ports[pname].domain is not SIGNAL:
            seen.setdefault(id(comp), (comp, []))[1].append((label, pname))
    for comp, got in seen.values():
        # all of the component's ports on this one node, all of one domain: a two-port
        # element (orifice, line, valve, spring) bridged. A valve's pilot joined to its outlet
        # at the tank, with its other ports elsewhere, is a circuit; so are the two chambers
        # of a cylinder joined (regeneration: a converter to another domain is not named)
        domain = type(comp).ports[got[0][1]].domain
        mine = [p for p, spec in type(comp).ports.items() if spec.domain is not SIGNAL]
        if len(got) > 1 and len(got) == len(mine) and all(
                type(comp).ports[p].domain is domain for p in mine):
            label, _ = got[0]
            shorted.append((label.rsplit(".", 1)[0], [p for _, p in got]))


def _connection_key(e):
    """``(key, names, nodes)`` of a connection equation (``a - b``, or ``q1 + q2 + ... + qn``
    summed from the left) for :class:`_Provenance` (``nodes``: the row's nodes in
    :func:`~pvgraph.expr.postorder`), or None for another form."""
    if e.op == "sub" and e.args[0].op == "sym" and e.args[1].op == "sym":
        key, names = ("sub",), [e.args[0].value, e.args[1].value]
        nodes = [e.args[0], e.args[1], e]
    else:
        names = []
        nodes = []      # outermost first: each sum, then the term it adds
        while e.op == "add" and e.args[1].op == "sym":
            names.append(e.args[1].value)
            nodes += (e, e.args[1])
            e = e.args[0]
        if e.op != "sym" or not names:
            return None
        names.append(e.value)
        names.reverse()
        nodes.append(e)
        nodes.reverse()
        key = ("sum", len(names))
    if len(set(names)) != len(names):
        return None
    return ("connection",) + key, tuple(names), nodes


def _node_label(labels):
    """``node{a.p, b.p, ...}`` naming a connection set; a wide one by a few ports and a count
    (every equation of the set carries the label)."""
    if len(labels) <= NAMES_IN_MESSAGES:
        return "node{" + ", ".join(labels) + "}"
    return ("node{" + ", ".join(labels[:NAMES_IN_MESSAGES - 2]) +
            f", ... ({len(labels) - NAMES_IN_MESSAGES + 1} more), {labels[-1]}}}")


class _PortKey:
    """A PortRef-like handle on a circuit's exposed port (hashable by owner id and name)."""

    def __init__(self, owner, name):
        self.owner = owner
        self.name = name


def _signal_set(labels, specs, exposed):
    outputs = [lab for lab, s in zip(labels, specs) if s.causality == "output"]
    inputs = [lab for lab, s in zip(labels, specs) if s.causality == "input"]
    if len(outputs) > 1:
        raise ConnectionError_(f"signal outputs {outputs} drive one connection; a signal has "
                               f"exactly one driver. Add a Sum block to combine them.")
    if not outputs:
        raise CircuitError(f"signal input(s) {inputs} are not driven by any output. Connect a "
                           f"source (Constant, Step, ...) or a component's output.")
    _check_signal_units(labels, specs, outputs[0])
    src = E.Expr("sym", (), outputs[0])
    return [_Equation(E.Expr("sym", (), lab) - src, f"signal{{{outputs[0]}}}",
                      f"signal {outputs[0]} drives {lab}") for lab in inputs]


def _check_signal_units(labels, specs, output):
    """Refuse a signal connection whose ports declare units of different dimensions (a
    pressure sensor's Pa into a flow input's m^3/s). Signals carry SI values, so only the
    dimension matters; a port without a unit (a Gain, a Sum, a source) takes any."""
    from .units import UnitError, parse_unit
    dims = {}
    for lab, spec in zip(labels, specs):
        if spec.unit:
            try:
                dims[lab] = (parse_unit(spec.unit)[1], spec.unit)
            except (UnitError, ValueError):
                continue
    if len({d for d, _ in dims.values()}) < 2:
        return
    # the output against each input; without a unit on the output, the inputs among themselves
    first = output if output in dims else next(iter(dims))
    for lab, (dim, unit) in dims.items():
        if dim != dims[first][0]:
            raise ConnectionError_(
                f"signal {first!r} [{dims[first][1]}] is joined to {lab!r} [{unit}]: the "
                f"ports' units are of different dimensions. A signal carries its SI value, "
                f"so {lab!r} would read a {dims[first][1]} value as {unit}. Put a Gain "
                f"between them (its k in {unit} per {dims[first][1]}), or connect it to a "
                f"signal of its own unit.")


def _check_symbols(equations, found, infos, modes):
    """Every symbol an equation reads is a variable or a mode (``found``: per equation, the
    names of the variables and derivatives it reads)."""
    syms = set().union(*[s for s, _ in found])
    ders = set().union(*[d for _, d in found])
    if (syms | ders) - infos.keys() <= modes and ders.isdisjoint(modes):
        return    # all is well (else the loop below names the first equation at fault)
    for eq in equations:
        for op, name in E.leaves(eq.expr, ("sym", "der")):
            if name not in infos and name not in modes:
                raise CircuitError(f"{eq.label} uses the unknown variable {name!r}")
            if op == "der" and name in modes:
                raise CircuitError(f"{eq.label} differentiates the mode {name!r}")


# 4. alias elimination ------------------------------------------------------------------------

def _affine(e: E.Expr):
    """``(coeffs, const)`` if ``e`` is affine in plain variables (no derivatives), else None.

    Coefficients and the constant are floats, or parametric expressions (constants and runtime
    parameters) where they depend on parameters.
    """
    if e.op in ("add", "sub"):   # the common case: a connection equality or flow balance
        a, b = e.args
        if a.op == "sym" and b.op == "sym" and a.value != b.value and "#" not in a.value \
                and "#" not in b.value:
            return {a.value: 1.0, b.value: 1.0 if e.op == "add" else -1.0}, 0.0
    # the nodes of :func:`~pvgraph.expr.postorder`, each given its form as soon as it is
    # reached: the first operation that is not affine (or the node past MAX_AFFINE_NODES)
    # ends the walk
    form: dict[int, tuple[dict, object]] = {}
    if not e.args:
        f = _affine_form(e, form)
        if f is None:
            return None
        form[id(e)] = f
    else:
        seen = {id(e)}
        stack = [(e, iter(e.args))]
        while stack:
            node, children = stack[-1]
            for a in children:
                if id(a) not in seen:
                    seen.add(id(a))
                    if len(seen) > MAX_AFFINE_NODES:
                        return None
                    if a.args:
                        stack.append((a, iter(a.args)))
                        break
                    f = _affine_form(a, form)
                    if f is None:
                        return None
                    form[id(a)] = f
            else:
                stack.pop()
                f = _affine_form(node, form)
                if f is None:
                    return None
                form[id(node)] = f
    coeffs, k = form[id(e)]
    return {v: w for v, w in coeffs.items() if not _kzero(w)}, k


def _affine_form(n, form):
    """The affine form ``(coeffs, const)`` of node ``n`` from its children's (in ``form``),
    or None where it is not affine."""
    op = n.op
    if op == "const":
        return ({}, n.value)
    elif op == "param":
        return ({}, n)
    elif op == "sym" and "#" not in n.value:
        return ({n.value: 1.0}, 0.0)
    elif op in E.LEAVES:
        return None
    else:
        kids = [form[id(a)] for a in n.args]
        if all(not c for c, _ in kids):
            return ({}, n)  # parametric: a number for any one run
        elif op in ("add", "sub"):
            (ca, ka), (cb, kb) = kids
            sub = op == "sub"
            c = dict(ca)
            for v, w in cb.items():
                w = _kneg(w) if sub else w
                c[v] = _kadd(c[v], w) if v in c else w
            return (c, _kadd(ka, _kneg(kb) if sub else kb))
        elif op == "neg":
            ca, ka = kids[0]
            return ({v: _kneg(w) for v, w in ca.items()}, _kneg(ka))
        elif op == "mul":
            (ca, ka), (cb, kb) = kids
            if ca and cb:
                return None
            if ca:
                return ({v: _kmul(w, kb) for v, w in ca.items()}, _kmul(ka, kb))
            else:
                return ({v: _kmul(w, ka) for v, w in cb.items()}, _kmul(ka, kb))
        elif op == "div":
            (ca, ka), (cb, kb) = kids
            if cb or (isinstance(kb, float) and kb == 0.0):
                return None
            return ({v: _kdiv(w, kb) for v, w in ca.items()}, _kdiv(ka, kb))
        else:
            return None


# arithmetic on affine coefficients: floats, or parametric expressions where parameters enter

def _knorm(x):
    return x.value if isinstance(x, E.Expr) and x.op == "const" else x


def _kzero(x):
    return isinstance(x, float) and x == 0.0


def _kadd(a, b):
    fa, fb = isinstance(a, float), isinstance(b, float)
    if fa and fb:
        return a + b
    if fa and a == 0.0 and b.op != "const":     # 0 + b folds to b (no node made for the 0)
        return b
    if fb and b == 0.0 and a.op != "const":
        return a
    return _knorm(E.as_expr(a) + E.as_expr(b))


def _kneg(a):
    return -a if isinstance(a, float) else _knorm(-a)


def _kmul(a, b):
    fa, fb = isinstance(a, float), isinstance(b, float)
    if fa and fb:
        return a * b
    if fa and a == 1.0 and b.op != "const":     # 1 * b folds to b (no node made for the 1)
        return b
    if fb and b == 1.0 and a.op != "const":
        return a
    return _knorm(E.as_expr(a) * E.as_expr(b))


def _kdiv(a, b):
    fb = isinstance(b, float)
    if fb and isinstance(a, float):
        return a / b
    if fb and (b == 1.0 or b == -1.0) and a.op != "const":   # folds to a or -a
        return a if b == 1.0 else _knorm(-a)
    return _knorm(E.as_expr(a) / E.as_expr(b))


def _scrambled(values) -> dict:
    """Other parameter values, for telling identically-zero coefficients from accidental ones."""
    return {nm: (v * (1.0 + 0.5 * (zlib.crc32(nm.encode()) % 1000) / 1000.0) + 0.1
                 if isinstance(v, float) else v) for nm, v in values.items()}


def _vanishes(w, values, other) -> bool:
    """True if a parametric coefficient is identically zero (``k1*k2 - k2*k1``).

    Tested by evaluation at the compile-time values and at a second, scrambled set of values:
    a non-zero rational function of the parameters vanishing at both is not a practical case.
    """
    if isinstance(w, float):
        return w == 0.0
    try:
        if E.evaluate(w, values) != 0.0:
            return False
        return E.evaluate(w, other) == 0.0
    except (ArithmeticError, ValueError):
        return False


def _kexpr(x):
    return x if isinstance(x, E.Expr) else E.const(x)


class _Provenance:
    """Rows known to be one graph up to the names of their leaves.

    A row built from a component template has the key ``(template, residual number)`` and the
    distinct names of its variable, derivative and parameter leaves, in the template's order
    (its classes). Substituting aliases into such a row gives a row whose graph follows from
    its key and the substitution's pattern alone (per class: kept, fixed, or expressed in a
    target, with the coefficient and offset as numbers, or the very expressions, and which
    classes share a target): the folding arithmetic looks at operations, constants and node
    identity, never at names. So rows of one key have one affine form (or none) and one row
    shape, computed once per key, and a substitution of one pattern into rows of one key is
    a generated builder (made from the second such row, checked against the third) that
    creates the changed nodes and reuses the row's unchanged ones, as
    :func:`pvgraph.expr.substitute` would.
    """

    def __init__(self):
        self.rows: dict[int, tuple] = {}   # id(row) -> (row, key number, names)
        self.nodes: dict[int, list] = {}   # id(row) -> its nodes in post-order, where known
        self.keys: dict = {}
        self._in_token: dict[int, tuple] = {}
        self._builders: dict[int, object] = {}   # key number -> builder, candidate or False
        self._of_template: dict = {}   # template -> the key numbers of its rows

    def number(self, key) -> int:
        k = self.keys.get(key)
        if k is None:
            k = self.keys[key] = len(self.keys)
        return k

    def add(self, row, key, names, nodes=None):
        self.rows[id(row)] = (row, self.number(key), names)
        if nodes is not None:
            self.nodes[id(row)] = nodes

    def template_keys(self, tpl, n) -> list:
        """The key numbers of the rows ``(tpl, 0)``, ..., ``(tpl, n - 1)``."""
        got = self._of_template.get(tpl)
        if got is None or len(got) != n:
            got = self._of_template[tpl] = [self.number((tpl, k)) for k in range(n)]
        return got

    def add_rows(self, rows, numbers, names, nodes):
        """:meth:`add` of each row with its key number, names and nodes (the first
        ``len(nodes)`` rows have theirs)."""
        got = self.rows
        for row, key, nm in zip(rows, numbers, names):
            got[id(row)] = (row, key, nm)
        self.nodes.update(zip(map(id, rows), nodes))

    def forget_nodes(self):
        """Drop the rows' node lists (needed while substituting only)."""
        self.nodes = {}

    def get(self, row):
        """``(key number, names)`` of ``row``, or None."""
        p = self.rows.get(id(row))
        return None if p is None or p[0] is not row else p[1:3]

    def substitute(self, old, subs, resolve):
        """``old`` with the aliases of ``subs`` substituted (as :func:`_apply` does), recorded
        with its key if ``old``'s is known."""
        p = self.rows.get(id(old))
        if p is None or p[0] is not old:
            return _apply(old, subs, resolve)
        _, key, names = p
        old_nodes = self.nodes.pop(id(old), None)
        pattern = []
        cls: dict[str, int] = {}
        out = []
        tokens = []

        def place(nm):
            c = cls.get(nm)
            if c is None:
                c = cls[nm] = len(out)
                out.append(nm)
            return c
        for nm in names:
            if nm not in subs:
                c = cls.get(nm)     # place(nm), inline (the common case)
                if c is None:
                    c = cls[nm] = len(out)
                    out.append(nm)
                pattern.append(("keep", c))
                continue
            coef, target, off = resolve(nm)
            # the parameters a parametric coefficient or offset brings in are names too
            brought = []
            if coef.__class__ is not float:
                tokens.append(coef)
                brought.extend(place(q) for q in self._params(coef))
            if off.__class__ is not float:
                tokens.append(off)
                brought.extend(place(q) for q in self._params(off))
            how = (_token(coef), _token(off), tuple(brought))
            pattern.append(("fix",) + how if target is None else ("sub", place(target)) + how)
        names = tuple(out)
        k = self.number((key, tuple(pattern)))
        del self.rows[id(old)]      # an equation is substituted into once per pass
        state = self._builders.get(k)
        if callable(state):
            if old_nodes is None:
                old_nodes = E.postorder([old])
            new, nodes = state(names, old_nodes)
            self.rows[id(new)] = (new, k, names)
            self.nodes[id(new)] = nodes
            return new
        new = _apply(old, subs, resolve)
        self.rows[id(new)] = (new, k, names)
        # the first row of a key is substituted as it is; the second gives a candidate
        # builder (a key met once costs no builder), the third checks it
        if state is None:
            self._builders[k] = 1
            return new
        if state is False:
            return new
        if old_nodes is None:
            old_nodes = E.postorder([old])
        if state == 1:
            fn = None
            if len(old_nodes) <= MAX_BUILDER_NODES:
                fn = _derived_builder(old_nodes, new, names, tokens)
            self._builders[k] = _Candidate(fn) if fn is not None else False
        elif _built_alike(state.fn, names, old_nodes, new, tokens):
            self._builders[k] = state.fn
        else:
            self._builders[k] = False
        return new

    def _params(self, x):
        """The names of the parameters in the parametric expression ``x`` (kept per node)."""
        got = self._in_token.get(id(x))
        if got is None or got[0] is not x:
            got = self._in_token[id(x)] = (x, [nm for _, nm in E.leaves(x, ("param",))])
        return got[1]


class _Candidate:
    """A builder made from one row of a key, not yet checked against another."""

    __slots__ = ("fn",)

    def __init__(self, fn):
        self.fn = fn


def _shared_nodes(tokens) -> set:
    """Nodes every row of a key holds as the same objects: the coefficients and offsets the
    substitution puts in (and what they hold) and the folding's constants."""
    ids = {id(E.ZERO), id(E.ONE)}
    if tokens:
        ids.update(id(n) for n in E.postorder(tokens))
    return ids


def _derived_builder(old_nodes, new, names, tokens):
    """A generated ``(names, old nodes) -> (row, its nodes in post-order)`` rebuilding ``new``
    (``old`` substituted) for another row of the same key, or None where ``new`` holds a
    node it cannot place."""
    old_pos = {id(n): j for j, n in enumerate(old_nodes)}
    shared = _shared_nodes(tokens)
    cls = {nm: c for c, nm in enumerate(names)}
    order = E.postorder([new])
    num: dict[int, str] = {}
    kept: list = []
    lines = ["def build(names, old):"]
    for i, node in enumerate(order):
        var = num[id(node)] = f"n{i}"
        if id(node) in old_pos:
            lines.append(f"    {var} = old[{old_pos[id(node)]}]")
        elif id(node) in shared:
            lines.append(f"    {var} = K[{len(kept)}]")
            kept.append(node)
        elif node.args:
            args = "".join(num[id(a)] + ", " for a in node.args)
            value = ""
            if node.value is not None:
                value = f", K[{len(kept)}]"
                kept.append(node.value)
            lines.append(f"    {var} = X({node.op!r}, ({args}){value})")
        elif node.op in ("sym", "der") and node.value in cls:
            lines.append(f"    {var} = X({node.op!r}, (), names[{cls[node.value]}])")
        elif node.op == "const":
            lines.append(f"    {var} = X('const', (), K[{len(kept)}])")
            kept.append(node.value)
        elif node.op == "time":
            lines.append(f"    {var} = X('time', (), None)")
        else:
            return None
    lines.append(f"    return n{len(order) - 1}, [{', '.join(num[id(n)] for n in order)}]")
    namespace = {"X": E.Expr, "K": kept}
    exec(compile("\n".join(lines), "<substitution builder>", "exec"),  # noqa: S102
         namespace)   # generated from the graph of a substituted row
    return namespace["build"]


def _built_alike(build, names, old_nodes, new, tokens) -> bool:
    """True if ``build`` gives ``new`` (``old`` substituted, by :func:`_apply`): the same
    operations, payloads and children node for node, the old and shared nodes themselves and
    fresh nodes elsewhere."""
    got, got_nodes = build(names, old_nodes)
    want = E.postorder([new])
    if len(want) != len(got_nodes) or got is not got_nodes[-1]:
        return False
    old_ids = {id(n) for n in old_nodes} | _shared_nodes(tokens)
    pos_w = {id(n): i for i, n in enumerate(want)}
    pos_g = {id(n): i for i, n in enumerate(got_nodes)}
    if len(pos_g) != len(got_nodes):
        return False
    for w, g in zip(want, got_nodes):
        if id(w) in old_ids:
            if g is not w:
                return False
            continue
        if g is w or id(g) in old_ids or w.op != g.op or len(w.args) != len(g.args):
            return False
        if w.args:
            if w.value is not g.value or [pos_w[id(a)] for a in w.args] != \
                    [pos_g[id(a)] for a in g.args]:
                return False
        elif repr(w.value) != repr(g.value):
            return False
    return True


def _token(x):
    """A coefficient or offset in a substitution pattern: a float by its value, a parametric
    expression by identity (the node the substitution puts in)."""
    return repr(x) if x.__class__ is float else x


def _eliminate_aliases(equations, infos, subs, values, found=None, incidence=None, prov=None,
                       why=None, held=None):
    """Remove unknowns defined by affine one- and two-variable equations (in place on subs).

    The unknown removed must have a constant coefficient, so that no parameter value can make
    the elimination divide by zero; the other coefficient and the offset may be parametric.
    ``values`` holds the parameters' compile-time values (for carrying start values);
    ``found`` the names of the values and of the derivatives each equation reads (two sets
    per equation, taken over), if known. ``incidence``, a list, receives ``(values read,
    derivatives read)`` (sets of names) of each equation returned; ``why``, a dict, the label
    of the equation that removed each unknown and the unknown it was expressed in (None where
    fixed to a value), for the messages of singular systems. ``held``, a dict, receives each
    unknown whose rate an equation reads and that is fixed to an expression of parameters:
    ``(names of those parameters, labels of the equations reading its rate)`` (the rate of
    such an unknown is zero: a parameter changed as an input moves it without a rate, see
    :attr:`System.held_rates`).
    """
    if why is None:
        why = {}
    if found is None:
        found = [read_sets(eq.expr) for eq in equations]
    used_der: set[str] = set().union(*[d for _, d in found])

    def num(x):
        return x if isinstance(x, float) else E.evaluate(x, values)

    # name -> the state of resolve's walk along the chain of substitutions where it ended
    # last: a chain only grows at its end (an unknown is eliminated once), so the walk goes on
    # from there, with the very same arithmetic
    walked: dict[str, tuple] = {}

    def resolve(name):
        got = walked.get(name)
        if got is None:
            coef, target, off = 1.0, name, 0.0
        else:
            coef, target, off = got
            if target not in subs:
                return got
        while target in subs:
            c2, t2, o2 = subs[target]
            if coef.__class__ is float and c2.__class__ is float and \
                    o2.__class__ is float and off.__class__ is float:
                coef, target, off = coef * c2, t2, coef * o2 + off   # as _kmul, _kadd do
            else:
                coef, target, off = _kmul(coef, c2), t2, _kadd(_kmul(coef, o2), off)
            if t2 is None:
                walked[name] = got = (0.0, None, off)
                return got
        walked[name] = got = (coef, target, off)
        return got

    def rank(name):
        info = infos[name]
        return (info.start_priority, name in used_der, name.count(".") == 2 and
                name.endswith((".p", ".x")), -len(name))

    def substituted(expr, syms, ders):
        """The equation with the eliminated unknowns replaced, the values and derivatives it
        reads, and whether those are exact. An unknown expressed in another maps its leaf
        onto that one's; one fixed to a value (or a vanishing coefficient) can fold other
        terms away: the names are then a superset (read exactly where needed)."""
        expr = _apply(expr, subs, resolve) if prov is None else \
            prov.substitute(expr, subs, resolve)
        exact = True
        out = []
        for group in (syms, ders):
            new = set()
            for nm in group:
                if nm in subs:
                    coef, target, _ = resolve(nm)
                    if target is None or _kzero(coef):
                        exact = False
                    else:
                        new.add(target)
                else:
                    new.add(nm)
            out.append(new)
        return expr, out[0], out[1], exact

    # per provenance key: the (kind, place of the name) of its rows' variable and derivative
    # leaves (one graph up to the names), or None where a leaf is not among the key's names
    read_forms: dict[int, object] = {}

    def read(expr):
        p = prov.get(expr) if prov is not None else None
        if p is not None:
            key, names = p
            got = read_forms.get(key, False)
            if got is None:
                p = None
            elif got is not False:
                syms_c, ders_c = got
                return {names[c] for c in syms_c}, {names[c] for c in ders_c}
        lv = E.leaves(expr, ("sym", "der"))
        if p is not None:
            place = {nm: c for c, nm in enumerate(p[1])}
            read_forms[p[0]] = ([place[nm] for op, nm in lv if op == "sym"],
                                [place[nm] for op, nm in lv if op == "der"]) \
                if all(nm in place for _, nm in lv) else None
        return {nm for op, nm in lv if op == "sym"}, {nm for op, nm in lv if op == "der"}

    eliminated = subs.keys()
    # per provenance key: its rows are not affine (None), or their affine form with float
    # coefficients and constant, by the places of the names (the key's classes); other forms
    # are found row by row
    forms: dict[int, object] = {}

    def affine(expr):
        """:func:`_affine` of ``expr`` and whether its coefficients are known to be floats."""
        p = prov.get(expr) if prov is not None else None
        if p is None:
            form = _affine(expr)
            return None if form is None else form + (False,)
        key, names = p
        known = forms.get(key, False)
        if known is None:
            return None
        if known is not False and known is not _PARAMETRIC:
            terms, k = known
            return {names[c]: w for c, w in terms}, k, True
        form = _affine(expr)
        if known is False:
            if form is None:
                forms[key] = None
            elif form[1].__class__ is float and all(w.__class__ is float
                                                    for w in form[0].values()):
                place = {nm: c for c, nm in enumerate(names)}
                forms[key] = ([(place[v], w) for v, w in form[0].items()], form[1])
            else:
                forms[key] = _PARAMETRIC
        return None if form is None else form + (False,)

    def plain(syms, ders):
        """False where :func:`_affine` cannot hold: a derivative or a mode is read."""
        return not ders and "#" not in "".join(syms)

    # Passes over the equations in order until nothing is eliminated. An equation none of whose
    # variables was eliminated since it was last looked at gives the same answer again, so it is
    # skipped: each pass costs the equations that changed, not the circuit. Each equation's
    # values and derivatives read are kept (exactly, or a superset read again where it
    # matters) for the affine test and the incidence of the later stages.
    remaining = [[eq, eq.expr, syms, ders, True, True]
                 for eq, (syms, ders) in zip(equations, found)]
    other = None
    changed = True
    while changed:
        changed = False
        keep = []
        for item in remaining:
            eq, expr, syms, ders, fresh, exact = item
            if not (eliminated.isdisjoint(syms) and eliminated.isdisjoint(ders)):
                expr, syms, ders, still = substituted(expr, syms, ders)
                exact = exact and still
                item[1], item[2], item[3], item[5], fresh = expr, syms, ders, exact, True
            if not fresh:
                keep.append(item)
                continue
            item[4] = False
            flat = plain(syms, ders)
            if not exact and not flat:   # a superset: the exact names decide
                syms, ders = read(expr)
                item[2], item[3], item[5] = syms, ders, True
                flat = plain(syms, ders)
            form = affine(expr) if flat else None
            if form is None:
                keep.append(item)
                continue
            coeffs, k, floats = form    # floats: every coefficient is known to be a float
            if not floats and not all(isinstance(w, float) for w in coeffs.values()):
                if other is None:
                    other = _scrambled(values)
                coeffs = {v: w for v, w in coeffs.items() if not _vanishes(w, values, other)}
            if len(coeffs) == 0:
                value = num(k)
                what = "contradicts the others" if abs(value) > 0 else "repeats the others"
                reads = repr(value)
                if not isinstance(k, float):
                    reads = f"{E.to_text(k)} = {value!r}"
                    what += " (it constrains parameters only)"
                cause = ("This happens when two sources fix the same quantity (two pressure "
                         "sources on one node, flow sources in series, a port closed twice). "
                         "Remove one of them.")
                if abs(value) > 0 and any(t in eq.label for t in ("sum of f ", "sum of tau ")):
                    cause = ("A force or torque acts on a node that nothing holds: no mass or "
                             "inertia to accelerate, no spring, damper or fixed end to take it "
                             "(a free end, a gear or lever with nothing behind it). Put a Mass "
                             "or an Inertia there, or the load the force works against. " + cause)
                raise StructureError(
                    f"{eq.label} {what}: after fixing the variables the other equations determine, "
                    f"it reads {reads} = 0. {cause}")
            if len(coeffs) == 1:
                (v, a), = coeffs.items()
                if not isinstance(a, float):
                    keep.append(item)
                    continue
                off = _kdiv(_kneg(k), a)
                subs[v] = (0.0, None, off)
                why[v] = (eq.label, None)
                _set_start(infos, v, None, 0.0, num(off))
                changed = True
                continue
            if len(coeffs) == 2:
                order = list(coeffs.items())    # by rank; the first of equals first
                if rank(order[1][0]) < rank(order[0][0]):
                    order.reverse()
                if not isinstance(order[0][1], float):
                    order.reverse()
                (u, a), (w, b) = order
                if not isinstance(a, float):
                    keep.append(item)
                    continue
                # eliminate u: u = -(b*w + k)/a
                if b.__class__ is float and k.__class__ is float:
                    coef, off = -b / a, -k / a      # as _kneg, _kdiv do
                else:
                    coef, off = _kdiv(_kneg(b), a), _kdiv(_kneg(k), a)
                subs[u] = (coef, w, off)
                why[u] = (eq.label, w)
                _set_start(infos, u, w, num(coef), num(off))
                changed = True
                continue
            keep.append(item)
        remaining = keep
    for name in subs:
        subs[name] = resolve(name)
    if held is not None:
        # an unknown fixed to a parametric value whose rate the equations read: its rate is
        # zero in the compiled system, which holds as long as the parameters are constants
        for name in used_der & subs.keys():
            off = subs[name][2]
            if off.__class__ is not float:
                held[name] = tuple(sorted({nm for _, nm in E.leaves(off, ("param",))}))
        if held:    # and the labels of the equations that read those rates
            readers: dict[str, list] = {name: [] for name in held}
            for eq, (_, ders) in zip(equations, found):
                for name in ders & held.keys():
                    readers[name].append(eq.label)
            for name, params in held.items():
                held[name] = (params, tuple(readers[name]))
    out = []
    for eq, expr, syms, ders, _, exact in remaining:
        if not (eliminated.isdisjoint(syms) and eliminated.isdisjoint(ders)):
            expr, syms, ders, still = substituted(expr, syms, ders)
            exact = exact and still
        out.append(eq if expr is eq.expr else _Equation(expr, eq.origin, eq.label))
        if incidence is not None:
            incidence.append((syms, ders) if exact else read(expr))
    if prov is not None:
        prov.forget_nodes()
    return out


def _set_start(infos, elim, keep, coef, off):
    """Carry an eliminated variable's start value to the one it is expressed in.

    The one of higher priority (see :func:`_declare_variables`) wins; two given ones that
    disagree are reported with a :class:`~pvgraph.errors.PlausibilityWarning` (the kept
    variable's value is used)."""
    ie = infos[elim]
    if keep is None:
        ie.start = off
        return
    ik = infos[keep]
    if coef != 0.0 and (ie.given > ik.given or (
            ie.given == ik.given and ie.start_priority > ik.start_priority)):
        if ie.given and ik.given:
            _start_conflict(ik, ie, coef, off, keep_elim=True)
        ik.start = (ie.start - off) / coef
        ik.start_priority = max(ik.start_priority, ie.start_priority)
        if ik.given != ie.given:
            ik.given = ie.given
    elif ie.given and ik.given:
        _start_conflict(ik, ie, coef, off, keep_elim=False)
    ie.start = coef * ik.start + off


START_CONFLICT_RTOL = 1e-9   # relative difference of two given start values reported


def _start_conflict(ik, ie, coef, off, keep_elim):
    """Warn if the given start values of ``ie`` and ``ik`` (``ie = coef * ik + off``)
    disagree; ``keep_elim``: ``ie``'s value is the one used."""
    carried = coef * ik.start + off
    if abs(carried - ie.start) <= START_CONFLICT_RTOL * max(abs(carried), abs(ie.start),
                                                             ie.nominal):
        return
    used = ie if keep_elim else ik
    tied = "are one variable" if coef == 1.0 and off == 0.0 else \
        f"are tied by the circuit ({ie.name} = {ik.name} * {coef:.6g} + {off:.6g})"

    def show(info):
        return f"{info.name} = {info.start:.6g}{' ' + info.unit if info.unit else ''}"
    warnings.warn(PlausibilityWarning(
        f"conflicting start values: {show(ie)} and {show(ik)} are both given, but they "
        f"{tied}; {used.name} = {used.start:.6g} is used. Give the start value on one of them "
        f"only."), stacklevel=outside_stacklevel())


def _unit(coef) -> bool:
    """True for the float coefficients with which ``coef * leaf (+ 0.0)`` folds to the leaf
    or its negation."""
    return coef.__class__ is float and (coef == 1.0 or coef == -1.0)


def _renamed(op, target, coef):
    """``coef * leaf`` for a coefficient ``_unit`` accepts, as the folding arithmetic builds
    it (the leaf, or ``neg`` of it)."""
    node = E.Expr(op, (), target)
    return node if coef == 1.0 else E.Expr("neg", (node,))


def _apply(e, subs, resolve):
    if not subs:
        return e

    def leaf(node):
        if node.op == "sym" and node.value in subs:
            coef, target, off = resolve(node.value)
            if target is None:
                return _kexpr(off)
            if _unit(coef) and off.__class__ is float and off == 0.0:
                return _renamed("sym", target, coef)
            return _kexpr(coef) * E.Expr("sym", (), target) + off
        if node.op == "der" and node.value in subs:
            coef, target, _ = resolve(node.value)
            if target is None or _kzero(coef):
                return E.ZERO
            if _unit(coef):
                return _renamed("der", target, coef)
            return _kexpr(coef) * E.Expr("der", (), target)
        return None

    if codegen.long_sum(e):
        return _apply_chain(e, leaf)
    return E.substitute([e], leaf)[0]


def _apply_chain(e, leaf):
    """:func:`pvgraph.expr.substitute` of ``e`` with ``leaf``, walking a long sum's chain of
    left operands (a node's flow balance of many ports) directly: each term substituted on its
    own, the chain rebuilt from the bottom with the same folding operations."""
    spine = []
    node = e
    while node.op == "add" or node.op == "sub":
        spine.append(node)
        node = node.args[0]
    acc = E.substitute([node], leaf)[0]
    old = node
    for link in reversed(spine):
        rhs = link.args[1]
        if rhs.args:
            new_rhs = E.substitute([rhs], leaf)[0]
        else:
            new_rhs = leaf(rhs)
            if new_rhs is None:
                new_rhs = rhs
        if acc is old and new_rhs is rhs:
            acc = link
        else:
            acc = E.rebuild(link, (acc, new_rhs))
        old = link
    return acc


# 5. structural checks ------------------------------------------------------------------------

def _fixed_elsewhere(exc, equations, infos, subs, why) -> str:
    """For a structurally singular system: what already fixes the unknowns of each
    over-determined component equation (the connections made them aliases of, or values set
    by, other components' equations), or "" where there is nothing to add."""
    over = getattr(exc, "over_determined", None)
    if not over or not subs:
        return ""
    origin = {eq.label: eq.origin for eq in equations}
    lines = []
    for label in over[:NAMES_IN_MESSAGES]:
        path = origin.get(label)
        if path is None or path.startswith("node "):
            continue
        gone = [nm for nm in infos if nm.startswith(path + ".") and nm in subs]
        told = []
        for nm in gone[:3]:
            steps, at = [], nm       # the chain of eliminations from nm to where it ends
            while at in why and len(steps) < 12:
                by, at = why[at]
                steps.append(f"  {by}" + (f" -> {at}" if at is not None else " (a value)"))
            told.append(f"{nm} is determined by the chain\n" + "\n".join(steps))
        if told:
            lines.append(f"{label}: " + "\n".join(told))
    if not lines:
        return ""
    return ("The unknowns of these equations are already determined by other equations "
            "(two components fixing one quantity: two position or pressure sources on one "
            "node, two flow sources in series):\n" + "\n".join(lines))

def check_structure(names, eq_labels, inc_y, inc_yp, differential):
    """Balance, structural regularity and index-one checks; raise StructureError with names.

    ``inc_y`` and ``inc_yp`` are lists (one per equation) of variable indices whose value or
    derivative the equation touches.
    """
    n_eq, n_var = len(eq_labels), len(names)
    if n_eq == 0 and n_var == 0:
        return  # everything was fixed by alias elimination
    rows_y, cols_y = _flat(inc_y)
    rows_yp, cols_yp = _flat(inc_yp)
    pencil = _incidence(n_eq, n_var, np.concatenate([rows_y, rows_yp]),
                        np.concatenate([cols_y, cols_yp]))
    match_eq = maximum_bipartite_matching(pencil, perm_type="column")
    unmatched_eq = np.flatnonzero(match_eq < 0).tolist()
    unmatched_var = _unmatched(match_eq, n_var)
    if n_eq != n_var or unmatched_eq or unmatched_var:
        head = (f"the system has {n_eq} equations for {n_var} unknowns"
                if n_eq != n_var else
                f"the system is structurally singular ({n_eq} equations, {n_var} unknowns, but "
                f"some equations cannot be solved for any free unknown)")
        parts = [head + "."]
        if unmatched_eq:
            over = _alternating(pencil, unmatched_eq, match_eq, from_equations=True)
            parts.append("Over-determined (equations with no unknown left to solve for): "
                         + _list([eq_labels[i] for i in over]))
        if unmatched_var:
            under = _alternating(pencil, unmatched_var, match_eq, from_equations=False)
            parts.append("Under-determined (unknowns no equation determines): "
                         + _list([names[j] for j in under]))
        parts.append("Check for missing connections, a missing volume or source, or two "
                     "components fixing the same quantity.")
        err = StructureError("\n".join(parts))
        err.over_determined = [eq_labels[i] for i in over] if unmatched_eq else []
        raise err

    # index one: solvable for (y' of differential variables, y of algebraic variables)
    differential = np.asarray(differential, dtype=bool)
    alg = ~differential[cols_y]
    dif = differential[cols_yp]
    solve_for = _incidence(n_eq, n_var, np.concatenate([rows_y[alg], rows_yp[dif]]),
                           np.concatenate([cols_y[alg], cols_yp[dif]]))
    match1 = maximum_bipartite_matching(solve_for, perm_type="column")
    bad_eq = np.flatnonzero(match1 < 0).tolist()
    if bad_eq:
        bad_var = _unmatched(match1, n_var)
        raise StructureError(
            "the DAE has index above one: these equations constrain differential variables "
            "algebraically: " + _list([eq_labels[i] for i in bad_eq]) +
            ". Unknowns left without an equation: " + _list([names[j] for j in bad_var]) +
            ". Typical causes: an incompressible node between two volumes or masses, a "
            "position source driving a mass, a flow source into a closed volume-free node. Add "
            "compliance (a VolumeNode, a spring) or remove the rigid constraint.")


def _unmatched(match, n_var) -> list:
    """The variables (in order) no equation of the matching ``match`` (a variable per
    equation, -1 for none) is matched to."""
    matched = np.zeros(n_var, dtype=bool)
    matched[match[match >= 0]] = True
    return np.flatnonzero(~matched).tolist()


def _flat(lists):
    """``(rows, cols)`` arrays of the entries of per-row lists of column numbers."""
    lens = np.fromiter(map(len, lists), dtype=np.int64, count=len(lists))
    cols = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64,
                       count=int(lens.sum()))
    return np.repeat(np.arange(len(lists), dtype=np.int64), lens), cols


def _incidence(n_eq, n_var, rows, cols):
    """The 0/1 incidence matrix (CSR, each row's columns sorted, once each) of the entries
    ``(rows[k], cols[k])`` (repeats allowed)."""
    key = np.unique(rows * max(n_var, 1) + cols)
    rows, cols = np.divmod(key, max(n_var, 1))
    return csr_matrix((np.ones(len(key)), (rows, cols)), shape=(n_eq, n_var))


def _alternating(inc, start, match_eq, *, from_equations):
    """Equations (or variables) reachable by alternating paths from unmatched ones."""
    n_eq, n_var = inc.shape
    var_of_eq = match_eq
    eq_of_var = np.full(n_var, -1)
    for i, j in enumerate(var_of_eq):
        if j >= 0:
            eq_of_var[j] = i
    csc = inc.tocsc()
    seen = set(start)
    frontier = list(start)
    while frontier:
        nxt = []
        for k in frontier:
            if from_equations:  # equation -> its variables -> the equations matched to them
                for j in inc.indices[inc.indptr[k]:inc.indptr[k + 1]]:
                    i = eq_of_var[j]
                    if i >= 0 and i not in seen:
                        seen.add(i)
                        nxt.append(i)
            else:  # variable -> equations touching it -> the variables matched to them
                for i in csc.indices[csc.indptr[k]:csc.indptr[k + 1]]:
                    j = var_of_eq[i]
                    if j >= 0 and j not in seen:
                        seen.add(j)
                        nxt.append(j)
        frontier = nxt
    return sorted(seen)


def _list(items):
    items = list(items)
    text = "; ".join(items[:NAMES_IN_MESSAGES])
    if len(items) > NAMES_IN_MESSAGES:
        text += f"; ... ({len(items) - NAMES_IN_MESSAGES} more)"
    return text
