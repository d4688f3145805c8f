"""Volumes: the compliance of oil in a fixed volume or a piston chamber (report appendix A.5).

``VolumeNode``, one port, many components connect to it::

    V / beta(p) * der(port.p) = port.q

``PistonChamber``, ports ``port`` and ``flange`` (report eqs. 4.14, 4.49, 4.52, 4.93-4.94)::

    V = V0 + side * A * flange.x                       (smoothly limited below at V_min)
    V / beta(p) * der(port.p) = port.q - side * A * der(flange.x)
    flange.f = -side * A * port.p

Sign convention: ``port.q`` is positive into the chamber; ``flange.f`` is the force the
mechanical node exerts on the chamber in +x, so the chamber pushes its piston with
``side * A * p`` in +x. ``side = +1`` is a chamber that grows with x (report V4, eq. 4.93),
``side = -1`` one that shrinks (V5, eq. 4.94; the PVP spring chamber, eq. 4.14).

``beta`` is the effective bulk modulus: constant (7000 bar, report A.5) or, with an entrained
air fraction ``air`` > 0, the pressure-dependent effective modulus of oil with free air
(report figure A.8; the usual mixture law, e.g. Merritt, Hydraulic Control Systems, 1967)::

    1/beta_e = 1/beta + (air / (1 - air)) * (p_atm / p_abs)^(1/kappa) / (kappa * p_abs)

normalised at atmospheric pressure, with ``p_abs = p + p_atm`` (gauge ``p``), smoothly limited
from below at ``p_min_abs``.

Cavitation (:mod:`pvgraph.components.hydraulic.fluid`): the compliance ``V / beta`` gains a term that
grows without bound as the absolute pressure nears the vapour pressure ``p_vap``, so a chamber
never falls below it; each chamber warns once (``CavitationWarning``, naming it) when it gets
there.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from pvgraph.component import Component, Hydraulic, Mechanical, Params, der
from pvgraph.laws import smooth_max

from .fluid import (P_ATM, FluidCompliance, cavitation_compliance,  # noqa: F401
                    cavitation_warning, compliance, effective_bulk_modulus, void_fraction)

class VolumeNodeParams(FluidCompliance):
    V: float = Field(..., gt=0.0, le=10.0, description="Volume [m^3]")
    p0: float = Field(0.0, ge=-1e5, le=1e9, description="Initial (gauge) pressure [Pa]")


class VolumeNode(Component):
    """Fixed volume of compressible oil: ``V/beta * der(p) = q``."""

    Params = VolumeNodeParams
    ports = {"port": Hydraulic("the node")}

    def starts(self, p):
        return {"port.p": p.p0}

    modes = {"cavitated": 0.0}

    def equations(self, v, p):
        cavitation_warning(v, v.port.p, p, "the volume")
        return [p.V * compliance(v.port.p, p) * der(v.port.p) - v.port.q]


def chamber_volume(V0, A_signed, x, V_min):
    """Chamber volume ``V0 + A_signed * x``, smoothly limited from below at ``V_min``.

    The limit keeps ``V / beta`` positive if a piston is pushed past its stroke; within the
    stroke (``V >> V_min``) it changes the volume by less than ``V_min^2 / (4 V)``.
    """
    return smooth_max(V0 + A_signed * x, V_min, V_min)


def chamber_continuity(V, p, q, A_signed, x, fp: FluidCompliance):
    """Residual of the continuity equation of a chamber with a moving wall (report A.7)::

        V ((1 - phi) / beta(p) + c_cav(p)) der(p) = q - (1 - phi) A_signed der(x)

    the oil's mass balance where a cavity takes the fraction ``phi(p)`` of the volume
    (:func:`~pvgraph.components.hydraulic.fluid.void_fraction`, ``c_cav = -dphi/dp``): the oil
    fills ``V (1 - phi)``, so a wall moving while the chamber cavitates grows the cavity, not
    the oil. Without cavitation (``phi = 0``) it is the report's ``V / beta der(p) = q - A
    der(x)``. (With the cavity a compliance of the whole volume, ``V c_cav der(p)`` alone, a
    chamber growing at the vapour pressure took oil it had no room for: a 20 L/min pump into
    a cylinder on 500 kg lost 79 of 333 cm^3 and the rod ran back.)
    """
    phi = void_fraction(p, fp)
    liquid = 1.0 - phi
    return V * (liquid / effective_bulk_modulus(p, fp) + cavitation_compliance(p, fp)) * der(p) \
        - (q - liquid * A_signed * der(x))


class PistonChamberParams(FluidCompliance):
    A: float = Field(..., gt=0.0, le=1.0,
                     description="Piston area [m^2] (PVE main spool end: 254 mm^2, report "
                                 "eq. 4.71/4.92)")
    V0: float = Field(..., gt=0.0, le=10.0,
                      description="Chamber volume at x = 0 [m^3] (PVE: V4 = 13 cm^3, V5 = 27 "
                                  "cm^3, report 4.5.2 / B.5)")
    side: Literal[1, -1] = Field(
        1, description="+1: the volume grows with x (V = V0 + A x, the pressure pushes the "
                       "piston towards +x); -1: it shrinks (V = V0 - A x, pushes towards -x) [-]")
    V_min: float = Field(1e-9, gt=0.0, le=1.0,
                         description="Smooth lower limit of the volume [m^3]")
    p0: float = Field(0.0, ge=-1e5, le=1e9, description="Initial (gauge) pressure [Pa]")

    @model_validator(mode="after")
    def _volume_above_limit(self):
        if self.V0 <= 10.0 * self.V_min:
            raise ValueError(f"V0 ({self.V0!r}) must be well above V_min ({self.V_min!r})")
        return self


class PistonChamber(Component):
    """Oil chamber closed by a piston on the mechanical port ``flange``.

    Report eqs. 4.14, 4.49, 4.52 (spool chambers) and 4.93-4.94, 4.98-4.99 (PVE end chambers)::

        V = V0 + side * A * flange.x
        V / beta(p) * der(p) = port.q - side * A * der(flange.x)
        flange.f = -side * A * p

    ``flange.f`` is the force the mechanical node exerts on the chamber; the chamber pushes the
    piston with ``F = side * A * p`` in +x (observed as ``F``).
    """

    Params = PistonChamberParams
    ports = {"port": Hydraulic("oil connection of the chamber"),
             "flange": Mechanical("the piston")}

    modes = {"cavitated": 0.0}

    def starts(self, p):
        return {"port.p": p.p0}

    def equations(self, v, p):
        cavitation_warning(v, v.port.p, p, "the chamber")
        A_s = p.side * p.A
        x, pr = v.flange.x, v.port.p
        V = v.observe("V", chamber_volume(p.V0, A_s, x, p.V_min), "m^3", "chamber volume")
        F = v.observe("F", A_s * pr, "N", "pressure force on the piston in +x")
        v.observe("q_displaced", A_s * der(x), "m^3/s", "volume growth rate")
        return [chamber_continuity(V, pr, v.port.q, A_s, x, p), v.flange.f + F]
