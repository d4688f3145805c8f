"""Orifice (report eq. A.4 with a laminar transition) and LaminarOrifice (eq. 4.132)."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import LaminarOrifice, Orifice, Tank, VolumeNode
from hydraulic_helpers import fixed_observed, jacobian_fd_error, requires_solver, value, vector
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.testing import Flow, Pressure, bench_circuit
from pvgraph.units import bar, cm3, lpm_per_bar, mm2

BETA, RHO = 7e8, 870.0


def test_orifice_residual_vanishes_at_the_analytic_point():
    orifice = Orifice(A=mm2(2.0))
    dp = bar(5.0)
    q = orifice_flow(0.6, mm2(2.0), dp, RHO, orifice.params.transition())
    system = bench_circuit(orifice, a=Pressure(bar(10)), b=Flow(-q)).compile()
    y = vector(system, {"dut.b.p": bar(10) - dp})
    assert np.max(np.abs(system.residual(0.0, y, np.zeros(system.n)))) < 1e-9 * q
    assert value(system, y, "dut.a.q") + value(system, y, "dut.b.q") == pytest.approx(0.0)
    assert value(system, y, "dut.a.q") == pytest.approx(q)


def test_orifice_is_the_turbulent_law_above_the_transition_and_linear_below():
    A = mm2(2.0)
    dp_t = Orifice(A=A).params.transition()
    k = 0.6 * A * math.sqrt(2 / RHO)
    [q_hi] = fixed_observed(Orifice(A=A), ["q"], a=Pressure(20 * dp_t), b=Pressure(0.0))
    assert q_hi == pytest.approx(k * math.sqrt(20 * dp_t), rel=3e-3)
    [q_lo] = fixed_observed(Orifice(A=A), ["q"], a=Pressure(1e-3 * dp_t), b=Pressure(0.0))
    assert q_lo == pytest.approx(k * 1e-3 * dp_t / math.sqrt(dp_t), rel=1e-5)


def test_orifice_flow_reverses_with_the_pressure_drop_and_grows_with_area():
    def q(A, pa, pb):
        return fixed_observed(Orifice(A=A), ["q"], a=Pressure(pa), b=Pressure(pb))[0]
    assert q(mm2(2), bar(1), bar(4)) == pytest.approx(-q(mm2(2), bar(4), bar(1)))
    assert q(mm2(3), bar(4), 0.0) > q(mm2(2), bar(4), 0.0) > 0


def test_laminar_orifice_residual_and_flows():
    K, V, dp = lpm_per_bar(1.6111), cm3(10), bar(2.0)
    c = Circuit("fill")
    c.add("src", Tank(p0=bar(3)))
    c.add("r", LaminarOrifice(K=K))
    c.add("vol", VolumeNode(V=V))
    c.connect("src.port", "r.a")
    c.connect("r.b", "vol.port")
    system = c.compile()
    y = vector(system, {"vol.port.p": bar(3) - dp})
    yp = np.array([BETA * K * dp / V])  # V/beta dp/dt = K dp
    assert np.max(np.abs(system.residual(0.0, y, yp))) < 1e-9 * K * dp
    assert value(system, y, "r.a.q") == pytest.approx(K * dp)
    assert value(system, y, "r.a.q") + value(system, y, "r.b.q") == pytest.approx(0.0)


@pytest.mark.parametrize("make, field", [
    (lambda: Orifice(A=-1e-6), "A"),
    (lambda: Orifice(A=mm2(1), Cd=1.5), "Cd"),
    (lambda: Orifice(A=mm2(1), dp_t=0.0), "dp_t"),
    (lambda: LaminarOrifice(K=0.0), "K"),
])
def test_bad_parameters_name_the_field(make, field):
    with pytest.raises(ParameterError, match=field):
        make()


def _discharge(restriction, V, p0):
    c = Circuit("discharge")
    c.add("vol", VolumeNode(V=V, p0=p0))
    c.add("r", restriction)
    c.add("tank", Tank())
    c.connect("vol.port", "r.a")
    c.connect("r.b", "tank.port")
    return c


@pytest.mark.parametrize("restriction", [Orifice(A=mm2(2)), LaminarOrifice(K=1e-11)])
def test_discharge_bench_is_well_posed_and_jacobian_exact(restriction):
    system = _discharge(restriction, cm3(10), bar(50)).compile()
    assert system.differential.sum() == 1
    assert jacobian_fd_error(system) < 1e-6


@requires_solver
def test_volume_discharges_exponentially_through_a_laminar_orifice():
    V, K, p0 = cm3(100), lpm_per_bar(0.2), bar(50)
    tau = V / (BETA * K)
    t = np.linspace(0.0, 3 * tau, 7)
    sol = simulate(_discharge(LaminarOrifice(K=K), V, p0), t[-1], rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["vol.port.p"], p0 * np.exp(-t / tau), rtol=1e-5, atol=10.0)
    np.testing.assert_allclose(sol["r.q"], -sol.der("vol.port.p") * V / BETA, rtol=1e-5,
                               atol=1e-12)


@requires_solver
def test_square_root_of_pressure_falls_linearly_through_a_turbulent_orifice():
    V, A, p0 = cm3(10), mm2(5), bar(100)
    rate = BETA * 0.6 * A * math.sqrt(2 / RHO) / (2 * V)  # d sqrt(p) / dt
    t_end = (math.sqrt(p0) - math.sqrt(0.04 * p0)) / rate  # stop at 4 bar >> dp_t
    t = np.linspace(0.0, t_end, 9)
    sol = simulate(_discharge(Orifice(A=A), V, p0), t_end, rtol=1e-8, t_eval=t)
    assert Orifice(A=A).params.transition() < 0.01 * 0.04 * p0
    np.testing.assert_allclose(np.sqrt(sol["vol.port.p"]), math.sqrt(p0) - rate * t,
                               rtol=2e-3)
