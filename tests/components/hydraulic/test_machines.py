"""Pumps and motors with shafts: efficiencies, speed and torque, PC and LS displacement control."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import (FixedDisplacementPump, HydraulicMotor, LoadSensingPump, Orifice,
                                  PressureCompensatedPump, PressureSource, Tank,
                                  VariableDisplacementPump, VolumeNode)
from pvgraph.components.mechanical import Inertia, RotationalDamper, SpeedSource
from pvgraph.components.signal import Constant
from hydraulic_helpers import jacobian_fd_error, requires_solver
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.units import bar, cm3, lpm, mm2

D = cm3(28) / (2 * math.pi)         # 28 cm^3/rev
W = 157.08                          # rated speed, 1500 rpm
DP = bar(200)


def _pump_circuit(pump, p_out, w=W):
    c = Circuit("pump")
    c.add("motor", SpeedSource(w0=w))
    c.add("tank", Tank())
    c.add("dut", pump)
    c.add("out", PressureSource(p0=p_out))
    c.connect("motor.shaft", "dut.shaft")
    c.connect("tank.port", "dut.a")
    c.connect("dut.b", "out.port")
    return c


@requires_solver
@pytest.mark.parametrize("w, p", [(W, DP), (0.5 * W, bar(80))])
def test_fixed_pump_flow_torque_and_efficiencies(w, p):
    sol = simulate(_pump_circuit(FixedDisplacementPump(D=D), p, w), 0.01, rtol=1e-9)
    K = 0.05 * D * W / DP
    assert sol.final("dut.q") == pytest.approx(D * w - K * p, rel=1e-9)
    assert sol.final("dut.T") == pytest.approx(D * p / 0.92, rel=1e-6)
    assert sol.final("motor.P") == pytest.approx(sol.final("dut.P_shaft"), rel=1e-9)
    if p == DP:   # exact at the rated point: total efficiency eta_v * eta_hm
        eta = sol.final("dut.P_hyd") / sol.final("dut.P_shaft")
        assert eta == pytest.approx(0.95 * 0.92, rel=1e-6)


@requires_solver
def test_variable_pump_delivers_its_displacement_fraction():
    c = _pump_circuit(VariableDisplacementPump(D=D), bar(100))
    c.add("u", Constant(k=0.4))
    c.connect("u.y", "dut.u")
    sol = simulate(c, 0.01, rtol=1e-9)
    K = 0.05 * D * W / DP
    assert sol.final("dut.q") == pytest.approx(0.4 * D * W - K * bar(100), rel=1e-9)


def _motor_circuit(p_in, J, d):
    c = Circuit("motor")
    c.add("supply", PressureSource(p0=p_in))
    c.add("tank", Tank())
    c.add("dut", HydraulicMotor(D=D))
    c.add("load", Inertia(J=J))
    c.add("brake", RotationalDamper(d=d))
    c.connect("supply.port", "dut.A")
    c.connect("dut.B", "tank.port")
    c.connect("dut.shaft", "load.shaft", "brake.shaft")
    return c


@requires_solver
def test_motor_speeds_up_its_inertia_to_the_torque_balance():
    """eta_hm D dp = d w, w(t) = w_ss (1 - exp(-d t / J)) once w >> w_eps."""
    J, d, p = 0.05, 0.5, bar(100)
    w_ss = 0.92 * D * p / d
    t = np.array([0.05, 0.1, 0.2, 0.5])
    sol = simulate(_motor_circuit(p, J, d), 0.5, rtol=1e-9, t_eval=t)
    np.testing.assert_allclose(sol["dut.w"], w_ss * (1 - np.exp(-d * t / J)), rtol=2e-3)
    K = (1 / 0.95 - 1) * D * W / DP
    assert sol.final("dut.q") == pytest.approx(D * sol.final("dut.w") + K * p, rel=1e-9)
    # power balance: hydraulic in = shaft out + leakage + friction losses
    P_loss = K * p * p + 0.08 * D * p * sol.final("dut.w")
    assert sol.final("dut.P_hyd") == pytest.approx(sol.final("dut.P_shaft") + P_loss, rel=1e-6)


@requires_solver
def test_pressure_compensated_pump_dead_headed_holds_its_setting():
    c = Circuit("pc")
    c.add("motor", SpeedSource(w0=W))
    c.add("tank", Tank())
    c.add("dut", PressureCompensatedPump(D=D, p_c=bar(180)))
    c.add("line", VolumeNode(V=cm3(200)))
    c.connect("motor.shaft", "dut.shaft")
    c.connect("tank.port", "dut.a")
    c.connect("dut.b", "line.port")
    sol = simulate(c, 2.0, rtol=1e-8)
    p = sol.final("line.port.p")
    assert bar(175) < p < bar(180)
    K = 0.05 * D * W / DP
    assert sol.final("dut.eps") == pytest.approx(K * p / (D * W), rel=1e-4)  # only the leakage


@requires_solver
def test_load_sensing_pump_holds_its_margin_across_a_metering_orifice():
    """Pump -> meter -> load orifice -> tank; LS senses after the meter."""
    A_m, A_load, margin = mm2(10), mm2(6), bar(20)
    c = Circuit("ls")
    c.add("motor", SpeedSource(w0=W))
    c.add("tank", Tank())
    c.add("dut", LoadSensingPump(D=D, p_c=bar(250), dp_ls=margin, dp_reg=bar(1)))
    c.add("vp", VolumeNode(V=cm3(100)))
    c.add("meter", Orifice(A=A_m))
    c.add("vl", VolumeNode(V=cm3(100)))
    c.add("load", Orifice(A=A_load))
    c.connect("motor.shaft", "dut.shaft")
    c.connect("tank.port", "dut.a", "load.b")
    c.connect("dut.b", "vp.port", "meter.a")
    c.connect("meter.b", "vl.port", "load.a", "dut.LS")
    sol = simulate(c, 2.0, rtol=1e-8)
    m = sol.final("dut.margin")
    assert margin - bar(1) < m < margin
    q = orifice_flow(0.6, A_m, m, 870.0, Orifice(A=A_m).params.transition())
    assert sol.final("dut.q") == pytest.approx(q, rel=1e-6)
    assert sol.final("dut.eps") < 1.0


def test_machine_benches_have_exact_jacobians():
    c = _motor_circuit(bar(100), 0.05, 0.5)
    assert jacobian_fd_error(c.compile()) < 1e-5
    c = _pump_circuit(LoadSensingPump(D=D, p_c=bar(250)), bar(50))
    c.add("ls", PressureSource(p0=bar(40)))
    c.connect("ls.port", "dut.LS")
    assert jacobian_fd_error(c.compile()) < 1e-5


def test_bad_machine_parameters():
    with pytest.raises(ParameterError, match="eta_v"):
        HydraulicMotor(D=D, eta_v=1.2)
    with pytest.raises(ParameterError, match="p_c"):
        PressureCompensatedPump(D=D)
