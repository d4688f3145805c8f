"""SpoolMass and Fixed: Newton's law on a bench, and a spring-mass-damper's free response."""

import numpy as np
import pytest

from pvgraph.components.mechanical import (LEVER_EQUIVALENT_MASS, MAIN_SPOOL_MASS, Damper, Fixed,
                                   LinearSpring, SpoolMass, TwoFlangeSpring)
from pvgraph import Circuit, ParameterError
from pvgraph.testing import Force, Position, bench_circuit


def test_newton_residual_vanishes_at_analytic_point(dae):
    F, m = 12.0, 0.185
    system = bench_circuit(SpoolMass(m=m), flange=Force(F)).compile()
    at = dict(values={"dut.flange.x": 2e-3, "dut.v": 0.3, "dut.flange.f": F},
              ders={"dut.flange.x": 0.3, "dut.v": F / m})
    np.testing.assert_allclose(dae.residual(system, **at), 0.0, atol=1e-12)
    wrong = dict(at, ders={"dut.flange.x": 0.3, "dut.v": 1.1 * F / m})
    assert np.max(np.abs(dae.residual(system, **wrong))) > 0.1


def test_lever_adds_its_equivalent_mass(dae):
    """Report eq. 4.82: the lever adds 1.569 kg to the 185 g spool (1.754 kg, table 4.15)."""
    assert MAIN_SPOOL_MASS + LEVER_EQUIVALENT_MASS == pytest.approx(1.754)
    F = 10.0
    spool = SpoolMass(m=MAIN_SPOOL_MASS, m_lever=LEVER_EQUIVALENT_MASS)
    system = bench_circuit(spool, flange=Force(F)).compile()
    r = dae.residual(system, values={"dut.v": 0.0}, ders={"dut.v": F / 1.754})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)


def test_start_values_from_parameters():
    system = bench_circuit(SpoolMass(m=1.0, x0=1e-3, v0=0.2), flange=Force(0.0)).compile()
    y, _ = system.y0, system.yp0
    assert y[system.index["dut.flange.x"]] == 1e-3
    assert y[system.index["dut.v"]] == 0.2
    assert system.differential[system.index["dut.flange.x"]]
    assert system.differential[system.index["dut.v"]]


@pytest.mark.parametrize("field, value", [("m", 0.0), ("m", -1.0), ("m_lever", -0.1),
                                          ("x0", float("nan")), ("v0", 1e3)])
def test_bad_parameters_name_the_field(field, value):
    kwargs = {"m": 1.0, field: value}
    with pytest.raises(ParameterError, match=field):
        SpoolMass(**kwargs)


def test_fixed_holds_its_position_and_takes_the_force(dae):
    c = Circuit("held")
    wall = c.add("wall", Fixed(x0=-3e-3))
    spring = c.add("spring", TwoFlangeSpring(k=1000.0, F0=5.0))
    c.connect(wall.flange, spring.a)
    c.connect(spring.b, c.add("src", Fixed(x0=2e-3)).flange)
    system = c.compile(eliminate_aliases=False)
    f = 5.0 + 1000.0 * (-3e-3 - 2e-3)
    r = dae.residual(system, values={"wall.flange.x": -3e-3, "src.flange.x": 2e-3,
                                     "spring.a.x": -3e-3, "spring.b.x": 2e-3,
                                     "spring.a.f": f, "spring.b.f": -f,
                                     "wall.flange.f": -f, "src.flange.f": f})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)
    with pytest.raises(ParameterError, match="x0"):
        Fixed(x0=2000.0)        # machine scale is allowed (+-1 km), not beyond


def test_bench_compiles_and_jacobian_matches_finite_differences(dae):
    system = bench_circuit(SpoolMass(m=0.3, m_lever=0.2), flange=Force(3.0)).compile()
    assert system.n == 2 and system.differential.all()
    dae.check_jacobian(system, values={"dut.flange.x": 1e-3, "dut.v": 0.1},
                       ders={"dut.flange.x": 0.1, "dut.v": 2.0})


def _spring_mass_damper(m=1.754, k=3596.0, d=25.0, x0=1e-3):
    c = Circuit("smd")
    mass = c.add("mass", SpoolMass(m=MAIN_SPOOL_MASS, m_lever=m - MAIN_SPOOL_MASS, x0=x0))
    spring = c.add("spring", LinearSpring(k=k))
    damper = c.add("damper", Damper(d=d))
    c.connect(mass.flange, spring.flange, damper.flange)
    return c


def test_spring_mass_damper_free_response(sim):
    """Main spool on its spring with the tuned viscous friction (report table 4.15 values)."""
    m, k, d, x0 = 1.754, 3596.0, 25.0, 1e-3
    sol = sim(_spring_mass_damper(m, k, d, x0), 1.0, rtol=1e-8,
              t_eval=np.linspace(0.0, 1.0, 20001))
    wn = np.sqrt(k / m)
    zeta = d / (2.0 * np.sqrt(k * m))
    wd = wn * np.sqrt(1.0 - zeta**2)
    t, x = sol.t, sol["mass.flange.x"]
    exact = x0 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    np.testing.assert_allclose(x, exact, atol=1e-4 * x0)

    # damped frequency from the upward zero crossings, decay ratio from successive maxima
    s = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    t_up = t[s] - x[s] * (t[s + 1] - t[s]) / (x[s + 1] - x[s])
    period = np.mean(np.diff(t_up))
    assert 2 * np.pi / period == pytest.approx(wd, rel=0.01)
    peaks = [np.max(x[(t >= a) & (t < b)]) for a, b in zip(t_up[:-1], t_up[1:])]
    ratio = np.mean(np.array(peaks[1:]) / np.array(peaks[:-1]))
    assert ratio == pytest.approx(np.exp(-2 * np.pi * zeta / np.sqrt(1 - zeta**2)), rel=0.01)
    assert sol.stats["nsteps"] < 3000


@pytest.mark.parametrize("F", [2.0, -2.0])
def test_constant_force_gives_parabola_in_its_direction(sim, F):
    m = 0.5
    sol = sim(bench_circuit(SpoolMass(m=m), flange=Force(F)), 0.1, rtol=1e-8,
              t_eval=[0.02, 0.05, 0.1])
    np.testing.assert_allclose(sol["dut.flange.x"], F * sol.t**2 / (2 * m), rtol=1e-6)
    np.testing.assert_allclose(sol["dut.v"], F * sol.t / m, rtol=1e-6)


def test_position_bench_on_a_mass_is_reduced_and_takes_m_times_a():
    """A position source driving a mass is index two; the compiler reduces it."""
    from pvgraph.simulate import simulate
    m, a = 2.0, 0.5
    bench = bench_circuit(SpoolMass(m=m), flange=Position(lambda t: 1e-3 * t + 0.5 * a * t * t))
    sol = simulate(bench, 1.0)
    np.testing.assert_allclose(sol["dut.v"], 1e-3 + a * sol.t, rtol=1e-9)
    np.testing.assert_allclose(sol["dut.flange.f"], m * a, rtol=1e-9)
