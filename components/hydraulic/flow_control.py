"""Flow control: the shuttle (OR) valve of LS lines and a 2-way pressure-compensated flow control.

``ShuttleValve``: ports ``a``, ``b`` (inlets) and ``out``. A ball shuttles to the lower inlet and
seals it, so ``out`` connects to the higher one. With ``s = ramp(a.p - b.p; -dp_switch/2,
dp_switch)`` (C1 smoothstep from 0 to 1, :func:`components.hydraulic.check_valve.smoothstep_ramp`)::

    A_a = A_leak + A * s,   A_b = A_leak + A * (1 - s)
    a.q = orifice(A_a, a.p - out.p),  b.q = orifice(A_b, b.p - out.p),  out.q = -(a.q + b.q)

Flow can return from ``out`` to the higher inlet (an LS line draining through the section that
sets it), as in a real shuttle.

``FlowControlValve`` (2-way, pressure compensated): a compensator spool in series with a
metering orifice ``A_meter`` keeps the drop across the metering orifice at about ``dp_c``, so
the flow ``Q_set = Cd A_meter sqrt(2 dp_c / rho)`` does not depend on the supply or load
pressure once the drop across the valve exceeds ``dp_c``. With ``p_i`` the pressure between the
two (an internal unknown) and ``dp_m = p_i - B.p``::

    A_c = A_leak + A_comp * (1 - ramp(dp_m; dp_c - dp_band, dp_band))
    q = orifice(A_comp_area=A_c, A.p - p_i) = orifice(A_meter, dp_m),   A.q = q, B.q = -q

so the metering drop stays within ``[dp_c - dp_band, dp_c]`` while the compensator throttles.
Below that (valve drop too small) the compensator is wide open and the valve is two orifices in
series. Reverse flow (B to A) passes both, unregulated.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pvgraph.component import Component, Hydraulic, Params, Variable
from pvgraph.laws import orifice_flow

from .check_valve import smoothstep_ramp
from .fluid import rho_field

__all__ = ["ShuttleValve", "FlowControlValve"]


class ShuttleValveParams(Params):
    A: float = Field(..., gt=0.0, le=1e-2, description="Open area of either seat [m^2]")
    dp_switch: float = Field(1e4, gt=0.0, le=1e6,
                             description="Pressure difference a - b over which the ball "
                                         "shuttles [Pa]")
    A_leak: float = Field(1e-12, gt=0.0, le=1e-5,
                          description="Leakage area of the sealed seat [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-]")
    rho: float = rho_field()
    dp_t: float = Field(1e3, gt=0.0, le=1e6,
                        description="Laminar-turbulent transition pressure drop [Pa]")


class ShuttleValve(Component):
    """Shuttle (OR) valve: ``out`` follows the higher of ``a`` and ``b``."""

    Params = ShuttleValveParams
    ports = {"a": Hydraulic("inlet a"), "b": Hydraulic("inlet b"),
             "out": Hydraulic("outlet (the higher inlet)")}

    def equations(self, v, p):
        s = v.observe("s", smoothstep_ramp(v.a.p - v.b.p, -0.5 * p.dp_switch, p.dp_switch), "",
                      "ball position (1: seals b, a open)")
        q_a = orifice_flow(p.Cd, p.A_leak + p.A * s, v.a.p - v.out.p, p.rho, p.dp_t)
        q_b = orifice_flow(p.Cd, p.A_leak + p.A * (1.0 - s), v.b.p - v.out.p, p.rho, p.dp_t)
        v.observe("q", q_a + q_b, "m^3/s", "flow to the outlet")
        return [v.a.q - q_a, v.b.q - q_b, v.a.q + v.b.q + v.out.q]


class FlowControlValveParams(Params):
    A_meter: float = Field(..., gt=0.0, le=1e-2, description="Metering orifice area [m^2]")
    dp_c: float = Field(8e5, gt=0.0, le=5e6,
                        description="Compensator setting: metering pressure drop [Pa]")
    dp_band: float = Field(1e5, gt=0.0, le=5e6,
                           description="Band of metering drop over which the compensator "
                                       "closes [Pa]")
    A_comp: float = Field(..., gt=0.0, le=1e-2,
                          description="Fully open compensator area [m^2]")
    A_leak: float = Field(1e-11, gt=0.0, le=1e-5,
                          description="Leakage area of the closed compensator [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-]")
    rho: float = rho_field()
    dp_t: float = Field(1e3, gt=0.0, le=1e6,
                        description="Laminar-turbulent transition pressure drop [Pa]")

    @model_validator(mode="after")
    def _band(self):
        if self.dp_band >= self.dp_c:
            raise ValueError(f"dp_band ({self.dp_band!r}) must be below dp_c ({self.dp_c!r})")
        return self

    @property
    def Q_set(self) -> float:
        """Regulated flow at the metering drop ``dp_c`` [m^3/s]."""
        return orifice_flow(self.Cd, self.A_meter, self.dp_c, self.rho, self.dp_t)


class FlowControlValve(Component):
    """2-way pressure-compensated flow control A -> B: a compensator ahead of a metering orifice."""

    Params = FlowControlValveParams
    ports = {"A": Hydraulic("inlet"), "B": Hydraulic("outlet")}
    variables = {"p_i": Variable("Pa", 0.0, 1e6, "pressure between compensator and orifice")}

    def equations(self, v, p):
        dp_m = v.observe("dp_meter", v.p_i - v.B.p, "Pa", "drop across the metering orifice")
        A_c = v.observe("A_comp_open", p.A_leak + p.A_comp * (1.0 - smoothstep_ramp(
            dp_m, p.dp_c - p.dp_band, p.dp_band)), "m^2", "compensator opening")
        q_c = orifice_flow(p.Cd, A_c, v.A.p - v.p_i, p.rho, p.dp_t)
        q = v.observe("q", orifice_flow(p.Cd, p.A_meter, dp_m, p.rho, p.dp_t), "m^3/s",
                      "flow A -> B")
        return [q_c - q, v.A.q - q, v.A.q + v.B.q]
