"""The PVE's PWM-driven NC and NO solenoid valves on the two-dimensional flow maps of
:mod:`pvgraph.circuits.pvg32.tables` (report 4.5.4-4.5.5, figures 4.22, 4.55, 4.56).

::

    tau der(d) = clip(DT, 0, 1) - d                        (switching delay as a lag, 4.5.5)
    q = Q_map(d, |dp|) dp / sqrt(dp^2 + dp_eps^2)          (Q_map: tables.nc_flow_map / no_flow_map)
    Q_map(d, dp) = sum_j hat_j(dp) Q_j(d)                  (bilinear in dp, pchip in d)

``a.q = q``, ``b.q = -q``, ``q`` positive from ``a`` to ``b``. Selected by
``pve.flow_map = "tables"`` (docs/pvg32_model.md, section 6, compares it with the default
separable map). The map follows figure 4.55's lines at 2 and 13.5 bar (NC) and 2 and 4 bar
(NO), and figure 4.56's flows linear in dp at 70 % (NC) and 80 % (NO), which a separable map
Q_ref(DT) sqrt(dp / dp_ref) cannot follow (it gives the NO 2.9 instead of 9.3 cm^3/s at 80 %
and 13.5 bar). ``dp_eps`` (0.05 bar) only rounds the sign of dp; the maps are zero at dp = 0.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params, SignalIn, Variable, der

from . import tables

__all__ = ["MappedPWMValve"]

DP_EPS = 5e3        # [Pa]
KNOT_TOL = 0.005    # dp columns dropped where linear interpolation is within 0.5 % of the peak


def _knots(dp: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """Indices of the dp columns kept: a column that the linear interpolation of its kept
    neighbours reproduces within KNOT_TOL of the map's largest flow adds nothing and is
    dropped (the NC map is linear in dp over 2-16 bar: 3 columns do for 18)."""
    tol = KNOT_TOL * float(np.max(flow))
    keep = [0]
    for j in range(1, dp.size - 1):
        i, k = keep[-1], j + 1
        t = (dp[i + 1:k, None] - dp[i]) / (dp[k] - dp[i])
        line = (1 - t) * flow[:, i] + t * flow[:, k]
        if np.max(np.abs(line - flow[:, i + 1:k].T)) > tol:
            keep.append(j)
    keep.append(dp.size - 1)
    return np.array(keep)


class MappedPWMValveParams(Params):
    kind: Literal["NC", "NO"] = Field(
        ..., description="Normally closed (NC1/NC3, pilot side) or normally open (NO2/NO4, "
                         "tank side) [-] (report 4.5.4); selects tables.nc_flow_map / no_flow_map")
    tau: float = Field(..., gt=0.0, le=1.0,
                       description="Switching delay as a first-order lag on DT [s] (4.5.5: "
                                   "20 ms NC, 3 ms NO)")
    DT0: float = Field(0.0, ge=0.0, le=1.0, description="Initial effective duty cycle [-]")

    def flow_map(self) -> tables.SolenoidFlowMap:
        return tables.nc_flow_map() if self.kind == "NC" else tables.no_flow_map()


class MappedPWMValve(Component):
    """PWM solenoid valve with the two-dimensional duty-cycle-averaged flow map of tables.py."""

    Params = MappedPWMValveParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet"),
             "DT": SignalIn("duty cycle, 0..1", "1", 1.0)}
    variables = {"d": Variable("1", lambda p: p.DT0, 1.0, "effective (delayed) duty cycle")}

    def equations(self, v, p):
        fmap = p.flow_map()
        dp = v.observe("dp", v.a.p - v.b.p, "Pa", "pressure drop a - b")
        mag = E.sqrt(dp * dp + DP_EPS * DP_EPS)
        keep = _knots(fmap.dp, fmap.flow)
        dp_k, flow_k = fmap.dp[keep], fmap.flow[:, keep]
        q_abs = 0.0
        for j in range(dp_k.size):
            column = flow_k[:, j]
            if not np.any(column):
                continue
            hat = np.zeros(dp_k.size)
            hat[j] = 1.0
            w = E.interp(E.Table(dp_k, hat, method="linear", name=f"{fmap.name} dp hat {j}"),
                         mag)
            q_j = E.interp(E.Table(fmap.duty, column, method="pchip",
                                   name=f"{fmap.name} flow at {dp_k[j] / 1e5:g} bar"), v.d)
            q_abs = q_abs + w * q_j
        q = v.observe("q", q_abs * dp / mag, "m^3/s", "flow from a to b")
        v.observe("P_loss", q * dp, "W", "hydraulic power dissipated")
        return [p.tau * der(v.d) - (E.clip(v.DT, 0.0, 1.0) - v.d), v.a.q - q, v.a.q + v.b.q]
