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


def test_a_body_rebounds_from_a_stop_that_only_pushes():
    """1 kg at 1 m/s into a stop of k = 1e7 N/m, d = 2e3 N s/m. In contact m x'' = -(k x + d x')
    while that force pushes; the body leaves where it would pull (k x + d x' = 0), as
    ElastoGap's. Reference: scipy's Radau on that law, to the separation event. The damping
    no longer pulls the body back (it left at 0.35 m/s against 0.43)."""
    from scipy.integrate import solve_ivp

    from pvgraph.components.mechanical import Mass
    from pvgraph.simulate import simulate
    m, k, d, v0 = 1.0, 1e7, 2e3, 1.0

    def contact(t, s):
        return [s[1], -(k * s[0] + d * s[1]) / m]

    def leaves(t, s):
        return k * s[0] + d * s[1]
    leaves.terminal, leaves.direction = True, -1
    ref = solve_ivp(contact, (0.0, 0.1), [0.0, v0], method="Radau", rtol=1e-10, atol=1e-14,
                    events=leaves)
    rebound = -ref.y_events[0][0][1]
    c = Circuit("bounce")
    c.add("body", Mass(m=m, x0=-0.01, v0=v0))
    c.add("stop", EndStop(x_min=-1.0, x_max=0.0, k=k, d=d))
    c.connect("body.flange", "stop.flange")
    sol = simulate(c, 0.05, rtol=1e-9, atol=1e-12, t_eval=[0.05])
    assert -sol["body.v"][-1] == pytest.approx(rebound, rel=2e-3)
    assert rebound == pytest.approx(0.4349, abs=1e-3)
