"""Tank, PressureSource, FlowSource, Pump and Plug on one-line benches."""

import numpy as np
import pytest

from pvgraph.components.hydraulic import FlowSource, Plug, PressureSource, Pump, Tank, VolumeNode
from hydraulic_helpers import jacobian_fd_error, requires_solver, value
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate
from pvgraph.testing import Flow, Pressure, bench_circuit
from pvgraph.units import bar, cm3, lpm

BETA = 7e8


@pytest.mark.parametrize("cls", [Tank, PressureSource])
def test_tank_fixes_pressure_and_takes_any_flow(cls):
    system = bench_circuit(cls(p0=bar(3)), port=Flow(lpm(2))).compile()
    assert system.n == 0
    assert value(system, [], "dut.port.p") == pytest.approx(bar(3))
    assert value(system, [], "dut.port.q") == pytest.approx(lpm(2))  # all of it flows in


def test_flow_source_and_plug_flows():
    system = bench_circuit(FlowSource(Q=lpm(5)), port=Pressure(bar(1))).compile()
    assert value(system, [], "dut.port.q") == pytest.approx(-lpm(5))
    system = bench_circuit(Plug(), port=Pressure(bar(1))).compile()
    assert value(system, [], "dut.port.q") == 0.0


def test_pump_draws_from_a_and_delivers_to_b():
    system = bench_circuit(Pump(Q0=lpm(16.3)), a=Pressure(0.0), b=Pressure(bar(10))).compile()
    q_a, q_b = value(system, [], "dut.a.q"), value(system, [], "dut.b.q")
    assert q_a == pytest.approx(lpm(16.3))
    assert q_a + q_b == 0.0


@pytest.mark.parametrize("kwargs, field", [
    (dict(Q0=-1e-3), "Q0"),
    (dict(Q0=1e-3, t_table=(0.0, 1.0)), "t_table and Q_table"),
    (dict(Q0=1e-3, t_table=(0.0, 1.0), Q_table=(0.0,)), r"t_table \(2 points\) and Q_table \(1 points\)"),
])
def test_pump_rejects_bad_parameters(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        Pump(**kwargs)


def test_tank_rejects_bad_pressure():
    with pytest.raises(ParameterError, match="p0"):
        Tank(p0=float("nan"))


def _pump_into_volume(pump, V):
    c = Circuit("fill")
    c.add("tank", Tank())
    c.add("pump", pump)
    c.add("vol", VolumeNode(V=V))
    c.connect("tank.port", "pump.a")
    c.connect("pump.b", "vol.port")
    return c


def test_pump_bench_is_well_posed_and_jacobian_exact():
    system = _pump_into_volume(Pump(Q0=lpm(1), t_table=(0.0, 0.1), Q_table=(0.0, lpm(1))),
                               cm3(100)).compile()
    assert system.differential.sum() == 1  # the volume pressure; the table flows are algebraic
    assert jacobian_fd_error(system) < 1e-6


@requires_solver
def test_constant_flow_fills_a_volume_linearly():
    Q, V = lpm(1), cm3(200)
    t = np.linspace(0.0, 0.1, 6)
    sol = simulate(_pump_into_volume(Pump(Q0=Q), V), t[-1], rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["vol.port.p"], BETA * Q / V * t, rtol=1e-6, atol=1.0)


@requires_solver
def test_tabulated_pump_flow_ramp_gives_quadratic_pressure():
    Q1, T, V = lpm(1), 0.1, cm3(200)
    pump = Pump(Q0=0.0, t_table=(0.0, T), Q_table=(0.0, Q1))
    t = np.linspace(0.0, T, 6)
    sol = simulate(_pump_into_volume(pump, V), T, rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["vol.port.p"], BETA / V * Q1 * t**2 / (2 * T), rtol=1e-5,
                               atol=10.0)
    np.testing.assert_allclose(sol["pump.Q"], Q1 * t / T, rtol=1e-9)


def test_a_tank_given_one_atmosphere_is_told_that_pressures_are_gauge():
    """Tank(p0="1 atm") is 1 atm above the atmosphere (pressures are gauge): a
    PlausibilityWarning at the user's line says so; the default and other values are quiet."""
    import warnings
    from pvgraph.components import Tank
    from pvgraph.errors import PlausibilityWarning
    with pytest.warns(PlausibilityWarning, match=r"p0 = 101325 Pa is about one atmosphere .* gauge \(0 = atmospheric") \
            as told:
        Tank(p0="1 atm")
    assert told[0].filename == __file__
    for written in ("1 bar", "14.7 psi", "1.013 bar", 101325):   # the same mistake
        with pytest.warns(PlausibilityWarning, match=r"about one atmosphere .* gauge"):
            Tank(p0=written)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Tank()
        Tank(p0="2 bar")
        Tank(p0="0.5 bar")
