"""Hydraulic sensors: pressure and flow as signal outputs.

``PressureSensor``: ``y = port.p`` [Pa], ``port.q = 0``. ``FlowSensor`` sits in a line between
``a`` and ``b`` without a pressure drop (``a.p = b.p``, ``a.q + b.q = 0``) and outputs the flow
from a to b, ``y = a.q`` [m^3/s].
"""

from __future__ import annotations

from pvgraph.component import Component, Hydraulic, SignalOut

__all__ = ["PressureSensor", "FlowSensor"]


class PressureSensor(Component):
    """Pressure as a signal ``y = port.p`` [Pa]; draws no flow."""

    ports = {"port": Hydraulic("measured node"), "y": SignalOut("pressure", "Pa", 1e6)}

    def equations(self, v, p):
        return [v.port.q, v.y - v.port.p]


class FlowSensor(Component):
    """Flow from ``a`` to ``b`` as a signal ``y`` [m^3/s], with no pressure drop."""

    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet"),
             "y": SignalOut("flow a -> b", "m^3/s", 1e-4)}

    def equations(self, v, p):
        return [v.a.p - v.b.p, v.a.q + v.b.q, v.y - v.a.q]
