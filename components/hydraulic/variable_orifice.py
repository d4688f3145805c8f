"""Variable orifice: a spool metering edge whose area follows a position on a mechanical port.

Ports ``a``, ``b`` (hydraulic) and ``flange`` (the spool, mechanical). With ``x = flange.x``
and ``dp = a.p - b.p``::

    A  = A_leak + A_open(x)
    q  = Cd * A * sqrt(2/rho) * dp / (dp^2 + dp_t^2)^(1/4)          (report eq. A.4)
    a.q = q,  b.q = -q
    F_flow = -c * 2 * Cd * A * dp_abs * cos(theta)                  (report eq. A.6)
    flange.f = -F_flow

The opening ``A_open(x)`` is analytic or tabulated:

- analytic, an overlap (dead band) ``x_dead`` then a linear opening of gradient ``w``, limited
  at ``A_max``. With ``u = s(x) - x_dead``::

      A_open = w * (smooth_pos(u, eps) - smooth_pos(u - A_max/w, eps))

  where ``s(x) = x`` (``opens="positive"``), ``-x`` (``"negative"``) or ``sqrt(x^2 + x_eps^2)``
  (``"both"``: a symmetric land such as the PVG main spool, which opens A_H for either sign of
  x_m, report 4.4.2). The difference of two smooth ramps is never negative.
- tabulated: ``A_open = table(x)``, a monotone pchip through ``(x_table, A_table)``, held at the
  ends. E.g. the main spool's A_H(x_m): dead band +-1.5 mm, 69.549 mm^2 at 7 mm (report 4.4.2,
  figure 4.14).

Flow force (report appendix A.4): the steady jet force ``2 Cd A |dp| cos(theta)`` always tends
to close the opening. ``F_flow`` is the force on the spool in +x; ``c`` is the direction in
which the edge opens: +1 (``"positive"``), -1 (``"negative"``), ``tanh(x / x_eps)``
(``"both"``: towards x = 0). ``dp_abs = dp^2 / sqrt(dp^2 + dp_t^2)`` is ``|dp|`` regularised
consistently with the flow law: ``2 Cd A dp_abs = rho q^2 / (Cd A)``, the momentum flux of the
regularised flow, so the force is smooth through dp = 0. Observed: ``q``, ``A``, ``F_flow``,
``dp``.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Mechanical, Params
from pvgraph.laws import flow_force, orifice_flow, smooth_abs, smooth_pos, smooth_sign

from .fluid import rho_field


def regularised_abs_dp(dp, dp_t):
    """``dp^2 / sqrt(dp^2 + dp_t^2)``: |dp| for |dp| >> dp_t, matching ``orifice_flow``.

    With it, ``flow_force(Cd, A, regularised_abs_dp(dp, dp_t), theta)`` equals
    ``rho * q^2 / (Cd * A) * cos(theta)`` for ``q = orifice_flow(Cd, A, dp, rho, dp_t)``.
    """
    return dp * dp / smooth_abs(dp, dp_t)


class VariableOrificeParams(Params):
    opens: Literal["positive", "negative", "both"] = Field(
        "both", description="Direction of x in which the edge opens [-]: 'positive', "
                            "'negative', or 'both' (symmetric, e.g. the PVG main spool, report "
                            "4.4.2); also sets the closing direction of the flow force")
    w: float | None = Field(
        None, gt=0.0, le=10.0,
        description="Area gradient past the dead band [m^2/m] (main spool: 69.549 mm^2 / 5.5 mm "
                    "= 12.65 mm, report 4.4.2); give w or a table")
    x_dead: float = Field(
        0.0, ge=-0.1, le=0.1,
        description="Overlap (dead band) before the edge opens [m] (main spool: 1.5 mm, report "
                    "4.4.2); negative for an underlap")
    A_max: float | None = Field(
        None, gt=0.0, le=1.0, description="Largest opening area [m^2] (None: no limit)")
    x_table: tuple[float, ...] | None = Field(
        None, description="Positions of an area table [m], strictly increasing")
    A_table: tuple[float, ...] | None = Field(
        None, description="Opening areas at x_table [m^2], >= 0 (e.g. A_H(x_m), report figure "
                          "4.14)")
    A_leak: float = Field(
        1e-12, ge=0.0, le=1e-3,
        description="Leakage area added to the opening, for regularity when closed [m^2]")
    Cd: float = Field(0.6, gt=0.0, le=1.0, description="Discharge coefficient [-] (report A.1)")
    theta: float = Field(
        math.radians(69.0), ge=0.0, le=math.pi / 2,
        description="Jet angle of the flow force [rad] (69 deg for a sharp-edged port; the PVG "
                    "main spool's angled slots: 0.48 rad, report eq. 4.70)")
    rho: float = rho_field()
    dp_t: float = Field(
        5e3, gt=0.0, le=1e7,
        description="Laminar-turbulent transition pressure drop [Pa] (regularisation of eq. A.4)")
    x_eps: float = Field(
        1e-5, gt=0.0, le=1e-2,
        description="Smoothing width in x of the |x| and opening kinks [m]")

    @model_validator(mode="after")
    def _geometry(self):
        has_table = self.x_table is not None or self.A_table is not None
        if has_table:
            if self.x_table is None or self.A_table is None:
                raise ValueError("x_table and A_table must be given together")
            if self.w is not None or self.A_max is not None:
                raise ValueError("give either a table (x_table, A_table) or the analytic "
                                 "geometry (w, x_dead, A_max), not both")
            if len(self.x_table) != len(self.A_table) or len(self.x_table) < 2:
                raise ValueError(f"x_table ({len(self.x_table)} points) and A_table "
                                 f"({len(self.A_table)} points) must have the same length >= 2")
            if any(b <= a for a, b in zip(self.x_table, self.x_table[1:])):
                raise ValueError("x_table must be strictly increasing")
            if min(self.A_table) < 0.0:
                raise ValueError("A_table must not be negative")
        elif self.w is None:
            raise ValueError("give the area gradient w (analytic opening) or x_table and "
                             "A_table (tabulated opening)")
        return self

    def table(self) -> E.Table | None:
        """The area table, or None for the analytic opening."""
        if self.x_table is None:
            return None
        return E.Table(self.x_table, self.A_table, method="pchip", name="opening area")

    def opening(self, x):
        """Opening area A_open(x) [m^2], without the leakage (numbers or expressions)."""
        table = self.table()
        if table is not None:
            return table(x)
        s = {"positive": x, "negative": -x, "both": smooth_abs(x, self.x_eps)}[self.opens]
        u = s - self.x_dead
        area = self.w * smooth_pos(u, self.x_eps)
        if self.A_max is not None:
            area = area - self.w * smooth_pos(u - self.A_max / self.w, self.x_eps)
        return area

    def opening_direction(self, x):
        """+1 where more x opens the edge, -1 where less x does (smooth for 'both')."""
        if self.opens == "both":
            return smooth_sign(x, self.x_eps)
        return 1.0 if self.opens == "positive" else -1.0


class VariableOrifice(Component):
    """Spool-controlled orifice with flow force on the spool (report 4.4.2, A.4, A.6)."""

    Params = VariableOrificeParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet"),
             "flange": Mechanical("spool position x and the flow force on it")}

    def equations(self, v, p):
        x = v.flange.x
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        A = v.observe("A", p.A_leak + p.opening(x), "m^2", "opening area")
        q = v.observe("q", orifice_flow(p.Cd, A, dp, p.rho, p.dp_t), "m^3/s",
                      "flow from a to b")
        F = v.observe("F_flow",
                      -p.opening_direction(x) * flow_force(p.Cd, A,
                                                           regularised_abs_dp(dp, p.dp_t),
                                                           p.theta),
                      "N", "flow force on the spool in +x (towards closing)")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [v.a.q - q, v.a.q + v.b.q, v.flange.f + F]
