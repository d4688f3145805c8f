"""Signal-driven force and position sources."""

import numpy as np
import pytest

from pvgraph.components.mechanical import ForceInput, LinearSpring, PositionInput, SpoolMass
from pvgraph.components.signal import Constant, Sine
from pvgraph import Circuit


def test_force_input_pushes_in_plus_x(dae):
    c = Circuit("push")
    mass = c.add("mass", SpoolMass(m=2.0))
    push = c.add("push", ForceInput())
    c.connect(c.add("u", Constant(k=6.0)).y, push.u)
    c.connect(mass.flange, push.flange)
    system = c.compile()
    r = dae.residual(system, values={"mass.v": 0.0}, ders={"mass.v": 3.0})
    np.testing.assert_allclose(r, 0.0, atol=1e-12)
    dae.check_jacobian(system, ders={"mass.v": 3.0})


def test_position_input_drives_a_spring(dae, sim):
    c = Circuit("stretch")
    spring = c.add("spring", LinearSpring(k=1000.0, F0=2.0))
    pos = c.add("pos", PositionInput())
    c.connect(c.add("u", Sine(amplitude=1e-3, f=5.0)).y, pos.u)
    c.connect(spring.flange, pos.flange)
    system = c.compile()
    # at the solver's own steps: a system without states has no error control on its
    # algebraic variables, so values interpolated to t_eval would not be checked
    sol = sim(system, 0.2)
    x = 1e-3 * np.sin(2 * np.pi * 5.0 * sol.t)
    np.testing.assert_allclose(sol["spring.flange.x"], x, atol=1e-9)  # Newton tolerance
    np.testing.assert_allclose(sol["spring.F"], 2.0 + 1000.0 * sol["spring.flange.x"],
                               rtol=1e-12)
    # the source takes the spring's force: it pushes the node with +F
    np.testing.assert_allclose(sol["pos.flange.f"], -sol["spring.F"], rtol=1e-12)


def test_inputs_have_no_parameters():
    assert ForceInput().params.model_dump() == {}
    assert PositionInput().params.model_dump() == {}
    with pytest.raises(Exception, match="k"):
        ForceInput(k=1.0)


def test_constant_force_and_velocity_sources():
    """ForceSource(F = 100 N) on a free 10 kg mass: x = F t^2 / (2 m) = 5 m at 1 s.
    VelocitySource(v0 = -0.1 m/s) pushes a 10 cm^2 piston's oil out through a 2 mm^2 orifice:
    the chamber holds rho/2 (A v / (Cd A_o))^2 = 30.21 bar, and the source delivers that
    pressure's force times the speed (its P)."""
    from pvgraph import Circuit
    from pvgraph.components import (Cylinder, ForceSource, Mass, Orifice, Tank,
                                    VelocitySource)
    from pvgraph.simulate import simulate
    c = Circuit("force")
    c.add("fs", ForceSource(F="100 N"))
    c.add("m", Mass(m=10.0))
    c.connect("fs.flange", "m.flange")
    assert simulate(c, 1.0, rtol=1e-8, t_eval=[1.0]).final("m.flange.x") == \
        pytest.approx(100.0 / (2 * 10.0), rel=1e-7)
    c = Circuit("push")
    c.add("vs", VelocitySource(v0=-0.1))
    c.add("cyl", Cylinder(A_A=1e-3, A_rod=5e-4, stroke=1.0, V_dead_A=1e-5, V_dead_B=1e-5,
                          start={"flange.x": 0.5}))
    c.add("o", Orifice(A=2e-6))
    c.add("t", Tank())
    c.connect("vs.flange", "cyl.flange")
    c.connect("cyl.A", "o.a")
    c.connect("o.b", "t.port", "cyl.B")
    sol = simulate(c, 1.0, t_eval=[1.0])
    p = 870.0 / 2 * (1e-3 * 0.1 / (0.6 * 2e-6)) ** 2
    assert sol.final("cyl.flange.x") == pytest.approx(0.4, rel=1e-9)
    assert sol.final("cyl.A.p") == pytest.approx(p, rel=1e-3)     # the laminar transition
    assert sol.final("vs.P") == pytest.approx(p * 1e-3 * 0.1, rel=1e-3)
