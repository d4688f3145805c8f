"""LVDT position sensor of the PVE actuator (report section 4.5.5, eq. 4.113).

The sensor reads the main spool position ``x_m = flange.x`` [m] and outputs the measured
position ``x_m0 = y`` [m] through Sauer-Danfoss's first-order model::

    x_m0 / x_m = K / (tau * s + 1),   K = 0.945,  tau = 0.0059 s
    tau * der(y) + y = K * flange.x

Both sides of eq. 4.113 are positions (the report's x_m and x_m0, compared in eq. 4.114 with
x_set of eq. 4.110, which is in metres), so input and output are in metres; the steady-state
gain 0.945 < 1 means the sensor under-reads. The sensor's core is moved by the spool and its
small spring (190 N/m, report eq. 4.74, appendix B.3) is neglected in the report; it is kept as
an option::

    flange.f = k_spring * flange.x
"""

from __future__ import annotations

from pydantic import Field

from pvgraph.component import Component, Mechanical, Params, SignalOut, der

__all__ = ["LVDT", "LVDTParams"]


class LVDTParams(Params):
    K: float = Field(0.945, gt=0.0, le=10.0,
                     description="Static gain, measured/actual position [-] (report eq. 4.113)")
    tau: float = Field(0.0059, gt=0.0, le=10.0,
                       description="Time constant [s] (report eq. 4.113)")
    k_spring: float = Field(0.0, ge=0.0, le=1e6,
                            description="Stiffness of the LVDT core spring on the spool [N/m] "
                                        "(190 N/m, report eq. 4.74; neglected there: default 0)")
    y0: float = Field(0.0, ge=-1.0, le=1.0, description="Initial reading [m]")


class LVDT(Component):
    """LVDT position sensor, ``0.945 / (0.0059 s + 1)`` from spool to reading (eq. 4.113)."""

    Params = LVDTParams
    ports = {"flange": Mechanical("the spool whose position is read"),
             "y": SignalOut("measured position x_m0", "m", 1e-3)}

    def starts(self, p):
        return {"y": p.y0}

    def equations(self, v, p):
        return [p.tau * der(v.y) + v.y - p.K * v.flange.x,
                v.flange.f - p.k_spring * v.flange.x]
