"""Parameters of the PVG 32 valve and its lab rig, with provenance.

Every value comes from the 2009 PVG 32 modelling report (not shipped with pvgraph) and
carries the section, equation or table in its field description. Everything is SI (Pa, m, m^2,
m^3, m^3/s, kg, N, N/m, N s/m, s, rad); report units are converted here, at the edge, with
the helpers of :mod:`pvgraph.units`. Opening-area tables and the solenoid-valve flow maps are in
:mod:`pvgraph.circuits.pvg32.tables`; the model they feed is summarised in ``docs/pvg32_model.md``.

Presets
-------
``report_initial()``
    The report's model before tuning: chapters 4.2-4.6 with the uncertain parameters of
    table 4.9 (pump 17 L/min, supply 12 V, viscous friction 9000/9000/25 N s/m, no Coulomb
    friction, PVP pressure chamber not modelled).
``report_tuned()``
    The validated model: table 4.14 (pump 16.3 L/min, supply 11.5 V, viscous friction
    35000/20000/25 N s/m, Coulomb 0 N (PVP) and 50 N (compensator), 0.3 mm orifice A7 to the PVP
    spool pressure chamber).

Where the report contradicts itself a value is chosen and the choice is stated in the field
description (marked "CHOICE:") and in ``docs/pvg32_model.md`` (section "Contradictions").
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from pvgraph.units import bar, circle_area, cm3, deg, litre, lpm, lpm_per_bar, mm, mm2

__all__ = [
    "FluidParams",
    "PVPParams",
    "CompensatorParams",
    "MainSpoolParams",
    "SolenoidValveParams",
    "PVEParams",
    "LoadOrificeParams",
    "RigSolenoidValveParams",
    "RigParams",
    "PVG32Params",
    "report_initial",
    "report_tuned",
    "parameter_paths",
    "parameter_field",
    "with_values",
    "parameter_table",
]

_SPOOL_D = mm(18.0)  # all three spools are 18 mm (eq 4.5, 4.32, 4.71)

#: A_H shape (c2 [-], c3 [1/m]) of both presets: least squares to the flows of
#: tables.MAIN_SPOOL_LAB_ANCHORS at the travel and main-spool drop this model settles at with
#: U_s = 11.5 V (three fixed-point passes of circuits.crossval's step 3; residuals -0.7 to
#: +0.7 L/min). These 12 flows are therefore fitted, not predicted (circuits.crossval).
TUNED_OPENING_SHAPE = (-0.5834, 338.46)


class _Params(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# --------------------------------------------------------------------------------------------
class FluidParams(_Params):
    """Hydraulic oil (report 4.2.3, 4.2.5, 4.7.2, A.5)."""

    density: float = Field(
        900.0, ge=700.0, le=1100.0,
        description="Oil density rho [kg/m^3] (4.2.3: 850-950, assumed 900)")
    bulk_modulus: float = Field(
        bar(7000.0), ge=bar(1000.0), le=bar(25000.0),
        description="Effective bulk modulus beta [Pa] (A.5, 4.2.3, table 4.9: 7000 bar)")
    kinematic_viscosity: float = Field(
        32e-6, gt=0.0, le=1e-3,
        description="Kinematic viscosity nu [m^2/s] (4.2.5, 4.7.2: ISO VG 32 assumed, 32 cSt; "
                    "datasheet range 12-75 cSt). Used only for Reynolds numbers and the "
                    "friction estimate eq 4.25; the laminar load constants are fitted (table 4.8)")
    temperature: float = Field(
        50.0, ge=-40.0, le=150.0,
        description="Oil temperature [degC] (4.5.4: condition of the solenoid-valve flow maps "
                    "figure 4.22; not used elsewhere)")

    @property
    def dynamic_viscosity(self) -> float:
        """Dynamic viscosity mu = nu * rho [Pa s] (eq 4.25: 0.029 Pa s)."""
        return self.kinematic_viscosity * self.density


# --------------------------------------------------------------------------------------------
class PVPParams(_Params):
    """PVP pump-side module: the pressure-adjustment (pump-side compensator) spool, section 4.2.

    Geometry: x_p = 0 with the spool against the left wall; +x_p compresses the spring and opens
    A3 (Vp -> tank) after a 2 mm dead band. Pressure side: Vp (pump line) or, with the tuned
    model, a small pressure chamber V6 fed from Vp through orifice A7. Spring side: chamber V3,
    fed from the compensator spring chamber V2 (pressure P2 ~ P_LS) through orifice A6.
    """

    spool_mass: float = Field(
        0.070, gt=0.0, le=5.0, description="Mass of the PVP spool M_p [kg] (eq 4.3: 70 g, weighed)")
    spool_diameter: float = Field(
        _SPOOL_D, gt=0.0, le=0.1, description="Spool diameter d_p [m] (4.2: 18 mm)")
    spool_area: float = Field(
        circle_area(_SPOOL_D), gt=0.0, le=1e-2,
        description="Spool end area A_p = pi d_p^2/4 [m^2] (eq 4.5: 2.54 cm^2); the pressure "
                    "force is (P_p - P3) A_p. CHOICE: eq 4.7/4.8 write P A3 (A3 is the tank "
                    "opening area, a typo); eq 4.29 and C.1 use A_p")
    spring_rate: float = Field(
        15000.0, gt=0.0, le=1e6,
        description="Spring constant k_p [N/m] (eq 4.4, 4.19, B.1: fit 14688, rounded 15000)")
    spring_preload: float = Field(
        300.0, ge=0.0, le=5000.0,
        description="Spring force at x_p = 0 F_preload-p [N] (eq 4.17, 4.19, B.1: 20 mm x 15000 "
                    "N/m). CHOICE: B.1 also quotes a mounted length of 28.9 mm, which would give "
                    "17 mm and 255 N; 300 N is the value used in eq 4.19 and the model")
    tank_area_dead_band: float = Field(
        mm(2.0), ge=0.0, le=mm(10.0),
        description="Overlap before A3 (Vp -> tank) starts to open [m] (4.7.3, figure 4.47, "
                    "C.1.2: 2 mm)")
    tank_area_full_stroke: float = Field(
        mm(5.0), gt=0.0, le=mm(20.0),
        description="Stroke x_p at which A3 reaches its maximum [m] (C.1.2: 5 mm)")
    tank_area_max: float = Field(
        mm2(180.0), gt=0.0, le=1e-3,
        description="Maximum opening area of A3 [m^2] (C.1.2: 180 mm^2; figure 4.2b ~1.7e-4)")
    stroke_max: float = Field(
        mm(10.0), gt=0.0, le=0.05,
        description="Largest x_p covered by the area data [m] (C.1.2 gives A3 up to 10 mm; no "
                    "mechanical stop is stated)")
    flow_angle: float = Field(
        deg(69.0), ge=0.0, le=math.pi / 2,
        description="Jet angle theta at A3 for the flow force 2 Cd A3 (P_p - P_T) cos(theta) [rad] "
                    "(eq 4.16: 69 deg, unslotted edge)")
    pump_volume: float = Field(
        litre(2.7), gt=0.0, le=0.1,
        description="Volume Vp from the pump through the piping to the compensator spool chamber "
                    "[m^3] (eq 4.2, B.6: hoses 1 + 2 = 0.19 L + 2.513 L); constant (4.2.3)")
    spring_chamber_volume: float = Field(
        cm3(8.0), gt=0.0, le=1e-3,
        description="Spring chamber volume V3 at x_p = 0 [m^3] (eq 4.1: 8 cm^3, V3(x_p) = V3 - "
                    "A_p x_p)")
    ls_orifice_area: float = Field(
        mm2(1.0), gt=0.0, le=1e-4,
        description="Orifice A6 from the PVB compensator spring chamber (P2) to the PVP spring "
                    "chamber (P3) [m^2] (eq 4.11, 4.37: 1 mm^2). CHOICE: 4.3.1 says d = 1 mm, "
                    "which is 0.785 mm^2; the stated area 1 mm^2 is kept")
    pressure_chamber_orifice_diameter: float | None = Field(
        None, gt=0.0, le=mm(5.0),
        description="Diameter of orifice A7 from Vp to the PVP spool pressure chamber V6 [m] "
                    "(4.7.3, table 4.14: 0.3 mm). None = chamber neglected, P_p acts directly on "
                    "the spool (4.2.2, initial model)")
    pressure_chamber_volume: float = Field(
        cm3(0.5), gt=0.0, le=1e-4,
        description="Volume of the PVP spool pressure chamber V6 at x_p = 0 [m^3]; V6(x_p) = V6 + "
                    "A_p x_p. Not given in the report: 4.7.3 says the chamber was added 'the same "
                    "way as for the compensator spool', so V1's 0.5 cm^3 (eq 4.30) is assumed. "
                    "Only used when pressure_chamber_orifice_diameter is set")
    viscous_friction: float = Field(
        9000.0, ge=0.0, le=1e6,
        description="Viscous friction coefficient c_vp [N s/m] (table 4.9: 9000 initial; table "
                    "4.14: 35000 tuned; eq 4.28 estimate 5760)")
    coulomb_friction: float = Field(
        0.0, ge=0.0, le=1e4,
        description="Coulomb friction force c_cp [N] (tables 4.9 and 4.14: 0 N; 4.2.5 estimate "
                    "2 * 0.57 * A_active * P_p)")

    @property
    def pressure_chamber_orifice_area(self) -> float | None:
        """Area of A7 [m^2] (table 4.14: pi (0.3 mm)^2 / 4 = 0.0707 mm^2), or None."""
        d = self.pressure_chamber_orifice_diameter
        return None if d is None else circle_area(d)


# --------------------------------------------------------------------------------------------
class CompensatorParams(_Params):
    """PVB pressure-compensator spool, section 4.3.

    x_k = 0 with the spool at its left end (A2 closed). +x_k (pushed by P1 against the spring and
    P2) opens A2 = pi D x_k and closes A1. V1 (pressure P1) is fed from P0 through A4; V2 (spring
    chamber, pressure P2) from the load-sense pressure P_LS through A5.
    """

    spool_mass: float = Field(
        0.066, gt=0.0, le=5.0, description="Mass of the compensator spool M_k [kg] (eq 4.33: 66 g)")
    spool_diameter: float = Field(
        _SPOOL_D, gt=0.0, le=0.1, description="Spool diameter [m] (4.3, eq 4.32: 18 mm)")
    spool_area: float = Field(
        circle_area(_SPOOL_D), gt=0.0, le=1e-2,
        description="End area A_k [m^2] (eq 4.32: 2.54 cm^2); pressure force (P1 - P2) A_k "
                    "(eq 4.54)")
    spring_rate_1: float = Field(
        9945.0, gt=0.0, le=1e6,
        description="Rate of the long, always active spring k_c1 [N/m] (eq 4.34, B.2 fit 9942.9)")
    spring_rate_2: float = Field(
        35000.0, gt=0.0, le=1e7,
        description="Combined rate of both springs k_c2 for x_k > second_stage_start [N/m] "
                    "(eq 4.35, B.2 fit 35113)")
    spring_preload: float = Field(
        105.12, ge=0.0, le=5000.0,
        description="Spring force at x_k = 0 F_preload-k [N] (eq 4.57, B.2: 10.57 mm x 9945 N/m)")
    second_stage_start: float = Field(
        mm(5.2), gt=0.0, le=0.05,
        description="Stroke x_k where the second spring engages [m] (4.3.5: 5.2 mm). NOTE: with "
                    "V2 = 1 cm^3 - A_k x_k (eq 4.31) V2 vanishes at 3.93 mm, so the report's "
                    "model never reaches this stage")
    opening_diameter: float = Field(
        _SPOOL_D, gt=0.0, le=0.1,
        description="Diameter of the unslotted edge forming A2 = pi D x_k [m] (eq 4.38: 18 mm)")
    inlet_orifice_area: float = Field(
        mm2(3.5), gt=0.0, le=1e-4,
        description="Orifice A4 from P0 (between A1 and A2) to the pressure chamber V1 [m^2] "
                    "(eq 4.36, 4.48: 3.5 mm^2). CHOICE: 4.3.1 gives D4 = 1.5 mm, i.e. "
                    "1.77 mm^2; the stated area 3.5 mm^2 is kept")
    ls_orifice_area: float = Field(
        mm2(1.0), gt=0.0, le=1e-4,
        description="Orifice A5 from the load-sense pressure P_LS to the spring chamber V2 [m^2] "
                    "(eq 4.37, 4.51, 4.72: 1 mm^2; A5 = A6). CHOICE: d = 1 mm would give "
                    "0.785 mm^2; the stated 1 mm^2 is kept")
    pressure_chamber_volume: float = Field(
        cm3(0.5), gt=0.0, le=1e-4,
        description="V1 at x_k = 0 [m^3] (eq 4.30: 0.5 cm^3 added 'to make the model work'); "
                    "V1(x_k) = V1 + A_k x_k")
    spring_chamber_volume: float = Field(
        cm3(1.0), gt=0.0, le=1e-4,
        description="V2 at x_k = 0 [m^3] (eq 4.31: 1 cm^3); V2(x_k) = V2 - A_k x_k")
    closing_flow_angle: float = Field(
        deg(69.0), ge=0.0, le=math.pi / 2,
        description="Jet angle phi1 at A1 [rad] (eq 4.55). Not given numerically in the report; "
                    "69 deg assumed (the value 4.2.4 uses for a spool edge)")
    opening_flow_angle: float = Field(
        deg(69.0), ge=0.0, le=math.pi / 2,
        description="Jet angle phi2 at A2 [rad] (eq 4.56). Not given numerically in the report; "
                    "69 deg assumed (unslotted edge, as 4.2.4)")
    viscous_friction: float = Field(
        9000.0, ge=0.0, le=1e6,
        description="Viscous friction coefficient c_vc [N s/m] (table 4.9: 9000 initial; table "
                    "4.14: 20000 tuned; 4.3.6 estimate 5760)")
    coulomb_friction: float = Field(
        0.0, ge=0.0, le=1e4,
        description="Coulomb friction force c_cc [N] (table 4.9: 0 N; table 4.14: 50 N tuned; "
                    "4.3.6 estimate 3.7e-4 m^2 * P_p)")
    friction_law: Literal["smooth", "lugre"] = Field(
        "smooth",
        description="Law of the Coulomb term [-]: 'smooth' F_c tanh(v / 1 mm/s) (no force at "
                    "rest: the spool creeps under any force), 'lugre' stick-slip "
                    "(circuits.pvg32.friction: holds up to F_c at rest, +-1.96 bar at 50 N)")

    @property
    def preload_stage_2(self) -> float:
        """Intercept of the second spring line F = k_c2 x_k + F2 [N], continuous at 5.2 mm.

        F2 = F_preload + (k_c1 - k_c2) * x_2 = -25.17 N for the report values. CHOICE: eq 4.59/4.60
        give -20 N from a slip (9945 * 5 mm and 35000 * 5 mm instead of 5.2 mm), which would put
        a 5.2 N step into the spring force; continuity is kept instead.
        """
        return self.spring_preload + (self.spring_rate_1 - self.spring_rate_2) * self.second_stage_start

    @property
    def stroke_max(self) -> float:
        """Stroke at which V2(x_k) = V2 - A_k x_k reaches zero [m] (eq 4.31: 3.93 mm)."""
        return self.spring_chamber_volume / self.spool_area


# --------------------------------------------------------------------------------------------
class MainSpoolParams(_Params):
    """Main spool (PVB), section 4.4.

    x_m = 0 in neutral; +x_m grows the PVE port-A chamber V4 and shrinks V5 (eq 4.93/4.94); the
    pressure force is (P4 - P5) A_m (eq 4.86). A_H(|x_m|) is the opening of both metering edges
    (P_K -> work port and work port -> tank), symmetric with a +-1.5 mm dead band.
    """

    spool_mass: float = Field(
        0.185, gt=0.0, le=5.0, description="Mass of the main spool [kg] (eq 4.67: 185 g)")
    lever_equivalent_mass: float = Field(
        1.569, ge=0.0, le=10.0,
        description="Translational equivalent of the manual lever inertia [kg] (eq 4.82: 1.569 "
                    "kg; table 4.15 uses M_m = 1.754 kg). CHOICE: kept as the report simulated it; "
                    "note I/r^2 = 62732 g mm^2 / (20 mm)^2 = 0.157 kg, the report's value is 10x "
                    "too large (arithmetic slip in eq 4.81-4.82)")
    spool_diameter: float = Field(
        _SPOOL_D, gt=0.0, le=0.1, description="Spool diameter D_m [m] (eq 4.71: 18 mm)")
    spool_area: float = Field(
        circle_area(_SPOOL_D), gt=0.0, le=1e-2,
        description="End area A_m acted on by P4 and P5 [m^2] (eq 4.71, 4.92: 254 mm^2)")
    spring_rate: float = Field(
        3596.0, gt=0.0, le=1e6,
        description="Centering spring constant k_m [N/m] (B.4 fit 3596 x + 4.791, eq 4.88). "
                    "CHOICE: eq 4.73 and table 4.15 print 3695 (digits transposed); the measured "
                    "3596 is also the one that reproduces the 65.05 N preload (B.7)")
    spring_preload: float = Field(
        65.05, ge=0.0, le=5000.0,
        description="Preload of the double-acting centering spring F_preload-m [N] (eq 4.87, "
                    "B.4: 18.09 mm x 3596 N/m); F_SM = k_m x_m + F_preload sign(x_m). Eq 4.91 "
                    "omits the preload, eq 4.88 keeps it")
    dead_band: float = Field(
        mm(1.5), ge=0.0, le=mm(7.0),
        description="Overlap of each metering edge: A_H = 0 for |x_m| <= dead_band [m] "
                    "(4.4.2, figure 4.14a: +-1.5 mm)")
    area_at_full_stroke: float = Field(
        mm2(69.549), gt=0.0, le=1e-3,
        description="A_H at |x_m| = 7 mm [m^2] (4.4.2, AMOC: 69.549 mm^2, spool type E)")
    stroke_max: float = Field(
        mm(7.0), gt=0.0, le=0.05,
        description="Maximum travel |x_m| [m] (4.4.2, 4.5.5: +-7 mm)")
    flow_angle: float = Field(
        deg(27.73), ge=0.0, le=math.pi / 2,
        description="Jet angle phi3 through the angled slots [rad] (eq 4.69: atan((3.115 - 0.15) "
                    "mm / 5.64 mm) = 27.73 deg = 0.48 rad)")
    flow_force_factor: float = Field(
        4.0, ge=0.0, le=10.0,
        description="Factor of the combined flow force F = factor * Cd A_H (P_K - P_LS) "
                    "cos(phi3) [-] (eq 4.85: 4 = two edges x 2 Cd, meter-in and meter-out assumed "
                    "equal); acts towards x_m = 0")
    viscous_friction: float = Field(
        25.0, ge=0.0, le=1e6,
        description="Viscous friction coefficient c_vm [N s/m] (tables 4.9 and 4.14: 25; 4.4.6 "
                    "estimate 5760; 4.8.4 shows the linear loop needs ~2500 to be damped)")
    coulomb_friction: float = Field(
        0.0, ge=0.0, le=1e4,
        description="Coulomb friction c_cm [N] (4.4.7: neglected; 4.4.6 estimate 8.8e-4 m^2 * P_p)")
    clearance_leakage: float = Field(
        1.35e-14, ge=0.0, le=1e-9,
        description="Laminar leakage conductance of each metering land through the radial "
                    "clearance, in parallel with the edge [m^3/(s Pa)]. Not in the report. An "
                    "annular gap leaks pi d c^3 dp / (12 mu L): d = 18 mm, c = 5 um, L = 1.5 mm "
                    "overlap, mu = 0.029 Pa s gives 1.35e-14 (8 cm^3/min at 100 bar; the PVG 32 "
                    "data sheet allows 20 cm^3/min A/B -> T at 100 bar). Negligible against the "
                    "metered flow (< 0.01 L/min), but in neutral the four equal leaks hold the "
                    "closed work ports at (P_K + P_T) / 2, with a time constant of about 17 s "
                    "for the rig's 0.63 L of hoses; 0 = no leakage (the report)")
    meter_out_overlap: float = Field(
        0.0, ge=0.0, le=mm(1.0),
        description="Extra overlap of the meter-out edges A->T and B->T beyond dead_band [m]: "
                    "A_out(x_m) = A_H(|x_m| - meter_out_overlap). The report uses one A_H for "
                    "all four edges (4.4.2, eq 4.84); spools are often cut with the return edges "
                    "opening later. 0 = the report. Identifiable only weakly from Pb (Pb - P_T "
                    "is the meter-out drop): docs/pvg32_model.md section 8b")
    meter_out_area_ratio: tuple[float, float] = Field(
        (1.0, 0.0),
        description="Meter-out edges A->T and B->T as a multiple of the meter-in opening: "
                    "A_out(x_m) = A_H(x_m) max(r0 + r1 u, 0.05), u = |x_m| - dead_band, given as "
                    "(r0 [-], r1 [1/m]). The report uses one A_H for all four edges (4.4.2, eq "
                    "4.84): (1, 0). Pb - P_T is the meter-out drop, so the rig's Pb, which falls "
                    "with the travel, identifies it (circuits.crossval.identify(meter_out="
                    "'ratio'); docs/pvg32_model.md section 8b)")
    opening_shape: tuple[float, float] | None = Field(
        TUNED_OPENING_SHAPE,
        description="Shape (c2 [-], c3 [1/m]) of the metering opening A_H = c1 u + c2 u^2 + "
                    "c3 u^3, u = |x_m| - dead_band, c1 fixed by area_at_full_stroke (4.4.2 gives "
                    "only the dead band and 69.549 mm^2 at 7 mm). Default: fitted to the 12 lab "
                    "flows of tables.MAIN_SPOOL_LAB_ANCHORS at the travel and drop this model "
                    "settles at (TUNED_OPENING_SHAPE). None = the cubic of "
                    "tables.main_spool_area under 4.7.3's assumptions (modules.main_spool_opening)."
                    " circuits.crossval.identify refits it from the data it is given")
    lvdt_spring_rate: float = Field(
        190.0, ge=0.0, le=1e5,
        description="Spring of the LVDT core acting on the spool [N/m] (eq 4.74, B.3). Neglected "
                    "in the report's model (4.4.2)")

    @property
    def total_mass(self) -> float:
        """Spool plus lever equivalent mass M_m [kg] (4.4.3; table 4.15: 1.754 kg)."""
        return self.spool_mass + self.lever_equivalent_mass


# --------------------------------------------------------------------------------------------
class SolenoidValveParams(_Params):
    """One PVE on/off solenoid valve, driven by a duty cycle (4.5.4, 4.5.5).

    The duty-cycle-averaged flow is the NC or NO map of
    :mod:`pvgraph.components.hydraulic.solenoid` (``PWMValve``: figure 4.55's lines at the
    report's linearisation pressures, orifice scaling in dp), the model's one map
    (docs/pvg32_model.md section 6). The report delays the duty-cycle signal by the switching
    delay ("time delay implemented in the control", 4.5.5).
    """

    kind: Literal["NC", "NO"] = Field(
        description="Normally closed (pilot side, flow grows with DT) or normally open (tank "
                    "side, flow falls with DT) [-] (4.5.4)")
    chamber: Literal["A", "B"] = Field(
        description="Which main-spool end chamber the valve connects: A = P4/V4, B = P5/V5 [-] "
                    "(figure 4.19)")
    switching_delay: float = Field(
        gt=0.0, le=0.5,
        description="Delay of the duty-cycle signal [s] (4.5.5: 20 ms NC, 3 ms NO; linear model "
                    "4.8.2 uses a 3 ms first-order lag for both)")


class PVEParams(_Params):
    """PVE electro-hydraulic actuator (PVEH), section 4.5.

    Pilot source P_pilot -> A_supply -> upper cavity -> NC1 -> V5 (P5, port B) and NC3 -> V4 (P4,
    port A); V5 -> NO2 and V4 -> NO4 -> lower cavity -> A_drain -> tank; check balls lower -> V5
    and lower -> V4 (anti-cavitation, one way). Controller: V_rel = U_in/U_s, x_set = K_in V_rel
    + x_0, LVDT 0.945/(0.0059 s + 1), e = x_set - x_m', duty cycles 28.4 % +- 70 %/mm * e.
    """

    pilot_pressure: float = Field(
        bar(13.5), ge=bar(1.0), le=bar(50.0),
        description="Pilot supply pressure P_pilot [Pa] (4.5.3, figure 4.20: 13-14 bar at 0.7-1.0 "
                    "L/min, 13.5 bar used); modelled as an ideal pressure source")
    supply_orifice_diameter: float = Field(
        mm(4.0), gt=0.0, le=mm(20.0),
        description="Supply orifice pilot -> upper cavity, diameter [m] (4.5.1: 4 mm, 12.6 mm^2)")
    drain_orifice_diameter: float = Field(
        mm(1.0), gt=0.0, le=mm(20.0),
        description="Drain orifice lower cavity -> tank, diameter [m] (4.5.1: 1 mm, 0.79 mm^2)")
    check_valve_seat_diameter: float = Field(
        mm(1.7), gt=0.0, le=mm(20.0),
        description="Seat diameter of the two check balls lower cavity -> port chamber [m] "
                    "(4.5.1: 1.7 mm, 2.3 mm^2); modelled as a rectified orifice (4.5.3)")
    check_valve_cracking_pressure: float = Field(
        0.0, ge=0.0, le=bar(10.0),
        description="Cracking pressure of the spring-loaded check balls [Pa]. Not given in the "
                    "report; 0 assumed (the report's rectified orifice opens at dp > 0)")
    port_a_volume: float = Field(
        cm3(13.0), gt=0.0, le=1e-3,
        description="Chamber V4 (port A, pressure P4) at x_m = 0 [m^3] (4.5.2: 13 cm^3; B.5 "
                    "measures 12.90 cm^3; table 4.15 uses 1.29e-5); V4(x_m) = V4 + A_m x_m")
    port_b_volume: float = Field(
        cm3(27.0), gt=0.0, le=1e-3,
        description="Chamber V5 (port B, pressure P5) at x_m = 0 [m^3] (4.5.2: 27 cm^3; B.5: "
                    "26.76 cm^3); V5(x_m) = V5 - A_m x_m. CHOICE: eq 4.94 prints 28 cm^3; the "
                    "measured 26.76 rounds to 27")
    upper_volume: float = Field(
        mm(1.0) ** 3 * 2000.0, gt=0.0, le=1e-3,
        description="Upper cavity (pilot piping to NC1/NC3) V_upper [m^3] (eq 4.96: 2000 mm^3)")
    lower_volume: float = Field(
        mm(1.0) ** 3 * 1000.0, gt=0.0, le=1e-3,
        description="Lower cavity (NO2/NO4 to drain) V_lower [m^3] (eq 4.95: 1000 mm^3)")
    nc1: SolenoidValveParams = Field(
        SolenoidValveParams(kind="NC", chamber="B", switching_delay=0.020),
        description="NC1: upper cavity -> V5 (port B) (figure 4.19, eq 4.98)")
    no2: SolenoidValveParams = Field(
        SolenoidValveParams(kind="NO", chamber="B", switching_delay=0.003),
        description="NO2: V5 (port B) -> lower cavity (figure 4.19, eq 4.98)")
    nc3: SolenoidValveParams = Field(
        SolenoidValveParams(kind="NC", chamber="A", switching_delay=0.020),
        description="NC3: upper cavity -> V4 (port A) (figure 4.19, eq 4.99 where it is "
                    "misprinted NC2)")
    no4: SolenoidValveParams = Field(
        SolenoidValveParams(kind="NO", chamber="A", switching_delay=0.003),
        description="NO4: V4 (port A) -> lower cavity (figure 4.19, eq 4.99)")
    input_gain: float = Field(
        0.028, gt=0.0, le=1.0,
        description="K_input in x_set = K_input V_rel + x_0 [m per unit V_rel] (eq 4.110: "
                    "0.028, i.e. +-7 mm for V_rel = 0.25..0.75). CHOICE: table 4.15 prints 0.0028, "
                    "inconsistent with figure 4.25 and eq 4.133 (14 mm / 0.5)")
    input_offset: float = Field(
        -0.014, ge=-0.1, le=0.1,
        description="x_0 in x_set = K_input V_rel + x_0 [m] (eq 4.110: -0.014; V_rel = 0.5 is "
                    "neutral)")
    lvdt_gain: float = Field(
        0.945, gt=0.0, le=2.0,
        description="Steady-state gain of the LVDT x_m'/x_m [-] (eq 4.113, Danfoss model)")
    lvdt_time_constant: float = Field(
        0.0059, gt=0.0, le=1.0,
        description="Time constant of the LVDT first-order lag [s] (eq 4.113)")
    duty_offset: float = Field(
        0.284, ge=0.0, le=1.0,
        description="Duty cycle of all four valves at zero position error [-] (eq 4.115: 28.4 %)")
    duty_gain: float = Field(
        700.0, gt=0.0, le=1e6,
        description="Slope of duty cycle vs position error [1/m] (eq 4.115: 70 % per mm). "
                    "DT_A (NC3/NO4, raises P4) = offset + gain e, DT_B (NC1/NO2, raises P5) = "
                    "offset - gain e, both clipped to [0, 1]. CHOICE: eq 4.115 gives the + sign "
                    "to port B, which with eq 4.86/4.93 (P4 pushes +x_m) is positive feedback; "
                    "the sign is assigned so the loop is stable (as the linear model 4.142 does)")
    delay_stages: int = Field(
        1, ge=1, le=16,
        description="Stages n of each valve's switching delay [-]: the duty-cycle signal passes "
                    "n first-order lags of delay/n in series (4.5.5's pure delay of 20 ms NC, "
                    "3 ms NO, as an Erlang chain: the same mean delay, phase -n atan(w tau/n), "
                    "the pure delay's -w tau as n grows; monotone, so the duty cycle stays in "
                    "[0, 1]). 1 = one lag (the model; the linear model 4.8.2 also uses lags). "
                    "docs/pvg32_model.md section 6 shows the effect of 4 stages")
    map_supply_voltage: float = Field(
        13.0, gt=0.0, le=50.0,
        description="Supply voltage at which the solenoid flow maps were made [V] (4.5.4, "
                    "figure 4.22: 13 V at 50 degC); informational. The rig ran at the identified "
                    "11.5 V (4.7.3); the report gives no map at that voltage, so the 13 V map is "
                    "used (docs/pvg32_model.md, section 6)")

    @property
    def supply_orifice_area(self) -> float:
        """A_supply = pi D^2 / 4 [m^2] (4.5.1: 12.6 mm^2)."""
        return circle_area(self.supply_orifice_diameter)

    @property
    def drain_orifice_area(self) -> float:
        """A_drain = pi D^2 / 4 [m^2] (4.5.1: 0.79 mm^2)."""
        return circle_area(self.drain_orifice_diameter)

    @property
    def check_valve_area(self) -> float:
        """A_checkvalve = pi D_seat^2 / 4 [m^2] (4.5.1: 2.3 mm^2)."""
        return circle_area(self.check_valve_seat_diameter)


# --------------------------------------------------------------------------------------------
class LoadOrificeParams(_Params):
    """An adjustable rig orifice with its two settings (4.7.2, tables 4.7 and 4.8)."""

    laminar_small: float = Field(
        gt=0.0, le=1e-8, description="Laminar constant K, Q = K dp, small setting [m^3/(s Pa)] "
                                     "(table 4.8)")
    laminar_large: float = Field(
        gt=0.0, le=1e-8, description="Laminar constant K, large setting [m^3/(s Pa)] (table 4.8)")
    quadratic_small: float = Field(
        0.0, ge=0.0, le=1e-13,
        description="Second coefficient b of the load law Q = K dp + b dp |dp|, small setting "
                    "[m^3/(s Pa^2)]. 0 = the report's laminar law (eq 4.132). The measured Q(dp) "
                    "curves upwards (4.7.2: 'the curvature of the plot are all greater or equal "
                    "to zero'); circuits.crossval.identify fits b >= 0 where the data span two "
                    "pressure levels")
    quadratic_large: float = Field(
        0.0, ge=0.0, le=1e-13,
        description="b of Q = K dp + b dp |dp|, large setting [m^3/(s Pa^2)] (see "
                    "quadratic_small)")
    area_small: float = Field(
        gt=0.0, le=1e-3, description="Turbulent equivalent area (Cd = 0.6), small setting [m^2] "
                                     "(table 4.7)")
    area_large: float = Field(
        gt=0.0, le=1e-3, description="Turbulent equivalent area (Cd = 0.6), large setting [m^2] "
                                     "(table 4.7)")

    def laminar(self, size: Literal["small", "large"]) -> float:
        """K [m^3/(s Pa)] for the named setting."""
        return {"small": self.laminar_small, "large": self.laminar_large}[size]

    def quadratic(self, size: Literal["small", "large"]) -> float:
        """b [m^3/(s Pa^2)] of Q = K dp + b dp |dp| for the named setting."""
        return {"small": self.quadratic_small, "large": self.quadratic_large}[size]

    def area(self, size: Literal["small", "large"]) -> float:
        """Turbulent area [m^2] for the named setting."""
        return {"small": self.area_small, "large": self.area_large}[size]


class RigSolenoidValveParams(_Params):
    """The rig's on/off solenoid valve L2 (f -> m), open or closed (4.6, 4.7.2)."""

    laminar_open: float = Field(
        lpm_per_bar(1.6111), gt=0.0, le=1e-8,
        description="Laminar constant K_L2 when open [m^3/(s Pa)] (table 4.8: 1.6111 L/(min bar), "
                    "figure 4.32)")
    area_open: float = Field(
        mm2(5.800), gt=0.0, le=1e-3,
        description="Turbulent equivalent area when open [m^2] (table 4.7: 5.800 mm^2, Cd = 0.6)")
    switching_time: float | None = Field(
        None, gt=0.0, le=1.0,
        description="Opening/closing time of L2, a first-order lag [s]. Not given in the "
                    "report (the measured traces are aligned to the step, 4.7.3); None = "
                    "pvgraph.circuits.rig.L2_SWITCH_TIME, 20 ms (a fast cartridge valve of this size)")


class RigParams(_Params):
    """The lab test rig, sections 4.6-4.7 and appendix B.6-B.7.

    Pump (constant flow Q_p into Vp) -> PVG 32; work port -> node f (P_f = P_LS); f -> L2 -> m ->
    L1 -> b; f -> L3 -> b; b (P_b = P_bp) -> return metering edge A_H -> tank. Load flows are
    laminar, Q = K dp (eq 4.132), by the report's conclusion of 4.7.2.
    """

    pump_flow: float = Field(
        lpm(17.0), gt=0.0, le=lpm(200.0),
        description="Constant pump flow Q_p [m^3/s] (table 4.9: 17 L/min; table 4.14 / 4.7.3: "
                    "16.3 L/min identified from the saturated sweep)")
    supply_voltage: float = Field(
        12.0, gt=0.0, le=50.0,
        description="PVE supply (battery) voltage U_s used in V_rel = U_in / U_s [V] (table 4.9: "
                    "12 V nominal; table 4.14 / eq 4.133: 11.5 V identified)")
    volume_f: float = Field(
        litre(0.127 + 0.19), gt=0.0, le=0.1,
        description="Volume of node f (PVG work port to L2/L3) V_f [m^3] (B.6 hose volumes; "
                    "ASSUMPTION, the report gives no hose-to-node map: hoses 6 + 4 = 0.127 + "
                    "0.19 L)")
    volume_m: float = Field(
        litre(0.063), gt=0.0, le=0.1,
        description="Volume of node m (between L2 and L1) V_m [m^3] (B.6; ASSUMPTION: hose 7, "
                    "0.5 m, 0.063 L)")
    volume_b: float = Field(
        litre(0.127 + 0.127), gt=0.0, le=0.1,
        description="Volume of node b (L1/L3 outlets to the PVG return port) V_b [m^3] (B.6; "
                    "ASSUMPTION: hoses 5 + 8 = 0.127 + 0.127 L)")
    L1: LoadOrificeParams = Field(
        LoadOrificeParams(laminar_small=lpm_per_bar(0.2105), laminar_large=lpm_per_bar(0.3544),
                          area_small=mm2(2.174), area_large=mm2(2.585)),
        description="Orifice L1, m -> b (tables 4.7, 4.8)")
    L3: LoadOrificeParams = Field(
        LoadOrificeParams(laminar_small=lpm_per_bar(0.2203), laminar_large=lpm_per_bar(0.4533),
                          area_small=mm2(3.422), area_large=mm2(4.635)),
        description="Orifice L3, f -> b (tables 4.7, 4.8)")
    L2: RigSolenoidValveParams = Field(
        RigSolenoidValveParams(), description="Solenoid on/off valve L2, f -> m (tables 4.7, 4.8)")
    return_line_K: float | None = Field(
        lpm_per_bar(16.3 / 3.2), gt=0.0, le=1e-6,
        description="Laminar constant of the rig's return line from the PVG tank port to the "
                    "reservoir (hoses, filter, flow meter) [m^3/(s Pa)]. Not in the report, "
                    "whose rig returns to 0 bar; the measured Pb (7-8.4 bar with the valve "
                    "feeding the load, B.7) is the meter-out drop over A_H (~4.7 bar) plus a "
                    "return-line pressure of about 3.2 bar at the full pump flow, which is what "
                    "always returns to tank in steady state. Identified from the closed-L2 "
                    "tests 1, 4, 7, 10 (Pb measured minus Pb simulated without this line: 2.9, "
                    "3.7, 3.0, 3.3 bar). None: no return line, as in the report")
    return_hose_K: float | None = Field(
        None, gt=0.0, le=1e-6,
        description="Laminar constant of the hose from the junction of L1 and L3 to the point "
                    "where Pb is measured [m^3/(s Pa)]. Not in the report (B.6 lists the hoses, "
                    "4.6 the transducers, not where they sit). With L2 closed no flow passes L1, "
                    "so Pm reads the junction: B.7's closed-L2 points give Pm - Pb = 0.475 bar + "
                    "0.0435 bar/(L/min) Q_total (15 points, both tables, residuals within 0.2 "
                    "bar), i.e. this hose carrying the load flow (23 L/(min bar)) and a Pb "
                    "transducer offset (pb_sensor_offset). None = no hose (the report's rig): "
                    "L1 and L3 end at node b. circuits.crossval.identify identifies it from the "
                    "training points")
    pb_sensor_offset: float = Field(
        0.0, ge=bar(-3.0), le=bar(3.0),
        description="Reading minus true pressure of the Pb transducer [Pa]. At zero flow "
                    "(neutral sweep points, B.7) Pf and Pm agree within 0.06 bar and Pb reads "
                    "0.47-0.51 bar below them; one offset on Pb explains it (the alternative, Pf "
                    "and Pm both reading high, predicts the same differences). Within the "
                    "transducers' +-1 bar (B.7). 0 = ideal transducer (the report)")
    load_flow_model: Literal["laminar", "turbulent"] = Field(
        "laminar",
        description="Flow law of L1/L2/L3 [-] (4.7.2: the measured Q(dp) is linear, so laminar "
                    "Q = K dp, eq 4.132, replaces the orifice equation 4.119-4.121)")


# --------------------------------------------------------------------------------------------
class PVG32Params(_Params):
    """All parameters of the PVG 32 + rig model (report chapter 4)."""

    fluid: FluidParams = Field(FluidParams(), description="Hydraulic oil (4.2.3, A.5)")
    pvp: PVPParams = Field(PVPParams(), description="PVP pump-side module spool (4.2)")
    compensator: CompensatorParams = Field(
        CompensatorParams(), description="PVB compensator spool (4.3)")
    main_spool: MainSpoolParams = Field(MainSpoolParams(), description="PVB main spool (4.4)")
    pve: PVEParams = Field(PVEParams(), description="PVE actuator and controller (4.5)")
    rig: RigParams = Field(RigParams(), description="Lab rig: pump, load, supply (4.6, 4.7, B.6)")
    discharge_coefficient: float = Field(
        0.6, gt=0.0, le=1.0,
        description="Discharge coefficient Cd of every turbulent orifice and flow-force term [-] "
                    "(4.2.3, A.1: 0.6)")
    tank_pressure: float = Field(
        0.0, ge=0.0, le=bar(20.0),
        description="Reservoir pressure P_T, gauge [Pa] (4.2: 0 bar relative)")


def report_initial() -> PVG32Params:
    """The report's untuned model: chapters 4.2-4.6 with table 4.9's uncertain parameters."""
    return PVG32Params(
        pvp=PVPParams(viscous_friction=9000.0, coulomb_friction=0.0,
                      pressure_chamber_orifice_diameter=None),
        compensator=CompensatorParams(viscous_friction=9000.0, coulomb_friction=0.0),
        main_spool=MainSpoolParams(viscous_friction=25.0),
        rig=RigParams(pump_flow=lpm(17.0), supply_voltage=12.0),
    )




def report_tuned() -> PVG32Params:
    """The report's validated model: table 4.14 (section 4.7.3)."""
    return PVG32Params(
        pvp=PVPParams(viscous_friction=35000.0, coulomb_friction=0.0,
                      pressure_chamber_orifice_diameter=mm(0.3)),
        compensator=CompensatorParams(viscous_friction=20000.0, coulomb_friction=50.0),
        main_spool=MainSpoolParams(viscous_friction=25.0),
        rig=RigParams(pump_flow=lpm(16.3), supply_voltage=11.5),
    )


# --------------------------------------------------------------------------------------------
def parameter_paths(p: PVG32Params | None = None) -> list[str]:
    """Every numeric parameter as a dotted path, e.g. ``"rig.pump_flow"``, ``"rig.L3.laminar_small"``."""
    out = []

    def walk(model, prefix):
        for name in type(model).model_fields:
            value = getattr(model, name)
            if isinstance(value, BaseModel):
                walk(value, f"{prefix}{name}.")
            elif isinstance(value, (int, float)) and not isinstance(value, bool):
                out.append(prefix + name)
    walk(p or PVG32Params(), "")
    return out


def parameter_field(p: PVG32Params, path: str) -> tuple[float, str]:
    """``(value, description)`` of the dotted-path parameter ``path`` in ``p``."""
    *groups, leaf = path.split(".")
    model = p
    for g in groups:
        model = getattr(model, g)
    return getattr(model, leaf), type(model).model_fields[leaf].description or ""


def with_values(p: PVG32Params, updates: dict[str, float]) -> PVG32Params:
    """A copy of ``p`` with the dotted-path parameters in ``updates`` replaced and re-validated.

    Raises :class:`pvgraph.errors.ParameterError` naming an unknown path (with the closest valid
    ones) or a value outside the field's bounds.
    """
    import difflib

    from pydantic import ValidationError

    from pvgraph.errors import ParameterError

    data = p.model_dump()
    valid = parameter_paths(p)
    for path, value in updates.items():
        if path not in valid:
            close = difflib.get_close_matches(path, valid, n=3, cutoff=0.5)
            hint = f" Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            raise ParameterError(f"{path!r} is not a PVG 32 parameter.{hint} "
                                 f"(circuits.pvg32.parameters.parameter_paths() lists them all)")
        *groups, leaf = path.split(".")
        node = data
        for g in groups:
            node = node[g]
        node[leaf] = value
    try:
        return PVG32Params.model_validate(data)
    except ValidationError as exc:
        lines = [f"  {'.'.join(str(x) for x in e['loc'])} = {e.get('input')!r}: {e['msg']}"
                 for e in exc.errors()]
        raise ParameterError("invalid PVG 32 parameter value(s):\n" + "\n".join(lines)) from None


def parameter_table() -> str:
    """The markdown table of every parameter of both presets (docs/pvg32_model.md, section 12).

    One row per leaf field: dotted path, value (SI; "initial / tuned" where the presets
    differ) and the field's description. ``tests/circuits/test_parameters.py`` checks that the
    document holds exactly this table.
    """
    def fmt(value):
        if isinstance(value, float):
            return f"{value:g}"
        if isinstance(value, tuple):
            return "(" + ", ".join(f"{v:g}" for v in value) + ")"
        return str(value)

    rows = []

    def walk(a, b, prefix):
        for name, info in type(a).model_fields.items():
            va, vb = getattr(a, name), getattr(b, name)
            if isinstance(va, BaseModel):
                walk(va, vb, f"{prefix}{name}.")
                continue
            value = fmt(va) if va == vb else f"{fmt(va)} / {fmt(vb)}"
            text = (info.description or "").replace("|", "/")
            rows.append(f"| `{prefix}{name}` | {value} | {text} |")
    walk(report_initial(), report_tuned(), "")
    head = ["| parameter | value (SI; initial / tuned where they differ) "
            "| description and source |", "|---|---|---|"]
    return "\n".join(head + rows)
