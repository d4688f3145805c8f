"""PVE electronics: set point from the input voltage and duty cycles from the position error.

Report section 4.5.5 (eqs. 4.109, 4.110, 4.114, 4.115, figures 4.24, 4.25, 4.28)::

    V_rel = V_in / V_s                                        (4.109)
    x_set = K_input * V_rel - x_offset      [m]               (4.110)
    e     = x_set - x_meas                  [m]               (4.114)
    DT_A% = clip(-K_dt * 1000*e + DT_0, 0, 100)                (4.115)
    DT_B% = clip( K_dt * 1000*e + DT_0, 0, 100)

with ``K_input = 0.028 m``, ``x_offset = 0.014 m``, ``K_dt = 70 %/mm`` (the error enters in mm,
as on the axis of figure 4.28) and ``DT_0 = 28.4 %``. The outputs ``DT_A`` and ``DT_B`` are
fractions 0..1 (duty cycle / 100) for the solenoid valve models; the percentages are observed
as ``DT_A_pct`` and ``DT_B_pct``.

K_input: eq. 4.110 gives 0.028, table 4.15 (linear model) 0.0028. Only 0.028 is consistent
with the rest of the report: with it V_rel = 0.25, 0.5, 0.75 give x_set = -7, 0, +7 mm, the
spool's full stroke and neutral position (section 4.5.5 text and figure 4.25); with 0.0028 the
neutral input V_rel = 0.5 would command -12.6 mm, outside the stroke.

``x_meas`` is the LVDT reading (:class:`pvgraph.components.signal.LVDT`), which under-reads by its gain
0.945; the loop therefore settles where 0.945 * x_m = x_set, as in the report's model. The
duty-cycle limits are kinked (``eps = 0``, exactly eq. 4.115) or rounded within ``eps`` %.
The 3 ms / 20 ms solenoid switching delays of the section belong to the valve models.
"""

from __future__ import annotations

from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Params, SignalIn, SignalOut
from pvgraph.laws import smooth_clip

__all__ = ["PVEController", "PVEControllerParams"]


class PVEControllerParams(Params):
    V_s: float = Field(11.5, gt=0.0, le=100.0,
                       description="Supply voltage [V] (11.5 V, report table 4.14)")
    K_input: float = Field(0.028, gt=0.0, le=1.0,
                           description="Set point per relative input voltage [m] (report eq. "
                                       "4.110; not 0.0028 of table 4.15)")
    x_offset: float = Field(0.014, ge=-1.0, le=1.0,
                            description="Set-point offset [m] (report eq. 4.110)")
    K_dt: float = Field(70.0, gt=0.0, le=1e4,
                        description="Duty cycle per position error [%/mm] (report eq. 4.115)")
    DT_0: float = Field(28.4, ge=0.0, le=100.0,
                        description="Duty cycle at zero error [%] (report eq. 4.115)")
    eps: float = Field(0.0, ge=0.0, le=10.0,
                       description="Rounding of the 0 % and 100 % limits [%]; 0 is exact")


class PVEController(Component):
    """PVE set point and duty cycles (report eqs. 4.109-4.110, 4.114-4.115)."""

    Params = PVEControllerParams
    ports = {
        "V_in": SignalIn("input voltage V_in", "V", 1.0),
        "x_meas": SignalIn("measured spool position (LVDT reading)", "m", 1e-3),
        "DT_A": SignalOut("duty cycle of the port A valves NC3/NO4, fraction 0..1", "1", 1.0),
        "DT_B": SignalOut("duty cycle of the port B valves NC1/NO2, fraction 0..1", "1", 1.0),
    }

    def equations(self, v, p):
        V_rel = v.observe("V_rel", v.V_in / p.V_s, "1", "relative input voltage (eq. 4.109)")
        x_set = v.observe("x_set", p.K_input * V_rel - p.x_offset, "m",
                          "spool position set point (eq. 4.110)")
        e = v.observe("e", x_set - v.x_meas, "m", "position error (eq. 4.114)")
        e_mm = 1000.0 * e
        dt_a = v.observe("DT_A_pct", self._limit(-p.K_dt * e_mm + p.DT_0, p.eps), "%",
                         "duty cycle of port A (eq. 4.115)")
        dt_b = v.observe("DT_B_pct", self._limit(p.K_dt * e_mm + p.DT_0, p.eps), "%",
                         "duty cycle of port B (eq. 4.115)")
        return [v.DT_A - 0.01 * dt_a, v.DT_B - 0.01 * dt_b]

    @staticmethod
    def _limit(duty, eps):
        return smooth_clip(duty, 0.0, 100.0, eps) if eps > 0.0 else E.clip(duty, 0.0, 100.0)
