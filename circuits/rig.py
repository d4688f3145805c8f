"""The laboratory test rig of the PVG 32 (report 4.6, figure 4.29) and swappable loads.

::

    pump (16.3 L/min) -> PVG 32 port P;  PVG T -> tank
    PVG port B -> node f -> L2 (solenoid on/off) -> node m -> L1 -> node b
                  node f -> L3 ------------------------------> node b -> PVG port A

``build_rig(params, load=...)`` takes any circuit exposing hydraulic ports ``A`` and ``B`` as the
load, so the valve is never touched when the load changes. Provided loads:

- :func:`laminar_load`: the report's rig load with laminar restrictions Q = K dp (eq. 4.132,
  table 4.8), the model the report validates with (4.7.2);
- :func:`turbulent_load`: the same with turbulent orifices of table 4.7 (eq. 4.119-4.121);
- optional (``rig.return_hose_K``): a hose from the junction of L1 and L3 to node b, where Pb
  is read (the closed-L2 Pm - Pb of B.7 grows with the load flow); :func:`readings` adds the Pb
  transducer's offset to the model's pressures;
- :func:`cylinder_load`: a double-acting cylinder carrying a mass on a spring (a crane-like
  load), to show a different load on the same valve.

In every load ``B`` is the supply side (node f) and ``A`` the return (node b), matching the
rig's hoses: a negative main spool travel (input below half the supply voltage) feeds port B.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from pvgraph.components.hydraulic import LaminarOrifice, Orifice, Pump, Tank, VolumeNode
from pvgraph.components.hydraulic.solenoid import TimedOnOffValve
from pvgraph.components.signal.sources import Constant
from pvgraph import Circuit
from pvgraph.component import Component, Hydraulic, Params
from pvgraph.units import circle_area

from .pvg32.modules import build_pvg32
from .pvg32.parameters import PVG32Params, report_tuned

__all__ = ["build_rig", "readings", "laminar_load", "turbulent_load", "cylinder_load",
           "LoadRestriction"]


class LoadRestrictionParams(Params):
    K: float = Field(..., gt=0.0, le=1.0, description="Linear coefficient [m^3/(s Pa)] "
                                                        "(report eq. 4.132)")
    b: float = Field(0.0, ge=0.0, le=1.0, description="Quadratic coefficient [m^3/(s Pa^2)]")


class LoadRestriction(Component):
    """An adjustable rig orifice ``q = K dp + b dp |dp|``, dp = a.p - b.p.

    With b = 0 the report's laminar law (eq. 4.132). The rig's measured Q(dp) curves upwards
    (report 4.7.2), which the turbulent law (downwards) and a dp + b sqrt(dp) (downwards for
    b > 0; for b < 0 the flow runs against the pressure drop below (b/a)^2, about 3 bar for L3)
    cannot represent; the quadratic term does, with q monotone in dp for K, b >= 0.
    """

    Params = LoadRestrictionParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        dp = v.a.p - v.b.p
        q = v.observe("q", p.K * dp + p.b * dp * abs(dp), "m^3/s", "flow from a to b")
        v.observe("dp", dp, "Pa", "pressure drop a - b")
        return [v.a.q - q, v.a.q + v.b.q]

# The rig's L2 has no stated switching time (the report aligns its traces on the step); a fast
# on/off cartridge valve of this size switches in about 20 ms.
L2_SWITCH_TIME = 0.02


def _l2(p: PVG32Params, law: str, l2_open: bool, t_switch: float | None) -> TimedOnOffValve:
    l2 = p.rig.L2
    law_kw = {"K": l2.laminar_open} if law == "laminar" else {
        "A": l2.area_open, "Cd": p.discharge_coefficient, "rho": p.fluid.density}
    tau = l2.switching_time or L2_SWITCH_TIME
    return TimedOnOffValve(u0=int(l2_open), t_switch=(t_switch,) if t_switch else (1e9,),
                           s0=float(l2_open), tau_open=tau, tau_close=tau, **law_kw)


def _restriction(orifice, size: str):
    """Laminar (eq. 4.132), or K dp + b dp |dp| where the parameters give b > 0."""
    b = orifice.quadratic(size)
    if b > 0.0:
        return LoadRestriction(K=orifice.laminar(size), b=b)
    return LaminarOrifice(K=orifice.laminar(size))


def _rig_load(p: PVG32Params, law: Literal["laminar", "turbulent"], L1: str, L3: str,
              l2_open: bool, t_switch: float | None) -> Circuit:
    r, beta = p.rig, p.fluid.bulk_modulus
    c = Circuit(f"{law}_load")
    f = c.add("f", VolumeNode(V=r.volume_f, beta=beta))
    m = c.add("m", VolumeNode(V=r.volume_m, beta=beta))
    b = c.add("b", VolumeNode(V=r.volume_b, beta=beta))
    if law == "laminar":
        l1 = c.add("L1", _restriction(r.L1, L1))
        l3 = c.add("L3", _restriction(r.L3, L3))
    else:
        fluid = {"Cd": p.discharge_coefficient, "rho": p.fluid.density}
        l1 = c.add("L1", Orifice(A=r.L1.area(L1), **fluid))
        l3 = c.add("L3", Orifice(A=r.L3.area(L3), **fluid))
    l2 = c.add("L2", _l2(p, law, l2_open, t_switch))
    c.connect(f.port, l2.a, l3.a)
    c.connect(l2.b, m.port, l1.a)
    if r.return_hose_K is not None:
        # the junction of L1 and L3 (no volume of its own) -> hose -> node b, where Pb is read
        hose = c.add("return_hose", LaminarOrifice(K=r.return_hose_K))
        c.connect(l1.b, l3.b, hose.a)
        c.connect(hose.b, b.port)
    else:
        c.connect(l1.b, l3.b, b.port)
    c.expose("B", f.port, "supply side (node f)")
    c.expose("A", b.port, "return side (node b)")
    return c


def laminar_load(p: PVG32Params | None = None, *, L1: str = "small", L3: str = "small",
                 l2_open: bool = False, t_switch: float | None = None) -> Circuit:
    """The rig load with laminar restrictions (report eq. 4.132, table 4.8)."""
    return _rig_load(p or report_tuned(), "laminar", L1, L3, l2_open, t_switch)


def turbulent_load(p: PVG32Params | None = None, *, L1: str = "small", L3: str = "small",
                   l2_open: bool = False, t_switch: float | None = None) -> Circuit:
    """The rig load with turbulent orifices (report eq. 4.119-4.121, table 4.7)."""
    return _rig_load(p or report_tuned(), "turbulent", L1, L3, l2_open, t_switch)


def cylinder_load(p: PVG32Params | None = None, *, mass: float = 200.0, k: float = 2e4,
                  F0: float = 2000.0) -> Circuit:
    """A double-acting cylinder lifting a mass against a spring: a crane-like load.

    Port ``B`` feeds the piston side, port ``A`` the rod side.
    """
    from pvgraph.components.hydraulic.cylinder import Cylinder
    from pvgraph.components.mechanical import EndStop, Friction, LinearSpring, SpoolMass

    p = p or report_tuned()
    c = Circuit("cylinder_load")
    cyl = c.add("cylinder", Cylinder(A_A=circle_area(0.04), A_rod=circle_area(0.022),
                                     stroke=0.3, V_dead_A=2e-5, V_dead_B=2e-5,
                                     beta=p.fluid.bulk_modulus))
    body = c.add("mass", SpoolMass(m=mass))
    spring = c.add("spring", LinearSpring(k=k, F0=F0))
    friction = c.add("friction", Friction(F_c=50.0, b=2000.0))
    stop = c.add("stop", EndStop(x_min=0.0, x_max=0.3, k=1e8, d=1e4))
    c.connect(cyl.flange, body.flange, spring.flange, friction.flange, stop.flange)
    c.expose("B", cyl.A, "piston side")
    c.expose("A", cyl.B, "rod side")
    return c


def readings(p: PVG32Params, Pf, Pm, Pb) -> dict:
    """What the rig's transducers read for the model's pressures at f, m, b [Pa] (B.7):
    Pb with the transducer offset ``rig.pb_sensor_offset``; Pf and Pm as they are."""
    return {"Pf": Pf, "Pm": Pm, "Pb": Pb + p.rig.pb_sensor_offset}


def build_rig(p: PVG32Params | None = None, *, load: Circuit | None = None,
              U_input: float = 4.24, name: str = "rig") -> Circuit:
    """The PVG 32 on the lab rig: pump, tank, input voltage and a load on ports A and B.

    Parameters
    ----------
    p : PVG32Params
        Valve and rig parameters (default: the report's tuned preset, table 4.14).
    load : Circuit
        Any circuit exposing hydraulic ports ``A`` and ``B`` (default: the laminar rig load with
        the small orifices and L2 closed).
    U_input : float
        PVE input voltage [V]; half the supply voltage is neutral, less moves the spool to
        feed port B.
    """
    p = p or report_tuned()
    load = load if load is not None else laminar_load(p)
    if not isinstance(load, Circuit):
        from pvgraph.errors import CircuitError
        raise CircuitError(f"build_rig: load must be a Circuit exposing hydraulic ports 'A' and "
                           f"'B' (e.g. laminar_load(p)), got {type(load).__name__} {load!r}")
    # a voltage, as the command line and the scenario sweep read it ("4.2 bar" was 420 000 V)
    from pvgraph.errors import ParameterError
    from pvgraph.units import number_in
    U_input = number_in(U_input, "V", "build_rig U_input")
    if not 0.0 <= U_input <= p.rig.supply_voltage:
        raise ParameterError(f"build_rig: U_input = {U_input!r} V is outside 0 .. "
                             f"{p.rig.supply_voltage:g} V (the PVE's input range, up to its "
                             f"supply voltage)")
    for port in ("A", "B"):
        if port not in load.ports:
            from pvgraph.errors import CircuitError
            raise CircuitError(f"build_rig: the load {load.name!r} must expose hydraulic ports "
                               f"'A' and 'B'; it exposes {sorted(load.ports)}")
    c = Circuit(name)
    tank = c.add("tank", Tank(p0=p.tank_pressure))
    pump = c.add("pump", Pump(Q0=p.rig.pump_flow))
    pvg = c.add("pvg", build_pvg32(p))
    c.add("load", load)
    u = c.add("U_input", Constant(k=U_input))
    if p.rig.return_line_K is not None:
        ret = c.add("return_line", LaminarOrifice(K=p.rig.return_line_K))
        c.connect(tank.port, pump.a, ret.b)
        c.connect(ret.a, pvg.T)
    else:
        c.connect(tank.port, pump.a, pvg.T)
    c.connect(pump.b, pvg.P)
    c.connect(pvg.B, load.B)
    c.connect(pvg.A, load.A)
    c.connect(u.y, pvg.U)
    return c
