"""Fixed restrictions: turbulent and laminar orifices.

``Orifice`` (report appendix A.1, eq. A.4, with a smooth laminar transition)::

    q = Cd * A * sqrt(2/rho) * dp / (dp^2 + dp_t^2)^(1/4),   dp = a.p - b.p
    a.q = q,  b.q = -q

For ``|dp| >> dp_t`` this is the turbulent law ``Cd*A*sqrt(2|dp|/rho)*sign(dp)`` (within 0.3 %
above 10 dp_t); near zero it is linear, as laminar flow is. ``dp_t`` is given directly or follows
from a critical Reynolds number (``Re_crit``, ``nu``): dp_t = rho/2 * (Re_crit*nu/(Cd*D_h))^2 with
the hydraulic diameter D_h of a round hole of area A.

``LaminarOrifice`` (report eq. 4.132, table 4.8)::

    q = K * dp
"""

from __future__ import annotations

import math

from pydantic import Field

from pvgraph.component import Component, Hydraulic, Params
from pvgraph.laws import orifice_flow, orifice_transition_pressure

from .fluid import nu_field, rho_field


class OrificeParams(Params):
    A: float = Field(..., gt=0.0, le=1.0, description="Opening area [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0,
                      description="Discharge coefficient [-] (0.6, report table 4.7)")
    rho: float = rho_field()
    dp_t: float | None = Field(
        None, gt=0.0, description="Laminar-turbulent transition pressure drop [Pa]; default from "
                                  "Re_crit")
    Re_crit: float = Field(100.0, gt=0.0, le=1e5,
                           description="Critical Reynolds number of the transition [-]")
    nu: float = nu_field()

    def transition(self) -> float:
        """The transition pressure drop in use [Pa]."""
        if self.dp_t is not None:
            return self.dp_t
        D_h = math.sqrt(4.0 * self.A / math.pi)
        return orifice_transition_pressure(self.Cd, D_h, self.rho, self.nu, self.Re_crit)


class Orifice(Component):
    """Sharp-edged orifice with a smooth laminar transition (report eq. A.4)."""

    Params = OrificeParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        dp = v.a.p - v.b.p
        q = v.observe("q", orifice_flow(p.Cd, p.A, dp, p.rho, p.transition()), "m^3/s",
                      "flow from a to b")
        v.observe("dp", dp, "Pa", "pressure drop a - b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.a.q - q, v.a.q + v.b.q]


class LaminarOrificeParams(Params):
    K: float = Field(..., gt=0.0, le=1.0,
                     description="Flow-pressure coefficient [m^3/(s Pa)] (report eq. 4.132, "
                                 "table 4.8)")


class LaminarOrifice(Component):
    """Laminar restriction ``q = K * (a.p - b.p)`` (report eq. 4.132)."""

    Params = LaminarOrificeParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        dp = v.a.p - v.b.p
        q = v.observe("q", p.K * dp, "m^3/s", "flow from a to b")
        v.observe("dp", dp, "Pa", "pressure drop a - b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.a.q - q, v.a.q + v.b.q]
