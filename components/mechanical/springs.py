"""Springs: linear (to ground and between two flanges), two-stage and double-acting centring.

Sign convention: ``flange.f`` is the force the node exerts on the spring in +x, so the spring
pushes the node with ``-flange.f``. A compression spring to ground sits on the +x side of its
flange: moving the flange in +x compresses it, and it pushes back in -x.

``LinearSpring`` (to ground)::

    flange.f = F0 + k * x                     x = flange.x

``TwoFlangeSpring`` (``a`` on the -x side, ``b`` on the +x side; ``f`` is the compression
force, positive when the spring pushes its flanges apart)::

    f = F0 + k * (a.x - b.x),   a.f = f,   b.f = -f

With ``b`` held at 0 it is a ``LinearSpring`` on ``a``.

``TwoStageSpring`` (the PVB compensator spring pair, report section 4.3.5, eqs. 4.57-4.61)::

    flange.f = F0 + k1 * x + (k2 - k1) * max(x - x_b, 0)

9945 N/m with a preload of 105.12 N up to x_b = 5.2 mm, where the second spring engages and the
stiffness becomes 35000 N/m. The force is continuous at ``x_b`` by construction: the second
stage's preload is ``F0 + (k1 - k2) * x_b = -25.17 N``. The report's -20 N (eq. 4.60) comes from
evaluating the first stage at 5 mm instead of 5.2 mm and leaves a 5.2 N jump, so it is not used.
``max`` is the kinked :func:`pvgraph.expr.maximum` when ``eps = 0``, otherwise
:func:`pvgraph.laws.smooth_pos` rounded within ``eps``. Below ``x = 0`` (the spool on its seat,
outside the report's range) the first stage is continued linearly; limit the stroke with an
``EndStop``.

``CenteringSpring`` (the double-acting, preloaded main spool spring, report section 4.4.5,
eqs. 4.87-4.88 and appendix B.4)::

    flange.f = k * x + F0 * tanh(x / x_eps)

i.e. ``k*x + F0*sign(x)``: the spring is preloaded both ways, so the spool leaves the centre
only once the force on it exceeds ``F0``. ``tanh`` (:func:`pvgraph.laws.smooth_sign`) spreads the
sign change over ``|x| < x_eps``, where the spring behaves as a stiff one of stiffness
``k + F0/x_eps`` (physically both spring seats are in contact there).
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Mechanical, Params
from pvgraph.laws import smooth_pos, smooth_sign

__all__ = ["LinearSpring", "LinearSpringParams", "TwoFlangeSpring", "TwoFlangeSpringParams",
           "TwoStageSpring", "TwoStageSpringParams", "CenteringSpring", "CenteringSpringParams"]


class LinearSpringParams(Params):
    k: float = Field(..., ge=0.0, le=1e10, description="Stiffness [N/m]")
    F0: float = Field(0.0, ge=-1e6, le=1e6,
                      description="Preload: the force at x = 0 [N], positive in compression")


class LinearSpring(Component):
    """Linear compression spring to ground with preload: ``flange.f = F0 + k*x``."""

    Params = LinearSpringParams
    ports = {"flange": Mechanical("the spring end; the other end is grounded on the +x side")}

    def equations(self, v, p):
        F = v.observe("F", p.F0 + p.k * v.flange.x, "N", "compression force")
        v.observe("E", p.F0 * v.flange.x + 0.5 * p.k * v.flange.x * v.flange.x, "J",
                  "energy stored since x = 0")
        return [v.flange.f - F]


class TwoFlangeSpringParams(LinearSpringParams):
    pass


class TwoFlangeSpring(Component):
    """Linear spring between two flanges, ``f = F0 + k*(a.x - b.x)`` in compression."""

    Params = TwoFlangeSpringParams
    ports = {"a": Mechanical("end on the -x side"), "b": Mechanical("end on the +x side")}

    def equations(self, v, p):
        F = v.observe("F", p.F0 + p.k * (v.a.x - v.b.x), "N",
                      "compression force (pushes a and b apart)")
        return [v.a.f - F, v.a.f + v.b.f]


class TwoStageSpringParams(Params):
    k1: float = Field(9945.0, gt=0.0, le=1e10,
                      description="First-stage stiffness [N/m] (report eqs. 4.34, 4.58)")
    k2: float = Field(35000.0, gt=0.0, le=1e10,
                      description="Stiffness with both springs engaged [N/m] (report eqs. "
                                  "4.35, 4.61)")
    x_b: float = Field(5.2e-3, gt=0.0, le=1.0,
                       description="Deflection at which the second spring engages [m] (5.2 mm, "
                                   "report section 4.3.5)")
    F0: float = Field(105.12, ge=-1e6, le=1e6,
                      description="Preload at x = 0 [N] (report eq. 4.57, appendix B.2)")
    eps: float = Field(1e-5, ge=0.0, le=1e-2,
                       description="Rounding of the stiffness change [m]; 0 gives the kink "
                                   "exactly (where)")

    @model_validator(mode="after")
    def _eps_small(self):
        if self.eps > 0.1 * self.x_b:
            raise ValueError(f"eps ({self.eps!r} m) must be at most a tenth of x_b "
                             f"({self.x_b!r} m)")
        return self


class TwoStageSpring(Component):
    """Two springs, the second engaging at ``x_b``: continuous force (report section 4.3.5)."""

    Params = TwoStageSpringParams
    ports = {"flange": Mechanical("the spool end; the springs are grounded on the +x side")}

    def equations(self, v, p):
        x = v.flange.x
        if p.eps > 0.0:
            engaged = smooth_pos(x - p.x_b, p.eps)
        else:
            engaged = E.maximum(x - p.x_b, 0.0)
        F = v.observe("F", p.F0 + p.k1 * x + (p.k2 - p.k1) * engaged, "N", "spring force")
        return [v.flange.f - F]


class CenteringSpringParams(Params):
    k: float = Field(3596.0, ge=0.0, le=1e10,
                     description="Stiffness [N/m] (measured 3596 N/m, report appendix B.4 and "
                                 "eq. 4.88; eq. 4.73 misprints it as 3695)")
    F0: float = Field(65.05, ge=0.0, le=1e6,
                      description="Preload in either direction [N] (report eq. 4.87, eq. B.7)")
    x_eps: float = Field(1e-5, gt=0.0, le=1e-2,
                         description="Width of the smoothed preload reversal around x = 0 [m]")


class CenteringSpring(Component):
    """Double-acting preloaded spring: ``flange.f = k*x + F0*sign(x)``, smoothed (eq. 4.88)."""

    Params = CenteringSpringParams
    ports = {"flange": Mechanical("the spool end; the spring centres it on x = 0")}

    def equations(self, v, p):
        x = v.flange.x
        F = v.observe("F", p.k * x + p.F0 * smooth_sign(x, p.x_eps), "N",
                      "centring force (the spring pushes the spool with -F)")
        return [v.flange.f - F]
