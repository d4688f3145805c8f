"""Rotational mechanics: the shaft domain, inertia, shaft spring/damper, sources and sensors.

Port ``shaft`` (or ``a``/``b``): angle ``phi`` [rad] and torque ``tau`` [N m], the torque the
node exerts on the component about +phi (positive into the component, as every port). So a
component that drives the shaft with a torque ``T`` has ``shaft.tau = -T``, and the power it
delivers is ``-shaft.tau * w`` with ``w = der(phi)``.

- ``Inertia``: ``der(phi) = w``, ``J der(w) = shaft.tau - b w`` (``b`` bearing friction).
- ``ShaftSpringDamper`` (two flanges): ``a.tau = k (phi_a - phi_b) + d (w_a - w_b)``,
  ``b.tau = -a.tau``.
- ``RotationalDamper`` (to ground): ``shaft.tau = d w``.
- ``TorqueSource``: applies ``T`` [N m] to the node, ``shaft.tau = -T``; ``TorqueInput`` takes it
  from a signal.
- ``SpeedSource``: turns the node at ``w0`` [rad/s], ``der(phi) = w0`` (with ``phi(0) = 0``);
  ``SpeedInput`` takes the speed from a signal (an ideal motor; it supplies any torque).
- ``RotationalFixed``: ``phi = phi0``; ``RotationalFree``: ``tau = 0`` (a free shaft end).
- ``SpeedSensor``, ``AngleSensor``: signal ``y`` = ``w`` or ``phi``; they take no torque.
  ``TorqueSensor`` sits between ``a`` and ``b`` (same angle) and outputs the torque passed from
  a to b.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph.component import (Component, Domain, Params, Port, SignalIn, SignalOut, Variable,
                               der)

__all__ = ["ROTATIONAL", "Rotational", "Inertia", "ShaftSpringDamper", "RotationalDamper",
           "TorqueSource", "TorqueInput", "SpeedSource", "SpeedInput", "RotationalFixed",
           "RotationalFree", "SpeedSensor", "AngleSensor", "TorqueSensor"]

ROTATIONAL = Domain("rotational", "phi", "rad", 1.0, "tau", "N m", 10.0)


def Rotational(description: str = "") -> Port:
    """A rotational port: angle ``phi`` [rad], torque ``tau`` [N m] into the component."""
    return Port(ROTATIONAL, description)


class InertiaParams(Params):
    J: float = Field(..., gt=0.0, le=1e6, description="Moment of inertia [kg m^2]")
    b: float = Field(0.0, ge=0.0, le=1e6, description="Viscous bearing friction [N m s/rad]")
    w0: float = Field(0.0, ge=-1e4, le=1e4, description="Initial speed [rad/s]")
    phi0: float = Field(0.0, ge=-1e6, le=1e6, description="Initial angle [rad]")


class Inertia(Component):
    """Rotating inertia: ``J der(w) = shaft.tau - b w``."""

    Params = InertiaParams
    ports = {"shaft": Rotational("the rotating body")}
    variables = {"w": Variable("rad/s", lambda p: p.w0, 10.0, "speed")}

    def starts(self, p):
        return {"shaft.phi": p.phi0}

    def equations(self, v, p):
        v.observe("E_kin", 0.5 * p.J * v.w * v.w, "J", "kinetic energy")
        return [der(v.shaft.phi) - v.w, p.J * der(v.w) - (v.shaft.tau - p.b * v.w)]


class ShaftParams(Params):
    k: float = Field(..., gt=0.0, le=1e9, description="Torsional stiffness [N m/rad]")
    d: float = Field(0.0, ge=0.0, le=1e7, description="Torsional damping [N m s/rad]")


class ShaftSpringDamper(Component):
    """Elastic shaft between ``a`` and ``b``: ``a.tau = k (phi_a - phi_b) + d (w_a - w_b)``."""

    Params = ShaftParams
    ports = {"a": Rotational("end a"), "b": Rotational("end b")}

    def equations(self, v, p):
        twist = v.a.phi - v.b.phi
        v.observe("twist", twist, "rad", "phi_a - phi_b")
        v.observe("E_spring", 0.5 * p.k * twist * twist, "J", "stored energy")
        return [v.a.tau - (p.k * twist + p.d * der(twist)), v.a.tau + v.b.tau]


class RotationalDamperParams(Params):
    d: float = Field(..., gt=0.0, le=1e7, description="Damping to ground [N m s/rad]")


class RotationalDamper(Component):
    """Viscous damper to ground: ``shaft.tau = d w``."""

    Params = RotationalDamperParams
    ports = {"shaft": Rotational("the damped shaft")}

    def equations(self, v, p):
        return [v.shaft.tau - p.d * der(v.shaft.phi)]


class TorqueSourceParams(Params):
    T: float = Field(..., ge=-1e6, le=1e6, description="Torque applied about +phi [N m]")


class TorqueSource(Component):
    """Constant torque ``T`` on the node: ``shaft.tau = -T``."""

    Params = TorqueSourceParams
    ports = {"shaft": Rotational("the driven node")}

    def equations(self, v, p):
        return [v.shaft.tau + p.T]


class TorqueInput(Component):
    """Torque from a signal: applies ``u`` [N m] to the node about +phi."""

    ports = {"shaft": Rotational("the driven node"),
             "u": SignalIn("torque about +phi", "N m", 10.0)}

    def equations(self, v, p):
        return [v.shaft.tau + v.u]


class SpeedSourceParams(Params):
    w0: float = Field(..., ge=-1e4, le=1e4, description="Speed [rad/s]")


class SpeedSource(Component):
    """Ideal motor at constant speed ``w0``: ``der(phi) = w0``; supplies any torque."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    Params = SpeedSourceParams
    ports = {"shaft": Rotational("the driven shaft")}

    def equations(self, v, p):
        v.observe("P", -v.shaft.tau * p.w0, "W", "mechanical power delivered")
        return [der(v.shaft.phi) - p.w0]


class SpeedInput(Component):
    """Ideal motor at the speed of a signal: ``der(phi) = u`` [rad/s]."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    ports = {"shaft": Rotational("the driven shaft"), "u": SignalIn("speed", "rad/s", 10.0)}

    def equations(self, v, p):
        return [der(v.shaft.phi) - v.u]


class RotationalFixedParams(Params):
    phi0: float = Field(0.0, ge=-1e6, le=1e6, description="Angle held [rad]")


class RotationalFixed(Component):
    """Rotational ground: ``phi = phi0``; takes any torque."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    Params = RotationalFixedParams
    ports = {"shaft": Rotational("the fixed point")}

    def equations(self, v, p):
        return [v.shaft.phi - p.phi0]


class RotationalFree(Component):
    """Rotational free end: no torque on the shaft, ``shaft.tau = 0`` (a shaft end left
    free, as an unconnected flange in Modelica or Simscape)."""

    ports = {"shaft": Rotational("the free end")}

    def equations(self, v, p):
        return [v.shaft.tau]


class SpeedSensor(Component):
    """Speed of the node as a signal ``y = der(phi)`` [rad/s]; takes no torque."""

    ports = {"shaft": Rotational("measured shaft"), "y": SignalOut("speed", "rad/s", 10.0)}

    def equations(self, v, p):
        return [v.shaft.tau, v.y - der(v.shaft.phi)]


class AngleSensor(Component):
    """Angle of the node as a signal ``y = phi`` [rad]; takes no torque."""

    ports = {"shaft": Rotational("measured shaft"), "y": SignalOut("angle", "rad", 1.0)}

    def equations(self, v, p):
        return [v.shaft.tau, v.y - v.shaft.phi]


class TorqueSensor(Component):
    """Torque passed from ``a`` to ``b`` as a signal ``y = a.tau`` [N m] (a rigid coupling)."""

    ports = {"a": Rotational("input side"), "b": Rotational("output side"),
             "y": SignalOut("torque a -> b", "N m", 10.0)}

    def equations(self, v, p):
        return [v.a.phi - v.b.phi, v.a.tau + v.b.tau, v.y - v.a.tau]
