"""Opening-area tables of the PVG 32 (report chapter 4).

Everything here is a plain, documented numpy table in SI units: positions x [m], areas [m^2].
Components take the arrays, so a user can pass their own table instead (any increasing ``x``
with non-negative ``area``). :class:`AreaTable` is a thin frozen holder with a convenience
``__call__`` (linear interpolation, clamped at the ends). The PVE solenoid valves' flow map is
the component library's (``pvgraph.components.hydraulic.solenoid``: one map, docs/pvg32_model.md
section 6).

The report's AMOC tables (compensator A1, figure 4.9c; main spool A_H, figure 4.14a) are not in
the report's text. Each table below says
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pvgraph.circuits.pvg32.parameters import PVG32Params
from pvgraph.units import bar, mm, mm2

__all__ = [
    "AreaTable",
    "pvp_tank_area",
    "compensator_closing_area",
    "compensator_opening_area",
    "main_spool_area",
    "MAIN_SPOOL_LAB_ANCHORS",
    "pilot_orifice_areas",
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
                    position_scale: float = 1.0,
                    shape: tuple[float, float] | None = None) -> AreaTable:
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

    ``shape = (c2, c3)`` [-, 1/m] gives the cubic directly (c1 still from the 7 mm anchor)
    instead of fitting it to ``anchors``; :func:`pvgraph.circuits.crossval.identify` uses it.

    ``position_scale`` maps the commanded to the actual travel, x_m = scale * x_set. The default
    1.0 is the report's own assumption (eq 4.133). A model with the LVDT of eq 4.113 settles at
    x_m = (x_set - e) / 0.945: about 6 % more travel, less the small proportional error e needed
    to hold the spool against its spring; check the model's steady flows against the sweep and
    refit with e.g. ``position_scale=1/0.945`` if they come out high.
    """
    if shape is None:
        c1, c2, c3 = _main_spool_cubic(dead_band, stroke, area_at_stroke, anchors,
                                       supply_voltage, dp, cd, rho, input_gain, input_offset,
                                       position_scale)
    else:
        c2, c3 = shape
        u_full = stroke - dead_band
        c1 = (area_at_stroke - c2 * u_full**2 - c3 * u_full**3) / u_full
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
