"""Two PVB sections on one PVP: the load-sensing shuttle network of a real PVG 32 stack.

Each section (PVB + its own PVE) drives its own load. The sections' LS pressures meet in a
shuttle (max-select): a CheckValve from each section's LS port into a common LS node, which
has a small drain orifice to tank and feeds the PVP's LS port. The PVP then holds the pump
pressure a margin above the *highest* LS pressure, and each section's compensator throttles
its own supply down to what its load needs.

Run: ``python examples/pvg32_stack.py`` (writes pvg32_stack.png).
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from pvgraph.circuits.pvg32.modules import build_pve, build_pvb, build_pvp  # noqa: E402
from pvgraph.circuits.pvg32.parameters import report_tuned  # noqa: E402
from pvgraph.circuits.rig import laminar_load  # noqa: E402
from pvgraph.components.hydraulic import CheckValve, LaminarOrifice, Orifice, Pump, Tank  # noqa: E402
from pvgraph.components.hydraulic import VolumeNode  # noqa: E402
from pvgraph.components.signal import Constant  # noqa: E402
from pvgraph import Circuit  # noqa: E402
from pvgraph.plotting import plot_solution  # noqa: E402
from pvgraph.simulate import simulate  # noqa: E402
from pvgraph.units import mm2, to_bar, to_lpm  # noqa: E402

VOLTAGES = {"sec1": 4.6, "sec2": 5.0}   # both below 5.75 V: both feed port B
T_END = 2.0

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def build_stack(p=None, voltages=VOLTAGES) -> Circuit:
    p = p or report_tuned()
    c = Circuit("stack")
    tank = c.add("tank", Tank(p0=p.tank_pressure))
    pump = c.add("pump", Pump(Q0=p.rig.pump_flow))
    pvp = c.add("pvp", build_pvp(p))
    ls = c.add("ls_node", VolumeNode(V=0.1e-6, beta=p.fluid.bulk_modulus))
    ls_drain = c.add("ls_drain", Orifice(A=mm2(0.02), Cd=p.discharge_coefficient,
                                         rho=p.fluid.density))
    tank_side = [tank.port, pump.a, ls_drain.b]
    if p.rig.return_line_K is not None:
        ret = c.add("return_line", LaminarOrifice(K=p.rig.return_line_K))
        tank_side.append(ret.b)
        return_port = ret.a
    else:
        return_port = None
    returns = [pvp.T]
    c.connect(pump.b, pvp.P, *[c.add(name, build_pvb(p)).P for name in voltages])
    c.connect(ls.port, ls_drain.a, pvp.LS)
    for name, volts in voltages.items():
        pvb = c[name]
        pve = c.add(f"{name}_pve", build_pve(p))
        load = c.add(f"{name}_load", laminar_load(p))
        u = c.add(f"{name}_U", Constant(k=volts))
        shuttle = c.add(f"{name}_shuttle", CheckValve(A=mm2(2), Cd=p.discharge_coefficient,
                                                      rho=p.fluid.density))
        c.connect(pvb.spool, pve.spool)
        c.connect(pvb.B, load.B)
        c.connect(pvb.A, load.A)
        c.connect(u.y, pve.U)
        c.connect(pvb.LS, shuttle.a)
        returns += [pvb.T, pve.T]
    c.connect(ls.port, *[c[f"{n}_shuttle"].b for n in voltages])
    if return_port is not None:
        c.connect(return_port, *returns)
        c.connect(*tank_side)
    else:
        c.connect(*tank_side, *returns)
    return c


def main(outdir=OUTPUT) -> dict:
    sol = simulate(build_stack(), t_end=T_END, rtol=1e-4)
    r = {"p_pump_bar": to_bar(sol.final("pvp.Vp.port.p")),
         "p_ls_common_bar": to_bar(sol.final("ls_node.port.p"))}
    for name in VOLTAGES:
        r[f"{name}_ls_bar"] = to_bar(sol.final(f"{name}.LS_channel.port.p"))
        r[f"{name}_port_B_bar"] = to_bar(sol.final(f"{name}.PB.b.p"))
        r[f"{name}_q_lpm"] = to_lpm(sol.final(f"{name}.PB.q"))
    r["ls_max_bar"] = max(r[f"{n}_ls_bar"] for n in VOLTAGES)
    r["margin_bar"] = r["p_pump_bar"] - r["ls_max_bar"]
    for name, volts in VOLTAGES.items():
        print(f"{name}: {volts:.2f} V  LS {r[f'{name}_ls_bar']:6.2f} bar  flow "
              f"{r[f'{name}_q_lpm']:5.2f} L/min")
    print(f"common LS {r['p_ls_common_bar']:.2f} bar, pump {r['p_pump_bar']:.2f} bar: "
          f"{r['margin_bar']:.2f} bar above the higher LS pressure")
    plot_solution(sol, ["pvp.Vp.port.p", "ls_node.port.p"] +
                  [f"{n}.LS_channel.port.p" for n in VOLTAGES] + [f"{n}.PB.q" for n in VOLTAGES],
                  os.path.join(outdir, "pvg32_stack.png"), title="two PVB sections on one PVP")
    return r


if __name__ == "__main__":
    main()
