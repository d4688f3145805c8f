"""Translational sensors: position, velocity and force as signal outputs.

``PositionSensor``: ``y = gain * (flange.x - x_ref)``, ``flange.f = 0`` (drives a valve from a
spool position with ``gain = 1 / x_max``). ``VelocitySensor``: ``y = der(flange.x)``,
``flange.f = 0``. ``ForceSensor`` sits between ``a`` and ``b`` (rigidly: ``a.x = b.x``) and
outputs the force passed from a to b, ``y = a.f`` (``a.f + b.f = 0``).
"""

from __future__ import annotations

from pydantic import Field

from pvgraph.component import Component, Mechanical, Params, SignalOut, der

__all__ = ["PositionSensor", "VelocitySensor", "ForceSensor"]


class PositionSensorParams(Params):
    gain: float = Field(1.0, ge=-1e6, le=1e6, description="Output per metre [1/m]")
    x_ref: float = Field(0.0, ge=-1e3, le=1e3, description="Position of zero output [m]")


class PositionSensor(Component):
    """Position as a signal: ``y = gain * (x - x_ref)``; takes no force."""

    Params = PositionSensorParams
    ports = {"flange": Mechanical("measured node"), "y": SignalOut("scaled position")}

    def equations(self, v, p):
        return [v.flange.f, v.y - p.gain * (v.flange.x - p.x_ref)]


class VelocitySensor(Component):
    """Velocity as a signal ``y = der(x)`` [m/s]; takes no force."""

    ports = {"flange": Mechanical("measured node"), "y": SignalOut("velocity", "m/s", 0.1)}

    def equations(self, v, p):
        return [v.flange.f, v.y - der(v.flange.x)]


class ForceSensor(Component):
    """Force passed from ``a`` to ``b`` as a signal ``y = a.f`` [N] (a rigid link)."""

    ports = {"a": Mechanical("input side"), "b": Mechanical("output side"),
             "y": SignalOut("force a -> b", "N", 10.0)}

    def equations(self, v, p):
        return [v.a.x - v.b.x, v.a.f + v.b.f, v.y - v.a.f]
