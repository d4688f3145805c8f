"""Gain, sums, saturation and the first-order lag."""

import numpy as np
import pytest

from pvgraph.components.signal import (Constant, FirstOrderLag, Gain, Saturation, Step, Sum, Sum3,
                               TimeTable)
from pvgraph import Circuit, ParameterError
from pvgraph.testing import Signal, bench_circuit


def _output(block, t=0.0, **inputs):
    """The block's output for constant inputs, solved from its (linear-in-y) residual."""
    system = bench_circuit(block, **{k: Signal(v) for k, v in inputs.items()}).compile(
        eliminate_aliases=False)
    row = [i for i, lab in enumerate(system.equations) if lab.startswith("dut equation 1")][0]
    y = np.array(system.y0, dtype=float)
    for name, value in inputs.items():
        y[system.index[f"dut.{name}"]] = value
    j = system.index["dut.y"]
    y[j] = 0.0
    r0 = system.residual(t, y, np.zeros(system.n))[row]
    y[j] = 1.0
    r1 = system.residual(t, y, np.zeros(system.n))[row]
    return -r0 / (r1 - r0)


def test_gain_and_sums():
    assert _output(Gain(k=-2.5), u=4.0) == pytest.approx(-10.0)
    assert _output(Sum(k1=1.0, k2=-1.0), u1=3.0, u2=5.0) == pytest.approx(-2.0)
    assert _output(Sum3(k1=2.0, k2=0.5, k3=-1.0), u1=1.0, u2=4.0, u3=3.0) == pytest.approx(1.0)


@pytest.mark.parametrize("u, expected", [(-5.0, -1.0), (-1.0, -1.0), (0.3, 0.3), (2.0, 2.0),
                                         (7.0, 2.0)])
def test_saturation_limits(u, expected):
    assert _output(Saturation(y_min=-1.0, y_max=2.0), u=u) == pytest.approx(expected)


def test_smooth_saturation_is_monotone_and_close():
    us = np.linspace(-3.0, 4.0, 71)
    ys = [_output(Saturation(y_min=-1.0, y_max=2.0, eps=0.05), u=u) for u in us]
    assert np.all(np.diff(ys) >= 0.0)
    np.testing.assert_allclose(ys, np.clip(us, -1.0, 2.0), atol=0.05)


def test_first_order_lag_residual(dae):
    system = bench_circuit(FirstOrderLag(k=2.0, tau=0.1), u=Signal(3.0)).compile()
    r = dae.residual(system, values={"dut.y": 1.0}, ders={"dut.y": (2.0 * 3.0 - 1.0) / 0.1})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)
    dae.check_jacobian(system, values={"dut.y": 1.0})


def test_first_order_lag_step_response(sim):
    """k/(tau s + 1) to a unit step: y = k * (1 - exp(-t/tau))."""
    k, tau = 0.945, 0.0059
    c = Circuit("lag")
    lag = c.add("lag", FirstOrderLag(k=k, tau=tau))
    c.connect(c.add("step", Step(t_step=0.0)).y, lag.u)
    t = np.array([0.5, 1.0, 2.0, 3.0, 5.0]) * tau
    sol = sim(c, 6 * tau, rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["lag.y"], k * (1.0 - np.exp(-t / tau)), rtol=1e-6)
    assert sol.stats["nsteps"] < 500


def test_lag_after_a_table_input_keeps_its_start_value(sim):
    c = Circuit("lag")
    lag = c.add("lag", FirstOrderLag(tau=0.05, y0=2.0))
    c.connect(c.add("u", TimeTable(t=(0.0, 1.0), y=(2.0, 2.0))).y, lag.u)
    sol = sim(c, 0.2)
    np.testing.assert_allclose(sol["lag.y"], 2.0, atol=1e-9)


@pytest.mark.parametrize("cls, kwargs, field", [
    (Gain, {}, "k"), (Sum, {"k1": float("inf")}, "k1"), (Sum3, {"k3": float("nan")}, "k3"),
    (Saturation, {"y_min": 1.0, "y_max": 1.0}, "y_min"),
    (Saturation, {"y_min": 0.0, "y_max": 1.0, "eps": 0.5}, "eps"),
    (FirstOrderLag, {"tau": 0.0}, "tau"), (FirstOrderLag, {}, "tau"),
])
def test_bad_parameters_name_the_field(cls, kwargs, field):
    with pytest.raises(ParameterError, match=field):
        cls(**kwargs)


def test_blocks_compile_in_a_chain(dae):
    c = Circuit("chain")
    g = c.add("g", Gain(k=3.0))
    s = c.add("s", Sum(k2=-1.0))
    sat = c.add("sat", Saturation(y_min=-1.0, y_max=1.0, eps=0.01))
    lag = c.add("lag", FirstOrderLag(tau=0.1))
    c.connect(c.add("a", Constant(k=0.2)).y, g.u)
    c.connect(g.y, s.u1)
    c.connect(lag.y, s.u2)
    c.connect(s.y, sat.u)
    c.connect(sat.y, lag.u)
    system = c.compile()
    assert system.differential.sum() == 1
    dae.check_jacobian(system, values={"lag.y": 0.1}, ders={"lag.y": 0.5})
