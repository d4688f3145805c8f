"""Mechanical sources driven by a signal.

``ForceInput``: applies the force ``u`` [N] to the node in +x::

    flange.f = -u

(the node exerts ``-u`` on the source, so the source exerts ``+u`` on the node).

``PositionInput``: moves the node along ``u`` [m]::

    flange.x = u

A position input driving a mass makes the mass's state algebraic (index above one); drive a
mass through a stiff spring instead, or use a ``ForceInput``.
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
    """Position source driven by a signal: ``flange.x = u`` [m]."""

    ports = {"flange": Mechanical("the driven node"),
             "u": SignalIn("position set point", "m", 1e-3)}

    def equations(self, v, p):
        return [v.flange.x - v.u]
