"""Traced equations reused across the instances of a component class.

Instances of one class whose parameters agree except in the values of runtime (float)
parameters trace to the same expression graphs up to the names of their leaves: a float
parameter is a parameter symbol while tracing unless the equations turn it into a number, and
then :class:`pvgraph.expr.ParameterTrace` records it as structural. So one instance is traced
(the template) and the others are built from its graphs by renaming the leaves (variables,
derivatives, modes and parameters, ``<template path>.<name>`` to ``<instance path>.<name>``),
which costs a fraction of running the component's Python again.

The key of a template is the class and the parameter values other than floats; the values of
the parameters the template read structurally must match too (a template per distinct set).
What the parameter contract does not cover turns templates off for the class, and its
instances are traced one by one:

- instance state besides the parameters and start values, a class overriding ``trace``,
  methods reading ``self.params`` or the component's path (by name, in their code);
- graphs with table look-ups (a table per instance) or runtime tables built from parameters;
- an instance that, traced for real, differs from the template renamed: the second instance
  of every template is traced and compared, node for node, before templates are used.

Event actions are closures of their component's trace; an instance built from a template
gets an action that traces its own component (once, when the event first fires) and runs
that trace's action.
"""

from __future__ import annotations

import copy
import keyword
import operator
import types

from pydantic import BaseModel

from . import expr as E
from .component import Component, EventSpec, Observed, ParameterInfo, ParamSymbols

#: names whose use in a component's methods turns templates off for its class
_INSTANCE_READS = frozenset(("params", "path", "_name", "_parent", "_start", "__dict__"))
_PLAIN_STATE = frozenset(("params", "_start", "_name", "_parent"))
_TEMPLATE_LEAVES = ("const", "sym", "der", "param", "time")


class _Traced:
    """What ``Component.trace`` returns as its second value, as far as the compiler reads it."""

    __slots__ = ("observed", "events")

    def __init__(self, observed, events):
        self.observed = observed
        self.events = events


class _RecordingParams(ParamSymbols):
    """Parameter symbols that log the parameters read, in the order first read."""

    __slots__ = ()

    def _leaf(self, name, value):
        E.active_trace().reads.setdefault(name, "leaf")
        return super()._leaf(name, value)

    def _array(self, name, value):
        E.active_trace().reads.setdefault(name, "array")
        return super()._array(name, value)


class Template:
    """The traced graphs of one instance and what it takes to rename them for another."""

    def __init__(self, comp, path, residuals, v, reads, structural, where, registry):
        self.path = path
        self.cls = type(comp)
        self.residuals = residuals
        self.observed = [(nm, ob.expr, ob.unit, ob.description) for nm, ob in v.observed.items()]
        self.events = [(ev.name, ev.condition, ev.direction, ev.action is None, ev.terminal,
                        ev.at_start) for ev in v.events]
        roots = list(residuals) + [ob[1] for ob in self.observed] + [ev[1] for ev in self.events]
        self.roots = roots
        self.order = E.postorder(roots)
        self.found = [E.leaves(r, ("sym", "der")) for r in residuals]
        # parameters read: (field path, kind, unit, description), in the order first read
        self.reads = [(registry[nm].field, kind, registry[nm].unit, registry[nm].description)
                      for nm, kind in reads.items()]
        suffix = f" in {where}"
        self.structural = []
        self.usable = True
        for nm, reason in structural.items():
            field = self._field(nm)
            if field is None or not reason.endswith(suffix):
                self.usable = False
                return
            self.structural.append((field, reason[:-len(suffix)]))
        self.values = {field: _value(comp.params, field) for field, _ in self.structural}
        self.keep: set[int] = set()   # nodes an instance shares with the template
        self.verified = False
        self._build = self._classes = None
        self.last_nodes = None   # the nodes of each residual built last, in post-order
        self.last_names = None   # (path, names) of the instance built last
        self.last_rows = None    # and its row_names
        for node in self.order:
            if node.op in ("interp", "interp_d") or (not node.args and
                                                     node.op not in _TEMPLATE_LEAVES):
                self.usable = False
                return

    def _field(self, name):
        head = self.path + "."
        return name[len(head):] if name.startswith(head) else None

    def matches(self, comp) -> bool:
        """True if ``comp``'s structurally read parameters have the template's values."""
        return all(_same(_value(comp.params, f), v) for f, v in self.values.items())

    def rename(self, path):
        head, n = self.path + ".", len(self.path)

        def name(nm):
            return path + nm[n:] if nm.startswith(head) else nm
        return name

    def _prepare(self):
        """The names an instance renames (by their tails after the template's path, in one
        list, so that each instance makes each name once) and where each use takes them."""
        head, n = self.path + ".", len(self.path)
        tails: dict[str, int] = {}

        def slot(nm):
            """(index of the renamed name, None) or (None, the name kept as it is)."""
            if not nm.startswith(head):
                return None, nm
            return tails.setdefault(nm[n:], len(tails)), None
        self._reads = [(slot(f"{self.path}.{field}")[0], field, unit, desc)
                       for field, _, unit, desc in self.reads]
        self._structural = [(slot(f"{self.path}.{field}")[0], how)
                            for field, how in self.structural]
        self._classes = []
        for r in list(self.residuals) + [ev[1] for ev in self.events]:
            names = {}
            for node in E.postorder([r]):
                if node.op in ("sym", "der", "param"):
                    names[node.value] = None
            self._classes.append([slot(nm) for nm in names])
        self._slots = {nm: slot(nm) for nm in
                       {node.value for node in self.order if node.op in ("sym", "der", "param")}}
        self._tails = list(tails)

    def instantiate(self, comp, path, registry, trace, where):
        """``(residuals, traced, found)`` of ``comp`` at ``path`` from the template.

        Registers the parameters read (in ``registry``), their leaves and the structural ones
        (in ``trace``) as the trace of ``comp`` would.
        """
        if self._build is None:
            self._prepare()
            self._build = self._builder()
        residuals, obs_exprs, conditions, self.last_nodes, found, self.last_rows, names = \
            self._build(path, trace, registry, comp.params)
        self.last_names = (path, names)
        for k, how in self._structural:
            trace.structural.setdefault(names[k], f"{how} in {where}")
        observed = {nm: Observed(e, unit, desc)
                    for (nm, _, unit, desc), e in zip(self.observed, obs_exprs)}
        events = []
        for k, ((ev_name, _, direction, no_action, terminal, at_start), cond) in \
                enumerate(zip(self.events, conditions)):
            action = None if no_action else _LazyAction(comp, path, k)
            events.append(EventSpec(ev_name, cond, direction, action, terminal, at_start))
        return residuals, _Traced(observed, events), found

    def row_names(self, path):
        """Per residual, then per event condition, the distinct names of its variable,
        derivative and parameter leaves (in the order first reached) for the instance at
        ``path``: two instances' residuals are the same graph with these names exchanged."""
        if self._classes is None:
            self._prepare()
        if self.last_names is not None and self.last_names[0] == path:
            return self.last_rows
        else:
            names = [path + tail for tail in self._tails]
        return [tuple([names[k] if k is not None else nm for k, nm in cl])
                for cl in self._classes]

    def _builder(self):
        """A generated function ``(path, trace, registry, params) -> (residuals, observed
        expressions, event conditions, each residual's nodes in post-order, the names each
        residual reads (:func:`read_sets`), the row names of :meth:`row_names`, the
        instance's names)`` building the template's graphs for an instance: its names (the
        template's tails after ``path``, see :meth:`_prepare`), the registry entries of the
        parameters read (in the order first read, as :class:`ParameterInfo`, values from
        ``params``), then one statement per node, leaves named from the instance's ``names``
        (see :meth:`_prepare`; parameter leaves shared per name through ``trace``, as
        :meth:`pvgraph.expr.ParameterTrace.leaf` makes them; constants are the template's
        nodes, shared by all instances: nothing downstream tells constant nodes apart by
        identity, only by value)."""
        num: dict[int, str] = {}
        kept = []
        lines = ["def build(path, trace, registry, P):",
                 "    N = [" + "".join(f"path + {tail!r}, " for tail in self._tails) + "]",
                 "    LV = trace._leaves",
                 "    VS = trace.values"]
        for k, field, unit, desc in self._reads:
            parts = field.split(".")
            attr = "".join("." + part for part in parts) if all(
                part.isidentifier() and not keyword.iskeyword(part) for part in parts) \
                else None
            value = f"P{attr}" if attr is not None else f"V(P, {field!r})"
            lines += [f"    i = registry.get(N[{k}])",
                      "    if i is None:",
                      f"        i = registry[N[{k}]] = PI(N[{k}], {value}, {unit!r}, "
                      f"{desc!r}, path, {field!r})",
                      "    i.in_equations = True"]

        def named(nm):
            k, kept_name = self._slots[nm]
            return f"N[{k}]" if k is not None else repr(kept_name)
        for node in self.order:
            var = num[id(node)] = f"x{len(num)}"
            if id(node) in self.keep:
                num[id(node)] = f"K[{len(kept)}]"
                kept.append(node)
                continue
            op = node.op
            if node.args:
                args = "".join(num[id(a)] + ", " for a in node.args)
                value = "" if node.value is None else f", K[{len(kept)}]"
                if node.value is not None:      # an operation's payload (not templated now)
                    kept.append(node.value)
                lines.append(f"    {var} = X({op!r}, ({args}){value})")
            elif op in ("sym", "der"):
                lines.append(f"    {var} = X({op!r}, (), {named(node.value)})")
            elif op == "param":
                full = named(node.value)
                lines += [f"    {var} = LV.get({full})",
                          f"    if {var} is None:",
                          f"        {var} = LV[{full}] = X('param', (), {full})",
                          f"        VS.setdefault({full}, registry[{full}].value)"]
            elif op == "const":     # a number: the template's node itself (never renamed)
                num[id(node)] = f"K[{len(kept)}]"
                kept.append(node)
            else:
                lines.append(f"    {var} = X({op!r}, (), None)")

        def tup(roots):
            return "(" + "".join(num[id(r)] + ", " for r in roots) + ")"
        # and each residual's nodes in its own post-order (for substituting into it later)
        nodes = "(" + "".join("[" + ", ".join(num[id(n)] for n in E.postorder([r])) + "], "
                              for r in self.residuals) + ")"
        # the names of the variables and derivatives each residual reads (two sets, see
        # read_sets) and the names of each row (see row_names), as literals

        def names_set(lv, kind):
            items = [named(nm) for op, nm in lv if op == kind]
            return "{" + ", ".join(items) + "}" if items else "set()"
        found = "[" + "".join(f"({names_set(lv, 'sym')}, {names_set(lv, 'der')}), "
                              for lv in self.found) + "]"
        rows = "[" + "".join("(" + "".join(
            (f"N[{k}], " if k is not None else f"{nm!r}, ") for k, nm in cl) + "), "
            for cl in self._classes) + "]"
        lines.append(f"    return ({tup(self.residuals)}, {tup([ob[1] for ob in self.observed])}, "
                     f"{tup([ev[1] for ev in self.events])}, {nodes}, {found}, {rows}, N)")
        namespace = {"X": E.Expr, "K": kept, "PI": ParameterInfo, "V": _value}
        exec(compile("\n".join(lines), f"<template of {self.cls.__name__}>", "exec"),
             namespace)  # noqa: S102 - generated from the template's graph
        return namespace["build"]

    def verify(self, path, residuals, v, registry, reads, structural, where) -> bool:
        """True if the real trace of an instance at ``path`` (its residuals, symbols,
        parameters read and made structural) is the template renamed; notes shared nodes."""
        head = path + "."
        if [(registry[nm].field, kind, registry[nm].unit, registry[nm].description)
                for nm, kind in reads.items()] != self.reads:
            return False
        if any(not nm.startswith(head) for nm in reads):
            return False
        if sorted((nm[len(head):], why) for nm, why in structural.items()) != sorted(
                (field, f"{how} in {where}") for field, how in self.structural):
            return False
        if list(v.observed) != [ob[0] for ob in self.observed] or len(v.events) != len(
                self.events) or len(residuals) != len(self.residuals):
            return False
        for (nm, _, unit, desc), ob in zip(self.observed, v.observed.values()):
            if (unit, desc) != (ob.unit, ob.description):
                return False
        for (ev_name, _, direction, no_action, terminal, at_start), ev in zip(self.events,
                                                                              v.events):
            if (ev_name, direction, no_action, terminal, at_start) != (
                    ev.name, ev.direction, ev.action is None, ev.terminal, ev.at_start):
                return False
        real = list(residuals) + [ob.expr for ob in v.observed.values()] + \
            [ev.condition for ev in v.events]
        # the real graphs walked alongside the template's: the same nodes, leaves renamed
        # (parameter leaves are shared per name), each template node one real node and back
        name = self.rename(path)
        pair: dict[int, E.Expr] = {}
        back: dict[int, int] = {}
        shared = set()
        stack = list(zip(self.roots, real))
        while stack:
            t, r = stack.pop()
            if id(t) in pair:
                if pair[id(t)] is not r:
                    return False
                continue
            if back.get(id(r), id(t)) != id(t):
                return False
            pair[id(t)] = r
            back[id(r)] = id(t)
            if r is t:
                shared.add(id(t))
            if t.op != r.op or len(t.args) != len(r.args):
                return False
            if not t.args:
                if t.op in ("sym", "der", "param"):
                    if not isinstance(r.value, str) or name(t.value) != r.value:
                        return False
                elif t.op == "const":
                    if repr(t.value) != repr(r.value):
                        return False
                elif t.value != r.value:
                    return False
                continue
            if t.value is not r.value and t.value != r.value:
                return False
            stack.extend(zip(t.args, r.args))
        # a node the two traces share (a module constant, E.ZERO) is shared by every instance
        self.keep = {k for k in shared
                     if not pair[k].args or all(id(a) in shared for a in pair[k].args)}
        return True


class _LazyAction:
    """The event action of a component built from a template: its own trace's action."""

    __slots__ = ("comp", "params", "path", "k", "fn")

    def __init__(self, comp, path, k):
        self.comp = comp
        self.params = comp.params     # those of the compilation
        self.path = path
        self.k = k
        self.fn = None

    def __call__(self, modes):
        if self.fn is None:
            comp = copy.copy(self.comp)
            comp.params = self.params
            with E.ParameterTrace({}):
                _, v = comp.trace(self.path, {})
            self.fn = v.events[self.k].action
        return self.fn(modes)


class Templates:
    """The templates of one compilation, by class and non-float parameter values."""

    def __init__(self):
        self.by_key: dict = {}
        self.off: set = set()     # classes traced instance by instance
        self._code_ok: dict = {}
        #: ``(template, path)`` when the residuals :meth:`trace` returned last are those of
        #: the template renamed for ``path`` (see :meth:`Template.row_names`), else None
        self.last = None

    def trace(self, comp, path, registry, trace):
        """``(residuals, traced, found)`` of ``comp``: built from a template or traced
        (``found``: per residual, the names it reads, as :func:`read_sets` gives them)."""
        self.last = None
        cls = type(comp)
        key = None
        if cls not in self.off and self._class_ok(cls) and \
                _PLAIN_STATE.issuperset(vars(comp)):
            key = _shape_key(comp.params)
        if key is None:
            return _plain(comp, path, registry)
        variants = self.by_key.setdefault((cls, key), [])
        where = trace.where
        for tpl in variants:
            if tpl.matches(comp):
                if tpl.verified:
                    self.last = (tpl, path)
                    return tpl.instantiate(comp, path, registry, trace, where)
                residuals, v, reads, structural, tables = _record(comp, path, registry, trace)
                if not tables and tpl.verify(path, residuals, v, registry, reads, structural,
                                             where):
                    tpl.verified = True
                else:
                    self.off.add(cls)
                return residuals, v, [read_sets(r) for r in residuals]
        residuals, v, reads, structural, tables = _record(comp, path, registry, trace)
        tpl = Template(comp, path, residuals, v, reads, structural, where, registry)
        if tpl.usable and not tables:
            variants.append(tpl)
            self.last = (tpl, path)
        else:
            self.off.add(cls)
        return residuals, v, [_split(lv) for lv in tpl.found]

    def _class_ok(self, cls) -> bool:
        ok = self._code_ok.get(cls)
        if ok is None:
            ok = self._code_ok[cls] = cls.trace is Component.trace and not _reads_instance(cls)
        return ok


def _record(comp, path, registry, trace):
    """``Component.trace`` of ``comp``, with the parameters it reads (in the order first
    read), the parameters it made structural and whether it built runtime tables."""
    from .component import Symbols
    from .errors import CircuitError
    n_tables = len(trace.tables)
    before = set(trace.structural)
    trace.reads = {}   # the parameters read, logged by _RecordingParams
    try:
        v = Symbols(comp, path)
        residuals = comp.equations(v, _RecordingParams(comp.params, "", path, registry))
        reads = trace.reads
    finally:
        del trace.reads
    if not isinstance(residuals, (list, tuple)):
        raise CircuitError(f"{type(comp).__name__}.equations must return a list of residual "
                           f"expressions, got {type(residuals).__name__}")
    structural = {nm: why for nm, why in trace.structural.items() if nm not in before}
    return ([E.as_expr(r) for r in residuals], v, reads, structural,
            len(trace.tables) != n_tables)


def _plain(comp, path, registry):
    residuals, v = comp.trace(path, registry)
    return residuals, v, [read_sets(r) for r in residuals]


def read_sets(row) -> tuple[set, set]:
    """``(names of the variables, names of the derivatives)`` that ``row`` reads."""
    return _split(E.leaves(row, ("sym", "der")))


def _split(leaves) -> tuple[set, set]:
    return {nm for op, nm in leaves if op == "sym"}, {nm for op, nm in leaves if op == "der"}


def _reads_instance(cls) -> bool:
    """True if a method of ``cls`` (below Component) names instance state in its code."""
    for klass in cls.__mro__:
        if klass is Component or klass is object:
            break
        for attr in vars(klass).values():
            fn = attr.__func__ if isinstance(attr, (staticmethod, classmethod)) else attr
            if isinstance(fn, property):
                fn = fn.fget
            code = getattr(fn, "__code__", None)
            if code is not None and _names(code) & _INSTANCE_READS:
                return True
    return False


def _names(code: types.CodeType) -> set:
    out = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            out |= _names(c)
    return out


def _value(params, field):
    value = params
    for part in field.split("."):
        value = getattr(value, part)
    return value


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return repr(a) == repr(b)
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


_FIELD_NAMES: dict = {}   # model class -> (field names, their values getter, all-float key)
_FLOAT_ONLY = {float}


def _shape_key(value):
    """Parameter values with floats (and tuples of floats) as placeholders; None where a value
    is of another type."""
    if type(value) is float:
        return float
    if isinstance(value, BaseModel):
        cls = type(value)
        got = _FIELD_NAMES.get(cls)
        if got is None:
            names = tuple(cls.model_fields)
            # the values of all fields at once (a tuple), and the key where all are floats
            get = operator.attrgetter(*names) if len(names) > 1 else \
                (lambda v: tuple(getattr(v, nm) for nm in names))
            got = _FIELD_NAMES[cls] = (names, get, (cls,) + (float,) * len(names))
        _, get, all_float = got
        items = get(value)
        if set(map(type, items)) == _FLOAT_ONLY:
            return all_float
        out = [cls]
        for item in items:
            kind = type(item)
            if kind is float:
                out.append(float)
            elif item is None or kind is bool or kind is int or kind is str:
                out.append((kind, item))    # as below, without the call
            else:
                item = _shape_key(item)
                if item is None:
                    return None
                out.append(item)
        return tuple(out)
    if isinstance(value, float):
        return float
    if isinstance(value, (tuple, list)):
        items = tuple(_shape_key(x) for x in value)
        return None if any(x is None for x in items) else (type(value), items)
    if value is None or isinstance(value, (bool, int, str)):
        return (type(value), value)
    return None
