"""Springs: force laws, continuity of the two-stage spring, centring, validation, Jacobians."""

import numpy as np
import pytest

from pvgraph.components.mechanical import (CenteringSpring, LinearSpring, SpoolMass, TwoFlangeSpring,
                                   TwoStageSpring)
from pvgraph import Circuit, ParameterError
from pvgraph.testing import Force, Position, bench_circuit
from pvgraph.units import mm


def test_linear_spring_law_and_direction(law):
    make = lambda: LinearSpring(k=3596.0, F0=65.05)  # noqa: E731
    assert law(make, 0.0) == pytest.approx(65.05)
    assert law(make, mm(2)) == pytest.approx(65.05 + 3596.0 * 2e-3)
    xs = np.linspace(-mm(5), mm(5), 11)
    assert np.all(np.diff([law(make, x) for x in xs]) > 0), "compression grows with x"


def test_spring_mass_equilibrium_residual(dae):
    """Mass pushed by F against a preloaded spring rests at x = (F - F0) / k."""
    k, F0, F = 2000.0, 10.0, 30.0
    mass = SpoolMass(m=1.0)
    spring = LinearSpring(k=k, F0=F0)
    bench = bench_circuit(mass, flange=Force(F))
    bench.add("spring", spring)
    bench.connect(mass.flange, spring.flange)
    system = bench.compile()
    r = dae.residual(system, values={"dut.flange.x": (F - F0) / k, "dut.v": 0.0})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)


def test_two_flange_spring_is_ground_spring_with_b_fixed(dae):
    """With b held at 0, a pushed by 7 N compresses the spring to (7 - F0)/k."""
    system = bench_circuit(TwoFlangeSpring(k=500.0, F0=3.0), a=Force(7.0),
                           b=Position(0.0)).compile()
    x = (7.0 - 3.0) / 500.0
    np.testing.assert_allclose(dae.residual(system, values={"dut.a.x": x}), 0.0, atol=1e-12)
    assert system.resolve("dut.b.f") == (0.0, None, -7.0)  # the wall takes the force


@pytest.mark.parametrize("eps", [0.0, 1e-5])
def test_two_stage_spring_follows_report(law, eps):
    """Report eqs. 4.58-4.61: 9945 N/m + 105.12 N, then 35000 N/m from 5.2 mm."""
    make = lambda: TwoStageSpring(eps=eps)  # noqa: E731
    # the rounding (eps) changes the force by less than 1 mN 2.8 mm away from the break
    assert law(make, mm(2)) == pytest.approx(9945.0 * 2e-3 + 105.12, abs=1e-3)
    F_b = 9945.0 * 5.2e-3 + 105.12
    assert law(make, mm(8)) == pytest.approx(F_b + 35000.0 * (8e-3 - 5.2e-3), abs=1e-3)
    # the second stage's preload is F_b - 35000 * 5.2 mm = -25.17 N (not the report's -20 N)
    assert law(make, mm(8)) == pytest.approx(35000.0 * 8e-3 - 25.166, abs=1e-3)


def test_two_stage_spring_force_is_continuous_at_the_break(law):
    for eps in (0.0, 1e-5):
        make = lambda: TwoStageSpring(eps=eps)  # noqa: E731
        below, above = law(make, 5.2e-3 - 1e-9), law(make, 5.2e-3 + 1e-9)
        assert above - below == pytest.approx(0.0, abs=1e-3)
        slope_lo = (law(make, mm(4.0)) - law(make, mm(3.9))) / mm(0.1)
        slope_hi = (law(make, mm(6.5)) - law(make, mm(6.4))) / mm(0.1)
        assert slope_lo == pytest.approx(9945.0, rel=1e-4)
        assert slope_hi == pytest.approx(35000.0, rel=1e-4)


def test_centering_spring_is_odd_and_preloaded_both_ways(law):
    """Report eq. 4.88: F = k*x + F0*sign(x), 3596 N/m and 65.05 N."""
    make = lambda: CenteringSpring()  # noqa: E731
    assert law(make, 0.0) == pytest.approx(0.0, abs=1e-12)
    for x in (mm(0.5), mm(3.0)):
        assert law(make, x) == pytest.approx(3596.0 * x + 65.05, rel=1e-9)
        assert law(make, -x) == pytest.approx(-law(make, x), rel=1e-12)
    xs = np.linspace(-mm(1), mm(1), 41)
    assert np.all(np.diff([law(make, x) for x in xs]) > 0)


def test_centering_spring_holds_spool_below_preload(law):
    """A force below the preload moves the spool less than the smoothing width x_eps."""
    from scipy.optimize import brentq
    F, x_eps = 40.0, CenteringSpring().params.x_eps
    x_eq = brentq(lambda x: law(CenteringSpring, x) - F, 0.0, 10 * x_eps, xtol=1e-15)
    assert x_eq < x_eps
    assert x_eq == pytest.approx(x_eps * np.arctanh(F / 65.05), rel=0.01)  # k*x is minor


@pytest.mark.parametrize("cls, field, value", [
    (LinearSpring, "k", -1.0), (LinearSpring, "F0", float("inf")), (TwoFlangeSpring, "k", -2.0),
    (TwoStageSpring, "k2", 0.0), (TwoStageSpring, "x_b", 0.0), (TwoStageSpring, "eps", 1e-3),
    (CenteringSpring, "F0", -1.0), (CenteringSpring, "x_eps", 0.0),
])
def test_bad_parameters_name_the_field(cls, field, value):
    kwargs = {"k": 100.0} if cls in (LinearSpring, TwoFlangeSpring) else {}
    kwargs[field] = value
    with pytest.raises(ParameterError, match=field):
        cls(**kwargs)


@pytest.mark.parametrize("make, x", [
    (lambda: LinearSpring(k=100.0, F0=1.0), 1e-3),
    (lambda: TwoStageSpring(), 5.2e-3 + 3e-6),
    (lambda: TwoStageSpring(eps=0.0), 6e-3),
    (lambda: CenteringSpring(), 4e-6),
    (lambda: TwoFlangeSpring(k=100.0), 1e-3),
])
def test_bench_compiles_and_jacobian_matches_finite_differences(dae, make, x):
    comp = make()
    ports = {"flange": Force(1.0)} if "flange" in type(comp).ports else \
        {"a": Force(1.0), "b": Position(0.0)}
    system = bench_circuit(comp, **ports).compile(eliminate_aliases=False)
    values = {f"dut.{n}.x": x * (i + 1) for i, n in enumerate(type(comp).ports)}
    dae.check_jacobian(system, values=values)


def test_two_stage_spring_mass_oscillates_about_equilibrium(sim):
    """A 20 g compensator-like spool released at 5.2 mm rests where F_spring = 200 N."""
    c = Circuit("comp")
    spool = c.add("spool", SpoolMass(m=0.02, x0=5.2e-3))
    spring = c.add("spring", TwoStageSpring())
    c.connect(spool.flange, spring.flange)
    from pvgraph.components.mechanical import Damper, ForceInput
    from pvgraph.components.signal import Constant
    c.add("damper", Damper(d=50.0))
    push = c.add("push", ForceInput())
    c.connect(c.add("F", Constant(k=200.0)).y, push.u)
    c.connect(spool.flange, c["damper"].flange, push.flange)
    sol = sim(c, 0.2, rtol=1e-7)
    x_eq = (200.0 + 25.166) / 35000.0
    assert sol.final("spool.flange.x") == pytest.approx(x_eq, rel=1e-3)
