"""End stops: free travel, contact force, damping only in contact, holding a pushed mass."""

import numpy as np
import pytest

from pvgraph.components.mechanical import EndStop, ForceInput, SpoolMass
from pvgraph.components.signal import Constant
from pvgraph import Circuit, ParameterError
from pvgraph.testing import Force, bench_circuit
from pvgraph.units import mm

STROKE = dict(x_min=-mm(7), x_max=mm(7))  # main spool, report 4.4.3


def make_stop(**kw):
    return lambda: EndStop(**{**STROKE, **kw})


def test_free_travel_has_almost_no_force(law):
    for x in (0.0, mm(3), -mm(6)):
        for v in (0.0, 0.5):
            assert abs(law(make_stop(), x, v)) < 1e-3


def test_contact_force_pushes_back_into_the_stroke(law):
    k, d = 1e7, 2e3
    pen = 5e-6
    assert law(make_stop(k=k, d=d), mm(7) + pen) == pytest.approx(k * pen, rel=1e-3)
    assert law(make_stop(k=k, d=d), -mm(7) - pen) == pytest.approx(-k * pen, rel=1e-3)
    # damping acts in contact only, opposing the velocity
    assert law(make_stop(k=k, d=d), mm(7) + pen, 0.01) == pytest.approx(k * pen + d * 0.01,
                                                                        rel=1e-3)
    assert law(make_stop(k=k, d=d), mm(7) - 1e-4, 0.01) < 1e-3
    pens = np.linspace(0.0, 1e-5, 11)
    assert np.all(np.diff([law(make_stop(), mm(7) + p) for p in pens]) > 0)


@pytest.mark.parametrize("kwargs, field", [
    (dict(x_min=mm(7), x_max=-mm(7)), "x_min"), (dict(STROKE, k=0.0), "k"),
    (dict(STROKE, d=-1.0), "d"), (dict(STROKE, eps=1e-3), "eps"), (dict(x_max=mm(7)), "x_min"),
])
def test_bad_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        EndStop(**kwargs)


def test_jacobian_matches_finite_differences(dae):
    system = bench_circuit(make_stop()(), flange=Force(0.0)).compile(eliminate_aliases=False)
    for x, v in ((0.0, 0.1), (mm(7) + 2e-7, -0.05), (-mm(7) - 1e-6, 0.02), (mm(7), 0.0)):
        dae.check_jacobian(system, values={"dut.flange.x": x}, ders={"dut.flange.x": v},
                           h_abs=1e-10)


def test_end_stop_holds_pushed_mass_with_small_penetration(sim):
    """1.754 kg pushed by 100 N from the centre hits +7 mm and rests F/k past it."""
    F, m, k = 100.0, 1.754, 1e8
    c = Circuit("stop")
    spool = c.add("spool", SpoolMass(m=m))
    stop = c.add("stop", EndStop(**STROKE, k=k, d=5e3))
    push = c.add("push", ForceInput())
    c.connect(c.add("force", Constant(k=F)).y, push.u)
    c.connect(spool.flange, stop.flange, push.flange)
    sol = sim(c, 0.1, rtol=1e-7)
    x = sol["spool.flange.x"]
    v_hit = np.sqrt(2 * F / m * mm(7))
    bound = v_hit * np.sqrt(m / k) + 2 * F / k  # undamped impact overshoot + static
    assert np.max(x) - mm(7) < bound
    assert np.max(x) - mm(7) < mm(0.15)
    assert np.min(x) > -1e-12
    assert sol.final("spool.flange.x") == pytest.approx(mm(7) + F / k, abs=0.01 * F / k)
    assert abs(sol.final("spool.v")) < 1e-6
