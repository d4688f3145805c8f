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

``Damper`` (viscous, to ground)::

    flange.f = d * v

``TwoFlangeDamper``::

    f = d * (der(a.x) - der(b.x)),   a.f = f,   b.f = -f
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph.component import Component, Mechanical, Params, der

from .laws import stribeck_friction

__all__ = ["Friction", "FrictionParams", "Damper", "DamperParams", "TwoFlangeDamper",
           "TwoFlangeDamperParams"]


class FrictionParams(Params):
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
    delta: float = Field(2.0, ge=1.0, le=2.0,
                         description="Stribeck shape exponent [-]: 1 as report eq. A.5, 2 "
                                     "Gaussian")
    v_eps: float = Field(1e-4, gt=0.0, le=1.0,
                         description="Velocity width of the smoothed sign(v) [m/s]")

    @model_validator(mode="after")
    def _static_above_coulomb(self):
        if self.F_s is not None and self.F_s < self.F_c:
            raise ValueError(f"F_s ({self.F_s!r} N) must not be below F_c ({self.F_c!r} N)")
        return self

    @property
    def static(self) -> float:
        """The breakaway force in use [N]."""
        return self.F_c if self.F_s is None else self.F_s


class Friction(Component):
    """Viscous + Coulomb + Stribeck friction, smooth at zero velocity (report eq. A.5)."""

    Params = FrictionParams
    ports = {"flange": Mechanical("the sliding body")}

    def equations(self, v, p):
        vel = der(v.flange.x)
        F = v.observe("F", stribeck_friction(vel, p.F_c, p.static, p.v_s, p.v_eps, p.b, p.delta),
                      "N", "friction force (opposes the velocity)")
        v.observe("P_loss", F * vel, "W", "power dissipated")
        return [v.flange.f - F]


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
