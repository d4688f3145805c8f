"""LuGre stick-slip friction of the PVG 32 compensator (circuits.pvg32.friction)."""

import pytest

from pvgraph.circuits.pvg32.friction import LuGreFriction
from pvgraph.components.mechanical import SpoolMass
from pvgraph.components.mechanical.inputs import ForceInput
from pvgraph.components.signal.sources import Constant
from pvgraph import Circuit
from pvgraph.simulate import simulate

F_C, B, SIGMA0 = 50.0, 20000.0, 5e6


def pushed_spool(force):
    """A 66 g spool (the compensator's, eq 4.33) pushed by ``force`` against the friction."""
    c = Circuit("pushed")
    spool = c.add("spool", SpoolMass(m=0.066))
    friction = c.add("friction", LuGreFriction(F_c=F_C, b=B, sigma0=SIGMA0))
    push = c.add("push", ForceInput())
    c.connect(spool.flange, friction.flange, push.flange)
    c.connect(c.add("f", Constant(k=force)).y, push.u)
    return c


def test_slides_above_the_coulomb_force():
    """150 N against 50 N Coulomb and 20000 N s/m: v = (150 - 50) / 20000 = 5 mm/s, with the
    bristles at their sliding deflection F_c / sigma0 = 10 um."""
    sol = simulate(pushed_spool(150.0), 0.2, rtol=1e-8)
    assert sol.final("spool.v") == pytest.approx((150.0 - F_C) / B, rel=1e-3)
    assert sol.final("friction.z") == pytest.approx(F_C / SIGMA0, rel=1e-3)


def test_sticks_below_the_coulomb_force():
    """30 N < F_c: the bristles carry it (z = 6 um) and the spool stops, where the smooth law
    F_c tanh(v / v_eps) would let it creep at v_eps atanh(30/50) for ever."""
    sol = simulate(pushed_spool(30.0), 0.2, rtol=1e-8)
    assert abs(sol.final("spool.v")) < 1e-7
    assert sol.final("friction.F") == pytest.approx(30.0, rel=1e-3)
    assert sol.final("spool.flange.x") < 2 * 30.0 / SIGMA0
