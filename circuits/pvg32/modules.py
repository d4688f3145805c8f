"""The PVG 32 modules as hierarchical circuits of library components (report chapter 4).

Each builder returns a :class:`~pvgraph.circuit.Circuit` with the ports a hydraulic engineer
expects, so that the modules assemble like the real valve:

``build_pvp``   PVP pump-side module (4.2): ports ``P`` (pump line, node Vp), ``T`` (tank),
                ``LS`` (load-sense input to the spring chamber V3 through A6).
``build_pvb``   PVB module (4.3, 4.4): compensator spool and main spool; ports ``P`` (from the
                PVP), ``T``, ``A``, ``B`` (work ports), ``LS`` (the compensator spring chamber
                P2, which feeds the PVP through A6), and the main spool's mechanical ``spool``
                port (driven by the PVE).
``build_pve``   PVE actuator (4.5): pilot circuit, solenoid valves NC1/NO2/NC3/NO4, check balls,
                end chambers V4/V5, LVDT and controller; ports ``spool`` (mechanical), ``T``,
                ``U`` (input voltage signal).
``build_pvg32`` the assembled valve: ports ``P``, ``T``, ``A``, ``B`` and the signal input
                ``U``.

Sign conventions: the main spool's x_m > 0 grows the PVE chamber V4 (port A side, eq. 4.93) and
opens P -> A and B -> T; x_m < 0 opens P -> B and A -> T (4.4.2). The compensator's x_k > 0 opens
A2 and closes A1 (4.3.1). The PVP spool's x_p > 0 compresses its spring and opens A3 to tank
(4.2). The equations, parameters and every choice made where the report is silent or
contradicts itself are summarised in ``docs/pvg32_model.md``.
"""

from __future__ import annotations

import numpy as np

from pvgraph.components.hydraulic import LaminarOrifice, Orifice, Tank, VolumeNode
from pvgraph.components.hydraulic.check_valve import CheckValve
from pvgraph.components.hydraulic.variable_orifice import VariableOrifice
from pvgraph.components.hydraulic.solenoid import PWMValve
from pvgraph.components.hydraulic.volumes import PistonChamber
from pvgraph.components.mechanical import EndStop, Friction, LinearSpring, SpoolMass
from pvgraph.components.mechanical.springs import CenteringSpring, TwoStageSpring
from pvgraph.components.signal import LVDT, PVEController
from pvgraph.components.signal.blocks import FirstOrderLag
from pvgraph.components.signal.sources import Constant
from pvgraph import Circuit

from . import tables
from .friction import LuGreFriction
from .parameters import PVG32Params, report_tuned

__all__ = ["build_pvp", "build_pvb", "build_pve", "build_pvg32", "opening_areas"]

# The LS pick-up from the work ports: an edge of the main spool that connects the fed port to
# the LS channel once the metering edge opens. Its size is not in the report, which takes
# P_LS as the work-port pressure itself (4.3.3); it is made large against A5 so that it adds
# no drop, and a small drain keeps the LS line at tank pressure in neutral, as in the real
# valve (the PVP then holds its stand-by pressure).
LS_PICKUP_AREA = 5e-6       # [m^2]
LS_DRAIN_AREA = 0.02e-6     # [m^2]

# The report neglects the oil between the compensator edges and the main spool (4.3.3: "the
# pressure build up ... would happen almost instantaneously"). With both edges closed (at rest,
# A2 = 0 and the main spool in its dead band) those nodes would be fixed only by leakage, which
# makes the algebraic equations nearly singular; these small cavities (of the size of the
# drillings) keep them well posed and add time constants far below a millisecond.
# Coulomb friction is regularised as F_c tanh(v / v_eps). With the default 0.1 mm/s the tuned
# compensator (F_c = 50 N, table 4.14) reverses through a band so narrow that the corrector
# iteration fails where the spool turns round; 1 mm/s keeps it smooth and is still below the
# spool speeds of interest (the compensator moves at about 1 cm/s in a transient; while it
# creeps slower the viscous term, 20000 N s/m, dominates anyway).
FRICTION_V_EPS = 1e-3       # [m/s]

# Stroke limits are stiff contacts whose onset is rounded over STOP_ROUNDING; the contact damping
# switches on across that band. The component default (0.1 um) makes the switch practically
# discontinuous for a spool leaving its stop at several cm/s, and the corrector iteration then
# fails at any step size. 10 um is still far below every opening the model resolves (the
# smallest dead band is 1.5 mm). The duty-cycle limits of the controller (0 and 100 %) are
# rounded over DUTY_ROUNDING per cent for the same reason.
STOP_ROUNDING = 1e-5        # [m]
DUTY_ROUNDING = 0.5         # [%]

P0_VOLUME = 0.2e-6          # [m^3] between A1 and A2
PK_VOLUME = 1.0e-6          # [m^3] between A2 and the main spool
LS_VOLUME = 0.1e-6          # [m^3] LS channel


def _fluid(p: PVG32Params) -> dict:
    return {"Cd": p.discharge_coefficient, "rho": p.fluid.density}


# The edges' tables are piecewise linear (tables.py, docs/pvg32_model.md): an unslotted land
# opens an annulus whose area grows linearly with travel (A3's 60 mm^2/mm is pi x 19 mm, about
# the 18 mm spool's circumference; A2 = pi D x_k, eq 4.38; A1 a linear slot edge). The orifice
# evaluates its table with a monotone pchip, which through a few break points rounds each
# kink over a whole segment (A3 at 2.1 mm: 0.59 instead of 6.0 mm^2). Sampling the linear
# table every TABLE_STEP keeps the pchip on the straight segments exactly and confines the
# rounding to one step at each kink.
TABLE_STEP = 2e-5           # [m]


def _table(area: tables.AreaTable, keep=None) -> dict:
    """x_table/A_table keywords of a VariableOrifice; ``keep(x)`` masks where the edge opens.

    The table is resampled every :data:`TABLE_STEP` (linear interpolation, break points kept).
    """
    x = np.asarray(area.x, dtype=float)
    n = int(np.ceil((x[-1] - x[0]) / TABLE_STEP))
    x = np.unique(np.concatenate([np.linspace(x[0], x[-1], n + 1), x]))
    a = area(x)
    if keep is not None:
        a = np.where(keep(x), a, 0.0)
    return {"x_table": tuple(x.tolist()), "A_table": tuple(a.tolist())}


def build_pvp(p: PVG32Params | None = None) -> Circuit:
    """PVP pump-side module: the pressure-adjustment spool (report 4.2, eq. 4.1-4.29).

    M_p x_p'' = (P_p - P3) A_p - (k_p x_p + F_preload) - 2 Cd A3 (P_p - P_T) cos(69 deg)
                - c_v x_p' - c_c sign(x_p')                                       (eq. 4.29)

    With the tuned preset the pressure side is a small chamber fed from Vp through the 0.3 mm
    orifice A7 (4.7.3); otherwise P_p acts on the spool directly (4.2.2).
    """
    p = p or report_tuned()
    pv, beta = p.pvp, p.fluid.bulk_modulus
    c = Circuit("pvp")
    vp = c.add("Vp", VolumeNode(V=pv.pump_volume, beta=beta))
    spool = c.add("spool", SpoolMass(m=pv.spool_mass))
    spring = c.add("spring", LinearSpring(k=pv.spring_rate, F0=pv.spring_preload))
    friction = c.add("friction", Friction(F_c=pv.coulomb_friction, b=pv.viscous_friction,
                                             v_eps=FRICTION_V_EPS))
    stop = c.add("stop", EndStop(x_min=0.0, x_max=pv.stroke_max, eps=STOP_ROUNDING))
    a3 = c.add("A3", VariableOrifice(opens="positive", theta=pv.flow_angle, **_fluid(p),
                                     **_table(opening_areas(p)["A3"])))
    v3 = c.add("V3", PistonChamber(A=pv.spool_area, V0=pv.spring_chamber_volume, side=-1,
                                   beta=beta))
    a6 = c.add("A6", Orifice(A=pv.ls_orifice_area, **_fluid(p)))
    v6 = c.add("V6", PistonChamber(A=pv.spool_area, V0=pv.pressure_chamber_volume, side=1,
                                   beta=beta))
    if pv.pressure_chamber_orifice_area is not None:
        # tuned model: the pressure chamber is fed from Vp through A7 (4.7.3)
        a7 = c.add("A7", Orifice(A=pv.pressure_chamber_orifice_area, **_fluid(p)))
        c.connect(vp.port, a3.a, a7.a)
        c.connect(a7.b, v6.port)
    else:
        c.connect(vp.port, a3.a, v6.port)
    c.connect(spool.flange, spring.flange, friction.flange, stop.flange, a3.flange, v3.flange,
              v6.flange)
    c.connect(a6.b, v3.port)
    c.expose("P", vp.port, "pump line (Vp)")
    c.expose("T", a3.b, "tank")
    c.expose("LS", a6.a, "load-sense pressure to the spring chamber V3 (through A6)")
    return c


def _build_compensator(c: Circuit, p: PVG32Params):
    """The PVB compensator spool (report 4.3, eq. 4.30-4.65) inside circuit ``c``."""
    k, beta = p.compensator, p.fluid.bulk_modulus
    areas = opening_areas(p)
    spool = c.add("comp_spool", SpoolMass(m=k.spool_mass))
    spring = c.add("comp_spring", TwoStageSpring(k1=k.spring_rate_1, k2=k.spring_rate_2,
                                                 x_b=k.second_stage_start, F0=k.spring_preload))
    if k.friction_law == "lugre" and k.coulomb_friction > 0.0:
        friction = c.add("comp_friction", LuGreFriction(F_c=k.coulomb_friction,
                                                        b=k.viscous_friction))
    else:
        friction = c.add("comp_friction", Friction(F_c=k.coulomb_friction,
                                                   b=k.viscous_friction, v_eps=FRICTION_V_EPS))
    # V2 = 1 cm^3 - A_k x_k vanishes at 3.93 mm (eq. 4.31): the stroke ends before that
    stop = c.add("comp_stop", EndStop(x_min=0.0, x_max=0.9 * k.stroke_max,
                                          eps=STOP_ROUNDING))
    a1 = c.add("A1", VariableOrifice(opens="negative", theta=k.closing_flow_angle, **_fluid(p),
                                     **_table(areas["A1"])))
    a2 = c.add("A2", VariableOrifice(opens="positive", theta=k.opening_flow_angle, **_fluid(p),
                                     **_table(areas["A2"])))
    a4 = c.add("A4", Orifice(A=k.inlet_orifice_area, **_fluid(p)))
    v1 = c.add("V1", PistonChamber(A=k.spool_area, V0=k.pressure_chamber_volume, side=1,
                                   beta=beta))
    v2 = c.add("V2", PistonChamber(A=k.spool_area, V0=k.spring_chamber_volume, side=-1,
                                   beta=beta))
    a5 = c.add("A5", Orifice(A=k.ls_orifice_area, **_fluid(p)))
    c.connect(spool.flange, spring.flange, friction.flange, stop.flange, a1.flange, a2.flange,
              v1.flange, v2.flange)
    p0 = c.add("P0", VolumeNode(V=P0_VOLUME, beta=beta))
    c.connect(a1.b, a2.a, a4.a, p0.port)  # P0, between the two metering edges (eq. 4.40-4.41)
    c.connect(a4.b, v1.port)             # P1 (eq. 4.48-4.50)
    c.connect(a5.b, v2.port)             # P2 (eq. 4.51-4.53)
    return a1, a2, a5, v2


# A_H between the dead band and 7 mm is not printed in the report (4.4.2 gives only the dead
# band and 69.549 mm^2 at 7 mm). Its shape is identified from the measured steady flows of
# appendix B.7 (:data:`tables.MAIN_SPOOL_LAB_ANCHORS`), as the report identified the supply
# voltage and pump flow from the same data (4.7.3), under the conditions this model settles
# at: the main-spool drop the compensator holds (4.7 bar, not the nominal 5) and the travel the
# PVE reaches (0.98 x_set: the LVDT's under-reading and the loop's proportional error nearly
# cancel). The steady flows are therefore a fit, not a prediction; pressures, margins and the
# dynamics after the solenoid steps are predictions.
A_H_FIT_DROP = 4.7e5        # [Pa]
A_H_FIT_POSITION_SCALE = 0.98


def main_spool_opening(p: PVG32Params) -> tables.AreaTable:
    """The main spool's A_H(x_m) table used by the model.

    With ``main_spool.opening_shape`` set (both presets: ``parameters.TUNED_OPENING_SHAPE``,
    refitted at the travel and drop the model settles at) that cubic; with None the anchor fit
    under ``A_H_FIT_DROP`` and ``A_H_FIT_POSITION_SCALE``.
    """
    m = p.main_spool
    return tables.main_spool_area(
        m.dead_band, m.stroke_max, m.area_at_full_stroke,
        supply_voltage=p.rig.supply_voltage, dp=A_H_FIT_DROP, cd=p.discharge_coefficient,
        rho=p.fluid.density, input_gain=p.pve.input_gain, input_offset=p.pve.input_offset,
        position_scale=A_H_FIT_POSITION_SCALE, shape=m.opening_shape)


METER_OUT_MIN_RATIO = 0.05


def _shifted(area: tables.AreaTable, overlap: float, dead_band: float = 0.0,
             ratio: tuple[float, float] = (1.0, 0.0)) -> tables.AreaTable:
    """The meter-out edge from the meter-in ``area``: its opening moved ``overlap`` further from
    x = 0 on both sides and scaled by r0 + r1 u, u = |x| - dead_band:
    A_out(x) = A(sign(x) max(|x| - overlap, 0)) max(r0 + r1 u, METER_OUT_MIN_RATIO)."""
    x0 = np.asarray(area.x, dtype=float)
    x = np.unique(np.concatenate([x0, np.sign(x0) * (np.abs(x0) + overlap)]))
    x = x[(x >= x0[0]) & (x <= x0[-1])]
    xs = np.sign(x) * np.clip(np.abs(x) - overlap, 0.0, None)
    r0, r1 = ratio
    scale = np.maximum(r0 + r1 * np.clip(np.abs(x) - dead_band, 0.0, None), METER_OUT_MIN_RATIO)
    return tables.AreaTable(f"{area.name}_out", x, np.asarray(area(xs)) * scale,
                            f"{area.source}; meter-out: overlap + {overlap * 1e3:.3f} mm, "
                            f"ratio {r0:.3f} + {r1 * 1e-3:.3f}/mm u")


def opening_areas(p: PVG32Params | None = None) -> dict[str, tables.AreaTable]:
    """The opening-area tables the model's spool edges use, by report symbol."""
    p = p or report_tuned()
    pv, k = p.pvp, p.compensator
    return {
        "A3": tables.pvp_tank_area(pv.tank_area_dead_band, pv.tank_area_full_stroke,
                                   pv.tank_area_max),
        "A1": tables.compensator_closing_area(),
        "A2": tables.compensator_opening_area(k.opening_diameter),
        "A_H": main_spool_opening(p),
    }


def build_pvb(p: PVG32Params | None = None) -> Circuit:
    """PVB module: compensator spool (4.3) and main spool (4.4) with its four metering edges.

    M_m x_m'' = (P4 - P5) A_m - F_spring(x_m) - c_v x_m' - flow forces        (eq. 4.91)

    The chambers P4/P5 belong to the PVE; they act on the ``spool`` port. Each metering edge
    applies its own flow force 2 Cd A_H dp cos(27.73 deg) towards neutral; with equal meter-in
    and meter-out drops they add up to the report's 4 Cd A_H dp cos(phi3) (eq. 4.85).
    """
    p = p or report_tuned()
    m = p.main_spool
    c = Circuit("pvb")
    a1, a2, a5, v2 = _build_compensator(c, p)
    spool = c.add("main_spool", SpoolMass(m=m.spool_mass, m_lever=m.lever_equivalent_mass))
    spring = c.add("main_spring", CenteringSpring(k=m.spring_rate, F0=m.spring_preload))
    friction = c.add("main_friction", Friction(F_c=m.coulomb_friction, b=m.viscous_friction,
                                                  v_eps=FRICTION_V_EPS))
    stop = c.add("main_stop", EndStop(x_min=-m.stroke_max, x_max=m.stroke_max,
                                          eps=STOP_ROUNDING))
    a_h = opening_areas(p)["A_H"]
    edge = dict(theta=m.flow_angle, **_fluid(p))
    pos = _table(a_h, lambda x: x > 0.0)
    neg = _table(a_h, lambda x: x < 0.0)
    p_a = c.add("PA", VariableOrifice(opens="positive", **edge, **pos))
    p_b = c.add("PB", VariableOrifice(opens="negative", **edge, **neg))
    if m.meter_out_overlap > 0.0 or tuple(m.meter_out_area_ratio) != (1.0, 0.0):
        # return edges of their own (parameters.MainSpoolParams.meter_out_overlap, _area_ratio)
        a_out = _shifted(a_h, m.meter_out_overlap, m.dead_band, m.meter_out_area_ratio)
        pos_out = _table(a_out, lambda x: x > 0.0)
        neg_out = _table(a_out, lambda x: x < 0.0)
    else:
        pos_out, neg_out = pos, neg
    a_t = c.add("AT", VariableOrifice(opens="negative", **edge, **neg_out))
    b_t = c.add("BT", VariableOrifice(opens="positive", **edge, **pos_out))
    # load-sense pick-up from the fed work port (no flow force: theta = 90 deg)
    pick = dict(x_dead=m.dead_band, w=LS_PICKUP_AREA / 1e-3, A_max=LS_PICKUP_AREA,
                theta=np.pi / 2, **_fluid(p))
    ls_a = c.add("LS_A", VariableOrifice(opens="positive", **pick))
    ls_b = c.add("LS_B", VariableOrifice(opens="negative", **pick))
    ls_drain = c.add("LS_drain", Orifice(A=LS_DRAIN_AREA, **_fluid(p)))
    c.connect(spool.flange, spring.flange, friction.flange, stop.flange, p_a.flange, p_b.flange,
              a_t.flange, b_t.flange, ls_a.flange, ls_b.flange)
    pk = c.add("PK", VolumeNode(V=PK_VOLUME, beta=p.fluid.bulk_modulus))
    ls = c.add("LS_channel", VolumeNode(V=LS_VOLUME, beta=p.fluid.bulk_modulus))
    c.connect(a2.b, p_a.a, p_b.a, pk.port)               # P_K (eq. 4.41-4.42)
    c.connect(p_a.b, ls_a.a, a_t.a)                      # work port A
    c.connect(p_b.b, ls_b.a, b_t.a)                      # work port B
    c.connect(ls_a.b, ls_b.b, ls_drain.a, a5.a, ls.port)  # LS channel to the spring chamber
    c.connect(a_t.b, b_t.b, ls_drain.b)                  # tank
    if m.clearance_leakage > 0.0:
        # clearance leakage of the four lands (parameters.MainSpoolParams.clearance_leakage)
        for name, a, b in (("leak_PA", p_a.a, p_a.b), ("leak_PB", p_b.a, p_b.b),
                           ("leak_AT", a_t.a, a_t.b), ("leak_BT", b_t.a, b_t.b)):
            leak = c.add(name, LaminarOrifice(K=m.clearance_leakage))
            c.connect(leak.a, a)
            c.connect(leak.b, b)
    c.expose("P", a1.a, "supply from the PVP (P_p)")
    c.expose("T", a_t.b, "tank")
    c.expose("A", p_a.b, "work port A")
    c.expose("B", p_b.b, "work port B")
    c.expose("LS", v2.port, "compensator spring chamber P2, load-sense signal to the PVP")
    c.expose("spool", spool.flange, "main spool, driven by the PVE")
    return c


def _delay_chain(c: Circuit, name: str, delay: float, stages: int, y0: float, target):
    """Connect ``stages - 1`` first-order lags of ``delay / stages`` in front of ``target``;
    return the input port of the chain (``target`` itself for one stage)."""
    port = target
    for k in range(stages - 1, 0, -1):
        lag = c.add(f"{name}_delay{k}", FirstOrderLag(tau=delay / stages, y0=y0))
        c.connect(lag.y, port)
        port = lag.u
    return port


def build_pve(p: PVG32Params | None = None) -> Circuit:
    """PVE electro-hydraulic actuator (report 4.5, eq. 4.92-4.115).

    Pilot supply 13.5 bar -> A_supply -> upper cavity -> NC valves -> end chambers V4/V5 -> NO
    valves -> lower cavity -> A_drain -> tank; check balls lower cavity -> V4/V5. The LVDT
    (eq. 4.113) reads the spool; the controller (eq. 4.109-4.115) turns the input voltage and
    the reading into duty cycles.

    Feedback sign: eq. 4.115 gives the duty cycle rising with the error (70 e + 28.4 %) to
    port B's valves, but with eq. 4.86/4.93 the chamber that pushes x_m up is V4 (port A); wired
    as printed, the loop is unstable. The rising duty cycle therefore drives the V4 valves (NC3,
    NO4), as the report's own linear model (4.8) requires for a stable loop.
    """
    p = p or report_tuned()
    e, m, beta = p.pve, p.main_spool, p.fluid.bulk_modulus
    c = Circuit("pve")
    pilot = c.add("pilot", Tank(p0=e.pilot_pressure))
    supply = c.add("supply", Orifice(A=e.supply_orifice_area, **_fluid(p)))
    upper = c.add("upper", VolumeNode(V=e.upper_volume, beta=beta))
    lower = c.add("lower", VolumeNode(V=e.lower_volume, beta=beta))
    drain = c.add("drain", Orifice(A=e.drain_orifice_area, **_fluid(p)))
    v4 = c.add("V4", PistonChamber(A=m.spool_area, V0=e.port_a_volume, side=1, beta=beta))
    v5 = c.add("V5", PistonChamber(A=m.spool_area, V0=e.port_b_volume, side=-1, beta=beta))
    # one flow map for all four valves: the library's (figure 4.55's lines; section 6 of
    # docs/pvg32_model.md says why the two-dimensional reconstruction was retired); the
    # switching delay (4.5.5) as the valve's own lag, after delay_stages - 1 lags of the same
    # time constant on its duty-cycle signal
    n = e.delay_stages
    valves = {}
    for name, kind, vp in (("NC1", "NC", e.nc1), ("NO2", "NO", e.no2), ("NC3", "NC", e.nc3),
                           ("NO4", "NO", e.no4)):
        valves[name] = c.add(name, PWMValve(kind=kind, tau=vp.switching_delay / n,
                                            DT0=e.duty_offset))
    nc1, no2, nc3, no4 = (valves[k] for k in ("NC1", "NO2", "NC3", "NO4"))
    check_a = c.add("check_A", CheckValve(A=e.check_valve_area,
                                          p_crack=e.check_valve_cracking_pressure, **_fluid(p)))
    check_b = c.add("check_B", CheckValve(A=e.check_valve_area,
                                          p_crack=e.check_valve_cracking_pressure, **_fluid(p)))
    lvdt = c.add("lvdt", LVDT(K=e.lvdt_gain, tau=e.lvdt_time_constant))
    controller = c.add("controller", PVEController(
        V_s=p.rig.supply_voltage, K_input=e.input_gain, x_offset=-e.input_offset,
        K_dt=e.duty_gain / 1000.0 * 100.0, DT_0=100.0 * e.duty_offset, eps=DUTY_ROUNDING))
    c.connect(pilot.port, supply.a)
    c.connect(supply.b, upper.port, nc1.a, nc3.a)
    c.connect(nc1.b, no2.a, check_b.b, v5.port)          # V5 / P5 (eq. 4.98)
    c.connect(nc3.b, no4.a, check_a.b, v4.port)          # V4 / P4 (eq. 4.99)
    c.connect(no2.b, no4.b, check_a.a, check_b.a, lower.port, drain.a)   # lower (eq. 4.100)
    c.connect(v4.flange, v5.flange, lvdt.flange)
    c.connect(lvdt.y, controller.x_meas)
    # DT_B rises with the error: it drives the V4 valves and pushes x_m up
    for signal, names in ((controller.DT_B, ("NC3", "NO4")), (controller.DT_A, ("NC1", "NO2"))):
        for name in names:
            c.connect(signal, _delay_chain(c, name, getattr(e, name.lower()).switching_delay, n,
                                           e.duty_offset, valves[name].DT))
    c.expose("spool", v4.flange, "main spool ends")
    c.expose("T", drain.b, "drain to tank")
    c.expose("U", controller.V_in, "input voltage U_in [V]")
    return c


def build_pvg32(p: PVG32Params | None = None, *, name: str = "pvg") -> Circuit:
    """The assembled PVG 32: PVP + PVB + PVE. Ports ``P``, ``T``, ``A``, ``B``, ``U``."""
    p = p or report_tuned()
    c = Circuit(name)
    pvp = c.add("pvp", build_pvp(p))
    pvb = c.add("pvb", build_pvb(p))
    pve = c.add("pve", build_pve(p))
    c.connect(pvp.P, pvb.P)
    c.connect(pvb.LS, pvp.LS)
    c.connect(pvb.spool, pve.spool)
    c.connect(pvp.T, pvb.T, pve.T)
    c.expose("P", pvp.P, "pump port")
    c.expose("T", pvb.T, "tank port")
    c.expose("A", pvb.A, "work port A")
    c.expose("B", pvb.B, "work port B")
    c.expose("U", pve.U, "PVE input voltage [V]")
    return c


def input_voltage(value: float) -> Constant:
    """A constant PVE input voltage source [V]."""
    return Constant(k=value)
