"""Translating masses and the mechanical ground.

``SpoolMass`` (Newton's second law, report section 4.4.3, eq. 4.75)::

    der(flange.x) = v
    (m + m_lever) * der(v) = flange.f

``flange.f`` is the sum of the forces the other components at the node exert on the spool in
+x (springs, friction, pressure forces, flow forces). The main spool of the PVG 32 weighs
``m = 185 g`` (eq. 4.67) and is coupled to the hand lever, whose rotational inertia
(62732 g mm^2 about its axis, 20 mm arm) adds an equivalent translating mass of
``m_lever = 1.569 kg`` (eq. 4.82), 1.754 kg in total (the value in table 4.15).

``Fixed`` (the mechanical ground)::

    flange.x = x0

It takes whatever force the node needs.

``Mass``: a generic translating body with gravity along x and viscous friction::

    der(flange.x) = v,   m * der(v) = flange.f + m * g - b * v
"""

from __future__ import annotations

from pydantic import Field

from pvgraph.component import Component, Mechanical, Params, Variable, der

MAIN_SPOOL_MASS = 0.185          # [kg] report eq. 4.67
LEVER_EQUIVALENT_MASS = 1.569    # [kg] report eq. 4.82

__all__ = ["SpoolMass", "SpoolMassParams", "Mass", "MassParams", "Fixed", "FixedParams",
           "MAIN_SPOOL_MASS",
           "LEVER_EQUIVALENT_MASS"]


class SpoolMassParams(Params):
    m: float = Field(..., gt=0.0, le=1e4,
                     description="Mass of the spool [kg] (PVG 32 main spool: 0.185 kg, report "
                                 "eq. 4.67)")
    m_lever: float = Field(0.0, ge=0.0, le=1e4,
                           description="Equivalent translating mass of a coupled lever [kg] "
                                       "(PVG 32 hand lever: 1.569 kg, report eq. 4.82)")
    x0: float = Field(0.0, ge=-1.0, le=1.0, description="Initial position [m]")
    v0: float = Field(0.0, ge=-100.0, le=100.0, description="Initial velocity [m/s]")


class SpoolMass(Component):
    """A translating spool: ``(m + m_lever) * der(v) = flange.f`` (report eq. 4.75)."""

    Params = SpoolMassParams
    ports = {"flange": Mechanical("the spool; all forces on it act through this node")}
    variables = {"v": Variable("m/s", lambda p: p.v0, 0.1, "velocity of the spool")}

    def starts(self, p):
        return {"flange.x": p.x0}

    def equations(self, v, p):
        m = p.m + p.m_lever
        v.observe("a", der(v.v), "m/s^2", "acceleration")
        v.observe("E_kin", 0.5 * m * v.v * v.v, "J", "kinetic energy")
        return [der(v.flange.x) - v.v,
                m * der(v.v) - v.flange.f]


class FixedParams(Params):
    x0: float = Field(0.0, ge=-1e3, le=1e3, description="Position held [m]")


class Fixed(Component):
    """Mechanical ground: the flange is held at ``x0`` and takes any force."""

    prescribes_motion = True   # sets its port's motion: no inertia needed there
    Params = FixedParams
    ports = {"flange": Mechanical("the fixed point")}

    def equations(self, v, p):
        return [v.flange.x - p.x0]


class Free(Component):
    """Mechanical free end: no force on the flange, ``flange.f = 0`` (what an unconnected
    flange is in Modelica or Simscape; pvgraph asks for it by name). A falling mass, a
    cylinder rod without load."""

    ports = {"flange": Mechanical("the free end")}

    def equations(self, v, p):
        return [v.flange.f]


class MassParams(Params):
    m: float = Field(..., gt=0.0, le=1e6, description="Mass [kg]")
    g: float = Field(0.0, ge=-100.0, le=100.0,
                     description="Gravity along +x [m/s^2] (-9.81: x points up)")
    b: float = Field(0.0, ge=0.0, le=1e8, description="Viscous friction to ground [N s/m]")
    x0: float = Field(0.0, ge=-1e3, le=1e3, description="Initial position [m]")
    v0: float = Field(0.0, ge=-100.0, le=100.0, description="Initial velocity [m/s]")


class Mass(Component):
    """A translating body under gravity: ``m der(v) = flange.f + m g - b v``.

    ``g`` is the acceleration of gravity along +x (``-9.81`` when x points up, 0 when the
    motion is horizontal). Observed: kinetic energy ``E_kin = m v^2 / 2`` and potential energy
    ``E_pot = -m g (x - x0)``.
    """

    Params = MassParams
    ports = {"flange": Mechanical("the body; all forces on it act through this node")}
    variables = {"v": Variable("m/s", lambda p: p.v0, 0.1, "velocity")}

    def starts(self, p):
        return {"flange.x": p.x0}

    def equations(self, v, p):
        v.observe("E_kin", 0.5 * p.m * v.v * v.v, "J", "kinetic energy")
        v.observe("E_pot", -p.m * p.g * (v.flange.x - p.x0), "J", "potential energy")
        return [der(v.flange.x) - v.v, p.m * der(v.v) - (v.flange.f + p.m * p.g - p.b * v.v)]
