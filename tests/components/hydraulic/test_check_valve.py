"""CheckValve: one-way orifice with a cracking pressure (report 4.5.3)."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import CheckValve, FlowSource, Tank, VolumeNode
from hydraulic_helpers import fixed_observed, jacobian_fd_error, requires_solver, value, vector
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.testing import Flow, Pressure, bench_circuit
from pvgraph.units import bar, cm3, lpm, mm2

RHO, BETA = 870.0, 7e8
A_CHECK = mm2(2.3)  # PVE check balls, report 4.5.1


def q_at(dp, **kw):
    valve = CheckValve(**{"A": A_CHECK, **kw})
    return fixed_observed(valve, ["q"], a=Pressure(max(dp, 0.0)), b=Pressure(max(-dp, 0.0)))[0]


def test_rectified_orifice_passes_forward_flow_and_blocks_reverse_flow():
    forward = q_at(bar(5))
    assert forward == pytest.approx(orifice_flow(0.6, A_CHECK, bar(5), RHO, 1e3), rel=1e-9)
    assert -1e-6 * forward < q_at(-bar(5)) < 0.0


def test_cracking_pressure_holds_the_valve_closed():
    p_crack, dp_open = bar(10), bar(1)
    full = orifice_flow(0.6, A_CHECK, bar(12), RHO, 1e3)
    assert q_at(bar(9.9), p_crack=p_crack, dp_open=dp_open) < 1e-6 * full
    assert q_at(bar(12), p_crack=p_crack, dp_open=dp_open) == pytest.approx(full, rel=1e-9)
    dps = np.linspace(-bar(2), bar(13), 61)
    qs = [q_at(d, p_crack=p_crack, dp_open=dp_open) for d in dps]
    assert np.all(np.diff(qs) >= 0.0)  # monotone in dp


def test_area_ramp_is_continuously_differentiable():
    params = CheckValve(A=A_CHECK, p_crack=bar(2), dp_open=bar(1)).params
    for edge in (bar(2), bar(3)):
        h = 1e-3
        slope_left = (params.area(edge) - params.area(edge - h)) / h
        slope_right = (params.area(edge + h) - params.area(edge)) / h
        assert abs(slope_left) < 1e-9 and abs(slope_right) < 1e-9


def test_residual_and_flows_at_the_analytic_point():
    dp, p_crack = bar(6), bar(5)
    valve = CheckValve(A=A_CHECK, p_crack=p_crack)
    q = orifice_flow(0.6, A_CHECK, dp, RHO, 1e3)
    system = bench_circuit(valve, a=Pressure(bar(20)), b=Flow(-q)).compile()
    y = vector(system, {"dut.b.p": bar(20) - dp})
    assert np.max(np.abs(system.residual(0.0, y, np.zeros(system.n)))) < 1e-9 * q
    assert value(system, y, "dut.a.q") + value(system, y, "dut.b.q") == pytest.approx(0.0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(A=0.0), "A"),
    (dict(A=A_CHECK, p_crack=-1.0), "p_crack"),
    (dict(A=A_CHECK, dp_open=0.0), "dp_open"),
    (dict(A=A_CHECK, A_leak=A_CHECK), "A_leak"),
])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        CheckValve(**kwargs)


def _relief_bench(Q, V, valve, p0=0.0):
    c = Circuit("relief")
    c.add("src", FlowSource(Q=Q))
    c.add("vol", VolumeNode(V=V, p0=p0))
    c.add("dut", valve)
    c.add("tank", Tank())
    c.connect("src.port", "vol.port", "dut.a")
    c.connect("dut.b", "tank.port")
    return c


def test_bench_is_well_posed_and_jacobian_exact():
    system = _relief_bench(lpm(1), cm3(10), CheckValve(A=A_CHECK, p_crack=bar(5))).compile()
    assert system.differential.sum() == 1
    assert jacobian_fd_error(system) < 1e-6


@requires_solver
def test_volume_pressure_rises_until_the_valve_cracks_then_settles():
    Q, V, p_crack, dp_open = lpm(1), cm3(10), bar(10), bar(1)
    valve = CheckValve(A=A_CHECK, p_crack=p_crack, dp_open=dp_open)
    t_crack = p_crack * V / (BETA * Q)
    t = np.array([0.25, 0.5, 0.75]) * t_crack
    sol = simulate(_relief_bench(Q, V, valve), 20 * t_crack, rtol=1e-7,
                   t_eval=np.concatenate([t, [20 * t_crack]]))
    np.testing.assert_allclose(sol["vol.port.p"][:3], BETA * Q / V * t, rtol=1e-5)
    # steady state: the valve passes Q at the pressure where orifice_flow(A(dp), dp) = Q
    from scipy.optimize import brentq
    p_star = brentq(lambda p: orifice_flow(0.6, valve.params.area(p), p, RHO, 1e3) - Q,
                    p_crack, p_crack + 10 * dp_open)
    assert p_crack < p_star < p_crack + dp_open
    assert sol.final("vol.port.p") == pytest.approx(p_star, rel=1e-4)
    assert sol.final("dut.q") == pytest.approx(Q, rel=1e-4)


@requires_solver
def test_reverse_pressure_is_held():
    V, p0 = cm3(10), bar(50)
    c = Circuit("hold")
    c.add("tank", Tank())
    c.add("dut", CheckValve(A=A_CHECK))
    c.add("vol", VolumeNode(V=V, p0=p0))
    c.connect("tank.port", "dut.a")
    c.connect("dut.b", "vol.port")
    sol = simulate(c, 1.0, rtol=1e-8, t_eval=[0.0, 1.0])
    leak = 0.6 * 1e-12 * math.sqrt(2 * p0 / RHO)  # only through A_leak = 1e-6 mm^2
    assert sol.final("dut.q") == pytest.approx(-leak, rel=1e-3)
    assert sol.final("vol.port.p") == pytest.approx(p0 - BETA * leak / V * 1.0, rel=1e-6)
    assert sol.final("vol.port.p") > 0.999 * p0


# --- pilot-operated check valve -------------------------------------------------------------

def _pocv_q(p_a, p_b, p_x, **kw):
    from pvgraph.components.hydraulic import PilotOperatedCheckValve
    valve = PilotOperatedCheckValve(**{"A": mm2(10), "k_p": 3.0, **kw})
    return fixed_observed(valve, ["q"], a=Pressure(p_a), b=Pressure(p_b), x=Pressure(p_x))[0]


def test_pilot_operated_check_valve_holds_until_the_pilot_opens_it():
    """Load at b: 100 bar, a at tank, k_p = 3: p_control = -100 bar + 3 p_x opens over
    [0, 0.1 bar], at p_x = 33.33-33.37 bar."""
    full_back = orifice_flow(0.6, mm2(10), -bar(100), RHO, 1e3)
    leak = orifice_flow(0.6, 1e-12, -bar(100), RHO, 1e3)
    assert _pocv_q(0.0, bar(100), bar(33.0)) == pytest.approx(leak, rel=1e-6)   # holds
    assert _pocv_q(0.0, bar(100), bar(40.0)) == pytest.approx(full_back, rel=1e-12)
    assert full_back < 0.0
    # free flow a -> b with no pilot, as the plain check valve
    assert _pocv_q(bar(5), 0.0, 0.0) == pytest.approx(q_at(bar(5)) * 10 / 2.3, rel=1e-9)
    # the opening is monotone in the pilot pressure
    qs = [-_pocv_q(0.0, bar(100), bar(px)) for px in np.linspace(33.0, 33.5, 26)]
    assert np.all(np.diff(qs) >= 0.0)


@requires_solver
def test_pilot_operated_check_valve_lowers_a_held_load_at_the_orifice_rate():
    """A 2000 kg mass on a 20 cm^2 piston (98.1 bar) held by the valve. A 30 bar pilot keeps
    holding it (p_control = 0 - 98.1 + 3 x 30 < 0); 40 bar lets it down at the speed where
    the orifice flow fills the piston's swept volume, v A = q(p) with p A = m g - b |v|."""
    from scipy.optimize import brentq

    from pvgraph.components.hydraulic import Cylinder, PilotOperatedCheckValve, PressureSource
    from pvgraph.components.mechanical import Mass
    m, g, A_p, b = 2000.0, 9.81, 20e-4, 1e5
    p_load = m * g / A_p
    speeds = {}
    for p_x in (bar(30), bar(40)):
        c = Circuit("pocv")
        cyl = c.add("cyl", Cylinder(A_A=A_p, A_rod=10e-4, stroke=1.0, V_dead_A=1e-4,
                                    V_dead_B=1e-4, p0_A=p_load))
        c.add("mass", Mass(m=m, g=-g, b=b, x0=0.5))
        c.connect("cyl.flange", "mass.flange")
        v = c.add("pocv", PilotOperatedCheckValve(A=mm2(2), k_p=3.0))
        c.connect(v.b, cyl.A)
        c.connect(v.a, c.add("tank", Tank()).port)
        c.connect(v.x, c.add("pilot", PressureSource(p0=p_x)).port)
        c.connect(cyl.B, c.add("tank_b", Tank()).port)
        sol = simulate(c, 1.0, rtol=1e-8, t_eval=np.linspace(0.6, 1.0, 5))
        speeds[p_x] = sol["mass.v"]
        pressures = sol["cyl.A.p"]
    np.testing.assert_allclose(pressures[0], pressures, rtol=1e-6)
    # held: it creeps down at the closed poppet's leakage, A_leak = 1e-12 m^2
    leak = orifice_flow(0.6, 1e-12, -p_load, RHO, 1e3)
    np.testing.assert_allclose(speeds[bar(30)], leak / A_p, rtol=1e-3)

    def gap(v):     # v < 0: the load goes down, friction b|v| carries part of it
        p = (m * g + b * v) / A_p
        return v * A_p - orifice_flow(0.6, mm2(2), -p, RHO, 1e3)
    v_closed = brentq(gap, -1.0, -1e-9, xtol=1e-14)
    np.testing.assert_allclose(speeds[bar(40)], v_closed, rtol=1e-6)
    np.testing.assert_allclose(pressures, (m * g + b * v_closed) / A_p, rtol=1e-6)


def test_pilot_operated_check_valve_bad_pilot_ratio_is_named():
    from pvgraph.components.hydraulic import PilotOperatedCheckValve
    with pytest.raises(ParameterError, match="k_p"):
        PilotOperatedCheckValve(A=mm2(2), k_p=0.0)
