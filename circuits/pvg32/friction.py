"""Stick-slip friction for the PVG 32 spools: the LuGre bristle model (Canudas de Wit et al.
1995) without the Stribeck dip.

::

    der(z) = v - sigma0 |v|_eps z / F_c                  (bristle deflection z [m])
    F = sigma0 z + sigma1 der(z) + b v                   (force on the spool, opposing v)

``flange.f = F`` (the force the friction exerts on the flange's node is -F, as for
:class:`pvgraph.components.mechanical.Friction`). At rest the bristles act as a stiff spring that holds
any force below F_c with a pre-sliding travel of at most F_c / sigma0; above it the spool
slides with F -> F_c sign(v) + b v. This is the +-F_c / A dead zone of the report's Coulomb term
(table 4.14: 50 N on the compensator, +-1.96 bar across its 2.545 cm^2) that the smooth
``F_c tanh(v / v_eps)`` law removes at rest (there, any force creeps the spool at
v = v_eps atanh(F / F_c)). ``|v|_eps = sqrt(v^2 + v_eps^2)``, v_eps = 0.01 um/s, only rounds the
absolute value; it lets a stuck bristle relax over F_c / (sigma0 v_eps), 1000 s at 50 N. A
steady-state solve (all derivatives zero) therefore finds z = 0, i.e. no friction force: the
dead zone is a property of the history, which only a simulation reproduces.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Mechanical, Params, Variable, der

__all__ = ["LuGreFriction", "LuGreFrictionParams"]

V_EPS = 1e-8        # [m/s]; the stuck bristle relaxes over F_c / (sigma0 V_EPS), 1000 s at 50 N


class LuGreFrictionParams(Params):
    F_c: float = Field(..., gt=0.0, le=1e6,
                       description="Coulomb (sliding) force [N] (report c_c, eq 4.27; table 4.14: "
                                   "50 N on the PVB compensator)")
    b: float = Field(0.0, ge=0.0, le=1e8, description="Viscous coefficient [N s/m] (report c_v)")
    sigma0: float = Field(5e6, gt=0.0, le=1e10,
                          description="Bristle stiffness [N/m]: pre-sliding travel F_c / sigma0 "
                                      "(5e6: 10 um at 50 N, the order of a spool's radial "
                                      "clearance)")
    sigma1: float = Field(1e3, ge=0.0, le=1e7,
                          description="Bristle damping [N s/m] (about 2 sqrt(sigma0 m) for a "
                                      "66 g spool)")


class LuGreFriction(Component):
    """LuGre friction: sticks below F_c, slides with F_c sign(v) + b v above it."""

    Params = LuGreFrictionParams
    ports = {"flange": Mechanical("the sliding body")}
    variables = {"z": Variable("m", 0.0, 1e-5, "bristle deflection")}

    def equations(self, v, p):
        vel = der(v.flange.x)
        speed = E.sqrt(vel * vel + V_EPS * V_EPS)
        zdot = der(v.z)
        F = v.observe("F", p.sigma0 * v.z + p.sigma1 * zdot + p.b * vel, "N",
                      "friction force (opposes the velocity)")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [zdot - (vel - p.sigma0 * speed * v.z / p.F_c), v.flange.f - F]
