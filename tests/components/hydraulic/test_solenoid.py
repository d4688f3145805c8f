"""OnOffValve / TimedOnOffValve (rig L2, tables 4.7-4.8) and PWMValve (report 4.5.4-4.5.5)."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import OnOffValve, PWMValve, TimedOnOffValve
from pvgraph.components.hydraulic.solenoid import L2_AREA, L2_K
from hydraulic_helpers import jacobian_fd_error, requires_solver, value, vector
from pvgraph import expr as E
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate
from pvgraph.testing import Pressure, Signal, bench_circuit
from pvgraph.units import bar

RHO = 870.0
K_TURB = 0.6 * L2_AREA * math.sqrt(2 / RHO)

# figure 4.55 least-squares lines, Q [m^3/s] over DT [%]
NC_13_5 = lambda dt: 3.0e-7 * dt - 3.7e-6   # noqa: E731
NC_2 = lambda dt: 1.1e-7 * dt - 2.4e-6      # noqa: E731
NO_4 = lambda dt: -1.8e-7 * dt + 1.6e-5     # noqa: E731
NO_2 = lambda dt: -1.7e-7 * dt + 1.3e-5     # noqa: E731
ANCHORS = [("NC", 13.5, dt, NC_13_5) for dt in (30, 50, 70, 100)] + \
          [("NC", 2.0, dt, NC_2) for dt in (70, 100)] + \
          [("NO", 4.0, dt, NO_4) for dt in (0, 25, 50, 75)] + \
          [("NO", 2.0, dt, NO_2) for dt in (0, 25, 50)]


def test_open_valve_residual_and_flows_at_the_analytic_point():
    dp = bar(2)
    system = bench_circuit(OnOffValve(A=L2_AREA, s0=1.0), a=Pressure(dp), b=Pressure(0.0),
                           u=Signal(1.0)).compile()
    y = vector(system, {"dut.s": 1.0})
    assert abs(system.residual(0.0, y, np.zeros(system.n))[0]) < 1e-15
    q = value(system, y, "dut.a.q")
    assert q == pytest.approx(K_TURB * math.sqrt(dp), rel=1e-4)
    assert q + value(system, y, "dut.b.q") == 0.0


def test_laminar_law_and_direction():
    for dp in (bar(2), -bar(2)):
        system = bench_circuit(OnOffValve(K=L2_K, s0=1.0), a=Pressure(max(dp, 0.0)),
                               b=Pressure(max(-dp, 0.0)), u=Signal(1.0)).compile()
        assert value(system, np.array([1.0]), "dut.a.q") == pytest.approx(L2_K * dp, rel=1e-8)


@pytest.mark.parametrize("kwargs, match", [
    (dict(), "exactly one of A"),
    (dict(A=L2_AREA, K=L2_K), "exactly one of A"),
    (dict(A=L2_AREA, tau_open=0.0), "tau_open"),
    (dict(A=L2_AREA, dynamics="step"), "dynamics"),
])
def test_on_off_bad_parameters_name_the_field(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        OnOffValve(**kwargs)


@pytest.mark.parametrize("t_switch", [(), (0.0,), (0.2, 0.1)])
def test_timed_valve_rejects_bad_schedules(t_switch):
    with pytest.raises(ParameterError, match="t_switch"):
        TimedOnOffValve(A=L2_AREA, t_switch=t_switch)


@pytest.mark.parametrize("make", [
    lambda: bench_circuit(OnOffValve(A=L2_AREA), a=Pressure(lambda t: bar(2) + bar(1) * t),
                          b=0.0, u=Signal(lambda t: E.where(t > 0.1, 1.0, 0.0))),
    lambda: bench_circuit(OnOffValve(K=L2_K, dynamics="ramp"), a=bar(2), b=0.0, u=Signal(0.3)),
    lambda: bench_circuit(TimedOnOffValve(A=L2_AREA, t_switch=(0.1,)), a=bar(2), b=0.0),
    lambda: bench_circuit(PWMValve(kind="NC"), a=bar(13.5), b=0.0, DT=Signal(0.5)),
])
def test_benches_are_well_posed_and_jacobians_exact(make):
    system = make().compile()
    assert system.differential.sum() == 1
    assert jacobian_fd_error(system) < 1e-6


@pytest.mark.parametrize("kind, dp_bar, dt, line", ANCHORS)
def test_pwm_flow_map_passes_the_report_anchor_points(kind, dp_bar, dt, line):
    q = PWMValve(kind=kind).params.flow(dt / 100, bar(dp_bar))
    assert q == pytest.approx(line(dt), rel=0.15)


def test_pwm_maps_against_figure_4_22_and_direction():
    nc, no = PWMValve(kind="NC").params, PWMValve(kind="NO").params
    assert 2.5e-5 < nc.flow(1.0, bar(16)) <= 3.0e-5  # the largest NC curve, below the axis
    dts = np.linspace(0, 1, 41)
    assert np.all(np.diff([nc.flow(d, bar(10)) for d in dts]) >= 0)  # NC opens with DT
    assert np.all(np.diff([no.flow(d, bar(10)) for d in dts]) <= 0)  # NO closes with DT
    assert nc.flow(0.0, bar(10)) == 0.0 and no.flow(1.0, bar(10)) == 0.0
    assert nc.flow(0.6, -bar(5)) == pytest.approx(-nc.flow(0.6, bar(5)))
    assert nc.flow(0.6, bar(8)) > nc.flow(0.6, bar(4))


@pytest.mark.parametrize("kwargs, match", [
    (dict(kind="XY"), "kind"),
    (dict(kind="NC", DT_table=(0.0, 1.0)), "together"),
    (dict(kind="NC", DT_table=(0.0, 1.5), Q_table=(0.0, 1e-5)), "DT_table"),
    (dict(kind="NC", DT_table=(0.0, 1.0), Q_table=(0.0, -1e-5)), "Q_table"),
    (dict(kind="NO", tau=0.0), "tau"),
])
def test_pwm_bad_parameters_name_the_field(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        PWMValve(**kwargs)


@requires_solver
@pytest.mark.parametrize("u, s0, tau", [(1.0, 0.0, 0.02), (0.0, 1.0, 0.05)])
def test_on_off_valve_opens_and_closes_through_a_first_order_lag(u, s0, tau):
    valve = OnOffValve(A=L2_AREA, s0=s0, tau_open=0.02, tau_close=0.05)
    t = np.linspace(0.0, 3 * tau, 7)
    sol = simulate(bench_circuit(valve, a=bar(2), b=0.0, u=Signal(u)), t[-1], rtol=1e-8,
                   t_eval=t)
    s = u + (s0 - u) * np.exp(-t / tau)
    np.testing.assert_allclose(sol["dut.s"], s, atol=1e-6)
    np.testing.assert_allclose(sol["dut.q"], K_TURB * math.sqrt(bar(2)) * s, rtol=1e-4,
                               atol=1e-9)


@requires_solver
def test_ramp_dynamics_open_linearly():
    valve = OnOffValve(K=L2_K, dynamics="ramp", tau_open=0.04)
    t = np.linspace(0.0, 0.03, 4)
    sol = simulate(bench_circuit(valve, a=bar(2), b=0.0, u=Signal(1.0)), 0.06, rtol=1e-8,
                   t_eval=np.concatenate([t, [0.06]]))
    np.testing.assert_allclose(sol["dut.s"][:4], t / 0.04, atol=1e-6)
    assert sol.final("dut.s") == pytest.approx(1.0, abs=1e-4)
    assert sol.final("dut.q") == pytest.approx(L2_K * bar(2), rel=1e-4)


@requires_solver
def test_timed_valve_switches_at_the_scheduled_times():
    tau = 0.01
    valve = TimedOnOffValve(A=L2_AREA, t_switch=(0.05, 0.15), tau_open=tau, tau_close=tau)
    t = np.array([0.04, 0.05 + tau, 0.15, 0.15 + tau])
    sol = simulate(bench_circuit(valve, a=bar(2), b=0.0), 0.2, rtol=1e-8, t_eval=t)
    s = sol["dut.s"]
    assert abs(s[0]) < 1e-6
    assert s[1] == pytest.approx(1 - math.exp(-1), abs=1e-4)
    opened = 1 - math.exp(-0.1 / tau)
    assert s[2] == pytest.approx(opened, abs=1e-4)
    assert s[3] == pytest.approx(opened * math.exp(-1), abs=1e-4)
    assert len(sol.events) == 2


@requires_solver
@pytest.mark.parametrize("kind, tau", [("NC", 0.020), ("NO", 0.003)])
def test_pwm_duty_cycle_lag_and_steady_flow(kind, tau):
    DT, dp = 0.6, bar(8)
    t = np.array([tau, 10 * tau])
    sol = simulate(bench_circuit(PWMValve(kind=kind), a=dp, b=0.0, DT=Signal(DT)), t[-1],
                   rtol=1e-8, t_eval=t)
    assert sol["dut.d"][0] == pytest.approx(DT * (1 - math.exp(-1)), abs=1e-5)
    assert sol.final("dut.q") == pytest.approx(PWMValve(kind=kind).params.flow(DT, dp), rel=1e-3)


def test_a_timed_valve_started_after_a_switching_time_starts_switched():
    """Toggled at 0.1, 0.2, 0.3 s from closed: a run from 0.15 s (or exactly 0.1 s) starts
    with the valve commanded open, as Step does; it stayed closed until 0.2 s."""
    from pvgraph import Circuit
    from pvgraph.components import PressureSource, Tank, TimedOnOffValve
    from pvgraph.simulate import simulate
    for t0 in (0.15, 0.1):
        c = Circuit("timed")
        c.add("src", PressureSource(p0="100 bar"))
        c.add("v", TimedOnOffValve(t_switch=(0.1, 0.2, 0.3), A="5 mm^2", tau_open="10 ms"))
        c.add("t", Tank())
        c.connect("src.port", "v.a")
        c.connect("v.b", "t.port")
        sol = simulate(c, 0.19, t_start=t0, t_eval=[0.19])
        # opening from the run's start with its lag (it stayed closed: 0.0)
        assert sol.final("v.s") == pytest.approx(1.0 - math.exp(-(0.19 - t0) / 0.01), rel=1e-5)
        assert sol.final("v.a.q") > 0.0         # and passing flow from the source
