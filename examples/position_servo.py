"""A closed-loop electro-hydraulic position servo: PI controller, servo valve, cylinder, mass.

    pump 20 L/min -> supply (0.5 L) -> servo valve P; relief at 160 bar -> tank
    servo valve A/B -> cylinder cap/rod side; rod -> 200 kg carriage with viscous friction
    position sensor -> PID(r = set point, m = position) -> servo valve command (limited to +-1)

The set point steps from 0 to 100 mm at t = 0.1 s. While the error is large the controller's
output sits at its limit (full spool stroke): the carriage moves at the valve's flow over the
cap area and the back-calculation keeps the integral from winding up. Near the set point the
loop takes over and the integral removes the steady error, so the steady state puts the rod
exactly at 100 mm. Linearised at that point, the closed loop from the set point to the position
has a DC gain of exactly 1 and stable poles.

Run: ``python examples/position_servo.py`` (writes examples/output/position_servo.png; about
3 s of CPU).
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np

from pvgraph import Circuit
from pvgraph.analysis import linearize_circuit, steady_state
from pvgraph.components import (PID, Cylinder, Mass, PilotReliefValve, PositionSensor, Pump,
                                ServoValve, Step, Tank, VolumeNode)
from pvgraph.plotting import plot_solution
from pvgraph.simulate import simulate
from pvgraph.units import to_bar

A_CAP = math.pi / 4 * 0.04 ** 2          # 40 mm bore
A_ROD = math.pi / 4 * 0.022 ** 2         # 22 mm rod
SET_POINT = 0.1                          # m

#: where the figures go unless a folder is given: examples/output/, not the repository root
OUTPUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "output")


def build(set_point: float = SET_POINT, t_step: float = 0.1) -> Circuit:
    c = Circuit("servo")
    tank = c.add("tank", Tank())
    pump = c.add("pump", Pump(Q0="20 L/min"))
    supply = c.add("supply", VolumeNode(V="0.5 L"))
    relief = c.add("relief", PilotReliefValve(p_set="160 bar", A_main="20 mm^2"))
    valve = c.add("valve", ServoValve(Q_nom="20 L/min", dp_nom="70 bar"))
    cyl = c.add("cylinder", Cylinder(A_A=A_CAP, A_rod=A_ROD, stroke=0.3, V_dead_A="20 cm^3",
                                     V_dead_B="20 cm^3"))
    carriage = c.add("carriage", Mass(m=200.0, b=3000.0))
    sensor = c.add("sensor", PositionSensor())
    pid = c.add("pid", PID(Kp=40.0, Ki=2.0, y_min=-1.0, y_max=1.0))
    ref = c.add("ref", Step(t_step=t_step, height=set_point))

    c.connect(tank.port, pump.a, relief.T, valve.T)
    c.connect(pump.b, supply.port, relief.P, valve.P)
    c.connect(valve.A, cyl.A)
    c.connect(valve.B, cyl.B)
    c.connect(cyl.flange, carriage.flange, sensor.flange)
    c.connect(ref.y, pid.r)
    c.connect(sensor.y, pid.m)
    c.connect(pid.y, valve.i)
    return c


def main(outdir=OUTPUT) -> dict:
    sol = simulate(build(), t_end=1.0, rtol=1e-6)
    x = sol["carriage.flange.x"]
    # at full command the pump's 20 L/min is the limit: once the supply has fallen to the
    # pressure the motion needs (0.3-0.36 s), the carriage moves at Q / A_cap
    t0, t1 = 0.30, 0.36
    speed = (np.interp(t1, sol.t, x) - np.interp(t0, sol.t, x)) / (t1 - t0)
    moving = (sol.t >= t0) & (sol.t <= t1)
    op = steady_state(build(t_step=0.0).compile())
    lin = linearize_circuit(lambda u: build(set_point=u["ref.height"], t_step=0.0),
                            {"ref.height": SET_POINT}, ["carriage.flange.x"])
    poles = lin.poles()
    result = {
        "x_final": sol.final("carriage.flange.x"),
        "overshoot_mm": 1000.0 * (float(x.max()) - SET_POINT),
        "command_max": float(sol["pid.y"].max()),
        "speed_saturated": float(speed),
        "speed_pump_limited": 20e-3 / 60.0 / A_CAP,
        "command_in_window": float(sol["pid.y"][moving].min()),
        "p_supply_bar": to_bar(float(sol["supply.port.p"][moving].mean())),
        "x_steady": op["carriage.flange.x"],
        "dc_gain": float(lin.dc_gain()[0, 0]),
        "max_pole_real": float(poles.real.max()),
        "n_poles": len(poles),
    }
    print(f"steady state              {1000 * result['x_steady']:9.4f} mm (set point "
          f"{1000 * SET_POINT:.0f} mm)")
    print(f"position at 1 s           {1000 * result['x_final']:9.4f} mm, overshoot "
          f"{result['overshoot_mm']:.2f} mm")
    print(f"speed at full command     {result['speed_saturated']:9.6f} m/s (pump flow / cap "
          f"area: {result['speed_pump_limited']:.6f} m/s), supply {result['p_supply_bar']:.1f} bar")
    print(f"closed loop: DC gain {result['dc_gain']:.6f}, {result['n_poles']} poles, all with "
          f"Re <= {result['max_pole_real']:.3f} 1/s")
    result["plot"] = plot_solution(sol, ["carriage.flange.x", "pid.y", "supply.port.p"],
                                   os.path.join(outdir, "position_servo.png"),
                                   title="PI position servo: 100 mm step")
    return result


if __name__ == "__main__":
    main()
