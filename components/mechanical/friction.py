"""Friction and viscous dampers on a translating flange.

The velocity is the derivative of the flange position, ``v = der(flange.x)``; the dissipative
force opposes it. ``flange.f`` is the force the node exerts on the component in +x, so the
component pushes the node with ``-flange.f``.

``Friction`` (report appendix A.3, eq. A.5; spool friction eqs. 4.27, 4.91)::

    flange.f = b*v + (F_c + (F_s - F_c) * exp(-(|v|/v_s)^delta)) * tanh(v / v_eps)

viscous (``b``, the report's c_v / sigma), Coulomb (``F_c``, the report's c_c / F_co) and
Stribeck (static level ``F_s``, the report's F_co + F_so, decaying over ``v_s``, the report's
C_s). ``delta = 1`` is the exponential decay of eq. A.5, ``delta = 2`` (default) the Gaussian
form of :func:`pvgraph.laws.coulomb_friction`. ``sign(v)`` is regularised as ``tanh(v/v_eps)``:
a force below the breakaway level does not stick the spool exactly but lets it creep at
``v = v_eps * atanh(F/F_s)`` (near rest the law is ``F_s tanh(v/v_eps) + b v``: ``F_s`` is the
level there, ``F_c`` only without a Stribeck term); choose ``v_eps`` well below the velocities
of interest.
The report's values for the main spool: c_v = 25 N s/m (tuned, table 4.14), Coulomb
c_cm = 8.8e-4 * P_P N (pressure dependent, section 4.4.6; neglected in eq. 4.91).

``LuGreFriction`` (Canudas de Wit, Olsson, Astrom and Lischinsky 1995, the bristle model)::

    der(z) = v - sigma0 |v|_eps z / g(v),   g(v) = F_c + (F_s - F_c) exp(-(|v|/v_s)^2)
    flange.f = sigma0 z + sigma1 der(z) + b v

holds a load: at rest the bristles (deflection ``z``) act as a stiff spring carrying any force
below the breakaway level with a pre-sliding travel of at most ``F_s / sigma0``; above it the
body slides with ``g(v) sign(v) + b v``. A cylinder pushed by 10 kN against a 1000 N/mm spring
with 1 kN of friction stops at (10 - 1) kN / k = 9.000 mm, where ``Friction`` creeps on to the
friction-free 10 mm over ``F_c / (k v_eps)`` (10 s). ``|v|_eps = sqrt(v^2 + v_eps^2)`` with
``v_eps`` = 0.01 um/s only rounds the absolute value; a stuck bristle relaxes over
``F_c / (sigma0 v_eps)`` (2000 s at 1 kN and the default ``sigma0``). The sticking is history:
a steady-state solve (every derivative zero) finds ``z = 0``, no friction force; simulate to
rest instead. ``sigma1`` damps the bristle mode ``sqrt(sigma0 / m)`` of the mass it holds
(critical at ``2 sqrt(sigma0 m)``).

``Damper`` (viscous, to ground)::

    flange.f = d * v

``TwoFlangeDamper``::

    f = d * (der(a.x) - der(b.x)),   a.f = f,   b.f = -f
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Mechanical, Params, Variable, der

from .laws import stribeck_friction

__all__ = ["Friction", "FrictionParams", "LuGreFriction", "LuGreFrictionParams", "Damper",
           "DamperParams", "TwoFlangeDamper", "TwoFlangeDamperParams"]

LUGRE_V_EPS = 1e-8   # [m/s]: rounds |v| in the bristle law (a stuck bristle relaxes over F/(sigma0 v))


class StribeckParams(Params):
    """Coulomb, viscous and Stribeck levels shared by the friction laws."""

    F_c: float = Field(..., ge=0.0, le=1e6,
                       description="Coulomb (sliding) friction force [N] (report c_c, eq. 4.27; "
                                   "PVB compensator tuned to 50 N, table 4.14)")
    b: float = Field(0.0, ge=0.0, le=1e8,
                     description="Viscous friction coefficient [N s/m] (report c_v: 5760 from "
                                 "eq. 4.28, main spool tuned to 25, table 4.14)")
    F_s: float | None = Field(None, ge=0.0, le=1e6,
                              description="Static (breakaway) friction force [N]; default F_c "
                                          "(no Stribeck effect) (report F_co + F_so, eq. A.5)")
    v_s: float = Field(1e-3, gt=0.0, le=10.0,
                       description="Stribeck velocity: decay of static to Coulomb friction "
                                   "[m/s] (report C_s, eq. A.5)")

    @model_validator(mode="after")
    def _static_above_coulomb(self):
        if self.F_s is not None and self.F_s < self.F_c:
            raise ValueError(f"F_s ({self.F_s!r} N) must not be below F_c ({self.F_c!r} N)")
        return self

    @property
    def static(self) -> float:
        """The breakaway force in use [N]."""
        return self.F_c if self.F_s is None else self.F_s


class FrictionParams(StribeckParams):
    delta: float = Field(2.0, ge=1.0, le=2.0,
                         description="Stribeck shape exponent [-]: 1 as report eq. A.5, 2 "
                                     "Gaussian")
    v_eps: float = Field(1e-4, gt=0.0, le=1.0,
                         description="Velocity width of the smoothed sign(v) [m/s]")


class Friction(Component):
    """Viscous + Coulomb + Stribeck friction, smooth at zero velocity (report eq. A.5).

    It does not hold a load at rest: a force below the breakaway level creeps the body at
    ``v_eps atanh(F / F_s)`` (a cylinder pushed against a spring ends where it would without
    friction, over ``F_c / (k v_eps)``). :class:`LuGreFriction` sticks."""

    Params = FrictionParams
    ports = {"flange": Mechanical("the sliding body")}

    def equations(self, v, p):
        vel = der(v.flange.x)
        F = v.observe("F", stribeck_friction(vel, p.F_c, p.static, p.v_s, p.v_eps, p.b, p.delta),
                      "N", "friction force (opposes the velocity)")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [v.flange.f - F]


class LuGreFrictionParams(StribeckParams):
    F_c: float = Field(..., gt=0.0, le=1e6,
                       description="Coulomb (sliding) friction force [N] (report c_c, eq. 4.27; "
                                   "PVB compensator tuned to 50 N, table 4.14)")
    sigma0: float = Field(5e6, gt=0.0, le=1e12,
                          description="Bristle stiffness [N/m]: pre-sliding travel F_s / sigma0 "
                                      "(5e6: 10 um at 50 N, the order of a spool's radial "
                                      "clearance)")
    sigma1: float = Field(1e3, ge=0.0, le=1e9,
                          description="Bristle damping [N s/m] (critical 2 sqrt(sigma0 m) for the "
                                      "mass m it holds: 1e3 for a 66 g spool)")


class LuGreFriction(Component):
    """LuGre friction: sticks below the breakaway force, slides with Coulomb + Stribeck +
    viscous friction above it (a bristle deflection ``z`` as state)."""

    Params = LuGreFrictionParams
    ports = {"flange": Mechanical("the sliding body")}
    variables = {"z": Variable("m", 0.0, 1e-5, "bristle deflection")}

    def equations(self, v, p):
        vel = der(v.flange.x)
        speed = E.sqrt(vel * vel + LUGRE_V_EPS * LUGRE_V_EPS)
        level = p.F_c if p.F_s is None or p.F_s == p.F_c else \
            p.F_c + (p.F_s - p.F_c) * E.exp(-(vel * vel) / (p.v_s * p.v_s))
        zdot = der(v.z)
        F = v.observe("F", p.sigma0 * v.z + p.sigma1 * zdot + p.b * vel, "N",
                      "friction force (opposes the velocity)")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [zdot - (vel - p.sigma0 * speed * v.z / level), v.flange.f - F]


class DamperParams(Params):
    d: float = Field(..., ge=0.0, le=1e8, description="Damping coefficient [N s/m]")


class Damper(Component):
    """Viscous damper to ground: ``flange.f = d * der(flange.x)``."""

    Params = DamperParams
    ports = {"flange": Mechanical("the damped body")}

    def equations(self, v, p):
        vel = der(v.flange.x)
        F = v.observe("F", p.d * vel, "N", "damping force (opposes the velocity)")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [v.flange.f - F]


class TwoFlangeDamperParams(DamperParams):
    pass


class TwoFlangeDamper(Component):
    """Viscous damper between two flanges: ``f = d * (der(a.x) - der(b.x))``."""

    Params = TwoFlangeDamperParams
    ports = {"a": Mechanical("end on the -x side"), "b": Mechanical("end on the +x side")}

    def equations(self, v, p):
        vel = der(v.a.x) - der(v.b.x)
        F = v.observe("F", p.d * vel, "N", "force on a, opposing the relative velocity")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [v.a.f - F, v.a.f + v.b.f]
