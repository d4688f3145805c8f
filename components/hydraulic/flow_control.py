"""Flow control: the shuttle (OR) valve of LS lines, a 2-way pressure-compensated flow control
and a gear-type flow divider.

``ShuttleValve``: ports ``a``, ``b`` (inlets) and ``out``. A ball shuttles to the lower inlet and
seals it, so ``out`` connects to the higher one. With ``s = ramp(a.p - b.p; -dp_switch/2,
dp_switch)`` (C1 smoothstep from 0 to 1, :func:`pvgraph.components.hydraulic.check_valve.smoothstep_ramp`)::

    A_a = A_leak + A * s,   A_b = A_leak + A * (1 - s)
    a.q = orifice(A_a, a.p - out.p),  b.q = orifice(A_b, b.p - out.p),  out.q = -(a.q + b.q)

Flow can return from ``out`` to the higher inlet (an LS line draining through the section that
sets it), as in a real shuttle.

``FlowControlValve`` (2-way, pressure compensated): a compensator spool in series with a
metering orifice ``A_meter`` keeps the drop across the metering orifice at ``dp_c``, so the
flow from A to B is held at ``Q_set = Cd A_meter sqrt(2 dp_c / rho)`` whatever the supply or
load pressure, once the drop across the valve exceeds what the two orifices in series need.
Below that the compensator is wide open and the valve is the two orifices in series, of
equivalent area ``A_s = A_meter A_comp / sqrt(A_meter^2 + A_comp^2)``; reverse flow (B to A)
passes both, unregulated. The static characteristic, with ``dp = A.p - B.p``::

    q_s = Cd A_s sqrt(2/rho) reg_root(dp, dp_t)          (series orifices, eq. A.4)
    q   = smooth_min(q_s, Q_set; w) - smooth_min(0, Q_set; w)   for dp >= 0,   q = q_s  below
    q  += Cd A_leak sqrt(2/rho) reg_root(dp, dp_t)       (past the closed compensator)
    A.q = q,  B.q = -q

The leakage ``A_leak`` (1e-12 m^2, a few ppm of the regulated flow) keeps the flow rising,
however little, with the pressure: a flow source feeding more than ``Q_set`` then gives an
absurdly high but finite steady pressure, which steady_state and simulate name, as for any
source into a closed valve, rather than no solution at all.

``smooth_min`` rounds the knee within ``w = 0.02 Q_set``; the constant ``smooth_min(0, Q_set;
w)`` (-1e-4 Q_set) makes the branches meet at dp = 0. The compensator's own dynamics (a fraction of a millisecond) are neglected.
"""

from __future__ import annotations

import math

from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, Variable
from pvgraph.laws import orifice_flow, smooth_min

from .check_valve import smoothstep_ramp
from .fluid import rho_field

__all__ = ["ShuttleValve", "FlowControlValve", "FlowDivider"]


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
    A_comp: float = Field(..., gt=0.0, le=1e-2,
                          description="Fully open compensator area [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-]")
    rho: float = rho_field()
    dp_t: float = Field(1e3, gt=0.0, le=1e6,
                        description="Laminar-turbulent transition pressure drop [Pa]")
    A_leak: float = Field(1e-12, gt=0.0, le=1e-6,
                          description="Leakage area past the closed compensator [m^2]")

    @property
    def Q_set(self) -> float:
        """Regulated flow at the metering drop ``dp_c`` [m^3/s]."""
        return self.Cd * self.A_meter * math.sqrt(2.0 * self.dp_c / self.rho)

    @property
    def A_series(self) -> float:
        """Equivalent area of the open compensator and the metering orifice in series [m^2]."""
        return self.A_meter * self.A_comp / math.hypot(self.A_meter, self.A_comp)


class FlowControlValve(Component):
    """2-way pressure-compensated flow control A -> B: holds ``Q_set = Cd A_meter
    sqrt(2 dp_c / rho)`` (a property of its parameters) against any pressure."""

    Params = FlowControlValveParams
    ports = {"A": Hydraulic("inlet"), "B": Hydraulic("outlet")}

    def equations(self, v, p):
        dp = v.observe("dp", v.A.p - v.B.p, "Pa", "pressure drop A - B")
        q_s = orifice_flow(p.Cd, p.A_series, dp, p.rho, p.dp_t)
        w = 0.02 * p.Q_set
        offset = smooth_min(0.0, p.Q_set, w)        # makes both branches 0 at dp = 0
        leak = orifice_flow(p.Cd, p.A_leak, dp, p.rho, p.dp_t)
        q = v.observe("q", E.where(dp > 0.0, smooth_min(q_s, p.Q_set, w) - offset, q_s) + leak,
                      "m^3/s", "flow A -> B")
        return [v.A.q - q, v.A.q + v.B.q]


class FlowDividerParams(Params):
    ratio: float = Field(0.5, gt=0.0, lt=1.0,
                         description="Share of the displaced flow that goes to A [-] (the "
                                     "sections' displacements D_A / (D_A + D_B))")
    C_leak: float = Field(0.0, ge=0.0, le=1e-9,
                          description="Laminar leakage of each section from its outlet back "
                                      "to the inlet [m^3/(s Pa)] (0: volumetrically ideal)")


class FlowDivider(Component):
    """Gear-type flow divider: two gear sections on one shaft split the inlet flow ``P`` into
    ``A`` and ``B`` in the ratio of their displacements, whatever the outlet pressures.

    The sections turn together, so each displaces its share of one flow ``Q``; the one facing
    the lower outlet pressure drives the other as a motor (the shaft carries no torque), so
    the inlet pressure is the displacement-weighted mean of the outlets' (an ideal divider
    intensifies: an outlet can be above the inlet)::

        A.q = -(r Q - C_leak (A.p - P.p)),   B.q = -((1 - r) Q - C_leak (B.p - P.p))
        P.q = -(A.q + B.q),                  P.p = r A.p + (1 - r) B.p
    """

    Params = FlowDividerParams
    ports = {"P": Hydraulic("inlet"), "A": Hydraulic("outlet, share ratio"),
             "B": Hydraulic("outlet, share 1 - ratio")}
    variables = {"Q": Variable("m^3/s", 0.0, 1e-4, "flow displaced by both sections")}

    def equations(self, v, p):
        r = p.ratio
        v.observe("P_shaft", (v.A.p - v.P.p) * r * v.Q, "W",
                  "power section B passes to section A through the shaft")
        return [v.A.q + r * v.Q - p.C_leak * (v.A.p - v.P.p),
                v.B.q + (1.0 - r) * v.Q - p.C_leak * (v.B.p - v.P.p),
                v.P.q + v.A.q + v.B.q,
                v.P.p - (r * v.A.p + (1.0 - r) * v.B.p)]
