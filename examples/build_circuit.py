"""A circuit from scratch: a pump with a relief valve lifting a load with a cylinder.

    tank -> pump -> node "supply" --orifice--> cylinder cap side (A)
                       |                        cylinder rod side (B) -> tank
                       +-- relief (CheckValve cracking at 100 bar) -> tank

The rod carries a 50 kg mass against a preloaded spring (grounded on the +x side) and a
damper. The pump pushes the piston out until the spring force balances the pressure; the flow
then has nowhere to go but the relief valve, which holds the supply at its cracking pressure.
At rest the piston sits where A_A * p_relief = F0 + k * x.

Run: ``python examples/build_circuit.py`` (writes examples/output/build_circuit.png).
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from pvgraph.components.hydraulic import CheckValve, Cylinder, Orifice, Pump, Tank, VolumeNode
from pvgraph.components.mechanical import Damper, EndStop, LinearSpring, SpoolMass
from pvgraph import Circuit
from pvgraph.plotting import plot_solution
from pvgraph.simulate import simulate
from pvgraph.units import bar, litre, lpm, mm2, to_bar

P_RELIEF = bar(100)
A_CAP = math.pi / 4 * 0.04 ** 2          # 40 mm bore
A_ROD = math.pi / 4 * 0.022 ** 2         # 22 mm rod
K_SPRING, F0_SPRING = 1e5, 1000.0       # N/m, N

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def build() -> Circuit:
    c = Circuit("lift")
    tank = c.add("tank", Tank())
    pump = c.add("pump", Pump(Q0=lpm(10)))
    supply = c.add("supply", VolumeNode(V=litre(0.2)))
    relief = c.add("relief", CheckValve(A=mm2(20), p_crack=P_RELIEF, dp_open=bar(5)))
    orifice = c.add("orifice", Orifice(A=mm2(10)))
    cyl = c.add("cylinder", Cylinder(A_A=A_CAP, A_rod=A_ROD, stroke=0.3,
                                     V_dead_A=1e-5, V_dead_B=1e-5))
    mass = c.add("mass", SpoolMass(m=50.0))
    spring = c.add("spring", LinearSpring(k=K_SPRING, F0=F0_SPRING))
    damper = c.add("damper", Damper(d=5000.0))
    stop = c.add("stop", EndStop(x_min=0.0, x_max=0.3, k=1e8, d=1e4))

    c.connect(tank.port, pump.a, relief.b, cyl.B)
    c.connect(pump.b, supply.port, relief.a, orifice.a)
    c.connect(orifice.b, cyl.A)
    c.connect(cyl.flange, mass.flange, spring.flange, damper.flange, stop.flange)
    return c


def main(outdir=OUTPUT) -> dict:
    sol = simulate(build(), t_end=3.0, rtol=1e-5)
    x = sol["cylinder.flange.x"]
    result = {
        "x_start": float(x[0]),
        "x_final": sol.final("cylinder.flange.x"),
        "x_expected": (A_CAP * P_RELIEF - F0_SPRING) / K_SPRING,
        "p_supply_bar": to_bar(sol.final("supply.port.p")),
        "p_cap_bar": to_bar(sol.final("cylinder.A.p")),
        "p_relief_bar": to_bar(P_RELIEF),
        "q_relief_lpm": sol.final("relief.a.q") * 60000.0,
    }
    print(f"supply pressure   {result['p_supply_bar']:7.2f} bar (relief cracks at "
          f"{result['p_relief_bar']:.0f} bar)")
    print(f"cap-side pressure {result['p_cap_bar']:7.2f} bar")
    print(f"piston position   {1000 * result['x_final']:7.2f} mm (statics with the relief "
          f"pressure: {1000 * result['x_expected']:.2f} mm)")
    print(f"relief flow       {result['q_relief_lpm']:7.2f} L/min")
    result["plot"] = plot_solution(sol, ["supply.port.p", "cylinder.A.p", "cylinder.flange.x"],
                                   os.path.join(outdir, "build_circuit.png"),
                                   title="pump, relief valve and cylinder")
    return result


if __name__ == "__main__":
    main()
