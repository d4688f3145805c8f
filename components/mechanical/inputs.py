"""Mechanical sources: driven by a signal, or constant.

``ForceSource`` / ``VelocitySource`` are the constant forms (Simscape's ideal force and
translational velocity sources): ``flange.f = -F`` and ``der(flange.x) = v0``;
``VelocityInput`` moves the node at the speed of a signal, ``der(flange.x) = u``.

``ForceInput``: applies the force ``u`` [N] to the node in +x::

    flange.f = -u

(the node exerts ``-u`` on the source, so the source exerts ``+u`` on the node).

``PositionInput``: moves the node along ``u`` [m]::

    flange.x = u

A position input may drive a mass directly, as on a test bench: the circuit is then of index
above one (the mass's position and velocity follow the input), and the compiler reduces it by
differentiating ``u`` (the signal source's own function of time) twice; ``flange.f`` is then the
force needed to move the node, ``m * der(u, 2)`` for a free mass. ``system.index_report()``
lists what was differentiated. Use a set point that is smooth where it drives a mass (a
``Sine``, any smooth expression of time): at the corners of a ``Ramp``, a ``Step`` or a linear
``TimeTable`` the required force is an impulse, and a pchip table cannot be differentiated
twice; there, drive the mass through a stiff spring instead.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph.component import Component, Mechanical, Params, SignalIn, der

__all__ = ["ForceInput", "PositionInput", "VelocityInput", "ForceSource", "ForceSourceParams",
           "VelocitySource", "VelocitySourceParams"]


class ForceInput(Component):
    """Force source driven by a signal: pushes the node with ``u`` [N] in +x."""

    ports = {"flange": Mechanical("the driven node"),
             "u": SignalIn("force applied in +x", "N", 10.0)}

    def equations(self, v, p):
        return [v.flange.f + v.u]


class PositionInput(Component):
    """Position source driven by a signal: ``flange.x = u`` [m]; it may drive a mass directly."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    ports = {"flange": Mechanical("the driven node"),
             "u": SignalIn("position set point", "m", 1e-3)}

    def equations(self, v, p):
        return [v.flange.x - v.u]


class VelocityInput(Component):
    """Velocity source driven by a signal: ``der(flange.x) = u`` [m/s]; it supplies any
    force (the rotational ``SpeedInput``'s translational twin)."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    ports = {"flange": Mechanical("the driven node"),
             "u": SignalIn("velocity in +x", "m/s", 0.1)}

    def equations(self, v, p):
        return [der(v.flange.x) - v.u]


class ForceSourceParams(Params):
    F: float = Field(..., ge=-1e9, le=1e9, description="Force applied to the node in +x [N]")


class ForceSource(Component):
    """Constant force ``F`` on the node in +x: ``flange.f = -F`` (a load, a weight on a
    rod; the rotational ``TorqueSource``'s twin)."""

    Params = ForceSourceParams
    ports = {"flange": Mechanical("the loaded node")}

    def equations(self, v, p):
        return [v.flange.f + p.F]


class VelocitySourceParams(Params):
    v0: float = Field(..., ge=-1e3, le=1e3, description="Velocity of the node in +x [m/s]")


class VelocitySource(Component):
    """Ideal translational velocity source: ``der(flange.x) = v0``; supplies any force (a rod
    pulled at constant speed; the rotational ``SpeedSource``'s twin)."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    Params = VelocitySourceParams
    ports = {"flange": Mechanical("the driven node")}

    def equations(self, v, p):
        v.observe("P", -v.flange.f * p.v0, "W", "mechanical power delivered")
        return [der(v.flange.x) - p.v0]
