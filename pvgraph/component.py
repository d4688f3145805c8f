"""Domains, ports, variables and the component base class.

Sign convention (stated once, obeyed everywhere): the through variable of a port is positive
*into* the component. A hydraulic port carries pressure ``p`` [Pa, gauge] and volume flow ``q``
[m^3/s] from the connection node into the component; a mechanical translational port carries
position ``x`` [m] and force ``f`` [N], the force the node exerts on the component in the +x
direction. Signal ports are causal: one output drives any number of inputs.

A component declares its parameters (a frozen pydantic model), ports, internal variables and
discrete modes, and writes its equations as residuals, acausally::

    class LaminarOrifice(Component):
        Params = LaminarOrificeParams
        ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

        def equations(self, v, p):
            q = v.observe("q", p.K * (v.a.p - v.b.p), "m^3/s", "flow a -> b")
            return [v.a.q - q, v.a.q + v.b.q]

``equations`` runs once, at compile time, with symbols (see :mod:`pvgraph.expr`). ``p`` is then a
:class:`ParamSymbols` view of the parameter model: its numeric fields are parameter symbols, so
the compiled system takes their values at run time (see :class:`pvgraph.expr.ParameterTrace` for
what makes a parameter structural).
"""

from __future__ import annotations

import difflib
import functools
import inspect
import math
import re
import types
from dataclasses import dataclass
import typing
from typing import Any, Callable, ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from . import expr as E
from .errors import CircuitError, ParameterError

__all__ = [
    "Domain", "HYDRAULIC", "MECHANICAL", "SIGNAL", "Port", "Hydraulic", "Mechanical",
    "SignalIn", "SignalOut", "Variable", "Params", "NoParams", "Component", "PortRef", "der",
    "EventSpec", "Observed", "ParamSymbols", "ParameterInfo",
]


@dataclass(frozen=True)
class Domain:
    """A physical domain: the across/through variable pair of its ports."""

    name: str
    across: str
    across_unit: str
    across_nominal: float
    through: str | None
    through_unit: str | None
    through_nominal: float | None


HYDRAULIC = Domain("hydraulic", "p", "Pa", 1e6, "q", "m^3/s", 1e-4)
MECHANICAL = Domain("mechanical", "x", "m", 1e-3, "f", "N", 10.0)
SIGNAL = Domain("signal", "u", "", 1.0, None, None, None)


@dataclass(frozen=True)
class Port:
    """A port declaration: its domain, a description and, for signals, its causality."""

    domain: Domain
    description: str = ""
    causality: str | None = None  # "input" or "output" for signal ports
    unit: str | None = None
    nominal: float | None = None

    @property
    def across_unit(self) -> str:
        return self.unit if self.unit is not None else self.domain.across_unit

    @property
    def across_nominal(self) -> float:
        return self.nominal if self.nominal is not None else self.domain.across_nominal


def Hydraulic(description: str = "") -> Port:
    """A hydraulic port: pressure ``p`` [Pa], flow ``q`` [m^3/s] positive into the component."""
    return Port(HYDRAULIC, description)


def Mechanical(description: str = "") -> Port:
    """A mechanical translational port: position ``x`` [m], force ``f`` [N] into the component."""
    return Port(MECHANICAL, description)


def SignalIn(description: str = "", unit: str = "", nominal: float = 1.0) -> Port:
    """A causal signal input, driven by exactly one output."""
    return Port(SIGNAL, description, "input", unit, nominal)


def SignalOut(description: str = "", unit: str = "", nominal: float = 1.0) -> Port:
    """A causal signal output; drives any number of inputs."""
    return Port(SIGNAL, description, "output", unit, nominal)


@dataclass(frozen=True)
class Variable:
    """An internal variable: unit, start value (or guess), nominal magnitude, description.

    A variable whose derivative appears in an equation is differential; its start value is its
    initial condition. Otherwise it is algebraic and its start value is the first Newton guess.
    ``start`` may be a callable of the parameters, e.g. ``lambda p: p.x0``.
    """

    unit: str = ""
    start: float | Callable[[Any], float] = 0.0
    nominal: float = 1.0
    description: str = ""


class Params(BaseModel):
    """Base of parameter models: frozen, no unknown fields, finite numbers only.

    A number is SI (or whatever unit the field declares in brackets in its description). A
    quantity with a unit, ``"150 bar"``, ``"0.5 L"``, ``"10 L/min"`` or a pint Quantity, is
    converted to the declared unit; a quantity of another dimension, a bool, or a magnitude
    no computation survives (below 1e-300 or above 1e300) is refused, naming the field.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _quantities(cls, value, info):
        if type(value) is float:                     # the common case: an SI number
            if value != 0.0 and not _PARAM_TINY <= abs(value) <= _PARAM_HUGE and \
                    math.isfinite(value):
                return _param_number(value, _field_unit(cls, info.field_name)[1],
                                     info.field_name)
            return value
        name = info.field_name
        takes_float, unit = _field_unit(cls, name)
        if not takes_float:
            if isinstance(value, bool) and not _takes_bool(cls.model_fields[name].annotation):
                # pydantic's lax mode would read True as 1 (Literal[1, 2], int)
                choices = typing.get_args(cls.model_fields[name].annotation)
                takes = " or ".join(map(repr, choices)) if all(
                    isinstance(c, (int, str)) for c in choices) and choices else "a number"
                raise ValueError(f"{value!r} is a bool; {name} takes {takes}")
            return value
        if isinstance(value, (list, tuple)):
            if all(type(v) is float and (v == 0.0 or _PARAM_TINY <= abs(v) <= _PARAM_HUGE)
                   for v in value):
                return value
            return type(value)(_param_number(v, unit, f"{name}[{k}]") for k, v in enumerate(value))
        if hasattr(value, "magnitude") and not isinstance(value, (int, float)) and \
                getattr(getattr(value, "magnitude", None), "ndim", 0) == 1:
            return tuple(_param_number(v, unit, f"{name}[{k}]") for k, v in enumerate(value))
        return _param_number(value, unit, name)


_FIELD_UNITS: dict = {}


def _field_unit(cls, name) -> tuple[bool, str | None]:
    """(the field takes floats, the unit its description declares), cached per class."""
    key = (cls, name)
    if key not in _FIELD_UNITS:
        from .units import declared_unit
        info = cls.model_fields.get(name)
        unit = declared_unit(info.description) if info is not None else None
        if unit is None and info is not None and "[unit of " in (info.description or ""):
            unit = SIGNAL_UNIT      # a signal's value: any quantity, in SI
        _FIELD_UNITS[key] = (info is not None and _takes_float(info.annotation), unit)
    return _FIELD_UNITS[key]


#: the unit of a field in a signal's units (``[unit of y]``): signals carry SI values, so a
#: quantity of any dimension is taken in SI (``Step(height="100 bar")`` is 1e7)
SIGNAL_UNIT = "SI of the signal"


#: [-] magnitudes outside this range overflow or underflow in the compiled equations
_PARAM_TINY, _PARAM_HUGE = 1e-300, 1e300


def _takes_float(annotation) -> bool:
    """True when a field's annotation admits floats (float, float | None, tuple[float, ...])."""
    if annotation is float:
        return True
    return any(_takes_float(a) for a in getattr(annotation, "__args__", ()) if a is not Ellipsis)


def _takes_bool(annotation) -> bool:
    """True when a field's annotation admits a bool (bool, bool | None, Any)."""
    if annotation is bool or annotation is Any:
        return True
    return any(_takes_bool(a) for a in getattr(annotation, "__args__", ()) if isinstance(a, type)
               or getattr(a, "__args__", None))


def _param_number(value, unit, name):
    if isinstance(value, bool):
        raise ValueError(f"{value!r} is a bool, not a number{f' [{unit}]' if unit else ''}")
    if isinstance(value, str) or hasattr(value, "dimensionality"):
        if unit is None and not (isinstance(value, str) and _is_plain_number(value)):
            raise ValueError(f"{value!r}: {name} declares no unit to convert to; give a plain "
                             f"number")
        if unit == SIGNAL_UNIT:
            from .units import to_si
            value = to_si(value, name)
        else:
            from .units import to_unit
            value = to_unit(value, unit or "1", name)
    if isinstance(value, (int, float)) and math.isfinite(value) and value != 0 and \
            not _PARAM_TINY <= abs(value) <= _PARAM_HUGE:
        raise ValueError(f"{value!r} is outside the magnitudes a model can compute with "
                         f"({_PARAM_TINY:g} .. {_PARAM_HUGE:g}); check its unit"
                         f"{f' [{unit}]' if unit else ''}")
    return value


def _is_plain_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def check_table(x, y, xname: str, yname: str, *, y_range=None, x_range=None) -> None:
    """Check a lookup table's points for a parameter validator: ``x`` and ``y`` of one length
    of at least 2, ``x`` strictly increasing, every value finite (and ``y``, ``x`` within
    ``y_range``, ``x_range``, ``(low, high)`` pairs, if given). Raises ``ValueError`` naming
    the field, which pydantic reports with the component (``invalid parameters for Pump:
    ...``)."""
    if len(x) != len(y) or len(x) < 2:
        raise ValueError(f"{xname} ({len(x)} points) and {yname} ({len(y)} points) must have "
                         f"the same length >= 2")
    for name, values in ((xname, x), (yname, y)):
        bad = [v for v in values if not math.isfinite(v)]
        if bad:
            raise ValueError(f"{name} holds {bad[0]!r}: every point must be a finite number")
    steps = [b - a for a, b in zip(x, x[1:])]
    if min(steps) <= 0.0:
        k = steps.index(min(steps))
        raise ValueError(f"{xname} must be strictly increasing: {x[k]!r} is followed by "
                         f"{x[k + 1]!r} (point {k + 2})")
    for name, values, bounds in ((xname, x, x_range), (yname, y, y_range)):
        if bounds is None:
            continue
        low, high = bounds
        out = [v for v in values if not low <= v <= high]
        if out:
            raise ValueError(f"{name} holds {out[0]!r}: its values must lie in "
                             f"[{low:g}, {high:g}]")


class NoParams(Params):
    """A component without parameters."""


@dataclass
class Observed:
    """A derived output: an expression evaluated on a solution after the run."""

    expr: E.Expr
    unit: str
    description: str


@dataclass
class EventSpec:
    """A zero-crossing function with the mode switch that happens at the crossing.

    ``action(modes)`` receives a mapping of the component's own mode names to values and sets
    new values; after it the solver recomputes consistent initial values and restarts.
    ``at_start``: the crossing is due already when the condition is at or past zero in its
    direction at the start of a run (a switch scheduled at or before the start time); the
    action is then applied before integrating (:meth:`pvgraph.system.System.apply_start_events`).
    """

    name: str
    condition: E.Expr
    direction: int = 0
    action: Callable[[Any], None] | None = None
    terminal: bool = False
    at_start: bool = False


def der(e) -> E.Expr:
    """Time derivative of an expression of variables (linear in the derivatives)."""
    e = E.as_expr(e)
    if e.op == "sym":
        return E.Expr("der", (), e.value)
    if e.op == "const":
        return E.ZERO
    total = E.ZERO
    for op, name in E.leaves(e, ("sym", "time", "der", "mode")):
        if op == "der":
            raise TypeError(f"second derivative of {name!r}: introduce a velocity variable")
        if op == "mode":
            continue
        partial = E.differentiate(e, (op, name))
        total = total + partial * (E.ONE if op == "time" else E.Expr("der", (), name))
    return total


class PortRef:
    """A reference to one port of a component or circuit, as used in ``connect``."""

    __slots__ = ("owner", "name")

    def __init__(self, owner, name: str):
        self.owner = owner
        self.name = name

    @property
    def port(self) -> Port:
        return self.owner._port_spec(self.name)

    def path(self) -> str:
        return f"{self.owner.path}.{self.name}"

    def __repr__(self):
        return f"<port {self.path()}>"


class _PortSymbols:
    """The symbols of one port during tracing: ``.p``/``.q`` or ``.x``/``.f``."""

    def __init__(self, prefix: str, port: Port):
        d = port.domain
        self._prefix, self._domain = prefix, d
        setattr(self, d.across, E.Expr("sym", (), f"{prefix}.{d.across}"))
        if d.through:
            setattr(self, d.through, E.Expr("sym", (), f"{prefix}.{d.through}"))

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        d = self._domain
        has = " and ".join(repr(v) for v in (d.across, d.through) if v)
        raise AttributeError(f"port {self._prefix!r} is {d.name}: its variables are {has}, "
                             f"not {name!r}")


class Symbols:
    """What ``equations(v, p)`` receives as ``v``: the component's variables as symbols."""

    def __init__(self, component: "Component", prefix: str):
        self._component = component
        self._prefix = prefix
        self.t = E.Expr("time")
        self.observed: dict[str, Observed] = {}
        self.events: list[EventSpec] = []
        for name, port in component.ports.items():
            if port.domain is SIGNAL:
                object.__setattr__(self, name, E.Expr("sym", (), f"{prefix}.{name}"))
            else:
                object.__setattr__(self, name, _PortSymbols(f"{prefix}.{name}", port))
        for name in component.variables:
            object.__setattr__(self, name, E.Expr("sym", (), f"{prefix}.{name}"))

    def __getattr__(self, name):
        comp = self.__dict__.get("_component")
        raise AttributeError(
            f"{type(comp).__name__} at {self.__dict__.get('_prefix')!r} has no port or variable "
            f"{name!r}; ports: {sorted(comp.ports)}, variables: {sorted(comp.variables)}")

    def mode(self, name: str) -> E.Expr:
        """The current value of one of the component's discrete modes."""
        if name not in self._component.modes:
            raise CircuitError(f"{type(self._component).__name__} at {self._prefix!r} has no "
                               f"mode {name!r}; declare it in `modes`")
        return E.Expr("sym", (), f"{self._prefix}.#{name}")

    def observe(self, name: str, expression, unit: str = "", description: str = "") -> E.Expr:
        """Register a derived output (available in results as ``<component>.<name>``)."""
        expression = E.as_expr(expression)
        self.observed[name] = Observed(expression, unit, description)
        return expression

    def event(self, name: str, condition, *, direction: int = 0,
              action: Callable[[Any], None] | None = None, terminal: bool = False,
              at_start: bool = False) -> None:
        """Declare a zero-crossing ``condition`` (an expression) and the mode switch at it.

        The solver finds an event where the condition changes sign between the ends of a step
        (``direction`` +1: rising only, -1: falling only, 0: either), as IDA's root finding
        does: a condition that rises and falls again within one step is not seen (write a
        periodic switch on the time of its next edge, as ``Pulse`` does, or give the run a
        ``max_step``), and a condition that starts at or past its zero fires only at its next
        crossing. ``at_start=True``: a run that starts with the condition at or past zero in
        its direction begins with the action applied: a switch scheduled in time (``t -
        t_switch``, ``direction=1``), or a state threshold a run may start at (a relay whose
        pump should switch on at once when it starts at or below its lower pressure).
        """
        self.events.append(EventSpec(name, E.as_expr(condition), direction, action, terminal,
                                     at_start))


@dataclass
class ParameterInfo:
    """A runtime parameter of a compiled system: ``owner.field`` of a component's model."""

    name: str
    value: float
    unit: str
    description: str
    owner: str          # component path
    field: str          # dotted field path inside the component's parameter model
    structural: str = ""   # why its value is baked into the compiled code ("" if it is not)
    in_equations: bool = False  # read by the equations (a symbol of the compiled code)
    in_starts: bool = False     # read by the start values


_UNIT = re.compile(r"\[([^\]]*)\]")
_META: dict = {}     # (model class, field) -> (unit, description)
_FIELDS: dict = {}   # model class -> its fields
_STATIC: dict = {}   # (model class, attribute) -> the class attribute, for views


def _field_meta(model: BaseModel, name: str) -> tuple[str, str]:
    key = (type(model), name)
    meta = _META.get(key)
    if meta is None:
        desc = type(model).model_fields[name].description or ""
        m = _UNIT.search(desc)
        meta = _META[key] = (m.group(1) if m else ""), desc
    return meta


def _fields(cls) -> dict:
    fields = _FIELDS.get(cls)
    if fields is None:
        fields = _FIELDS[cls] = dict(cls.model_fields)
    return fields


class _ModelView:
    """Attribute access on a parameter model that reports every numeric field read."""

    __slots__ = ("_model", "_prefix", "_owner", "_registry")

    def __init__(self, model, prefix, owner, registry):
        object.__setattr__(self, "_model", model)
        object.__setattr__(self, "_prefix", prefix)
        object.__setattr__(self, "_owner", owner)
        object.__setattr__(self, "_registry", registry)

    def _leaf(self, name, value):
        raise NotImplementedError

    def _array(self, name, value):
        return value

    def __getattr__(self, name):
        model = self._model
        cls = type(model)
        if name in _fields(cls):
            value = getattr(model, name)
            if isinstance(value, float):
                full = f"{self._owner}.{self._prefix}{name}"
                if full not in self._registry:
                    unit, desc = _field_meta(model, name)
                    self._registry[full] = ParameterInfo(full, value, unit, desc, self._owner,
                                                         self._prefix + name)
                return self._leaf(full, value)
            if isinstance(value, BaseModel):
                return type(self)(value, f"{self._prefix}{name}.", self._owner, self._registry)
            if isinstance(value, tuple) and value and all(isinstance(x, float) for x in value):
                full = f"{self._owner}.{self._prefix}{name}"
                if full not in self._registry:
                    unit, desc = _field_meta(model, name)
                    self._registry[full] = ParameterInfo(full, value, unit, desc, self._owner,
                                                         self._prefix + name)
                return self._array(full, value)
            return value
        key = (cls, name)
        if key in _STATIC:
            attr = _STATIC[key]
        else:
            attr = _STATIC[key] = inspect.getattr_static(cls, name, None)
        if isinstance(attr, property):
            return attr.fget(self)
        if isinstance(attr, functools.cached_property):
            return attr.func(self)
        if isinstance(attr, types.FunctionType):
            return types.MethodType(attr, self)
        if attr is None and not hasattr(model, name):
            close = difflib.get_close_matches(name, list(_fields(cls)), n=3)
            hint = f"; close: {', '.join(close)}" if close else ""
            raise AttributeError(
                f"{self._owner}: its parameters ({cls.__name__}) have no field {name!r}"
                f"{hint}. Declare it in the Params class, e.g. "
                f"{name}: float = Field(..., description='... [unit]')")
        return getattr(model, name)

    def __setattr__(self, name, value):
        raise AttributeError("parameters are read-only inside equations")

    def __repr__(self):
        return f"<parameters of {self._owner}: {type(self._model).__name__}>"


class ParamSymbols(_ModelView):
    """What ``equations(v, p)`` receives as ``p`` when compiled: numeric fields are symbols.

    ``p.A`` is the parameter leaf ``<component>.A`` (see :mod:`pvgraph.expr`); other fields
    (strings, integers, tuples, ``None``) and nested models read as usual; properties and methods
    of the model run on this view, so derived quantities stay symbolic.
    """

    __slots__ = ()

    def _leaf(self, name, value):
        self._registry[name].in_equations = True
        trace = E.active_trace()
        if trace is not None:
            return trace.leaf(name, value)
        return E.Expr("param", (), name)

    def _array(self, name, value):
        self._registry[name].in_equations = True
        return E.ParamValues(value, name)


class _StartView(_ModelView):
    """The parameters as numbers, noting which ones the start values read."""

    __slots__ = ()

    def _leaf(self, name, value):
        self._registry[name].in_starts = True
        return value

    def _array(self, name, value):
        self._registry[name].in_starts = True
        return value


class Component:
    """Base class of every component.

    Subclasses set ``Params`` (a :class:`Params` model), ``ports``, ``variables`` and ``modes``
    and implement ``equations(v, p)`` returning the list of residual expressions. Build one with
    keyword parameters, ``Orifice(A=mm2(2.2))``, or a ready model, ``Orifice(params)``. Start
    values may be overridden per instance: ``VolumeNode(V=..., start={"port.p": bar(10)})``.
    """

    Params: ClassVar[type[Params]] = NoParams
    ports: ClassVar[dict[str, Port]] = {}
    variables: ClassVar[dict[str, Variable]] = {}
    modes: ClassVar[dict[str, float]] = {}

    def __init__(self, params: Params | None = None, *, start: dict[str, float] | None = None,
                 **kwargs):
        cls = type(self)
        if params is not None and kwargs:
            raise ParameterError(f"{cls.__name__}: give either a parameter model or keyword "
                                 f"parameters, not both")
        if params is None:
            try:
                params = cls.Params(**kwargs)
            except ValidationError as exc:
                raise ParameterError(_describe_validation(
                    cls.__name__, exc, list(cls.Params.model_fields), kwargs,
                    cls.Params)) from None
        elif not isinstance(params, cls.Params):
            raise ParameterError(f"{cls.__name__} takes parameters of type {cls.Params.__name__}, "
                                 f"got {type(params).__name__}")
        self.params = params
        self._start = dict(start or {})
        self._name: str | None = None
        self._parent = None
        known = set(cls.variables) | {f"{n}.{pt.domain.across}" for n, pt in cls.ports.items()}
        known |= {n for n, pt in cls.ports.items() if pt.domain is SIGNAL}
        for key in self._start:
            if key not in known:
                raise CircuitError(f"{cls.__name__}: start value for unknown variable {key!r}; "
                                   f"known: {sorted(known)}")
            self._start[key] = _start_number(cls, key, self._start[key])

    # interface the subclass implements -------------------------------------------------------
    def equations(self, v: Symbols, p: Params) -> list:
        """Residual expressions; zero when the component's physics holds."""
        raise NotImplementedError(f"{type(self).__name__} does not define equations()")

    def starts(self, p: Params) -> dict[str, float]:
        """Start values that depend on the parameters (override in subclasses)."""
        return {}

    # framework side ----------------------------------------------------------------------------
    @property
    def path(self) -> str:
        if self._name is None:
            return type(self).__name__
        parent = self._parent.path if self._parent is not None and self._parent._parent is not None \
            else None
        return f"{parent}.{self._name}" if parent else self._name

    def _port_spec(self, name: str) -> Port:
        try:
            return type(self).ports[name]
        except KeyError:
            raise CircuitError(_unknown_port_message(self, name, type(self).ports)) from None

    def __getattr__(self, name):
        # reached for a missing attribute only: a private one, or a property whose getter
        # failed (a component whose parameters were refused has no name or parameters yet)
        if name.startswith("_") or isinstance(getattr(type(self), name, None), property):
            raise AttributeError(name)
        ports = type(self).ports
        if name in ports:
            return PortRef(self, name)
        raise AttributeError(_unknown_port_message(self, name, ports))

    def start_values(self) -> dict[str, float]:
        """All start values of this instance: declared, parameter-derived, then overrides."""
        values = {}
        for name, var in type(self).variables.items():
            values[name] = var.start(self.params) if callable(var.start) else var.start
        values.update(self.starts(self.params))
        values.update(self._start)
        return values

    def start_values_traced(self, prefix: str, registry: dict) -> dict[str, float]:
        """:meth:`start_values`, recording the parameters read in ``registry``."""
        view = _StartView(self.params, "", prefix, registry)
        values = {}
        for name, var in type(self).variables.items():
            values[name] = var.start(view) if callable(var.start) else var.start
        values.update(self.starts(view))
        values.update(self._start)
        return values

    def trace(self, prefix: str, registry: dict | None = None):
        """Run ``equations`` with symbols; return (residuals, symbols).

        With ``registry`` (a dict), the numeric parameters are parameter symbols named
        ``<prefix>.<field>`` and each one read is entered in ``registry`` as a
        :class:`ParameterInfo`; without it they are plain numbers.
        """
        v = Symbols(self, prefix)
        if registry is None:
            residuals = self.equations(v, self.params)
        else:
            residuals = self.equations(v, ParamSymbols(self.params, "", prefix, registry))
        if not isinstance(residuals, (list, tuple)):
            raise CircuitError(f"{type(self).__name__}.equations must return a list of residual "
                               f"expressions, got {type(residuals).__name__}")
        return [E.as_expr(r) for r in residuals], v

    def __repr__(self):
        try:
            return f"<{type(self).__name__} {self.path}>"
        except AttributeError:      # refused in __init__: no name yet
            return f"<{type(self).__name__} (not built)>"


def _unknown_port_message(owner, name, ports) -> str:
    import difflib
    close = difflib.get_close_matches(name, list(ports), n=1)
    hint = f" Did you mean {close[0]!r}?" if close else ""
    params = getattr(owner, "params", None)
    if params is not None and name in type(params).model_fields:
        hint += f" {name!r} is a parameter: read it as .params.{name}."
    return (f"{type(owner).__name__} {getattr(owner, 'path', '')!r} has no port {name!r}; its "
            f"ports are {sorted(ports)}.{hint}")


#: the unit engineers usually write a quantity of each SI unit in (for the hint of a bound)
_USUAL = {"Pa": "bar", "m^3/s": "L/min", "m^2": "mm^2", "m^3": "L", "m": "mm",
          "m^3/rad": "cm^3/rev", "rad/s": "rpm"}

_BOUNDS = {"greater_than": ("gt", "greater than"), "greater_than_equal": ("ge", "at least"),
           "less_than": ("lt", "less than"), "less_than_equal": ("le", "at most")}


def _start_number(cls, key: str, value) -> float:
    """A start value override as an SI float: a number, or a quantity with a unit
    (``"50 bar"``) converted to the variable's unit; anything else is named."""
    from .units import number_in
    if key in cls.variables:
        unit = cls.variables[key].unit
    else:
        port = cls.ports[key.split(".")[0]]
        unit = port.domain.across_unit if port.domain is not SIGNAL else ""
    return number_in(value, unit, f"{cls.__name__} start value {key!r}")


def _describe_validation(where: str, exc: ValidationError, fields=(), given=None,
                         model=None) -> str:
    """The errors of a parameter model, one line each. ``given``: the values as the user wrote
    them, so that a bound broken by a quantity with a unit (``p_crack="1500 bar"``) is told in
    that unit as well as in the field's SI one."""
    lines = []
    for err in exc.errors():
        loc = ".".join(str(x) for x in err["loc"]) or "(model)"
        if err["type"] == "missing":
            lines.append(f"  {loc}: required parameter not given")
        elif err["type"] == "extra_forbidden":
            close = difflib.get_close_matches(loc, list(fields), n=2,
                                              cutoff=0.5 if len(loc) <= 3 else 0.7) or \
                [f for f in fields if f.lower() == loc.lower()]
            mean = f"did you mean {' or '.join(map(repr, close))}? " if close else ""
            lines.append(f"  {loc} = {err.get('input')!r}: not a parameter of {where}; {mean}it "
                         f"accepts {', '.join(fields)}")
        else:
            msg = err["msg"].removeprefix("Value error, ")
            bound = _bound_in_units(err, loc, given, model)
            value = err.get("input")
            unit = _field_unit(model, loc)[1] if model is not None and \
                loc in model.model_fields else None
            limit = (err.get("ctx") or {}).get("le")
            if err["type"] == "less_than_equal" and limit == 1 and unit == "-" and \
                    isinstance(value, (int, float)) and 2 <= value <= 100:
                msg += f" (a fraction: {value:g} % is {value / 100:g}, or write '{value:g} %')"
            elif err["type"] in _BOUNDS and unit and unit != "-" and \
                    isinstance(value, (int, float)) and not isinstance(value, bool):
                msg += f" [{unit}]"
                if err["type"].startswith("less") and unit in _USUAL:
                    # too large for SI: most likely meant in the unit engineers write it in
                    msg += (f": a plain number is in {unit}; give the unit with the number, "
                            f"e.g. {loc}=\"{value:g} {_USUAL[unit]}\"")
            if not bound and msg.startswith(f"{loc} = {value!r}"):
                lines.append(f"  {msg}")     # a units message names the field itself
                continue
            lines.append(f"  {loc} = {bound or repr(value)}{'' if bound else ': ' + msg}")
    return f"invalid parameters for {where}:\n" + "\n".join(lines)


def _bound_in_units(err, loc, given, model) -> str:
    """``"'1500 bar' (1.5e+08 Pa): must be at most 1e+08 Pa (1000 bar)"`` for a bound broken
    by a quantity written with a unit, else ""."""
    from .units import _NUMBER, parse_unit
    kind = _BOUNDS.get(err["type"])
    raw = (given or {}).get(loc)
    if kind is None or not isinstance(raw, str) or model is None:
        return ""
    limit = (err.get("ctx") or {}).get(kind[0])
    match = _NUMBER.match(raw)
    _, unit = _field_unit(model, loc)
    if limit is None or match is None or not match.group(2):
        return ""
    try:
        factor = parse_unit(match.group(2))[0]
    except ParameterError:
        return ""
    si = f" {unit}" if unit else ""
    return (f"{raw!r} ({err.get('input'):g}{si}): must be {kind[1]} {float(limit):g}{si} "
            f"({float(limit) / factor:g} {match.group(2)})")


def finite(value: float, what: str) -> float:
    """``value`` if finite, else a :class:`ParameterError` naming ``what``."""
    if not math.isfinite(value):
        raise ParameterError(f"{what} must be finite, got {value!r}")
    return value
