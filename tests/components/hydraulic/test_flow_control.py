"""Shuttle valve and 2-way pressure-compensated flow control valve."""

import numpy as np
import pytest
from scipy.optimize import brentq

from components.hydraulic import FlowControlValve, PressureSource, ShuttleValve, Tank
from hydraulic_helpers import fixed_observed, jacobian_fd_error, value
from pvgraph.errors import ParameterError
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


FCV = dict(A_meter=mm2(5), A_comp=mm2(20), dp_c=bar(8), dp_band=bar(1))


def _fcv_flow(p_in, p_out):
    system = bench_circuit(FlowControlValve(**FCV), A=Pressure(p_in), B=Pressure(p_out)).compile()
    guess = np.array(system.y0, dtype=float)
    guess[system.index["dut.p_i"]] = p_out + min(bar(7.5), 0.9 * (p_in - p_out))
    y = _solve_static(system, guess)
    out = system.evaluate_observed(np.zeros(1), y[None, :], np.zeros((1, system.n)),
                                   np.zeros((1, len(system.mode_start))))
    return out["dut.q"][0], out["dut.dp_meter"][0]


def test_flow_control_holds_its_flow_against_supply_and_load_pressure():
    Q_set = FlowControlValve(**FCV).params.Q_set
    Q_lo = orifice_flow(CD, FCV["A_meter"], bar(7), RHO, 1e3)
    flows = []
    for p_in, p_out in ((bar(50), 0.0), (bar(200), 0.0), (bar(200), bar(150))):
        q, dp_m = _fcv_flow(p_in, p_out)
        assert bar(7) < dp_m < bar(8)
        assert Q_lo < q < Q_set
        flows.append(q)
    assert max(flows) / min(flows) < 1.02     # 40 to 200 bar across: within 2 %


def test_flow_control_below_its_setting_is_two_orifices_in_series():
    q, _ = _fcv_flow(bar(3), 0.0)
    # compensator fully open: 1/q^2 = (rho/2)(1/(Cd A_c)^2 + 1/(Cd A_m)^2) / dp
    A_eq = 1.0 / np.sqrt(1 / (FCV["A_comp"] + 1e-11) ** 2 + 1 / FCV["A_meter"] ** 2)
    assert q == pytest.approx(CD * A_eq * np.sqrt(2 * bar(3) / RHO), rel=1e-3)


def test_flow_control_jacobian_and_bad_band():
    system = bench_circuit(FlowControlValve(**FCV), A=Pressure(bar(100)),
                           B=Pressure(bar(20))).compile()
    assert jacobian_fd_error(system) < 1e-6
    with pytest.raises(ParameterError, match="dp_band"):
        FlowControlValve(**{**FCV, "dp_band": bar(9)})
