"""Check valve: a one-way orifice with an optional cracking pressure (report 4.5.3).

Ports ``a`` (inlet) and ``b`` (outlet); flow passes from ``a`` to ``b`` only. With
``dp = a.p - b.p``::

    s  = clip((dp - p_crack) / dp_open, 0, 1)
    A  = A_leak + (A - A_leak) * (3 s^2 - 2 s^3)
    q  = Cd * A * sqrt(2/rho) * dp / (dp^2 + dp_t^2)^(1/4)          (report eq. A.4)
    a.q = q,  b.q = -q

Below the cracking pressure only the tiny leakage area ``A_leak`` (kept for regularity) passes
flow; above ``p_crack + dp_open`` the full area does. The smoothstep ramp has zero slope at both
ends, so the area is continuously differentiable in dp. The PVE check balls (report 4.5.1,
4.5.3) are rectified orifices of A_checkvalve = 2.3 mm^2 (seat 1.7 mm) from the lower cavity to
the end chambers: ``CheckValve(A=mm2(2.3))`` with the default ``p_crack = 0``.

``PilotOperatedCheckValve`` adds a pilot port ``x`` that pushes the poppet off its seat, so the
valve also passes flow back from ``b`` to ``a`` (lowering a load it holds). The poppet sees the
control pressure (the usual definition of Simscape Fluids' and Hopsan's pilot-operated check
valves)::

    p_control = a.p - b.p + k_p * x.p          k_p = pilot area / seat area
    s = clip((p_control - p_crack) / dp_open, 0, 1),   A = A_leak + (A - A_leak)(3 s^2 - 2 s^3)
    q = Cd * A * sqrt(2/rho) * dp / (dp^2 + dp_t^2)^(1/4)      dp = a.p - b.p, either sign
    a.q = q,  b.q = -q,  x.q = 0

With the pilot at tank pressure it is a check valve; holding a load at ``b.p`` it opens when
``x.p > (b.p - a.p + p_crack) / k_p``.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params
from pvgraph.laws import orifice_flow

from .fluid import rho_field


def smoothstep_ramp(dp, p_crack, dp_open):
    """0 below ``p_crack``, 1 above ``p_crack + dp_open``, C1 smoothstep in between."""
    s = (dp - p_crack) / dp_open
    if isinstance(s, E.Expr):
        s = E.clip(s, 0.0, 1.0)
    else:
        s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


class CheckValveParams(Params):
    A: float = Field(..., gt=0.0, le=1.0,
                     description="Fully open area [m^2] (PVE check balls: 2.3 mm^2, report 4.5.1)")
    p_crack: float = Field(0.0, ge=0.0, le=1e8,
                           description="Cracking pressure drop a - b [Pa] (0: the report's "
                                       "rectified orifice, 4.5.3)")
    dp_open: float = Field(1e4, gt=0.0, le=1e8,
                           description="Pressure rise above p_crack over which the valve opens "
                                       "fully [Pa]")
    A_leak: float = Field(1e-12, gt=0.0, le=1e-3,
                          description="Leakage area when closed, for regularity [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-] (report A.1)")
    rho: float = rho_field()
    dp_t: float = Field(1e3, gt=0.0, le=1e7,
                        description="Laminar-turbulent transition pressure drop [Pa] "
                                    "(regularisation of eq. A.4)")

    @model_validator(mode="after")
    def _leak_below_area(self):
        if self.A_leak >= self.A:
            raise ValueError(f"A_leak ({self.A_leak!r}) must be smaller than A ({self.A!r})")
        return self

    def area(self, dp):
        """Opening area at the pressure drop ``dp`` [m^2] (numbers or expressions)."""
        return self.A_leak + (self.A - self.A_leak) * smoothstep_ramp(dp, self.p_crack,
                                                                     self.dp_open)


class CheckValve(Component):
    """One-way orifice a -> b opening over ``[p_crack, p_crack + dp_open]`` (report 4.5.3)."""

    Params = CheckValveParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        A = v.observe("A", p.area(dp), "m^2", "opening area")
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s",
                      "flow from a to b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.a.q - q, v.a.q + v.b.q]


class PilotOperatedCheckValveParams(CheckValveParams):
    k_p: float = Field(3.0, gt=0.0, le=100.0,
                       description="Pilot ratio: pilot piston area / seat area [-] (typically "
                                   "3-10)")


class PilotOperatedCheckValve(Component):
    """Check valve a -> b that a pilot pressure at ``x`` opens in both directions.

    Opening law on ``p_control = a.p - b.p + k_p * x.p`` (module docstring); the pilot port takes
    no flow.
    """

    Params = PilotOperatedCheckValveParams
    ports = {"a": Hydraulic("inlet (free flow a -> b)"),
             "b": Hydraulic("outlet, load side (held against flow back to a)"),
             "x": Hydraulic("pilot; no flow")}

    def equations(self, v, p):
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        p_ctrl = v.observe("p_control", dp + p.k_p * v.x.p, "Pa",
                           "control pressure a.p - b.p + k_p x.p")
        A = v.observe("A", p.area(p_ctrl), "m^2", "opening area")
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s",
                      "flow from a to b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.a.q - q, v.a.q + v.b.q, v.x.q]
