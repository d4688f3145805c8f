"""Cylinder: two piston chambers on one rod (report A.5 applied per chamber, eqs. 4.93-4.94)."""

import numpy as np
import pytest

from pvgraph.components.hydraulic import Cylinder, FlowSource, Plug, PressureSource, Tank
from hydraulic_helpers import (MassDamper, VelocityDrive, jacobian_fd_error, requires_solver,
                               value, vector)
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate
from pvgraph.units import bar, cm3, lpm

BETA = 7e8
GEOMETRY = dict(A_A=1e-3, A_rod=4e-4, stroke=0.2, V_dead_A=cm3(20), V_dead_B=cm3(20))
A_A, A_B = 1e-3, 6e-4


def _driven(x0, v, port_A, port_B, **kw):
    c = Circuit("bench")
    c.add("drive", VelocityDrive(x0=x0, v=v))
    c.add("dut", Cylinder(**{**GEOMETRY, **kw}))
    c.add("src_A", port_A)
    c.add("src_B", port_B)
    c.connect("drive.flange", "dut.flange")
    c.connect("src_A.port", "dut.A")
    c.connect("src_B.port", "dut.B")
    return c


def test_port_flows_are_the_volume_change_rates_and_force_balances_pressures():
    x, v, p_A, p_B = 0.05, 0.1, bar(50), bar(5)
    system = _driven(x, v, PressureSource(p0=p_A), PressureSource(p0=p_B)).compile()
    values = {"drive.flange.x": x, "dut.A.q": A_A * v, "dut.B.q": -A_B * v,
              "dut.flange.f": -(A_A * p_A - A_B * p_B)}   # no end-stop force in free travel
    y = vector(system, values)
    yp = vector(system, {"drive.flange.x": v, "dut.A.q": 0.0, "dut.B.q": 0.0,
                         "dut.flange.f": 0.0})
    assert np.max(np.abs(system.residual(0.0, y, yp))) < 1e-8 * A_A * v
    assert value(system, y, "dut.flange.f") == pytest.approx(-(A_A * p_A - A_B * p_B))


@pytest.mark.parametrize("kwargs, field", [
    (dict(GEOMETRY, A_rod=1e-3), "A_rod"),
    (dict(GEOMETRY, stroke=0.0), "stroke"),
    (dict(GEOMETRY, V_dead_A=-1.0), "V_dead_A"),
    (dict(GEOMETRY, K_leak=-1.0), "K_leak"),
])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        Cylinder(**kwargs)


@pytest.mark.parametrize("K_leak", [0.0, 1e-12])
def test_bench_is_well_posed_and_jacobian_exact(K_leak):
    system = _driven(0.05, 0.1, Plug(), Plug(), K_leak=K_leak, p0_A=bar(10),
                     p0_B=bar(10)).compile()
    assert system.differential.sum() == 3
    assert jacobian_fd_error(system) < 1e-6


@requires_solver
def test_closed_cylinder_driven_by_a_position_ramp():
    """Both ports plugged: p = p0 + beta ln(V(0) / V(t)) in each chamber."""
    x0, v, p0, T = 0.1, 0.01, bar(100), 0.1
    t = np.linspace(0.0, T, 6)
    sol = simulate(_driven(x0, v, Plug(), Plug(), p0_A=p0, p0_B=p0), T, rtol=1e-8, t_eval=t)
    x = x0 + v * t
    V_A = GEOMETRY["V_dead_A"] + A_A * x
    V_B = GEOMETRY["V_dead_B"] + A_B * (GEOMETRY["stroke"] - x)
    np.testing.assert_allclose(sol["dut.A.p"], p0 + BETA * np.log(V_A[0] / V_A), rtol=1e-5)
    np.testing.assert_allclose(sol["dut.B.p"], p0 + BETA * np.log(V_B[0] / V_B), rtol=1e-5)


@requires_solver
def test_pump_extends_the_rod_against_a_damper():
    """Steady state: v = Q / A_A, A_A p_A = b v (rod side to tank), B returns A_B v."""
    Q, b, m = lpm(6), 2e5, 10.0
    c = Circuit("extend")
    c.add("pump", FlowSource(Q=Q))
    c.add("dut", Cylinder(**GEOMETRY))
    c.add("tank", Tank())
    c.add("load", MassDamper(m=m, b=b, x0=0.02))
    c.connect("pump.port", "dut.A")
    c.connect("dut.B", "tank.port")
    c.connect("dut.flange", "load.flange")
    sol = simulate(c, 0.5, rtol=1e-8, t_eval=[0.0, 0.5])
    v = Q / A_A
    assert sol.final("load.v") == pytest.approx(v, rel=1e-5)
    assert sol.final("dut.A.p") == pytest.approx(b * v / A_A, rel=1e-5)
    assert sol.final("dut.B.q") == pytest.approx(-A_B * v, rel=1e-5)
    assert sol.final("dut.F") == pytest.approx(b * v, rel=1e-5)


@requires_solver
def test_rod_stops_at_the_end_of_its_stroke():
    """Statics at the stop: k_stop * (penetration - eps/2) = A_A p_s: the stop takes the force."""
    p_s, k_stop = bar(50), 1e9
    c = Circuit("stop")
    c.add("supply", PressureSource(p0=p_s))
    c.add("dut", Cylinder(**GEOMETRY, k_stop=k_stop))
    c.add("tank", Tank())
    c.add("load", MassDamper(m=20.0, b=5e3, x0=0.15))
    c.connect("supply.port", "dut.A")
    c.connect("dut.B", "tank.port")
    c.connect("dut.flange", "load.flange")
    sol = simulate(c, 1.0, rtol=1e-7)
    v_hit = A_A * p_s / 5e3   # terminal speed against the damper
    overshoot = sol["load.flange.x"].max() - GEOMETRY["stroke"]
    assert A_A * p_s / k_stop < overshoot < v_hit * np.sqrt(20.0 / k_stop)  # below undamped bound
    eps = Cylinder(**GEOMETRY).params.eps_stop
    x_rest = GEOMETRY["stroke"] + A_A * p_s / k_stop + eps / 2
    assert sol.final("load.flange.x") - GEOMETRY["stroke"] == pytest.approx(
        x_rest - GEOMETRY["stroke"], rel=1e-4)
    assert sol.final("dut.F_stop") == pytest.approx(A_A * p_s, rel=1e-4)


@requires_solver
def test_cushion_brakes_the_rod_before_the_stop():
    """In the cushion the rod creeps at v = F / (b + d_cush w(x)), w the documented smoothstep."""
    p_s, b, d_cush = bar(20), 1e4, 4e5
    def run(**kw):
        c = Circuit("cushion")
        c.add("supply", PressureSource(p0=p_s))
        c.add("dut", Cylinder(**GEOMETRY, **kw))
        c.add("tank", Tank())
        c.add("load", MassDamper(m=5.0, b=b, x0=0.05))
        c.connect("supply.port", "dut.A")
        c.connect("dut.B", "tank.port")
        c.connect("dut.flange", "load.flange")
        return simulate(c, 2.0, rtol=1e-7, t_eval=np.linspace(0, 2.0, 2001))
    free, cushioned = run(), run(l_cush=0.02, d_cush=d_cush)
    x, vel = cushioned["load.flange.x"], cushioned["load.v"]
    inside = (x > GEOMETRY["stroke"] - 0.004) & (x < GEOMETRY["stroke"] - 0.001)
    assert inside.any()
    u = np.clip((x[inside] - GEOMETRY["stroke"]) / 0.02 + 1.0, 0.0, 1.0)
    w = u * u * (3.0 - 2.0 * u)
    np.testing.assert_allclose(vel[inside], A_A * p_s / (b + d_cush * w), rtol=1e-3)
    assert free["load.v"].max() == pytest.approx(A_A * p_s / b, rel=1e-3)


def test_end_stop_parameters_are_checked():
    with pytest.raises(ParameterError, match="l_cush"):
        Cylinder(**GEOMETRY, l_cush=0.15, d_cush=1e3)
    with pytest.raises(ParameterError, match="d_cush"):
        Cylinder(**GEOMETRY, d_cush=1e3)
