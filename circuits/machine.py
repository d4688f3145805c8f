"""A load-sensing machine circuit: a boom cylinder and a swing motor on two PVG 32 sections.

The second reference circuit, built only from the component library and the PVG 32 sections
(PVB + PVE, report chapter 4):

- an electric motor turns a **load-sensing variable pump** (``pump``, 28 cm^3/rev at 1500 rpm,
  LS margin 20 bar, cut-off 250 bar) protected by a **system relief valve** (280 bar), with a
  **gas accumulator** on the pump line;
- a **pressure hose** (pi-line) carries the pump flow to the two sections, whose LS pressures
  meet in a **shuttle valve**; the higher one, through a small LS volume with a bleed to tank,
  sets the pump;
- section ``boom`` (PVB + PVE) feeds a **boom cylinder** (cap side through a **counterbalance
  valve** piloted by the rod-side line) that lifts a **mass** under gravity; both cylinder lines
  are hoses; the cylinder has cushions and end stops;
- section ``swing`` feeds a **hydraulic motor** turning the swing **inertia**, with two
  **cross-port relief valves** (shock valves, 150 bar) between its lines.

PVE inputs: 6 V is neutral (half the 12 V supply); above it the main spool feeds port A, below
it port B (report 4.4.2, 4.5). Port A lifts the boom and turns the swing in +phi.

``build_machine(cycle=...)`` takes the two input voltages as tables in time (``t``,
``U_boom``, ``U_swing``, linear between the points); :data:`CYCLE` is the lift-swing-lower cycle
of ``examples/machine_cycle.py``, :data:`SPEC` the sizes and settings (:class:`MachineSpec`).
"""

from __future__ import annotations

import math

from pvgraph.circuits.pvg32.modules import build_pvb, build_pve
from pvgraph.circuits.pvg32.parameters import PVG32Params, report_tuned
from pvgraph.components.hydraulic import (CounterbalanceValve, Cylinder, GasAccumulator,
                                  HydraulicMotor, LoadSensingPump, Orifice, PiLine, ReliefValve,
                                  ShuttleValve, Tank, VolumeNode)
from pvgraph.components.mechanical import Inertia, Mass, RotationalDamper, SpeedSource
from pvgraph.components.signal import TimeTable
from pvgraph import Circuit
from pvgraph.units import bar, cm3, litre, mm2

__all__ = ["build_machine", "MachineSpec", "CYCLE", "SPEC", "RTOL"]


class MachineSpec:
    """The machine's sizes and settings (SI), for the circuit and the tests."""

    w_motor = 2 * math.pi * 1500 / 60        # [rad/s] electric motor, 1500 rpm
    D_pump = cm3(28) / (2 * math.pi)        # [m^3/rad]
    dp_ls = bar(20)                         # [Pa] pump LS margin
    p_cutoff = bar(250)                     # [Pa] pump pressure cut-off
    p_relief = bar(280)                     # [Pa] system relief cracking pressure
    p_shock = bar(150)                      # [Pa] swing cross-port relief cracking pressure
    boom_mass = 1500.0                      # [kg] lifted mass (incl. boom), vertical
    bore, rod, stroke = 0.063, 0.036, 0.25  # [m] boom cylinder
    p_cb = bar(100)                         # [Pa] counterbalance setting (2 x holding)
    cb_ratio = 3.0                          # [-] counterbalance pilot ratio
    D_motor = cm3(50) / (2 * math.pi)       # [m^3/rad] swing motor
    J_swing = 40.0                          # [kg m^2] swing inertia at the motor shaft
    hose_d = 0.0127                         # [m] 1/2" hoses
    hose_l = 2.0                            # [m]

    @property
    def A_cap(self):
        return math.pi * self.bore ** 2 / 4

    @property
    def A_annulus(self):
        return self.A_cap - math.pi * self.rod ** 2 / 4


SPEC = MachineSpec()

#: lift (A, 7.5 V) into the cushion and the end stop, hold, swing out and stop, then lower
#: (B, 5 V) while the swing brakes on its shock valves
CYCLE = {"t": (0.0, 0.2, 0.3, 3.0, 3.1, 4.6, 4.7, 7.5),
         "U_boom": (6.0, 6.0, 7.5, 7.5, 6.0, 6.0, 5.0, 5.0),
         "U_swing": (6.0, 6.0, 6.0, 6.0, 7.5, 7.5, 6.0, 6.0)}


#: relative tolerance the cycle is simulated at. Its absolute tolerance on a pressure (``rtol``
#: times the 10 bar nominal) must stay below the width of the chambers' cavitation limit
#: (``fluid.py``: a cavity of 1 % of a chamber's volume sits 40 Pa above p_vap). At 1e-4 (100 Pa)
#: the step that lets the PVB compensator's spring chamber V2 (0.03 cm^3 with the compensator
#: shut) cavitate as the boom spool opens for lowering puts its pressure a few hundred Pa below
#: p_vap, where the compliance stands for a cavity of 5 x 10^5 chamber volumes: the LS channel
#: then fills it at 13 cm^3/s for the rest of the run, the section's LS signal stays at 1.2 bar,
#: the B line at 2.8 bar, and the counterbalance valve never gets the pilot pressure to open.
#: At 1e-5 (10 Pa) the chamber refills and the boom lowers under the valve (0.012 m/s); at
#: 3e-5 it does not (with the cavity a fraction of a chamber's volume, the oil keeping the rest).
RTOL = 1e-5


def _hose(spec, p0=0.0):
    return PiLine(l=spec.hose_l, d=spec.hose_d, beta_wall=3e9, p0=p0)


def build_machine(p: PVG32Params | None = None, *, cycle=CYCLE, spec: MachineSpec = SPEC,
                  name: str = "machine") -> Circuit:
    """The machine circuit driven by the voltage tables of ``cycle`` (see :data:`CYCLE`)."""
    p = p or report_tuned()
    fluid = dict(rho=p.fluid.density)
    vol = dict(beta=p.fluid.bulk_modulus)
    c = Circuit(name)
    tank = c.add("tank", Tank(p0=p.tank_pressure))
    tank_ports = [tank.port]

    # power unit ------------------------------------------------------------------------------
    motor = c.add("e_motor", SpeedSource(w0=spec.w_motor))
    pump = c.add("pump", LoadSensingPump(D=spec.D_pump, dp_ls=spec.dp_ls, p_c=spec.p_cutoff,
                                         dp_reg=bar(5), tau=0.05, eps0=0.0))
    relief = c.add("relief", ReliefValve(p_crack=spec.p_relief, A_s=mm2(30), k=3e5, x_max=1e-3,
                                         w=0.03, **fluid))
    acc = c.add("accumulator", GasAccumulator(V0=litre(0.7), p_pre=bar(20), **vol))
    pump_node = c.add("pump_line", VolumeNode(V=cm3(100), **vol))
    p_hose = c.add("p_hose", _hose(spec))
    c.connect(motor.shaft, pump.shaft)
    tank_ports += [pump.a, relief.T]
    c.connect(pump.b, relief.P, acc.port, pump_node.port, p_hose.a)

    # load sensing ----------------------------------------------------------------------------
    shuttle = c.add("ls_shuttle", ShuttleValve(A=mm2(2), **fluid))
    ls_node = c.add("ls_line", VolumeNode(V=cm3(5), **vol))
    ls_bleed = c.add("ls_bleed", Orifice(A=mm2(0.02), Cd=p.discharge_coefficient, **fluid))
    c.connect(shuttle.out, ls_node.port, ls_bleed.a, pump.LS)
    tank_ports.append(ls_bleed.b)

    # sections --------------------------------------------------------------------------------
    supply = [p_hose.b]
    for sec, key in (("boom", "U_boom"), ("swing", "U_swing")):
        pvb = c.add(sec, build_pvb(p))
        pve = c.add(f"{sec}_pve", build_pve(p))
        u = c.add(f"{sec}_U", TimeTable(t=cycle["t"], y=cycle[key]))
        c.connect(pvb.spool, pve.spool)
        c.connect(u.y, pve.U)
        supply.append(pvb.P)
        tank_ports += [pvb.T, pve.T]
    c.connect(*supply)
    c.connect(c["boom"].LS, shuttle.a)
    c.connect(c["swing"].LS, shuttle.b)

    # boom: hoses, counterbalance valve, cylinder, mass -----------------------------------------
    hose_a = c.add("boom_hose_A", _hose(spec))
    hose_b = c.add("boom_hose_B", _hose(spec))
    cb = c.add("counterbalance", CounterbalanceValve(p_set=spec.p_cb, ratio=spec.cb_ratio,
                                                     A_max=mm2(40), A_check=mm2(60), **fluid))
    p_hold = spec.boom_mass * 9.81 / spec.A_cap
    cyl = c.add("boom_cylinder", Cylinder(A_A=spec.A_cap, A_rod=spec.A_cap - spec.A_annulus,
                                          stroke=spec.stroke, V_dead_A=cm3(50),
                                          V_dead_B=cm3(50), p0_A=p_hold, k_stop=2e8,
                                          d_stop=5e5, l_cush=0.02, d_cush=3e6, **vol))
    load = c.add("boom_mass", Mass(m=spec.boom_mass, g=-9.81, x0=0.02))
    c.connect(c["boom"].A, hose_a.a)
    c.connect(hose_a.b, cb.valve)
    c.connect(cb.load, cyl.A)
    c.connect(c["boom"].B, hose_b.a)
    c.connect(hose_b.b, cyl.B, cb.pilot)
    c.connect(cyl.flange, load.flange)

    # swing: hoses, shock valves, motor, inertia ------------------------------------------------
    hose_sa = c.add("swing_hose_A", _hose(spec))
    hose_sb = c.add("swing_hose_B", _hose(spec))
    shock = dict(p_crack=spec.p_shock, A_s=mm2(20), k=2e5, x_max=1e-3, w=0.02, **fluid)
    shock_ab = c.add("shock_AB", ReliefValve(**shock))
    shock_ba = c.add("shock_BA", ReliefValve(**shock))
    sw_motor = c.add("swing_motor", HydraulicMotor(D=spec.D_motor, w_nom=30.0,
                                                   dp_nom=bar(150)))
    inertia = c.add("swing_inertia", Inertia(J=spec.J_swing))
    bearing = c.add("swing_bearing", RotationalDamper(d=2.0))
    c.connect(c["swing"].A, hose_sa.a)
    c.connect(c["swing"].B, hose_sb.a)
    c.connect(hose_sa.b, sw_motor.A, shock_ab.P, shock_ba.T)
    c.connect(hose_sb.b, sw_motor.B, shock_ab.T, shock_ba.P)
    c.connect(sw_motor.shaft, inertia.shaft, bearing.shaft)

    c.connect(*tank_ports)
    return c
