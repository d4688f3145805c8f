"""Shuttle valve and 2-way pressure-compensated flow control valve."""

import numpy as np
import pytest
from scipy.optimize import brentq

from pvgraph.components.hydraulic import FlowControlValve, PressureSource, ShuttleValve, Tank
from hydraulic_helpers import fixed_observed, jacobian_fd_error, value
from pvgraph.circuit import Circuit
from pvgraph.laws import orifice_flow
from pvgraph.testing import Flow, Pressure, bench_circuit
from pvgraph.units import bar, lpm, mm2

RHO, CD = 870.0, 0.6


def _solve_static(circuit_system, guess):
    """Newton on the algebraic bench (no states): returns the solved y."""
    from scipy.optimize import fsolve
    s = circuit_system
    y = fsolve(lambda y: s.residual(0.0, y, np.zeros(s.n)), guess, xtol=1e-13)
    assert np.max(np.abs(s.residual(0.0, y, np.zeros(s.n)))) < 1e-12
    return y


def test_shuttle_passes_the_higher_inlet():
    A = mm2(2)
    # out held at 50 bar: a at 60 bar feeds it, b at 40 bar is sealed (leak only, reverse)
    s, q = fixed_observed(ShuttleValve(A=A), ["s", "q"], a=Pressure(bar(60)),
                          b=Pressure(bar(40)), out=Pressure(bar(50)))
    assert s == 1.0
    assert q == pytest.approx(orifice_flow(CD, A + 1e-12, bar(10), RHO, 1e3)
                                            + orifice_flow(CD, 1e-12, -bar(10), RHO, 1e3),
                                            rel=1e-12)


def test_shuttle_output_follows_the_max_of_its_inputs_into_a_small_drain():
    A, drain = mm2(2), lpm(0.5)
    for pa, pb in ((bar(80), bar(30)), (bar(30), bar(80)), (bar(50), bar(50) + 1e3)):
        system = bench_circuit(ShuttleValve(A=A), a=Pressure(pa), b=Pressure(pb),
                               out=Flow(-drain)).compile()
        guess = np.array(system.y0, dtype=float)
        guess[system.index["dut.out.p"]] = max(pa, pb)
        y = _solve_static(system, guess)
        p_out = value(system, y, "dut.out.p")
        hi = max(pa, pb)
        if abs(pa - pb) > bar(1):
            dp = (drain / (CD * (A + 1e-12))) ** 2 * RHO / 2   # turbulent, >> dp_t
            assert hi - p_out == pytest.approx(dp, rel=2e-3)
        else:
            assert hi - bar(1) < p_out < hi


def test_shuttle_jacobian():
    system = bench_circuit(ShuttleValve(A=mm2(2)), a=Pressure(bar(50)), b=Pressure(bar(50) + 2e3),
                           out=Flow(-lpm(0.5))).compile()
    assert jacobian_fd_error(system) < 1e-6


FCV = dict(A_meter=mm2(5), A_comp=mm2(20), dp_c=bar(8))


def _fcv_flow(p_in, p_out):
    (q,) = fixed_observed(FlowControlValve(**FCV), ["q"], A=Pressure(p_in), B=Pressure(p_out))
    return q


def test_flow_control_holds_its_flow_against_supply_and_load_pressure():
    Q_set = CD * FCV["A_meter"] * np.sqrt(2 * bar(8) / RHO)
    for p_in, p_out in ((bar(50), 0.0), (bar(200), 0.0), (bar(200), bar(150))):
        assert _fcv_flow(p_in, p_out) == pytest.approx(Q_set, rel=1e-3)


def test_flow_control_below_its_setting_is_two_orifices_in_series_and_free_in_reverse():
    A_eq = 1.0 / np.sqrt(1 / FCV["A_comp"] ** 2 + 1 / FCV["A_meter"] ** 2)
    q_series = orifice_flow(CD, A_eq, bar(1), RHO, 1e3)
    assert _fcv_flow(bar(1), 0.0) == pytest.approx(q_series, rel=2e-3)
    assert _fcv_flow(0.0, bar(30)) == pytest.approx(orifice_flow(CD, A_eq, -bar(30), RHO, 1e3)
                                                    + orifice_flow(CD, 1e-12, -bar(30), RHO, 1e3),
                                                    rel=1e-12)   # + the compensator's leakage
    dps = np.linspace(-bar(1), bar(30), 200)
    qs = [_fcv_flow(d, 0.0) if d > 0 else _fcv_flow(0.0, -d) for d in dps]
    assert np.all(np.diff(qs) > 0.0)           # monotone, continuous through dp = 0


def test_flow_control_jacobian():
    system = bench_circuit(FlowControlValve(**FCV), A=Pressure(bar(2)),   # at the knee
                           B=Flow(-lpm(1))).compile()
    assert jacobian_fd_error(system) < 1e-6


def test_flow_source_above_the_setting_gives_an_absurd_pressure_that_is_named():
    """20 L/min into a valve regulated to 4.63 L/min: only the closed compensator's leakage can
    take the rest, at a pressure no circuit holds: steady_state says so, naming the node."""
    import warnings

    from pvgraph.analysis import steady_state
    from pvgraph.components.hydraulic import FlowSource
    from pvgraph.errors import PlausibilityWarning
    c = Circuit("fcv")
    c.add("src", FlowSource(Q=lpm(20)))
    c.add("fcv", FlowControlValve(A_meter=mm2(3), A_comp=mm2(12), dp_c=bar(8)))
    c.add("tank", Tank())
    c.connect("src.port", "fcv.A")
    c.connect("fcv.B", "tank.port")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        with pytest.raises(PlausibilityWarning, match=r"implausible steady pressure .* "
                                                      r"src.port.p|fcv.A.p"):
            steady_state(c.compile())


def _divider_circuit(ratio=0.5, C_leak=0.0, A_a="2 mm^2", A_b="4 mm^2"):
    from pvgraph.components import FlowDivider, FlowSource, Orifice, Tank, VolumeNode
    c = Circuit("divider")
    c.add("pump", FlowSource(Q="20 L/min"))
    c.add("hose", VolumeNode(V="0.1 L"))
    c.add("div", FlowDivider(ratio=ratio, C_leak=C_leak))
    for side, area in (("A", A_a), ("B", A_b)):
        c.add(f"v{side}", VolumeNode(V="0.05 L"))
        c.add(f"o{side}", Orifice(A=area))
    c.add("tank", Tank())
    c.connect("pump.port", "hose.port", "div.P")
    c.connect("div.A", "vA.port", "oA.a")
    c.connect("div.B", "vB.port", "oB.a")
    c.connect("oA.b", "oB.b", "tank.port")
    return c


@pytest.mark.parametrize("ratio", [0.5, 0.3])
def test_a_flow_divider_splits_the_flow_by_its_displacements_whatever_the_loads(ratio):
    """20 L/min into a gear divider feeding a 2 mm^2 and a 4 mm^2 orifice: each outlet gets
    its share (r Q, (1 - r) Q) although their pressures differ fourfold; the inlet is at the
    shares' mean pressure r p_A + (1 - r) p_B (the shaft passes the power between the
    sections); flow and power balance."""
    from pvgraph.analysis import steady_state
    op = steady_state(_divider_circuit(ratio).compile())
    Q = 20.0 / 60000.0
    assert op["oA.q"] == pytest.approx(ratio * Q, rel=1e-9)
    assert op["oB.q"] == pytest.approx((1.0 - ratio) * Q, rel=1e-9)
    p_a = 870.0 / 2.0 * (ratio * Q / (0.6 * 2e-6)) ** 2
    p_b = 870.0 / 2.0 * ((1.0 - ratio) * Q / (0.6 * 4e-6)) ** 2
    assert op["div.A.p"] == pytest.approx(p_a, rel=1e-3)
    assert op["div.B.p"] == pytest.approx(p_b, rel=1e-3)
    assert op["div.P.p"] == pytest.approx(ratio * op["div.A.p"] + (1 - ratio) * op["div.B.p"],
                                          rel=1e-12)
    power_in = op["div.P.p"] * Q
    power_out = op["div.A.p"] * op["oA.q"] + op["div.B.p"] * op["oB.q"]
    assert power_out == pytest.approx(power_in, rel=1e-9)


def test_a_leaking_divider_loses_flow_on_its_higher_pressure_side():
    """C_leak = 1e-11 m^3/(s Pa) per section: the side above the inlet pressure leaks back,
    the other gains, the split moves by C_leak (p_A - p_P) (solved by hand with brentq)."""
    from pvgraph.analysis import steady_state
    C = 1e-11
    op = steady_state(_divider_circuit(0.5, C).compile())
    Q, k = 20.0 / 60000.0, 870.0 / 2.0

    def split(qa):
        qb = Q - qa
        pa, pb = k * (qa / 1.2e-6) ** 2, k * (qb / 2.4e-6) ** 2
        pp = 0.5 * pa + 0.5 * pb
        disp = (Q + C * (pa - pp) + C * (pb - pp))      # both sections displace Q_disp / 2
        return qa - (0.5 * disp - C * (pa - pp))
    qa = brentq(split, 0.1 * Q, 0.9 * Q, xtol=1e-15)
    assert op["oA.q"] == pytest.approx(qa, rel=1e-6)
    assert op["oA.q"] < 0.5 * Q < op["oB.q"]
