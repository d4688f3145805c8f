"""Pressure valves: relief (static, dynamic, pilot-operated), reducing, sequence, counterbalance."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from pvgraph.components.hydraulic import (CounterbalanceValve, DynamicReliefValve, FlowSource, Orifice,
                                  PilotReliefValve, PressureReducingValve, PressureSource,
                                  ReliefValve, SequenceValve, Tank, VolumeNode)
from hydraulic_helpers import fixed_observed, jacobian_fd_error, requires_solver
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.testing import Pressure
from pvgraph.units import bar, cm3, lpm, mm2

RHO, CD, DP_T = 870.0, 0.6, 1e4
RELIEF = dict(p_crack=bar(100), A_s=mm2(20), k=2e5, x_max=1e-3, w=0.02)   # p_full = 200 bar


def x_relief(dp, theta=math.radians(69.0), **kw):
    """The documented static opening, written out: force balance, then the stroke limits."""
    p = {**RELIEF, **kw}
    k_f = 2 * CD * p["w"] * math.cos(theta)
    x = p["A_s"] * (dp - p["p_crack"]) / (p["k"] + k_f * dp)
    return min(max(x - 0.5e-3 * p["x_max"], 0.0), p["x_max"])


def q_relief(dp, **kw):
    return fixed_observed(ReliefValve(**{**RELIEF, **kw}), ["q"], P=Pressure(dp),
                          T=Pressure(0.0))[0]


def test_relief_is_closed_below_cracking_and_follows_its_force_balance_above():
    assert 0 < q_relief(bar(99)) < orifice_flow(CD, 2e-11, bar(99), RHO, DP_T)
    for dp in (bar(120), bar(150), bar(190)):
        x = x_relief(dp)
        assert 0 < x < RELIEF["x_max"]
        assert q_relief(dp) == pytest.approx(orifice_flow(CD, 1e-11 + RELIEF["w"] * x, dp, RHO,
                                                          DP_T), rel=1e-7)  # max(dp,0) within 1 Pa


def test_relief_full_open_pressure_without_flow_force():
    p = ReliefValve(**RELIEF, theta=math.pi / 2).params
    assert p.p_full == pytest.approx(bar(200))
    full = orifice_flow(CD, 1e-11 + RELIEF["w"] * RELIEF["x_max"], bar(201), RHO, DP_T)
    assert q_relief(bar(201), theta=math.pi / 2) == pytest.approx(full, rel=1e-9)
    # the flow force closes the valve: less flow at the same pressure
    assert q_relief(bar(150)) < q_relief(bar(150), theta=math.pi / 2)


def _pump_bench(valve, Q, V=cm3(50), p0=0.0):
    c = Circuit("relief")
    c.add("pump", FlowSource(Q=Q))
    c.add("line", VolumeNode(V=V, p0=p0))
    c.add("dut", valve)
    c.add("tank", Tank())
    c.connect("pump.port", "line.port", "dut.P")
    c.connect("dut.T", "tank.port")
    return c


def _p_star(Q, theta):
    return brentq(lambda dp: orifice_flow(CD, 1e-11 + RELIEF["w"] * x_relief(dp, theta), dp, RHO,
                                          DP_T) - Q, RELIEF["p_crack"] + 1.0, bar(400))


@requires_solver
@pytest.mark.parametrize("theta", [math.pi / 2, math.radians(69.0)])
def test_relief_holds_the_pump_pressure(theta):
    Q = lpm(20)
    sol = simulate(_pump_bench(ReliefValve(**RELIEF, theta=theta), Q), 0.3, rtol=1e-8)
    assert sol.final("line.port.p") == pytest.approx(_p_star(Q, theta), rel=1e-6)
    assert sol.final("dut.q") == pytest.approx(Q, rel=1e-6)


@requires_solver
def test_dynamic_relief_settles_on_the_static_characteristic():
    Q = lpm(20)
    valve = DynamicReliefValve(**RELIEF, m=0.02, b=200.0)
    sol = simulate(_pump_bench(valve, Q), 0.5, rtol=1e-8)
    # the static model's opening is rounded by eps/2 = 0.5 um (0.4 % of x here)
    assert sol.final("line.port.p") == pytest.approx(_p_star(Q, math.radians(69.0)), rel=1e-3)
    assert sol.final("dut.x") == pytest.approx(x_relief(sol.final("line.port.p")), rel=1e-2)
    # closed on its seat until the pressure reaches p_crack: no flow before
    t_crack = RELIEF["p_crack"] * cm3(50) / (7e8 * Q)
    early = sol.t < 0.9 * t_crack
    assert np.all(sol["dut.q"][early] < 1e-4 * Q)


@requires_solver
def test_pilot_relief_has_a_flat_characteristic():
    """Pilot setting 150 bar: from 10 to 100 L/min the pressure rises by a few bar only."""
    kw = dict(p_set=bar(150), A_main=mm2(60))
    ps = []
    for Q in (lpm(10), lpm(100)):
        sol = simulate(_pump_bench(PilotReliefValve(**kw), Q), 0.3, rtol=1e-8)
        assert sol.final("dut.q") == pytest.approx(Q, rel=1e-6)
        assert sol.final("dut.q_pilot") + sol.final("dut.q_main") == pytest.approx(Q, rel=1e-9)
        ps.append(sol.final("line.port.p"))
    assert bar(150) < ps[0] < ps[1] < bar(150) + bar(8)
    # the pilot stage alone passes its flow at the pilot chamber pressure above p_set
    assert sol.final("dut.q_pilot") < 0.05 * lpm(100)


def _settled_flow(valve, p_in, p_out_orifice):
    c = Circuit("prv")
    c.add("supply", PressureSource(p0=p_in))
    c.add("dut", valve)
    c.add("out", VolumeNode(V=cm3(10)))
    c.add("load", Orifice(A=p_out_orifice, dp_t=DP_T))
    c.add("tank", Tank())
    c.connect("supply.port", "dut.P")
    c.connect("dut.A", "out.port", "load.a")
    c.connect("load.b", "tank.port")
    return c


def _ramp(u, u0, du):
    s = min(max((u - u0) / du, 0.0), 1.0)
    return s * s * (3 - 2 * s)


@requires_solver
def test_reducing_valve_holds_its_outlet_below_the_setting():
    p_set, A_max, A_load = bar(40), mm2(20), mm2(3)
    sol = simulate(_settled_flow(PressureReducingValve(p_set=p_set, A_max=A_max), bar(150),
                                 A_load), 0.2, rtol=1e-8)
    p_a = sol.final("out.port.p")
    area = lambda pa: 1e-11 + A_max * (1 - _ramp(pa, p_set - bar(5), bar(5)))
    p_exp = brentq(lambda pa: orifice_flow(CD, area(pa), bar(150) - pa, RHO, DP_T)
                   - orifice_flow(CD, A_load, pa, RHO, DP_T), 0.0, p_set)
    assert p_a == pytest.approx(p_exp, rel=1e-6)
    assert p_set - bar(5) < p_a < p_set


@requires_solver
def test_reducing_valve_holds_a_dead_ended_outlet_at_the_setting():
    # a clamp at stall: 200 bar supply, 50 bar setting, nothing drawing from the outlet. The
    # closed valve's leak no longer fills the outlet up to the supply (it did: 200.000 bar
    # steady, creeping 1.9 bar/min): the drain above the setting takes it
    from pvgraph import steady_state
    p_set, dp_open, A_max = bar(50), bar(5), mm2(10)
    A_leak, A_drain, p_drain = 1e-11, 1e-9, 0.0     # the drain at tank (gauge 0)
    c = Circuit("clamp")
    c.add("supply", PressureSource(p0=bar(200)))
    c.add("dut", PressureReducingValve(p_set=p_set, A_max=A_max))
    c.add("clamp", VolumeNode(V=cm3(50), p0=bar(45)))
    c.connect("supply.port", "dut.P")
    c.connect("dut.A", "clamp.port")

    def balance(pa):       # flow in through the (almost) closed valve = flow to the drain
        a_in = A_leak + A_max * (1 - _ramp(pa, p_set - dp_open, dp_open))
        return orifice_flow(CD, a_in, bar(200) - pa, RHO, DP_T) - orifice_flow(
            CD, A_drain * _ramp(pa, p_set, dp_open), pa - p_drain, RHO, DP_T)
    p_exp = brentq(balance, p_set + 1.0, p_set + dp_open)
    assert p_set < p_exp < p_set + 0.1 * dp_open
    op = steady_state(c.compile())
    assert op["clamp.port.p"] == pytest.approx(p_exp, rel=1e-7)
    sol = simulate(c, 120.0, rtol=1e-8)
    assert sol.final("clamp.port.p") == pytest.approx(p_exp, rel=1e-5)
    assert np.max(sol["clamp.port.p"]) < p_exp * (1 + 1e-5)


def test_sequence_valve_opens_at_its_setting():
    seq = dict(p_set=bar(80), A_max=mm2(10))
    q = lambda p_in: fixed_observed(SequenceValve(**seq), ["q"], P=Pressure(p_in),
                                    A=Pressure(bar(20)))[0]
    assert abs(q(bar(79))) < orifice_flow(CD, 2e-11, bar(59), RHO, DP_T)
    assert q(bar(86)) == pytest.approx(orifice_flow(CD, mm2(10) + 1e-11, bar(66), RHO, DP_T),
                                       rel=1e-9)


def test_counterbalance_holds_the_load_until_piloted_and_passes_free_flow_to_it():
    cb = dict(p_set=bar(200), A_max=mm2(15), A_check=mm2(20), ratio=3.0)
    q = lambda p_load, p_valve, p_pilot: fixed_observed(
        CounterbalanceValve(**cb), ["q"], load=Pressure(p_load), valve=Pressure(p_valve),
        pilot=Pressure(p_pilot))[0]
    leak = orifice_flow(CD, 2e-11, bar(120), RHO, DP_T)
    assert 0 < q(bar(120), 0.0, 0.0) < 1.001 * leak               # holds 120 bar of load
    full = orifice_flow(CD, mm2(15) + 1e-11, bar(120), RHO, DP_T) \
        + orifice_flow(CD, 1e-11, bar(120), RHO, DP_T)
    assert q(bar(120), 0.0, bar(30)) == pytest.approx(full, rel=1e-9)  # 120 + 3*30 > 205
    assert q(bar(120), 0.0, bar(25)) < full                             # 195: still closing
    # free flow towards the load through the check
    free = orifice_flow(CD, mm2(20) + 1e-11, -bar(10), RHO, DP_T)
    assert q(bar(100), bar(110), 0.0) == pytest.approx(
        free + orifice_flow(CD, 1e-11, -bar(10), RHO, DP_T), rel=1e-9)


@pytest.mark.parametrize("valve", [
    ReliefValve(**RELIEF), DynamicReliefValve(**RELIEF, m=0.02, b=200.0),
    PilotReliefValve(p_set=bar(150), A_main=mm2(60)),
])
def test_relief_benches_have_exact_jacobians(valve):
    system = _pump_bench(valve, lpm(20), p0=bar(160)).compile()
    assert jacobian_fd_error(system) < 1e-5


@pytest.mark.parametrize("make, field", [
    (lambda: ReliefValve(**{**RELIEF, "k": 0.0}), "k"),
    (lambda: ReliefValve(**RELIEF, A_leak=1e-6), "A_leak"),
    (lambda: PilotReliefValve(p_set=-1.0, A_main=1e-5), "p_set"),
    (lambda: CounterbalanceValve(p_set=1e7, A_max=1e-5, A_check=1e-5, ratio=-1), "ratio"),
])
def test_bad_parameters_name_the_field(make, field):
    with pytest.raises(ParameterError, match=field):
        make()


def test_dynamic_relief_fed_straight_is_told_to_take_a_volume():
    """A poppet with mass straight on a flow source, no volume: the inlet pressure is
    algebraic, the source's flow through the closed poppet's leak at the start, 1e18 Pa (told
    with a PlausibilityWarning); the corrector fails as the poppet lifts and the run goes on
    past it (the pressure solved with a line search a step further) to the relief's pressure,
    within 1 % of the circuit with a 0.1 L volume."""
    from pvgraph.components.hydraulic import FlowSource, VolumeNode
    from pvgraph.errors import PlausibilityWarning

    def build(volume):
        c = Circuit("s")
        c.add("src", FlowSource(Q="20 L/min"))
        c.add("v", DynamicReliefValve(p_crack="150 bar", A_s="50 mm^2", k=5e4, x_max="2 mm",
                                      w="10 mm", m=0.02, b=50.0))
        c.add("tank", Tank())
        if volume:
            c.add("node", VolumeNode(V="0.1 L"))
        c.connect("src.port", "v.P", *(["node.port"] if volume else []))
        c.connect("v.T", "tank.port")
        return c
    with pytest.warns(PlausibilityWarning, match=r"v.P.p .* reaches 1.\d+e\+13 bar"):
        stiff = simulate(build(False), 0.5)
    assert stiff.stats["nrescue"] >= 1
    sol = simulate(build(True), 0.5)
    assert bar(150) < sol.final("v.P.p") < bar(170)
    assert stiff.final("v.P.p") == pytest.approx(sol.final("v.P.p"), rel=0.01)


@pytest.mark.parametrize("Q_lpm", [60.0, 30.0, 5.0])
def test_a_relief_valve_from_its_data_sheet_setting(Q_lpm):
    """ReliefValve.from_setting("200 bar", "60 L/min", "15 bar"): 60 L/min fully open at
    215 bar; below, the opening grows in proportion to dp - p_crack, so a flow Q holds
    dp - p_crack = 15 bar (Q / 60 L/min) sqrt(215 bar / dp) (solved by brentq)."""
    from scipy.optimize import brentq
    from pvgraph.analysis import steady_state
    from pvgraph.components.hydraulic import FlowSource, VolumeNode
    c = Circuit("rv")
    c.add("pump", FlowSource(Q=f"{Q_lpm} L/min"))
    c.add("node", VolumeNode(V="0.1 L"))
    c.add("rv", ReliefValve.from_setting("200 bar", "60 L/min", "15 bar"))
    c.add("tank", Tank())
    c.connect("pump.port", "node.port", "rv.P")
    c.connect("rv.T", "tank.port")
    p = steady_state(c.compile())["node.port.p"]
    want = brentq(lambda dp: (dp - 200e5) - 15e5 * Q_lpm / 60.0 * (215e5 / dp) ** 0.5,
                  200e5, 230e5)
    assert p == pytest.approx(want, abs=0.02e5)


@pytest.mark.parametrize("how", ["use_fluid", "runtime rho"])
def test_a_relief_valve_from_its_data_sheet_keeps_its_point_in_the_circuits_fluid(how):
    """ReliefValve.from_setting("150 bar", "20 L/min", "10 bar") passes 20 L/min fully open
    at 160 bar. The opening was sized with the default oil (870 kg/m^3), so a circuit of
    water glycol (1060) held 160 x 1060 / 870 = 195 bar at the rated flow; it holds the
    data sheet's 160 (the smoothing of the seat takes 5e-4 of the stroke: 160.008)."""
    from pvgraph.analysis import steady_state
    from pvgraph.components import Fluid
    from pvgraph.components.hydraulic import FlowSource, VolumeNode
    c = Circuit("rv")
    if how == "use_fluid":
        c.use_fluid(Fluid(rho=1060))
    c.add("pump", FlowSource(Q="20 L/min"))
    c.add("node", VolumeNode(V="0.1 L"))
    c.add("rv", ReliefValve.from_setting("150 bar", "20 L/min", "10 bar"))
    c.add("tank", Tank())
    c.connect("pump.port", "node.port", "rv.P")
    c.connect("rv.T", "tank.port")
    params = {"rv.rho": 1060.0} if how == "runtime rho" else None
    got = steady_state(c.compile(), params=params)
    assert got["node.port.p"] == pytest.approx(160e5, abs=0.02e5)
    assert got["rv.q"] == pytest.approx(20e-3 / 60, rel=1e-9)


def test_a_relief_setting_that_is_not_positive_is_refused():
    from pvgraph import ParameterError
    with pytest.raises(ParameterError, match="dp_rated must be positive"):
        ReliefValve.from_setting("200 bar", "60 L/min", "0 bar")
    with pytest.raises(ParameterError, match="is a pressure|dimension|p_crack"):
        ReliefValve.from_setting("200 L/min", "60 L/min", "15 bar")


def test_from_setting_checks_the_fluid_and_refuses_the_spool_it_chooses():
    from pvgraph import ParameterError
    with pytest.raises(ParameterError, match=r"invalid parameters for ReliefValve:\n  Cd = 0"):
        ReliefValve.from_setting("200 bar", "60 L/min", "15 bar", Cd=0)
    with pytest.raises(ParameterError, match="from_setting chooses k from the setting"):
        ReliefValve.from_setting("200 bar", "60 L/min", "15 bar", k=5e4)
    assert ReliefValve.from_setting("200 bar", "60 L/min", "15 bar",
                                    rho="900 kg/m^3").params.rho == 900.0


def test_a_valve_from_its_setting_has_no_dead_area_gradient():
    """from_setting sizes the opening from Q_rated at run time, so the area gradient w it
    used to store did nothing (a sweep of rv.w changed nothing, silently). The valve holds
    Q_rated instead of w: its Q_rated moves the pressure, and a w given beside it is
    refused."""
    from pvgraph import ParameterError
    from pvgraph.analysis import steady_state
    from pvgraph.components.hydraulic import FlowSource, VolumeNode
    rv = ReliefValve.from_setting("150 bar", "60 L/min", "15 bar")
    assert rv.params.w is None and rv.params.Q_rated == pytest.approx(1e-3)
    assert rv.params.p_rated == pytest.approx(165e5)
    c = Circuit("rv")
    c.add("pump", FlowSource(Q="60 L/min"))
    c.add("node", VolumeNode(V="0.1 L"))
    c.add("rv", rv)
    c.add("tank", Tank())
    c.connect("pump.port", "node.port", "rv.P")
    c.connect("rv.T", "tank.port")
    system = c.compile()
    assert steady_state(system)["node.port.p"] == pytest.approx(165e5, abs=0.02e5)
    # rated for twice the flow: 60 L/min is then half open, at 150 + 7.5 bar (dp ~ Q^2/x^2)
    p = steady_state(system, params={"rv.Q_rated": 2e-3})["node.port.p"]
    assert 150e5 < p < 160e5
    with pytest.raises(ParameterError, match="area gradient w or as the flow Q_rated"):
        steady_state(system, params={"rv.w": 0.01})
    # a setting turned up keeps the opening (rated at 165 bar): 60 L/min opens it to
    # x/x_max = sqrt(165 bar / dp), so dp - 300 bar = 15 bar x/x_max
    from scipy.optimize import brentq
    want = brentq(lambda dp: dp - 300e5 - 15e5 * (165e5 / dp) ** 0.5, 300e5, 320e5)
    got = steady_state(system, params={"rv.p_crack": 300e5})["node.port.p"]
    assert got == pytest.approx(want, abs=0.05e5)
    with pytest.raises(ParameterError, match="area gradient w or as the flow Q_rated"):
        ReliefValve(p_crack="150 bar", A_s="20 mm^2", k=3e4, x_max="1 mm")
