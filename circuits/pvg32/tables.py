"""Opening-area tables and solenoid-valve flow maps of the PVG 32 (report chapter 4).

Everything here is a plain, documented numpy table in SI units: positions x [m], areas [m^2],
duty cycles DT [0..1], pressure drops dp [Pa], flows Q [m^3/s]. Components take the arrays, so a
user can pass their own table instead (any increasing ``x`` with non-negative ``area``, or any
``duty`` x ``dp`` grid of flows). :class:`AreaTable` and :class:`SolenoidFlowMap` are thin frozen
holders with a convenience ``__call__`` (linear / bilinear interpolation, clamped at the ends).

The report's AMOC tables (compensator A1, figure 4.9c; main spool A_H, figure 4.14a) and the
Danfoss 4-D solenoid-valve model (figure 4.22) are not in the report's text. Each table below says
exactly how it was reconstructed: from the report's equations, its stated anchor points, and,
where the text is silent, from the lab data and the report's own identification assumptions.
Reconstructions are monotone where the physics is (tests check this and the anchor points).

Tables
------
``pvp_tank_area``             A3(x_p), PVP spool, Vp -> tank (4.2.1, C.1.2)
``compensator_closing_area``  A1(x_k), compensator, P_p -> P0 (4.3.1, figure 4.9)
``compensator_opening_area``  A2(x_k) = pi 18 mm x_k, compensator, P0 -> P_K (eq 4.38)
``main_spool_area``           A_H(x_m), main spool, both metering edges (4.4.2, figure 4.14a)
``pilot_orifice_areas``       the fixed orifices A4, A5, A6, A7, supply, drain, check balls
``nc_flow_map`` / ``no_flow_map``  duty-cycle-averaged Q(DT, dp) of the PVE solenoid valves
                              (4.5.4 figure 4.22; anchors from figures 4.55 and 4.56)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pvgraph.circuits.pvg32.parameters import PVG32Params
from pvgraph.units import BAR, bar, mm, mm2

__all__ = [
    "AreaTable",
    "FlowAnchor",
    "SolenoidFlowMap",
    "pvp_tank_area",
    "compensator_closing_area",
    "compensator_opening_area",
    "main_spool_area",
    "MAIN_SPOOL_LAB_ANCHORS",
    "pilot_orifice_areas",
    "nc_flow_map",
    "no_flow_map",
    "NC_LINEAR_FITS",
    "NO_LINEAR_FITS",
]


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class AreaTable:
    """An opening area as a function of spool position, A(x).

    Attributes
    ----------
    name : str
        Report symbol, e.g. ``"A_H"``.
    x : ndarray
        Strictly increasing positions [m].
    area : ndarray
        Opening areas [m^2], >= 0, same length as ``x``.
    source : str
        How the table was obtained (report sections, anchors).
    """

    name: str
    x: np.ndarray
    area: np.ndarray
    source: str

    def __post_init__(self):
        x, a = _frozen(self.x), _frozen(self.area)
        if x.ndim != 1 or a.shape != x.shape or x.size < 2:
            raise ValueError(f"AreaTable {self.name}: x and area must be 1-D of equal length >= 2")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(a))):
            raise ValueError(f"AreaTable {self.name}: non-finite values")
        if np.any(np.diff(x) <= 0):
            raise ValueError(f"AreaTable {self.name}: x must be strictly increasing")
        if np.any(a < 0):
            raise ValueError(f"AreaTable {self.name}: areas must be >= 0")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "area", a)

    def __call__(self, x):
        """Linear interpolation of the area [m^2] at position(s) ``x`` [m], clamped at the ends."""
        return np.interp(x, self.x, self.area)


# ---------------------------------------------------------------------------------- PVP A3
def pvp_tank_area(dead_band: float = mm(2.0), full_stroke: float = mm(5.0),
                  area_max: float = mm2(180.0), x_end: float = mm(12.0)) -> AreaTable:
    """A3(x_p): PVP spool opening from the pump volume Vp to tank.

    Reconstruction (report C.1.2, 4.7.3, figure 4.2b): A3 = 0 for 0 <= x_p <= 2 mm (dead band,
    4.7.3 "it will first open to tank when it reaches 2 mm"; figure 4.47), then a linear ramp to
    180 mm^2 at x_p = 5 mm, then constant 180 mm^2 (figure 4.2b's axis tops at 1.8e-4 m^2 and
    its x-axis runs to 12 mm). C.1.2 writes the middle piece as "180 mm^2 / 3 mm * x_p for
    2 <= x_p <= 5 mm", which would jump to 120 mm^2 at 2 mm and overshoot to 300 mm^2 at 5 mm;
    the continuous ramp 60 mm^2/mm * (x_p - 2 mm) is taken as what is meant. The cone geometry of
    4.2.1 (slopes 11.45 and 41.82 deg, radii 9.00 / 8.84 / 8.15 mm) is not enough to rebuild the
    report's "two 6-point vectors" and is not used.
    """
    if not 0.0 <= dead_band < full_stroke < x_end:
        raise ValueError("pvp_tank_area: need 0 <= dead_band < full_stroke < x_end")
    return AreaTable(
        name="A3",
        x=[0.0, dead_band, full_stroke, x_end],
        area=[0.0, 0.0, area_max, area_max],
        source="report C.1.2 (A3: 0 to 2 mm, ramp to 180 mm^2 at 5 mm, constant after), 4.7.3 "
               "(2 mm dead band), figure 4.2b",
    )


# ---------------------------------------------------------------------------------- compensator
def compensator_closing_area(x_close: float = mm(2.7), gradient: float = mm2(20.0) / mm(1.0),
                             x_end: float = mm(6.0)) -> AreaTable:
    """A1(x_k): compensator metering edge P_p -> P0, closing as x_k grows.

    The report's AMOC table (4.3.1, figure 4.9c: 4 "Disc 1" and 4 "Disc 2" slots, 100 points
    interpolated to 10000) is only shown as a plot; no value is printed. Reconstruction:
    A1 = gradient * (x_close - x_k) for 0 <= x_k <= x_close, 0 beyond (a linear slot edge; the
    "Disc 1 area almost constant beyond ~4.5 mm of opening" of 4.3.1 lies outside the range
    reached because x_close < 4.5 mm). The two numbers are chosen, not read:

    * ``x_close`` = 2.7 mm puts the regulating point (A1 of 1-9 mm^2 for 2-14 L/min at about
      8 bar drop) at x_k = 2.24-2.64 mm, where the spring balances
      (P0 - P_LS) A_k + F_flow,1 = 105.12 N + 9945 N/m x_k  ->  P0 - P_LS = 4.9-5.1 bar
      (with a 13 bar PVP margin), i.e. the "5 bar" compensator margin of sections 2.2 and
      4.7.3 / figure 4.37.
    * ``gradient`` = 20 mm^2/mm (about 2.5 mm of slot width per slot for 8 slots) keeps that
      margin within 0.2 bar over the flow range, as figure 4.50 (constant drops) shows.

    Both are uncertain; treat them as calibration parameters.
    """
    if not 0.0 < x_close < x_end:
        raise ValueError("compensator_closing_area: need 0 < x_close < x_end")
    return AreaTable(
        name="A1",
        x=[0.0, x_close, x_end],
        area=[gradient * x_close, 0.0, 0.0],
        source="reconstruction (AMOC table of figure 4.9c not in text): linear closing edge, "
               "closed at 2.7 mm, 20 mm^2/mm, placed to give the 5 bar margin of 2.2 / 4.7.3",
    )


def compensator_opening_area(diameter: float = mm(18.0), x_end: float = mm(6.0)) -> AreaTable:
    """A2(x_k) = pi * D * x_k, compensator edge P0 -> P_K, opening as x_k grows (eq 4.38).

    Unslotted cylindrical edge of diameter 18 mm; A2 = 0 at x_k = 0 (the compensator blocks flow
    at rest, section 2.2, and stops reverse flow when P_p < P_LS, 4.3).
    """
    return AreaTable(
        name="A2",
        x=[0.0, x_end],
        area=[0.0, math.pi * diameter * x_end],
        source="report eq 4.38: A2 = pi * 18 mm * x_k",
    )


# ---------------------------------------------------------------------------------- main spool
#: Lab points used to shape A_H between the dead band and 7 mm: (U_input [V], Q_total [L/min],
#: record). Closed-L2 steady states of B.7 (first table: tests 1, 3, 4, 6, 7, 9, 10, 12) and the
#: unsaturated voltage-sweep points (second table: tests 3-6).
MAIN_SPOOL_LAB_ANCHORS: tuple[tuple[float, float, str], ...] = (
    (4.93, 1.98, "sweep-3"), (4.65, 6.74, "sweep-4"), (4.45, 9.85, "sweep-5"),
    (4.21, 15.70, "sweep-6"),
    (4.24, 13.67, "test-1"), (4.24, 14.04, "test-3"), (4.62, 7.23, "test-4"),
    (4.62, 7.23, "test-6"), (4.29, 13.70, "test-7"), (4.29, 13.75, "test-9"),
    (4.60, 8.20, "test-10"), (4.60, 8.00, "test-12"),
)


def _main_spool_cubic(dead_band: float, stroke: float, area_at_stroke: float,
                      anchors, supply_voltage: float, dp: float, cd: float, rho: float,
                      input_gain: float, input_offset: float,
                      position_scale: float = 1.0) -> tuple[float, float, float]:
    """Coefficients (c1, c2, c3) of A = c1 u + c2 u^2 + c3 u^3, u = |x| - dead_band [m]."""
    u_full = stroke - dead_band
    u, a = [], []
    for volts, q_lpm, _ in anchors:
        x = position_scale * abs(input_gain * volts / supply_voltage + input_offset)
        u.append(x - dead_band)
        a.append(q_lpm / 60000.0 / (cd * math.sqrt(2.0 * dp / rho)))
    u, a = np.asarray(u), np.asarray(a)
    # c1 eliminated by the constraint A(u_full) = area_at_stroke; least squares for c2, c3.
    m = np.column_stack([u**2 - u * u_full, u**3 - u * u_full**2])
    c2, c3 = np.linalg.lstsq(m, a - area_at_stroke * u / u_full, rcond=None)[0]
    c1 = (area_at_stroke - c2 * u_full**2 - c3 * u_full**3) / u_full
    return float(c1), float(c2), float(c3)


def main_spool_area(dead_band: float = mm(1.5), stroke: float = mm(7.0),
                    area_at_stroke: float = mm2(69.549), step: float = mm(0.05),
                    anchors=MAIN_SPOOL_LAB_ANCHORS, supply_voltage: float = 11.5,
                    dp: float = bar(5.0), cd: float = 0.6, rho: float = 900.0,
                    input_gain: float = 0.028, input_offset: float = -0.014,
                    position_scale: float = 1.0) -> AreaTable:
    """A_H(x_m): main spool opening, the same for the meter-in (P_K -> work port) and meter-out
    (work port -> tank) edges, symmetric in x_m.

    Stated by the report (4.4.2, figure 4.14a): A_H = 0 for |x_m| <= 1.5 mm, A_H(+-7 mm) =
    69.549 mm^2, symmetric about 0; AMOC geometry of a type-E spool (figure 4.37). The AMOC
    points in between are not printed. Section 4.7.3 states that, with the supply voltage
    corrected to 11.5 V, the model with this area reproduces the measured steady flows
    (figure 4.39), with 5 bar across the main spool (the assumption of figure 4.37).

    Reconstruction: A_H = c1 u + c2 u^2 + c3 u^3, u = |x_m| - 1.5 mm, with c1 fixed by the
    69.549 mm^2 anchor and (c2, c3) least-squares fitted to the areas the lab data imply under
    the report's own assumptions: x_m = x_set = 0.028 U/11.5 V - 0.014 (eq 4.110, 4.133),
    A = Q / (Cd sqrt(2 dp / rho)) with dp = 5 bar, Cd = 0.6, rho = 900 (points in
    :data:`MAIN_SPOOL_LAB_ANCHORS`). Result (mm units): c1 = 4.769 mm, c2 = -0.3438,
    c3 = 0.3229 /mm; slope > 0 everywhere (monotone), A_H(3.75 mm) = 13 mm^2. The fitted points
    scatter +-8 % around the curve (the 1.98 L/min point, within the +-1 L/min accuracy, +41 %).

    ``position_scale`` maps the commanded to the actual travel, x_m = scale * x_set. The default
    1.0 is the report's own assumption (eq 4.133). A model with the LVDT of eq 4.113 settles at
    x_m = (x_set - e) / 0.945: about 6 % more travel, less the small proportional error e needed
    to hold the spool against its spring; check the model's steady flows against the sweep and
    refit with e.g. ``position_scale=1/0.945`` if they come out high.
    """
    c1, c2, c3 = _main_spool_cubic(dead_band, stroke, area_at_stroke, anchors, supply_voltage,
                                   dp, cd, rho, input_gain, input_offset, position_scale)
    n = int(round(stroke / step))
    half = np.unique(np.concatenate([np.linspace(0.0, stroke, n + 1), [dead_band]]))
    x = np.concatenate([-half[:0:-1], half])
    u = np.abs(x) - dead_band
    u[u < 1e-12] = 0.0  # grid round-off must not open the dead band
    area = c1 * u + c2 * u**2 + c3 * u**3
    if np.any(np.diff(area[x >= 0]) < 0):
        raise ValueError("main_spool_area: fitted A_H is not monotone; check the anchors")
    return AreaTable(
        name="A_H",
        x=x, area=np.clip(area, 0.0, None),
        source="report 4.4.2 (1.5 mm dead band, 69.549 mm^2 at 7 mm, symmetric) + cubic shape "
               "fitted to B.7 lab flows with 4.7.3's assumptions (11.5 V, 5 bar, Cd 0.6)",
    )


# ---------------------------------------------------------------------------------- orifices
def pilot_orifice_areas(params: PVG32Params) -> dict[str, float | None]:
    """The fixed orifice areas [m^2] of the pilot and LS lines, keyed by report symbol.

    ``A4`` P0 -> V1 (eq 4.36, 3.5 mm^2); ``A5`` P_LS -> V2 (eq 4.37, 1 mm^2); ``A6`` V2 -> V3
    (eq 4.37, 1 mm^2); ``A7`` Vp -> V6 (table 4.14, d 0.3 mm; None if the chamber is neglected);
    ``A_supply`` pilot -> upper cavity (4.5.1, d 4 mm); ``A_drain`` lower cavity -> tank (4.5.1,
    d 1 mm); ``A_checkvalve`` lower cavity -> V4 / V5 (4.5.1, d 1.7 mm).
    """
    return {
        "A4": params.compensator.inlet_orifice_area,
        "A5": params.compensator.ls_orifice_area,
        "A6": params.pvp.ls_orifice_area,
        "A7": params.pvp.pressure_chamber_orifice_area,
        "A_supply": params.pve.supply_orifice_area,
        "A_drain": params.pve.drain_orifice_area,
        "A_checkvalve": params.pve.check_valve_area,
    }


# ---------------------------------------------------------------------------------- PVE valves
@dataclass(frozen=True)
class FlowAnchor:
    """A point (DT, dp, Q) the report's text gives for a solenoid valve, with its tolerance."""

    duty: float        # [-], 0..1
    dp: float          # [Pa]
    flow: float        # [m^3/s]
    source: str
    rel_tol: float     # relative tolerance a reconstruction must meet
    abs_tol: float = 2e-7  # [m^3/s] floor for near-zero flows


@dataclass(frozen=True, eq=False)
class SolenoidFlowMap:
    """Duty-cycle-averaged flow of a PVE solenoid valve, Q(DT, dp) >= 0 for dp >= 0.

    Attributes
    ----------
    name : str
    kind : {"NC", "NO"}
    duty : ndarray
        Increasing duty cycles in [0, 1].
    dp : ndarray
        Increasing pressure drops [Pa], starting at 0.
    flow : ndarray
        Flows [m^3/s], shape (len(duty), len(dp)).
    anchors : tuple of FlowAnchor
        Points stated in the report that the table must pass through (within tolerance).
    source : str

    Use ``Q = map(DT, |dp|) * sign(dp)`` (regularised near dp = 0) for reverse flow; the report
    models these valves as uni-directional in practice (pilot side above chamber above tank side).
    """

    name: str
    kind: str
    duty: np.ndarray
    dp: np.ndarray
    flow: np.ndarray
    anchors: tuple[FlowAnchor, ...]
    source: str

    def __post_init__(self):
        duty, dp, flow = _frozen(self.duty), _frozen(self.dp), _frozen(self.flow)
        if duty.ndim != 1 or dp.ndim != 1 or flow.shape != (duty.size, dp.size):
            raise ValueError(f"SolenoidFlowMap {self.name}: flow must have shape (len(duty), len(dp))")
        if np.any(np.diff(duty) <= 0) or np.any(np.diff(dp) <= 0):
            raise ValueError(f"SolenoidFlowMap {self.name}: duty and dp must be strictly increasing")
        if duty[0] < 0 or duty[-1] > 1 or dp[0] != 0.0:
            raise ValueError(f"SolenoidFlowMap {self.name}: duty must lie in [0, 1] and dp start at 0")
        if not np.all(np.isfinite(flow)) or np.any(flow < 0):
            raise ValueError(f"SolenoidFlowMap {self.name}: flows must be finite and >= 0")
        object.__setattr__(self, "duty", duty)
        object.__setattr__(self, "dp", dp)
        object.__setattr__(self, "flow", flow)

    def __call__(self, duty, dp):
        """Bilinear interpolation of Q [m^3/s] at (duty [0..1], dp [Pa] >= 0), clamped to the grid."""
        d = np.clip(np.asarray(duty, dtype=float), self.duty[0], self.duty[-1])
        p = np.clip(np.asarray(dp, dtype=float), self.dp[0], self.dp[-1])
        d, p = np.broadcast_arrays(d, p)
        i = np.clip(np.searchsorted(self.duty, d, side="right") - 1, 0, self.duty.size - 2)
        j = np.clip(np.searchsorted(self.dp, p, side="right") - 1, 0, self.dp.size - 2)
        td = (d - self.duty[i]) / (self.duty[i + 1] - self.duty[i])
        tp = (p - self.dp[j]) / (self.dp[j + 1] - self.dp[j])
        f = self.flow
        q = ((1 - td) * (1 - tp) * f[i, j] + td * (1 - tp) * f[i + 1, j]
             + (1 - td) * tp * f[i, j + 1] + td * tp * f[i + 1, j + 1])
        return q if q.ndim else float(q)


#: Linear fits printed in figure 4.55, Q = slope * DT[%] + intercept [m^3/s], by dp [bar].
NC_LINEAR_FITS: dict[float, tuple[float, float]] = {13.5: (3.0e-7, -3.7e-6), 2.0: (1.1e-7, -2.4e-6)}
NO_LINEAR_FITS: dict[float, tuple[float, float]] = {4.0: (-1.8e-7, 1.6e-5), 2.0: (-1.7e-7, 1.3e-5)}
#: Figure 4.56: Q vs dp [Pa] at fixed duty, Q = slope * dp + intercept.
NC_DP_FIT_70 = (1.2e-11, 1.5e-6)   # NC, DT = 70 %
NO_DP_FIT_80 = (8.3e-12, -1.9e-6)  # NO, DT = 80 %

_DUTY_GRID = np.linspace(0.0, 1.0, 101)
_DP_GRID_BAR = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 13.5, 14, 15, 16], float)


def _fit(fits, dp_bar, duty):
    slope, intercept = fits[dp_bar]
    return np.maximum(slope * 100.0 * duty + intercept, 0.0)


def nc_flow_map() -> SolenoidFlowMap:
    """Normally-closed valve (NC1, NC3; pilot side): Q rises with DT and dp.

    Reconstruction of figure 4.22 (left; curves 2-16 bar, 50 degC, 13 V, max ~3e-5 m^3/s at
    16 bar and 100 %) from the numbers the text gives:

    * figure 4.55 linear fits, Q = 3.0e-7 DT[%] - 3.7e-6 at 13.5 bar and
      Q = 1.1e-7 DT[%] - 2.4e-6 at 2 bar, clipped at 0 (the NC passes nothing below ~12 % resp.
      ~22 % duty: its 20 ms switching delay, 4.5.5);
    * between 0 and 2 bar Q scales linearly with dp to 0; between 2 and 13.5 bar it is linear in
      dp, which figure 4.56 shows at DT = 70 % (Q = 1.2e-11 dp + 1.5e-6); above 13.5 bar the same
      slope is extended to 16 bar, giving 3.0e-5 m^3/s at 100 %, the top of figure 4.22.

    Anchors: the two fit lines (exact) and the figure-4.56 line at 8 and 12 bar (10 %).
    """
    duty = _DUTY_GRID
    q2, q135 = _fit(NC_LINEAR_FITS, 2.0, duty), _fit(NC_LINEAR_FITS, 13.5, duty)
    cols = []
    for p in _DP_GRID_BAR:
        if p <= 2.0:
            cols.append(q2 * p / 2.0)
        else:
            cols.append(q2 + (q135 - q2) * (p - 2.0) / 11.5)
    anchors = []
    for p in (2.0, 13.5):
        slope, icpt = NC_LINEAR_FITS[p]
        for d in (0.3, 0.5, 0.7, 1.0):
            anchors.append(FlowAnchor(d, bar(p), slope * 100 * d + icpt,
                                      f"figure 4.55 NC linear fit at {p} bar", 1e-9))
    for p in (8.0, 12.0):
        anchors.append(FlowAnchor(0.7, bar(p), NC_DP_FIT_70[0] * bar(p) + NC_DP_FIT_70[1],
                                  "figure 4.56 NC, DT = 70 %", 0.10))
    return SolenoidFlowMap(
        name="NC", kind="NC", duty=duty, dp=_DP_GRID_BAR * BAR, flow=np.column_stack(cols),
        anchors=tuple(anchors),
        source="figure 4.22 (left) reconstructed from the figure 4.55 fits (2, 13.5 bar) and "
               "figure 4.56 (DT 70 %)",
    )


def no_flow_map() -> SolenoidFlowMap:
    """Normally-open valve (NO2, NO4; tank side): Q falls with DT, rises with dp.

    Reconstruction of figure 4.22 (right; 2-16 bar, "larger constant region" than the NC) from
    the numbers the text gives:

    * 2 and 4 bar: figure 4.55 linear fits Q = -1.7e-7 DT[%] + 1.3e-5 (2 bar) and
      Q = -1.8e-7 DT[%] + 1.6e-5 (4 bar), clipped at 0 (text 4.8.2 says 4 bar; the caption's
      "6 bar" contradicts the legend);
    * 6-16 bar: piecewise linear in DT through (0 %, Q0), (80 %, Q80), (100 %, 0), with
      Q80 = 8.3e-12 dp - 1.9e-6 (figure 4.56, DT = 80 %) and the fully open flow
      Q0 = 1.6e-5 sqrt(dp / 4 bar) (orifice scaling of the 4 bar fit's intercept; figure 4.22's
      peak value at 16 bar is not printed). Continuously energised (100 %) the NO is shut;
    * between grid pressures Q is linear in dp.

    At 4 bar the 6-bar construction and the 4-bar fit agree within 1 % at 30 %, which supports it.
    Anchors: the two fit lines (exact) and the figure-4.56 line at 8 and 13.5 bar (exact).
    """
    duty = _DUTY_GRID
    cols = []
    for p in _DP_GRID_BAR:
        if p == 0.0:
            cols.append(np.zeros_like(duty))
        elif p in (2.0, 4.0):
            cols.append(_fit(NO_LINEAR_FITS, p, duty))
        elif p >= 6.0:
            q0 = NO_LINEAR_FITS[4.0][1] * math.sqrt(p / 4.0)
            q80 = max(NO_DP_FIT_80[0] * bar(p) + NO_DP_FIT_80[1], 0.0)
            cols.append(np.interp(duty, [0.0, 0.8, 1.0], [q0, q80, 0.0]))
        else:
            cols.append(None)
    # fill 1, 3, 5 bar by linear interpolation in dp between the defined columns
    defined = [k for k, c in enumerate(cols) if c is not None]
    for k, c in enumerate(cols):
        if c is None:
            lo = max(i for i in defined if _DP_GRID_BAR[i] < _DP_GRID_BAR[k])
            hi = min(i for i in defined if _DP_GRID_BAR[i] > _DP_GRID_BAR[k])
            t = (_DP_GRID_BAR[k] - _DP_GRID_BAR[lo]) / (_DP_GRID_BAR[hi] - _DP_GRID_BAR[lo])
            cols[k] = (1 - t) * cols[lo] + t * cols[hi]
    anchors = []
    for p in (2.0, 4.0):
        slope, icpt = NO_LINEAR_FITS[p]
        for d in (0.0, 0.3, 0.5, 0.7):
            anchors.append(FlowAnchor(d, bar(p), slope * 100 * d + icpt,
                                      f"figure 4.55 NO linear fit at {p} bar", 1e-9))
    for p in (8.0, 13.5):
        anchors.append(FlowAnchor(0.8, bar(p), NO_DP_FIT_80[0] * bar(p) + NO_DP_FIT_80[1],
                                  "figure 4.56 NO, DT = 80 %", 1e-9))
    return SolenoidFlowMap(
        name="NO", kind="NO", duty=duty, dp=_DP_GRID_BAR * BAR, flow=np.column_stack(cols),
        anchors=tuple(anchors),
        source="figure 4.22 (right) reconstructed from the figure 4.55 fits (2, 4 bar) and "
               "figure 4.56 (DT 80 %), orifice scaling of the fully open flow",
    )
