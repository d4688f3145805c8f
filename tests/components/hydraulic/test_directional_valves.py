"""Directional spool valves (4/3 with centre types, 4/2, 3/2, 2/2) and the servo valve."""

import math

import numpy as np
import pytest

from pvgraph.components.hydraulic import (DirectionalValve22, DirectionalValve32, DirectionalValve42,
                                  DirectionalValve43, ServoValve, Tank, VolumeNode, FlowSource)
from hydraulic_helpers import fixed_observed, jacobian_fd_error, requires_solver
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.laws import orifice_flow
from pvgraph.simulate import simulate
from pvgraph.testing import Pressure, Signal, bench_circuit
from pvgraph.units import bar, lpm, mm2

RHO, CD, DP_T, LEAK, EPS = 870.0, 0.6, 1e4, 1e-11, 1e-3
A_MAX = mm2(20)
PRESSURES = dict(P=Pressure(bar(200)), A=Pressure(bar(120)), B=Pressure(bar(60)),
                 T=Pressure(bar(2)))
EDGES = ("PA", "BT", "PB", "AT")


def area(s, lap):
    """The documented linear edge, written out: exact up to full stroke, s = 1, and level at
    A_max (1 + eps / (2 (1 - lap))) past the rounding beyond it."""
    assert not (lap - EPS < s < lap + EPS or 1 < s < 1 + EPS), "in a rounded corner"
    if s >= 1.0 + EPS:
        return LEAK + A_MAX * (1.0 + EPS / (2.0 * (1.0 - lap)))
    return LEAK + A_MAX * min(max(s - lap, 0.0), 1.0 - lap) / (1 - lap)


def flows(valve, u, extra=()):
    names = [f"q_{e}" for e in EDGES] + list(extra)
    return dict(zip(names, fixed_observed(valve, names, u=Signal(u), **PRESSURES)))


def q(A, dp):
    return orifice_flow(CD, A, dp, RHO, DP_T)


@pytest.mark.parametrize("u", [0.5, -0.3, 1.0, -1.0, 1.2])
def test_closed_centre_metering_edges(u):
    r = flows(DirectionalValve43(A_max=A_MAX, lap=0.1), u)
    assert r["q_PA"] == pytest.approx(q(area(u, 0.1), bar(80)), rel=1e-9)
    assert r["q_BT"] == pytest.approx(q(area(u, 0.1), bar(58)), rel=1e-9)
    assert r["q_PB"] == pytest.approx(q(area(-u, 0.1), bar(140)), rel=1e-9)
    assert r["q_AT"] == pytest.approx(q(area(-u, 0.1), bar(118)), rel=1e-9)


def test_centre_types_at_the_centre():
    lap, ul = 0.1, 0.05
    closed = flows(DirectionalValve43(A_max=A_MAX, lap=lap, centre="closed"), 0.0)
    assert all(abs(v) <= q(LEAK, bar(200)) for v in closed.values())
    opened = flows(DirectionalValve43(A_max=A_MAX, centre="open", underlap=ul), 0.0)
    assert opened["q_PA"] == pytest.approx(q(area(0.0, -ul), bar(80)), rel=1e-9)
    assert opened["q_AT"] == pytest.approx(q(area(0.0, -ul), bar(118)), rel=1e-9)
    tandem = flows(DirectionalValve43(A_max=A_MAX, lap=lap, centre="tandem", underlap=ul), 0.0,
                   ["q_PT"])
    assert tandem["q_PT"] == pytest.approx(q(LEAK + A_MAX * (1 - EPS), bar(198)), rel=1e-6)
    assert max(abs(tandem[f"q_{e}"]) for e in EDGES) <= q(LEAK, bar(200))
    tandem_shifted = flows(DirectionalValve43(A_max=A_MAX, lap=lap, centre="tandem",
                                              underlap=ul), 0.5, ["q_PT"])
    assert tandem_shifted["q_PT"] < 1e-4 * tandem["q_PT"]
    floating = flows(DirectionalValve43(A_max=A_MAX, lap=lap, centre="float", underlap=ul), 0.0)
    assert floating["q_AT"] == pytest.approx(q(area(0.0, -ul), bar(118)), rel=1e-9)
    assert floating["q_BT"] == pytest.approx(q(area(0.0, -ul), bar(58)), rel=1e-9)
    assert max(abs(floating["q_PA"]), abs(floating["q_PB"])) <= q(LEAK, bar(140))


def test_table_edges_follow_the_table():
    valve = DirectionalValve43(A_max=A_MAX, lap=0.1, edge="table", s_table=(0.0, 0.5, 0.9),
                               A_table=(0.0, 0.2, 1.0))
    r = flows(valve, 0.5)   # s - lap = 0.4: area 0.16 A_max
    assert r["q_PA"] == pytest.approx(q(LEAK + 0.16 * A_MAX, bar(80)), rel=1e-9)
    assert abs(r["q_PB"]) <= q(LEAK, bar(140))


def test_two_position_and_three_way_valves():
    r42 = flows(DirectionalValve42(A_max=A_MAX), 1.0)
    assert r42["q_PA"] == pytest.approx(q(LEAK + A_MAX, bar(80)), rel=1e-9)
    r42 = flows(DirectionalValve42(A_max=A_MAX), 0.0)
    assert r42["q_PB"] == pytest.approx(q(LEAK + A_MAX, bar(140)), rel=1e-9)
    p3 = dict(P=Pressure(bar(100)), A=Pressure(bar(40)), T=Pressure(0.0))
    q_pa, q_at = fixed_observed(DirectionalValve32(A_max=A_MAX), ["q_PA", "q_AT"],
                                u=Signal(1.0), **p3)
    assert q_pa == pytest.approx(q(LEAK + A_MAX, bar(60)), rel=1e-9) and q_at <= q(LEAK, bar(40))
    for normally_open, u, open_ in ((False, 1.0, True), (False, 0.0, False), (True, 0.0, True)):
        (q_22,) = fixed_observed(DirectionalValve22(A_max=A_MAX, normally_open=normally_open),
                                 ["q_PA"], u=Signal(u), P=Pressure(bar(50)), A=Pressure(0.0))
        assert q_22 == pytest.approx(q(LEAK + A_MAX, bar(50)) if open_ else q(LEAK, bar(50)),
                                     rel=1e-9)


def test_flow_force_closes_the_valve():
    (F,) = fixed_observed(DirectionalValve43(A_max=A_MAX), ["F_flow"], u=Signal(0.5),
                          **PRESSURES)
    a = area(0.5, 0.05)
    expected = -2 * CD * math.cos(math.radians(69.0)) * (
        a * (math.hypot(bar(80), DP_T) + math.hypot(bar(58), DP_T))
        - LEAK * (math.hypot(bar(140), DP_T) + math.hypot(bar(118), DP_T)))
    assert F == pytest.approx(expected, rel=1e-9) and F < 0


def _servo_bench(**kw):
    return bench_circuit(ServoValve(Q_nom=lpm(40), **kw), P=Pressure(bar(70)),
                         A=Pressure(bar(35)), B=Pressure(bar(35)), T=Pressure(0.0),
                         i=Signal(lambda t: 0.8))


@requires_solver
def test_servo_first_order_step_and_rated_flow():
    t = np.array([0.002, 0.005, 0.02, 0.1])
    sol = simulate(_servo_bench(order=1, tau=5e-3), 0.1, rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["dut.x"], 0.8 * (1 - np.exp(-t / 5e-3)), rtol=1e-5)
    A_rated = lpm(40) / (CD * math.sqrt(bar(70) / RHO))   # rated flow at 35 bar per edge
    assert q(A_rated, bar(35)) == pytest.approx(lpm(40), rel=1e-5)   # (dp_t rounding 2e-6)
    assert sol.final("dut.q_PA") == pytest.approx(q(0.8 * A_rated + LEAK, bar(35)), rel=1e-7)
    assert sol.final("dut.q_BT") == pytest.approx(q(0.8 * A_rated + LEAK, bar(35)), rel=1e-7)


@requires_solver
@pytest.mark.parametrize("command", [1.0, -1.0, 1.5])
def test_servo_at_full_command_passes_its_rated_flow(command):
    """Full command (or beyond: clipped) at the rated drop, 35 bar per edge: Q_nom, up to the
    2e-6 of the laminar rounding (dp_t), not short of it by the edge's corner rounding."""
    bench = bench_circuit(ServoValve(Q_nom=lpm(40), order=1, tau=1e-3), P=Pressure(bar(70)),
                          A=Pressure(bar(35)), B=Pressure(bar(35)), T=Pressure(0.0),
                          i=Signal(command))
    sol = simulate(bench, 0.05, rtol=1e-9)
    assert abs(sol.final("dut.P.q")) == pytest.approx(lpm(40), rel=3e-6)


@requires_solver
def test_servo_second_order_step():
    wn, zeta = 2 * math.pi * 50, 0.5
    t = np.linspace(0.001, 0.05, 12)
    sol = simulate(_servo_bench(order=2, wn=wn, zeta=zeta), 0.05, rtol=1e-9, atol=1e-10,
                   t_eval=t)
    wd = wn * math.sqrt(1 - zeta ** 2)
    x = 0.8 * (1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))
    np.testing.assert_allclose(sol["dut.x"], x, atol=1e-6)


def test_valve_bench_jacobians_and_conservation():
    c = Circuit("dcv")
    c.add("pump", FlowSource(Q=lpm(20)))
    c.add("vp", VolumeNode(V=1e-4, p0=bar(50)))
    c.add("va", VolumeNode(V=1e-4, p0=bar(20)))
    c.add("vb", VolumeNode(V=1e-4, p0=bar(10)))
    c.add("tank", Tank())
    c.add("dut", DirectionalValve43(A_max=A_MAX, centre="tandem"))
    from pvgraph.components.signal import Constant
    c.add("u", Constant(k=0.03))
    c.connect("pump.port", "vp.port", "dut.P")
    c.connect("dut.A", "va.port")
    c.connect("dut.B", "vb.port")
    c.connect("dut.T", "tank.port")
    c.connect("u.y", "dut.u")
    system = c.compile()
    assert jacobian_fd_error(system) < 1e-5
    sol = simulate(system, 0.01, rtol=1e-7)
    total = sol["dut.P.q"] + sol["dut.A.q"] + sol["dut.B.q"] + sol["dut.T.q"]
    assert np.max(np.abs(total)) < 1e-12


def test_bad_parameters_name_the_field():
    with pytest.raises(ParameterError, match="s_table"):
        DirectionalValve43(A_max=A_MAX, edge="table")
    with pytest.raises(ParameterError, match="centre"):
        DirectionalValve43(A_max=A_MAX, centre="star")
    with pytest.raises(ParameterError, match="order"):
        ServoValve(Q_nom=1e-3, order=3)
