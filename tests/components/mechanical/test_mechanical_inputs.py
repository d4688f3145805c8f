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
