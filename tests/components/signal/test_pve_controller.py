"""PVE controller: set point (eq. 4.110) and duty cycles (eq. 4.115) with saturation."""

import numpy as np
import pytest

from pvgraph.components.mechanical import SpoolMass
from pvgraph.components.signal import LVDT, PVEController
from pvgraph import ParameterError
from pvgraph.testing import Signal, bench_circuit
from pvgraph.units import mm

V_S = 11.5


def _report_duty(e_mm):
    """Report eq. 4.115 in percent, limited to 0..100 %."""
    return (float(np.clip(-70.0 * e_mm + 28.4, 0.0, 100.0)),
            float(np.clip(70.0 * e_mm + 28.4, 0.0, 100.0)))


def _outputs(V_in, x_meas, **params):
    """DT_A, DT_B [fraction] and the observed set point and error for constant inputs."""
    system = bench_circuit(PVEController(**params), V_in=Signal(V_in),
                           x_meas=Signal(x_meas)).compile()
    y = np.array(system.y0, dtype=float)
    for _ in range(3):  # outputs enter their residuals linearly: one Newton step suffices
        J = system.jacobian_dense(0.0, y, np.zeros(system.n), 0.0)
        y -= np.linalg.solve(J, system.residual(0.0, y, np.zeros(system.n)))
    obs = system.evaluate_observed(np.zeros(1), y[None, :], np.zeros((1, system.n)),
                                   np.zeros((1, len(system.mode_names))))

    def val(name):
        if name in obs:
            return float(obs[name][0])
        coef, idx, off = system.resolve(name)
        return off if idx is None else coef * y[idx] + off
    return val("dut.DT_A"), val("dut.DT_B"), val("dut.x_set"), val("dut.e")


@pytest.mark.parametrize("V_rel, x_set_mm", [(0.25, -7.0), (0.5, 0.0), (0.75, 7.0),
                                              (0.6, 2.8)])
def test_set_point_spans_the_stroke(V_rel, x_set_mm):
    """Eq. 4.110 with K_input = 0.028: V_rel 0.25 / 0.5 / 0.75 -> -7 / 0 / +7 mm."""
    *_, x_set, e = _outputs(V_rel * V_S, 0.0)
    assert x_set == pytest.approx(mm(x_set_mm), abs=1e-12)
    assert e == pytest.approx(x_set, abs=1e-12)


@pytest.mark.parametrize("e_mm", [-1.5, -0.5, -0.4057, -0.2, 0.0, 0.1, 0.5, 1.0, 1.0229, 1.5])
def test_duty_cycles_match_report_with_saturation(e_mm):
    x_meas = -mm(e_mm) + mm(2.8)           # x_set = 2.8 mm at V_rel = 0.6
    DT_A, DT_B, _, e = _outputs(0.6 * V_S, x_meas)
    assert e == pytest.approx(mm(e_mm), abs=1e-12)
    A, B = _report_duty(e_mm)
    assert 100 * DT_A == pytest.approx(A, abs=1e-9)
    assert 100 * DT_B == pytest.approx(B, abs=1e-9)
    assert 0.0 <= DT_A <= 1.0 and 0.0 <= DT_B <= 1.0


def test_duty_cycles_move_opposite_ways_with_the_error():
    es = np.linspace(-0.3, 0.3, 13)  # inside the unsaturated band
    duties = np.array([_outputs(0.5 * V_S, -mm(e))[:2] for e in es])
    assert np.all(np.diff(duties[:, 0]) < 0) and np.all(np.diff(duties[:, 1]) > 0)
    np.testing.assert_allclose(duties[:, 0] + duties[:, 1], 2 * 0.284, atol=1e-12)


def test_smooth_limits_stay_close_to_the_report():
    for e_mm in (-1.0, 0.0, 0.3, 2.0):
        DT_A, DT_B, *_ = _outputs(0.5 * V_S, -mm(e_mm), eps=0.5)
        A, B = _report_duty(e_mm)
        assert 100 * DT_A == pytest.approx(A, abs=0.5)
        assert 100 * DT_B == pytest.approx(B, abs=0.5)


@pytest.mark.parametrize("kwargs, field", [({"V_s": 0.0}, "V_s"), ({"K_input": -0.028},
                                                                   "K_input"),
                                           ({"DT_0": 120.0}, "DT_0"), ({"eps": -1.0}, "eps")])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        PVEController(**kwargs)


def test_closed_loop_with_lvdt_settles_at_the_proportional_equilibrium(sim):
    """Spool, LVDT and controller in a loop through an idealised actuator.

    The actuator pushes with ``F = G * (DT_B - DT_A)`` (G = 20 N) against the main spool
    spring; in the unsaturated band ``DT_B - DT_A = 1.4 /mm * e``, so the loop settles where
    ``k * x = G * 1.4e3 * (x_set - 0.945 * x)``: the LVDT's gain and the finite loop gain both
    show in the final position.
    """
    from pvgraph.components.mechanical import Damper, ForceInput, LinearSpring
    from pvgraph.components.signal import Constant, Sum
    from pvgraph import Circuit
    G, k = 20.0, 3596.0
    c = Circuit("loop")
    spool = c.add("spool", SpoolMass(m=1.754))
    spring = c.add("spring", LinearSpring(k=k))
    damper = c.add("damper", Damper(d=400.0))
    lvdt = c.add("lvdt", LVDT())
    pve = c.add("pve", PVEController())
    diff = c.add("diff", Sum(k1=G, k2=-G))
    push = c.add("push", ForceInput())
    c.connect(c.add("V_in", Constant(k=0.55 * V_S)).y, pve.V_in)
    c.connect(lvdt.y, pve.x_meas)
    c.connect(pve.DT_B, diff.u1)
    c.connect(pve.DT_A, diff.u2)
    c.connect(diff.y, push.u)
    c.connect(spool.flange, spring.flange, damper.flange, lvdt.flange, push.flange)
    sol = sim(c, 1.0, rtol=1e-7)
    x_set = 0.028 * 0.55 - 0.014
    gain = G * 1.4e3  # N/m
    assert sol.final("spool.flange.x") == pytest.approx(gain * x_set / (k + 0.945 * gain),
                                                        rel=1e-4)
    assert sol.final("pve.DT_B_pct") < 100.0 and sol.final("pve.DT_A_pct") > 0.0
