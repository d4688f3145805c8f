"""Start values on variables tied by constraints (index reduction) and on shared nodes.

Closed forms: a lever (ratio i) with mass m_A on end a and mass m_B plus a spring k on end b is
one oscillator of mass m_A + i^2 m_B and stiffness i^2 k seen from end a; two ideal
rack-pinions (radii r1, r2) couple two free inertias at w2 = (r1/r2) w1; two masses rigidly on
one flange under a force F move as one mass m1 + m2.
"""

import math
import warnings

import numpy as np
import pytest

from pvgraph import Circuit, InitializationError
from pvgraph.components import Cylinder, Plug, VolumeNode
from pvgraph.components.mechanical import (ForceInput, Inertia, Lever, LinearSpring, Mass,
                                           RackPinion)
from pvgraph.components.signal import Constant
from pvgraph.errors import PlausibilityWarning
from pvgraph.simulate import simulate

M_A, M_B, I_LEV, K = 4.0, 2.0, 2.0, 1000.0
W = math.sqrt(I_LEV ** 2 * K / (M_A + I_LEV ** 2 * M_B))     # 18.257 rad/s


def lever(vA=0.0, vB=0.0, xA=0.0, xB=0.0):
    c = Circuit("lev")
    A = c.add("A", Mass(m=M_A, v0=vA, x0=xA))
    B = c.add("B", Mass(m=M_B, v0=vB, x0=xB))
    lev = c.add("lev", Lever(i=I_LEV))
    sp = c.add("sp", LinearSpring(k=K))
    c.connect(A.flange, lev.a)
    c.connect(lev.b, B.flange, sp.flange)
    return c


def assert_lever_swings(sol, v0=0.5):
    t = sol.t
    exact = v0 / W * np.sin(W * t)
    assert abs(W - 18.257418583505537) < 1e-9
    assert np.max(np.abs(sol["A.flange.x"] - exact)) < 1e-5 * v0 / W      # amplitude 27.39 mm
    assert np.max(np.abs(sol["B.flange.x"] - I_LEV * exact)) < 1e-5 * v0 / W * I_LEV
    assert abs(sol["A.v"][0] - v0) < 1e-9 and abs(sol["B.v"][0] - I_LEV * v0) < 1e-9


@pytest.mark.parametrize("kw", [dict(vA=0.5), dict(vB=1.0), dict(vA=0.5, vB=1.0)])
def test_lever_started_moving_by_a_given_velocity(kw):
    sol = simulate(lever(**kw), 0.4, rtol=1e-9, t_eval=np.linspace(0, 0.4, 81))
    assert_lever_swings(sol)


def test_lever_started_moving_through_simulate_start_and_runtime_parameter():
    system = lever().compile()
    t = np.linspace(0, 0.4, 81)
    assert_lever_swings(simulate(system, 0.4, rtol=1e-9, t_eval=t, start={"A.v": 0.5}))
    assert_lever_swings(simulate(system, 0.4, rtol=1e-9, t_eval=t, start={"B.v": 1.0}))
    assert_lever_swings(simulate(system, 0.4, rtol=1e-9, t_eval=t, params={"B.v0": 1.0}))


def test_lever_contradicting_velocities_are_refused_with_both_values():
    with pytest.raises(InitializationError) as info:
        lever(vA=0.5, vB=0.5).compile()
    assert "B.v = 0.5 given, the constraints force 1 (with A.v = 0.5)" in str(info.value)
    system = lever().compile()
    with pytest.raises(InitializationError, match=r"B\.v = 3 given, the constraints force 1"):
        simulate(system, 0.1, start={"A.v": 0.5, "B.v": 3.0})
    with pytest.raises(InitializationError, match=r"B\.v = 0\.5 given, the constraints force 1"):
        system.with_params({"A.v0": 0.5, "B.v0": 0.5})


def test_lever_positions_given_on_either_end_agree_at_build_and_run_time():
    fresh = lever(xB=0.1).compile()
    runtime = lever().compile().with_params({"B.x0": 0.1})
    for system in (fresh, runtime):
        sol = simulate(system, 0.2, rtol=1e-9, t_eval=np.linspace(0, 0.2, 41))
        # released from x_B = 0.1 at rest: x_A = 0.05 cos(w t)
        assert np.max(np.abs(sol["A.flange.x"] - 0.05 * np.cos(W * sol.t))) < 1e-6
    with pytest.raises(InitializationError, match=r"flange\.x = 0\.\d+ given, the constraints "
                                                  r"force"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlausibilityWarning)
            lever(xA=0.01, xB=0.1).compile()
    with pytest.raises(InitializationError, match=r"B\.flange\.x = 0\.1 given, the constraints "
                                                  r"force 0\.02"):
        lever().compile().with_params({"A.x0": 0.01, "B.x0": 0.1})


def gears(w1=0.0, w2=0.0):
    c = Circuit("gears")
    i1 = c.add("i1", Inertia(J=0.1, w0=w1))
    i2 = c.add("i2", Inertia(J=0.4, w0=w2))
    p1 = c.add("p1", RackPinion(r=0.05))
    p2 = c.add("p2", RackPinion(r=0.02))
    c.connect(i1.shaft, p1.shaft)
    c.connect(p1.flange, p2.flange)
    c.connect(p2.shaft, i2.shaft)
    return c


def test_gear_train_started_at_consistent_speeds_free_wheels():
    for kw in (dict(w1=10.0, w2=25.0), dict(w1=10.0), dict(w2=25.0)):
        sol = simulate(gears(**kw), 1.0, rtol=1e-9)
        assert abs(sol.final("i1.w") - 10.0) < 1e-8
        assert abs(sol.final("i2.w") - 25.0) < 1e-8      # w2 = (r1/r2) w1
        assert abs(sol.final("i1.shaft.phi") - 10.0) < 1e-6
    with pytest.raises(InitializationError, match=r"i2\.w = 20 given, the constraints force 25"):
        gears(w1=10.0, w2=20.0).compile()


def two_masses():
    c = Circuit("two")
    f = c.add("f", ForceInput())
    k = c.add("k", Constant(k=10.0))
    m1 = c.add("m1", Mass(m=2.0))
    m2 = c.add("m2", Mass(m=3.0))
    c.connect(k.y, f.u)
    c.connect(f.flange, m1.flange, m2.flange)
    return c


def test_start_on_the_algebraic_mass_moves_the_state():
    system = two_masses().compile()
    sol = simulate(system, 1.0, rtol=1e-9, start={"m2.v": 1.0})
    # x(1) = v0 t + F t^2 / (2 (m1 + m2)) = 1 + 1 = 2, v(1) = 1 + 2 = 3
    assert abs(sol["m1.v"][0] - 1.0) < 1e-12 and abs(sol["m2.v"][0] - 1.0) < 1e-12
    assert abs(sol.final("m1.flange.x") - 2.0) < 1e-7
    assert abs(sol.final("m2.v") - 3.0) < 1e-7
    with pytest.raises(InitializationError,
                       match=r"m2\.v = 2 given, the constraints force 1\b"):
        simulate(system, 1.0, start={"m1.v": 1.0, "m2.v": 2.0})


def cylinder_volume(**vol):
    c = Circuit("s")
    v = c.add("v", VolumeNode(V="0.1 L", **vol))
    cyl = c.add("cyl", Cylinder(A_A=1e-3, A_rod=4e-4, stroke=0.5, V_dead_A=1e-5, V_dead_B=1e-5))
    m = c.add("m", Mass(m=10.0))
    pl = c.add("pl", Plug())
    c.connect(v.port, cyl.A)
    c.connect(cyl.B, pl.port)
    c.connect(cyl.flange, m.flange)
    return c


def test_a_given_node_start_wins_over_a_default_one():
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        system = cylinder_volume(p0="5 bar").compile()
    assert system.y0[system.resolve("v.port.p")[1]] == 5e5
    sol = simulate(system, 1e-4)
    assert abs(sol["v.port.p"][0] - 5e5) < 1e-6 and abs(sol["cyl.A.p"][0] - 5e5) < 1e-6


def test_two_given_node_starts_that_differ_are_reported():
    c = Circuit("s3")
    a = c.add("a", VolumeNode(V="0.1 L", p0="5 bar"))
    b = c.add("b", VolumeNode(V="0.1 L", p0="10 bar"))
    pl = c.add("pl", Plug())
    c.connect(a.port, b.port, pl.port)
    with pytest.warns(PlausibilityWarning, match=r"conflicting start values") as got:
        c.compile()
    text = " ".join(str(w.message) for w in got)
    assert "a.port.p = 500000 Pa" in text and "b.port.p = 1e+06 Pa" in text


def test_start_values_with_a_runtime_ratio_win_over_the_build_time_ones():
    """Lever built with x_A0 = 0.1, x_B0 = 0.2 (i = 2); run with i = 3 and start x_A = 0.1:
    the given start holds and the other end follows, x_B = 0.3 (the build-time 0.2 no longer
    fits the ratio). Without a start (a sweep over the ratio), the run goes on from the
    states' start values, the other end following, and says so."""
    system = lever(xA=0.1, xB=0.2).compile()
    sol = simulate(system, 0.01, params={"lev.i": 3.0}, start={"A.flange.x": 0.1})
    assert sol["A.flange.x"][0] == pytest.approx(0.1, abs=1e-12)
    assert sol["B.flange.x"][0] == pytest.approx(0.3, abs=1e-12)
    sol = simulate(system, 0.01, params={"lev.i": 3.0}, start={"B.flange.x": 0.45})
    assert sol["A.flange.x"][0] == pytest.approx(0.15, abs=1e-12)
    from pvgraph.errors import StartValueWarning
    with pytest.warns(StartValueWarning, match=r"new value of lev.i the start values given "
                                               r"when building no longer fit"):
        sol = simulate(system, 0.01, params={"lev.i": 3.0})
    xa, xb = sol["A.flange.x"][0], sol["B.flange.x"][0]
    assert xb == pytest.approx(3.0 * xa, abs=1e-12)
    assert xa == pytest.approx(0.1, abs=1e-12) or xb == pytest.approx(0.2, abs=1e-12)
