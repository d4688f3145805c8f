"""Stroke limits: a stiff spring-damper contact at each end of the travel.

With ``x = flange.x``, ``v = der(flange.x)`` and the penetrations past each limit::

    pen_hi = max(x - x_max, 0),   pen_lo = max(x_min - x, 0)       (rounded within eps)
    flange.f = max(k * pen_hi + d * v * c_hi, 0) - max(k * pen_lo - d * v * c_lo, 0)

``c_hi``, ``c_lo`` are the contact indicators d(pen)/dx: 0 in free travel, 1 in contact, so the
damping acts only while a stop is touched (a Kelvin-Voigt contact, as in
``Modelica.Mechanics.Translational.Components.ElastoGap``), and a stop only pushes: while the
body leaves it, the damping does not pull it back. The stop pushes the node with
``-flange.f``: back into the stroke. Max is rounded as :func:`pvgraph.laws.smooth_pos` within
``eps`` (evaluated without cancellation, :mod:`pvgraph.components.mechanical.laws`), so the force and its
derivative are continuous; in free travel a residual force of
about ``k*eps^2 / (4*distance to the stop)`` remains (2.5e-4 N at 1 mm with the defaults).
At rest against a stop under a force ``F`` the penetration is ``F/k``; a mass ``m`` hitting it at
speed ``v`` penetrates up to about ``v*sqrt(m/k)``.

The PVG 32 main spool travels +-7 mm (report sections 4.4.3 and 4.5.5, figure 4.25).
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Mechanical, Params, der

from .laws import contact_indicator, contact_penetration

__all__ = ["EndStop", "EndStopParams"]


class EndStopParams(Params):
    x_min: float = Field(..., ge=-1e3, le=1e3,
                         description="Lower stroke limit [m] (main spool: -7 mm, report 4.4.3)")
    x_max: float = Field(..., ge=-1e3, le=1e3,
                         description="Upper stroke limit [m] (main spool: +7 mm, report 4.4.3)")
    k: float = Field(1e7, gt=0.0, le=1e12, description="Contact stiffness [N/m]")
    d: float = Field(2e3, ge=0.0, le=1e9, description="Contact damping [N s/m]")
    eps: float = Field(1e-7, gt=0.0, le=1e-3,
                       description="Rounding of the contact onset [m]")

    @model_validator(mode="after")
    def _ordered(self):
        if not self.x_min < self.x_max:
            raise ValueError(f"x_min ({self.x_min!r} m) must be below x_max ({self.x_max!r} m)")
        if self.eps > 0.01 * (self.x_max - self.x_min):
            raise ValueError(f"eps ({self.eps!r} m) must be at most 1 % of the stroke "
                             f"x_max - x_min")
        return self


class EndStop(Component):
    """Stroke limits ``x_min <= x <= x_max`` as stiff, damped, smooth contacts."""

    Params = EndStopParams
    ports = {"flange": Mechanical("the limited body")}

    def equations(self, v, p):
        x = v.flange.x
        vel = der(x)
        pen_hi = contact_penetration(x - p.x_max, p.eps)
        pen_lo = contact_penetration(p.x_min - x, p.eps)
        c_hi = contact_indicator(x - p.x_max, p.eps)
        c_lo = contact_indicator(p.x_min - x, p.eps)
        v.observe("penetration", pen_hi - pen_lo, "m",
                  "past x_max (positive) or x_min (negative)")
        # each stop only pushes (as ElastoGap): its damping does not pull a body that leaves
        push_hi = E.maximum(p.k * pen_hi + p.d * vel * c_hi, 0.0)
        push_lo = E.maximum(p.k * pen_lo - p.d * vel * c_lo, 0.0)
        F = v.observe("F", push_hi - push_lo, "N",
                      "contact force (the stop pushes the body with -F)")
        return [v.flange.f - F]
