"""Test benches: put one component between ideal sources in one line.

::

    bench = bench_circuit(Orifice(A=mm2(2)), a=Pressure(bar(10)), b=Pressure(0.0))
    system = bench.compile()

Every port of the component gets the boundary named after it: :class:`Pressure` or
:class:`Flow` for hydraulic ports, :class:`Position` or :class:`Force` for mechanical ones and
:class:`Signal` (or a plain number) for signal inputs. A value is a number or a function of
time written with the expression vocabulary (``lambda t: bar(10) * where(t > 0.1, 1, 0)``).
The component under test is named ``dut``; the sources are named after the ports.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Union

from . import expr as E
from .circuit import Circuit
from .component import SIGNAL, Component, Hydraulic, Mechanical, SignalOut
from .errors import CircuitError

__all__ = ["Pressure", "Flow", "Position", "Force", "Signal", "bench_circuit"]

Value = Union[float, Callable[[E.Expr], E.Expr]]


def _value(value: Value, t: E.Expr) -> E.Expr:
    return E.as_expr(value(t) if callable(value) else value)


@dataclass(frozen=True)
class Pressure:
    """Ideal pressure at a hydraulic port [Pa]."""
    value: Value


@dataclass(frozen=True)
class Flow:
    """Ideal flow delivered into a hydraulic port's node [m^3/s] (drawn out if negative)."""
    value: Value


@dataclass(frozen=True)
class Position:
    """Ideal position of a mechanical port [m]."""
    value: Value


@dataclass(frozen=True)
class Force:
    """Ideal force applied to a mechanical port in +x [N]."""
    value: Value


@dataclass(frozen=True)
class Signal:
    """A signal value driving a signal input."""
    value: Value


class _AcrossSource(Component):
    """Fixes the across variable (p or x) of its port to a value of time."""

    def __init__(self, value):
        super().__init__()
        self._value = value

    def equations(self, v, p):
        domain = self.ports["port"].domain
        return [getattr(v.port, domain.across) - _value(self._value, v.t)]


class _ThroughSource(_AcrossSource):
    """Delivers the through variable (q or f) of its port into the node."""

    def equations(self, v, p):
        domain = self.ports["port"].domain
        return [getattr(v.port, domain.through) + _value(self._value, v.t)]


def _source_class(base, port, label):
    return type(label, (base,), {"ports": {"port": port}, "__doc__": base.__doc__})


_SOURCES = {
    Pressure: _source_class(_AcrossSource, Hydraulic("bench pressure"), "BenchPressure"),
    Flow: _source_class(_ThroughSource, Hydraulic("bench flow"), "BenchFlow"),
    Position: _source_class(_AcrossSource, Mechanical("bench position"), "BenchPosition"),
    Force: _source_class(_ThroughSource, Mechanical("bench force"), "BenchForce"),
}
_DOMAIN_OF = {Pressure: "hydraulic", Flow: "hydraulic", Position: "mechanical",
              Force: "mechanical"}


class _SignalSource(Component):
    ports = {"y": SignalOut("bench signal")}

    def __init__(self, value):
        super().__init__()
        self._value = value

    def equations(self, v, p):
        return [v.y - _value(self._value, v.t)]


def bench_circuit(component: Component, name: str = "bench", **boundaries) -> Circuit:
    """A circuit with ``component`` (as ``dut``) and one ideal source per named port."""
    circuit = Circuit(name)
    circuit.add("dut", component)
    ports = type(component).ports
    for port_name in boundaries:
        if port_name not in ports:
            raise CircuitError(f"bench: {type(component).__name__} has no port {port_name!r}; "
                               f"its ports are {sorted(ports)}")
    for port_name, boundary in boundaries.items():
        decl = ports[port_name]
        if decl.domain is SIGNAL:
            if decl.causality != "input":
                raise CircuitError(f"bench: {port_name!r} is a signal output; only inputs take a "
                                   f"boundary")
            value = boundary.value if isinstance(boundary, Signal) else boundary
            src = circuit.add(f"src_{port_name}", _SignalSource(value))
            circuit.connect(src.y, getattr(component, port_name))
            continue
        if isinstance(boundary, (int, float)):
            boundary = (Pressure if decl.domain.name == "hydraulic" else Position)(boundary)
        if _DOMAIN_OF.get(type(boundary)) != decl.domain.name:
            allowed = ", ".join(k.__name__ for k, d in _DOMAIN_OF.items()
                                if d == decl.domain.name)
            raise CircuitError(f"bench: port {port_name!r} is {decl.domain.name}; give it one of "
                               f"{allowed}, not {type(boundary).__name__}")
        src = circuit.add(f"src_{port_name}", _SOURCES[type(boundary)](boundary.value))
        circuit.connect(src.port, getattr(component, port_name))
    return circuit
