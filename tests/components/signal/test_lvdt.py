"""LVDT sensor: 0.945 / (0.0059 s + 1) from spool position to reading (report eq. 4.113)."""

import numpy as np
import pytest

from pvgraph.components.mechanical import SpoolMass
from pvgraph.components.signal import LVDT
from pvgraph import ParameterError
from pvgraph.testing import Force, Position, bench_circuit
from pvgraph.units import mm


def test_defaults_are_the_reports():
    p = LVDT().params
    assert (p.K, p.tau, p.k_spring) == (0.945, 0.0059, 0.0)


def test_residual_at_analytic_point(dae):
    x = mm(3)
    system = bench_circuit(LVDT(), flange=Position(x)).compile()
    r = dae.residual(system, values={"dut.y": mm(1)}, ders={"dut.y": (0.945 * x - mm(1)) / 0.0059})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)
    dae.check_jacobian(system, values={"dut.y": mm(1)})


def test_sensor_exerts_only_its_optional_spring_force(dae):
    system = bench_circuit(LVDT(k_spring=190.0), flange=Position(mm(2))).compile()
    assert system.resolve("dut.flange.f") == (0.0, None, pytest.approx(190.0 * mm(2)))
    free = bench_circuit(LVDT(), flange=Position(mm(2))).compile()
    assert free.resolve("dut.flange.f") == (0.0, None, 0.0)


def test_step_response_reads_below_the_true_position(sim):
    x, tau = mm(5), 0.0059
    t = np.array([0.5, 1.0, 3.0, 6.0]) * tau
    sol = sim(bench_circuit(LVDT(), flange=Position(x)), 8 * tau, rtol=1e-8, t_eval=t)
    np.testing.assert_allclose(sol["dut.y"], 0.945 * x * (1 - np.exp(-t / tau)), rtol=1e-6)
    assert sol.final("dut.y") < x


def test_reads_a_moving_spool(sim):
    """On a spool accelerated by a constant force the reading lags by about tau."""
    spool = SpoolMass(m=1.0)
    bench = bench_circuit(spool, flange=Force(1.0))
    lvdt = bench.add("lvdt", LVDT(K=1.0))
    bench.connect(spool.flange, lvdt.flange)
    sol = sim(bench, 0.1, rtol=1e-8, t_eval=[0.1])
    # y'' dynamics: for x = t^2/2, y = (t - tau)^2/2 + tau^2/2 - tau^2 exp(-t/tau)
    tau, t = 0.0059, 0.1
    exact = 0.5 * (t - tau) ** 2 + 0.5 * tau**2 - tau**2 * np.exp(-t / tau)
    assert sol.final("lvdt.y") == pytest.approx(exact, rel=1e-5)


@pytest.mark.parametrize("kwargs, field", [({"K": 0.0}, "K"), ({"tau": -1.0}, "tau"),
                                           ({"k_spring": -190.0}, "k_spring")])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        LVDT(**kwargs)
