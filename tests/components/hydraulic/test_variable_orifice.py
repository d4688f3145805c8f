"""VariableOrifice: opening area from the spool position, flow force on the spool (4.4.2, A.4)."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import Tank, VariableOrifice, VolumeNode
from hydraulic_helpers import (VelocityDrive, fixed_observed, jacobian_fd_error, requires_solver,
                               value, vector)
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.testing import Flow, Position, Pressure, bench_circuit
from pvgraph.units import bar, cm3, mm, mm2

RHO = 870.0
# PVG main spool A_H(x_m): +-1.5 mm dead band, 69.549 mm^2 at 7 mm (report 4.4.2)
MAIN_SPOOL = dict(w=mm2(69.549) / mm(5.5), x_dead=mm(1.5), A_max=mm2(69.549), theta=0.48)


def main_spool(**kw):
    return VariableOrifice(**{**MAIN_SPOOL, **kw})


def observe(orifice, x, pa=bar(10), pb=0.0, names=("A", "q", "F_flow")):
    return fixed_observed(orifice, names, a=Pressure(pa), b=Pressure(pb), flange=Position(x))


def test_main_spool_area_dead_band_and_full_opening():
    # 7 mm is the corner of the A_max limit, rounded by w * x_eps / 2 (0.1 %)
    assert observe(main_spool(), mm(7))[0] == pytest.approx(mm2(69.549), rel=1e-3)
    assert observe(main_spool(), mm(-7))[0] == pytest.approx(mm2(69.549), rel=1e-3)
    assert observe(main_spool(), mm(4))[0] == pytest.approx(MAIN_SPOOL["w"] * mm(2.5), rel=1e-4)
    assert observe(main_spool(), mm(9))[0] == pytest.approx(mm2(69.549), rel=1e-4)  # limited
    assert observe(main_spool(), mm(1.0))[0] < 1e-5 * mm2(69.549)                   # dead band
    assert observe(main_spool(), 0.0)[0] > 0.0                                      # leakage


def test_tabulated_area_follows_the_table():
    x = (-mm(7), -mm(1.5), mm(1.5), mm(7))
    A = (mm2(69.549), 0.0, 0.0, mm2(69.549))
    params = VariableOrifice(x_table=x, A_table=A).params
    assert observe(VariableOrifice(params), mm(7))[0] == pytest.approx(mm2(69.549), rel=1e-9)
    assert observe(VariableOrifice(params), 0.0)[0] == pytest.approx(params.A_leak)
    assert observe(VariableOrifice(params), mm(4))[0] == pytest.approx(
        params.A_leak + params.table().value(mm(4)))


def test_flow_reverses_with_pressure_and_grows_with_opening():
    q = lambda x, pa, pb: observe(main_spool(), x, pa, pb)[1]  # noqa: E731
    assert q(mm(4), bar(2), bar(8)) == pytest.approx(-q(mm(4), bar(8), bar(2)))
    assert 0.0 < q(mm(3), bar(10), 0.0) < q(mm(4), bar(10), 0.0) < q(mm(7), bar(10), 0.0)


def test_flow_force_closes_the_opening_for_either_flow_direction():
    dp = bar(10)
    A, q, F = observe(main_spool(), mm(5), dp, 0.0)
    F_closing = 2 * 0.6 * A * dp * math.cos(0.48)  # report eq. A.6 (dp >> dp_t)
    assert F == pytest.approx(-F_closing, rel=1e-4)
    assert observe(main_spool(), mm(5), 0.0, dp)[2] == pytest.approx(-F_closing, rel=1e-4)
    assert observe(main_spool(), -mm(5), dp, 0.0)[2] == pytest.approx(F_closing, rel=1e-4)
    def one_way():
        return VariableOrifice(opens="positive", w=mm(10))
    assert observe(one_way(), mm(2), dp, 0.0)[2] < 0
    assert observe(one_way(), mm(2), 0.0, dp)[2] < 0
    assert observe(one_way(), -mm(2), dp, 0.0)[0] < 1e-5 * mm2(20)  # tail w x_eps^2 / (4|u|)
    # momentum flux of the regularised flow: F = rho q^2 / (Cd A) cos(theta)
    assert -F == pytest.approx(RHO * q * q / (0.6 * A) * math.cos(0.48), rel=1e-9)


def test_residual_port_flows_and_flange_force_at_the_analytic_point():
    x, pa, dp = mm(5), bar(12), bar(4)
    orifice = main_spool()
    A = orifice.params.A_leak + orifice.params.opening(x)
    q = orifice_flow(0.6, A, dp, RHO, orifice.params.dp_t)
    system = bench_circuit(orifice, a=Pressure(pa), b=Flow(-q), flange=Position(x)).compile()
    F_flow = -2 * 0.6 * A * dp ** 2 / math.hypot(dp, orifice.params.dp_t) * math.cos(0.48)
    y = vector(system, {"dut.b.p": pa - dp, "dut.flange.f": -F_flow})
    r = system.residual(0.0, y, np.zeros(system.n))  # flow rows ~ q, force row ~ F_flow
    assert np.max(np.abs(r)) < 1e-12 * abs(F_flow)
    assert value(system, y, "dut.a.q") + value(system, y, "dut.b.q") == pytest.approx(0.0)
    assert value(system, y, "dut.a.q") == pytest.approx(q)


@pytest.mark.parametrize("kwargs, field", [
    (dict(), "w"),
    (dict(w=-1.0), "w"),
    (dict(w=0.01, opens="up"), "opens"),
    (dict(x_table=(0.0, 1e-3), A_table=(0.0,)), "x_table"),
    (dict(x_table=(1e-3, 0.0), A_table=(0.0, 1e-6)), "strictly increasing"),
    (dict(x_table=(0.0, 1e-3), A_table=(0.0, -1e-6)), "A_table"),
    (dict(w=0.01, x_table=(0.0, 1e-3), A_table=(0.0, 1e-6)), "not both"),
    (dict(w=0.01, theta=2.0), "theta"),
])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        VariableOrifice(**kwargs)


def _moving_spool_discharge(orifice, V, p0, x0, v):
    c = Circuit("discharge")
    c.add("vol", VolumeNode(V=V, p0=p0))
    c.add("dut", orifice)
    c.add("tank", Tank())
    c.add("drive", VelocityDrive(x0=x0, v=v))
    c.connect("vol.port", "dut.a")
    c.connect("dut.b", "tank.port")
    c.connect("drive.flange", "dut.flange")
    return c


@pytest.mark.parametrize("orifice", [
    main_spool(),
    VariableOrifice(x_table=(-mm(7), -mm(1.5), mm(1.5), mm(7)),
                    A_table=(mm2(69.5), 0.0, 0.0, mm2(69.5))),
])
def test_bench_is_well_posed_and_jacobian_exact(orifice):
    system = _moving_spool_discharge(orifice, cm3(10), bar(20), mm(3), 0.01).compile()
    assert system.differential.sum() == 2  # the pressure and the spool position
    assert jacobian_fd_error(system) < 1e-6


@requires_solver
def test_volume_discharge_through_a_fixed_opening_follows_the_square_root_law():
    V, p0, x = cm3(200), bar(50), mm(1.5) + mm(0.4)
    orifice = main_spool()
    A = orifice.params.A_leak + orifice.params.opening(x)
    rate = 7e8 * 0.6 * A * math.sqrt(2 / RHO) / (2 * V)
    t_end = (math.sqrt(p0) - math.sqrt(bar(5))) / rate
    t = np.linspace(0.0, t_end, 6)
    sol = simulate(_moving_spool_discharge(orifice, V, p0, x, 0.0), t_end, rtol=1e-8,
                   t_eval=t)
    np.testing.assert_allclose(np.sqrt(sol["vol.port.p"]), math.sqrt(p0) - rate * t, rtol=2e-3)
    np.testing.assert_allclose(sol["dut.F_flow"],
                               -2 * 0.6 * A * sol["vol.port.p"] * math.cos(0.48), rtol=1e-3)
