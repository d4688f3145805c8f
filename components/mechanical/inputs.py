"""Mechanical sources driven by a signal.

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

from pvgraph.component import Component, Mechanical, SignalIn

__all__ = ["ForceInput", "PositionInput"]


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
