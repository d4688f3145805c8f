"""Friction and dampers: force laws, direction, Stribeck, stick below and slide above F_c."""

import numpy as np
import pytest

from pvgraph.components.mechanical import (Damper, ForceInput, Friction, SpoolMass, TwoFlangeDamper)
from pvgraph.components.mechanical.laws import stribeck_friction
from pvgraph.components.signal import Constant
from pvgraph import Circuit, ParameterError
from pvgraph.laws import coulomb_friction
from pvgraph.testing import Force, Position, bench_circuit


def test_friction_law_at_operating_points(law):
    make = lambda: Friction(F_c=50.0, b=25.0, v_eps=1e-4)  # noqa: E731
    assert law(make, 0.0, 0.0) == pytest.approx(0.0, abs=1e-12)
    for v in (0.01, 0.1):  # v >> v_eps and >> v_s: Coulomb + viscous
        assert law(make, 0.0, v) == pytest.approx(50.0 + 25.0 * v, rel=1e-9)
        assert law(make, 0.0, -v) == pytest.approx(-(50.0 + 25.0 * v), rel=1e-9)
    assert law(make, 3e-3, 0.05) == law(make, -2e-3, 0.05), "independent of position"


def test_friction_opposes_motion_and_grows_with_speed(law):
    make = lambda: Friction(F_c=10.0, b=100.0)  # noqa: E731
    vs = np.linspace(-0.05, 0.05, 21)
    F = np.array([law(make, 0.0, v) for v in vs])
    assert np.all(np.sign(F) == np.sign(vs))
    assert np.all(np.diff(F) > 0)


def test_stribeck_peak_above_coulomb_level(law):
    make = lambda: Friction(F_c=10.0, F_s=15.0, v_s=1e-3, v_eps=1e-5)  # noqa: E731
    near = law(make, 0.0, 2e-4)   # several v_eps, well below v_s
    far = law(make, 0.0, 1e-2)    # ten v_s: static part decayed
    assert near > 14.0 and far == pytest.approx(10.0, rel=1e-6)


def test_report_exponential_stribeck_shape():
    """delta = 1 is report eq. A.5: sigma*v + sign(v)*(F_co + F_so*exp(-|v|/C_s))."""
    v, F_co, F_so, C_s = 3e-3, 20.0, 8.0, 2e-3
    F = stribeck_friction(v, F_co, F_co + F_so, C_s, 1e-6, 5.0, delta=1.0)
    assert F == pytest.approx(5.0 * v + F_co + F_so * np.exp(-v / C_s), rel=1e-6)
    assert stribeck_friction(v, 1.0, 2.0, 1e-3, 1e-4, 3.0) == coulomb_friction(
        v, 1.0, 2.0, 1e-3, 1e-4, 3.0)


def test_dampers_force_laws(law, dae):
    assert law(lambda: Damper(d=40.0), 1e-3, -0.2) == pytest.approx(-8.0)
    system = bench_circuit(TwoFlangeDamper(d=40.0), a=Force(12.0), b=Position(0.0)).compile()
    np.testing.assert_allclose(dae.residual(system, ders={"dut.a.x": 0.3}), 0.0, atol=1e-12)
    assert np.max(np.abs(dae.residual(system, ders={"dut.a.x": -0.3}))) > 1.0


@pytest.mark.parametrize("kwargs, field", [
    (dict(F_c=-1.0), "F_c"), (dict(F_c=1.0, b=-1.0), "b"), (dict(F_c=1.0, v_eps=0.0), "v_eps"),
    (dict(F_c=1.0, delta=3.0), "delta"), (dict(F_c=5.0, F_s=4.0), "F_s"),
])
def test_bad_friction_parameters_name_the_field(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        Friction(**kwargs)


def test_bad_damper_parameter_names_the_field():
    with pytest.raises(ParameterError, match="d"):
        Damper(d=-3.0)


@pytest.mark.parametrize("make", [
    lambda: Friction(F_c=50.0, b=25.0),
    lambda: Friction(F_c=10.0, F_s=15.0, v_s=1e-3, delta=1.0),
    lambda: Damper(d=3.0),
])
def test_jacobian_matches_finite_differences(dae, make):
    system = bench_circuit(make(), flange=Force(1.0)).compile(eliminate_aliases=False)
    for v in (0.0, 5e-5, -2e-3, 0.05):
        dae.check_jacobian(system, values={"dut.flange.x": 1e-3}, ders={"dut.flange.x": v})


def _mass_with_friction(F, m=0.5, F_c=10.0, b=0.0, v_eps=1e-4):
    c = Circuit("slide")
    mass = c.add("mass", SpoolMass(m=m))
    fr = c.add("friction", Friction(F_c=F_c, b=b, v_eps=v_eps))
    push = c.add("push", ForceInput())
    c.connect(c.add("force", Constant(k=F)).y, push.u)
    c.connect(mass.flange, fr.flange, push.flange)
    return c


def test_force_below_coulomb_level_barely_moves(sim):
    F, F_c, m, v_eps, T = 5.0, 10.0, 0.5, 1e-4, 0.5
    sol = sim(_mass_with_friction(F, m, F_c, v_eps=v_eps), T, rtol=1e-7)
    creep = v_eps * np.arctanh(F / F_c)           # the regularisation's creep velocity
    assert sol.final("mass.v") == pytest.approx(creep, rel=1e-3)
    assert abs(sol.final("mass.flange.x")) <= 1.01 * creep * T
    assert abs(sol.final("mass.flange.x")) < 1e-3 * F * T**2 / (2 * m)  # vs. no friction


def test_force_above_coulomb_level_accelerates_at_net_force(sim):
    F, F_c, m = 25.0, 10.0, 0.5
    sol = sim(_mass_with_friction(F, m, F_c), 0.2, rtol=1e-8, t_eval=[0.05, 0.1, 0.2])
    a = (F - F_c) / m
    np.testing.assert_allclose(sol.der("mass.v"), a, rtol=1e-4)
    np.testing.assert_allclose(sol["mass.v"], a * sol.t, rtol=1e-3)


def _cylinder_against_a_spring(friction):
    """A 2000 mm^2 piston at 50 bar (10 kN) against a 1000 N/mm spring, 50 kg, 20 kN s/m."""
    from pvgraph.components import Cylinder, LinearSpring, Mass, Orifice, PressureSource, Tank
    c = Circuit("spring")
    src, tank = c.add("src", PressureSource(p0="50 bar")), c.add("tank", Tank())
    orf = c.add("orf", Orifice(A="5 mm^2"))
    cyl = c.add("cyl", Cylinder(A_A="2000 mm^2", A_rod="1000 mm^2", stroke="200 mm",
                                V_dead_A="20 cm^3", V_dead_B="20 cm^3"))
    m = c.add("m", Mass(m="50 kg", b="20 kN s/m"))
    spring = c.add("spring", LinearSpring(k="1000 N/mm"))
    fr = c.add("fr", friction)
    c.connect(src.port, orf.a)
    c.connect(orf.b, cyl.A)
    c.connect(cyl.B, tank.port)
    c.connect(cyl.flange, m.flange, spring.flange, fr.flange)
    return c


def test_lugre_friction_holds_a_cylinder_where_coulomb_friction_first_balances():
    """Coulomb friction of 1 kN: the rod stops where the net force first falls to F_c,
    x = (p A - F_c) / k = 9.000 mm, and stays (the smooth law creeps on to the friction-free
    10 mm over F_c / (k v_eps) = 10 s)."""
    from pvgraph.components import LuGreFriction
    from pvgraph.simulate import simulate
    sol = simulate(_cylinder_against_a_spring(LuGreFriction(F_c="1 kN", sigma0=1e9,
                                                            sigma1=4e5)), 20.0, rtol=1e-7)
    x = sol["cyl.flange.x"]
    # within the bristles' pre-sliding travel F_c / sigma0 = 1 um, then a creep of their
    # relaxation, F_c / (sigma0 v_eps) = 100 s: 3 um over 18 s
    assert sol.at("cyl.flange.x", 2.0) == pytest.approx(9.0e-3, abs=2e-6)
    assert sol.final("cyl.flange.x") == pytest.approx(9.0e-3, abs=5e-6)
    assert sol.final("fr.F") == pytest.approx(1e3, rel=1e-2)
    assert np.max(x) < 9.0e-3 + 5e-6
    creep = simulate(_cylinder_against_a_spring(Friction(F_c="1 kN")), 20.0, rtol=1e-7)
    assert creep.final("cyl.flange.x") > 9.8e-3


def test_lugre_friction_breaks_away_at_its_static_force():
    """F_s = 80 N, F_c = 50 N on a 66 g spool, the force ramped up over 1 s: 70 N is held
    (below breakaway); 100 N breaks it away near 80 N, and it slides at
    (100 - 50) / b (v >> v_s: the Coulomb level)."""
    from pvgraph.components import LuGreFriction, Ramp
    from pvgraph.simulate import simulate

    def pushed(force):
        c = Circuit("pushed")
        spool = c.add("spool", SpoolMass(m=0.066))
        fr = c.add("fr", LuGreFriction(F_c=50.0, F_s=80.0, b=2000.0))
        push = c.add("push", ForceInput())
        c.connect(spool.flange, fr.flange, push.flange)
        c.connect(c.add("f", Ramp(height=force, duration=1.0)).y, push.u)
        return c
    held = simulate(pushed(70.0), 1.5, rtol=1e-8)
    assert abs(held.final("spool.v")) < 1e-7
    assert held.final("fr.F") == pytest.approx(70.0, rel=1e-3)
    # pre-sliding: the bristles carry it (sigma0 z = 70 N) after a micro-slip of a few
    # bristle deflections (LuGre's, near breakaway): 33 um
    assert held.final("fr.z") == pytest.approx(70.0 / 5e6, rel=1e-3)
    assert abs(held.final("spool.flange.x")) < 5.0 * 80.0 / 5e6
    slides = simulate(pushed(100.0), 1.5, rtol=1e-8)
    assert slides.final("spool.v") == pytest.approx(50.0 / 2000.0, rel=1e-3)
    t_away = slides.t[np.argmax(slides["spool.v"] > 1e-3)]
    # the ramp passes 80 N at 0.8 s; at a finite loading rate LuGre breaks away a little
    # below F_s (75 N at 100 N/s), well above the Coulomb level (0.5 s)
    assert 0.7 < t_away < 0.81
    with pytest.raises(ParameterError, match="F_s .* must not be below F_c"):
        LuGreFriction(F_c=50.0, F_s=40.0)
