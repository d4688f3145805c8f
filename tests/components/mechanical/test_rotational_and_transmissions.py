"""Rotational parts, the generic Mass, rack and pinion, lever and the sensors."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from pvgraph.components.hydraulic import FlowSensor, Orifice, PressureSensor, PressureSource, Tank
from pvgraph.components.mechanical import (AngleSensor, ForceSensor, Inertia, Lever, Mass, PositionSensor,
                                   RackPinion, RotationalFixed, ShaftSpringDamper, SpeedSensor,
                                   SpeedSource, TorqueInput, TorqueSensor, TorqueSource,
                                   VelocitySensor, LinearSpring, Fixed, ForceInput)
from pvgraph.components.signal import Constant
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "hydraulic"))
from hydraulic_helpers import jacobian_fd_error, requires_solver, value  # noqa: E402
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate
from pvgraph.units import bar, mm2


@requires_solver
def test_torque_accelerates_an_inertia_and_the_sensors_read_it():
    J, T = 0.2, 3.0
    c = Circuit("spin")
    c.add("load", Inertia(J=J))
    c.add("drive", TorqueSource(T=T))
    c.add("w", SpeedSensor())
    c.add("phi", AngleSensor())
    c.connect("load.shaft", "drive.shaft", "w.shaft", "phi.shaft")
    t = np.array([0.5, 1.0, 2.0])
    sol = simulate(c, 2.0, rtol=1e-9, t_eval=t)
    np.testing.assert_allclose(sol["w.y"], T / J * t, rtol=1e-8)
    np.testing.assert_allclose(sol["phi.y"], 0.5 * T / J * t ** 2, rtol=1e-8)
    np.testing.assert_allclose(sol["load.E_kin"], T * sol["phi.y"], rtol=1e-8)   # work = T phi


@requires_solver
def test_two_inertias_on_an_elastic_shaft_oscillate_at_the_analytic_frequency():
    J1, J2, k = 0.1, 0.3, 400.0
    c = Circuit("shaft")
    c.add("j1", Inertia(J=J1, w0=10.0))
    c.add("j2", Inertia(J=J2))
    c.add("s", ShaftSpringDamper(k=k))
    c.connect("j1.shaft", "s.a")
    c.connect("s.b", "j2.shaft")
    wn = math.sqrt(k * (J1 + J2) / (J1 * J2))
    t = np.linspace(0, 1.0, 201)
    sol = simulate(c, 1.0, rtol=1e-10, atol=1e-10, t_eval=t)
    w_cm = (J1 * 10.0) / (J1 + J2)             # momentum conserved
    np.testing.assert_allclose(J1 * sol["j1.w"] + J2 * sol["j2.w"], J1 * 10.0, rtol=1e-7)
    rel = sol["j1.w"] - w_cm
    np.testing.assert_allclose(rel, (10.0 - w_cm) * np.cos(wn * t), atol=1e-5 * 10)


@requires_solver
def test_torque_sensor_between_source_and_load():
    c = Circuit("ts")
    c.add("src", TorqueSource(T=5.0))
    c.add("sensor", TorqueSensor())
    c.add("load", Inertia(J=1.0, b=0.25))
    c.connect("src.shaft", "sensor.a")
    c.connect("sensor.b", "load.shaft")
    sol = simulate(c, 40.0, rtol=1e-9)
    np.testing.assert_allclose(sol["sensor.y"], 5.0, rtol=1e-12)       # all of T passes
    assert sol.final("load.w") == pytest.approx(5.0 / 0.25 * (1 - math.exp(-10.0)), rel=1e-6)


@requires_solver
def test_mass_under_gravity_falls_freely_and_hangs_on_a_spring():
    g = -9.81
    c = Circuit("fall")
    c.add("m", Mass(m=2.0, g=g, x0=1.0))
    c.add("v", VelocitySensor())
    c.connect("m.flange", "v.flange")
    t = np.array([0.1, 0.3])
    sol = simulate(c, 0.3, rtol=1e-10, t_eval=t)
    np.testing.assert_allclose(sol["m.flange.x"], 1.0 + 0.5 * g * t ** 2, rtol=1e-9)
    np.testing.assert_allclose(sol["v.y"], g * t, rtol=1e-9)
    np.testing.assert_allclose(sol["m.E_kin"] + sol["m.E_pot"], 0.0, atol=1e-9)


@requires_solver
def test_rack_and_pinion_lifts_a_mass():
    """Ideal: torque T on the pinion, mass m on the rack: m a = T / r - m g."""
    r, m, T = 0.05, 10.0, 7.0
    c = Circuit("rack")
    c.add("pinion", Inertia(J=0.01))     # the pinion's inertia: the rack has none of its own
    c.add("drive", TorqueSource(T=T))
    c.add("rp", RackPinion(r=r))
    c.add("load", ForceSensor())
    c.add("grav", ForceInput())
    c.add("weight", Constant(k=-m * 9.81))
    c.add("rack_pos", PositionSensor())
    c.connect("pinion.shaft", "drive.shaft", "rp.shaft")
    c.connect("rp.flange", "rack_pos.flange", "load.a")
    c.connect("load.b", "grav.flange")
    c.connect("weight.y", "grav.u")
    sol = simulate(c, 0.5, rtol=1e-10, t_eval=[0.5])
    alpha = (T - r * m * 9.81) / 0.01        # the pinion carries the weight through r
    assert sol.final("pinion.w") == pytest.approx(alpha * 0.5, rel=1e-8)
    assert sol.final("rack_pos.y") == pytest.approx(r * 0.5 * alpha * 0.25, rel=1e-8)
    assert sol.final("load.y") == pytest.approx(m * 9.81, rel=1e-9)   # the rack holds it up


@requires_solver
def test_compliant_rack_between_two_inertias_and_lever_ratio():
    c = Circuit("mesh")
    c.add("pinion", Inertia(J=0.01))
    c.add("drive", TorqueSource(T=1.0))
    c.add("rp", RackPinion(r=0.05, k=1e6, d=50.0))
    c.add("rack", Mass(m=4.0))
    c.connect("pinion.shaft", "drive.shaft", "rp.shaft")
    c.connect("rp.flange", "rack.flange")
    sol = simulate(c, 0.2, rtol=1e-9)
    m_eq = 0.01 / 0.05 ** 2 + 4.0              # inertia seen at the rack
    assert sol.final("rack.v") == pytest.approx(1.0 / 0.05 / m_eq * 0.2, rel=1e-3)
    # lever: a spring of rate k at b seen at a is i^2 k
    c = Circuit("lever")
    c.add("push", ForceInput())
    c.add("f", Constant(k=100.0))
    c.add("lv", Lever(i=2.0))
    c.add("spring", LinearSpring(k=1e4))
    c.add("m", Mass(m=1.0, b=200.0))
    c.connect("f.y", "push.u")
    c.connect("push.flange", "lv.a", "m.flange")
    c.connect("lv.b", "spring.flange")
    sol = simulate(c, 2.0, rtol=1e-9)
    assert sol.final("m.flange.x") == pytest.approx(100.0 / (4 * 1e4), rel=1e-6)


def test_hydraulic_sensors_and_jacobians():
    c = Circuit("hs")
    c.add("src", PressureSource(p0=bar(50)))
    c.add("fs", FlowSensor())
    c.add("orf", Orifice(A=mm2(2)))
    c.add("ps", PressureSensor())
    c.add("tank", Tank())
    c.connect("src.port", "fs.a", "ps.port")
    c.connect("fs.b", "orf.a")
    c.connect("orf.b", "tank.port")
    system = c.compile()
    from pvgraph.laws import orifice_flow
    from scipy.optimize import fsolve
    y = np.array(system.y0, dtype=float)
    if system.n:
        y = fsolve(lambda y: system.residual(0.0, y, np.zeros(system.n)), y + 1e-4, xtol=1e-14)
    assert value(system, y, "fs.y") == pytest.approx(
        orifice_flow(0.6, mm2(2), bar(50), 870.0, Orifice(A=mm2(2)).params.transition()),
        rel=1e-9)
    assert value(system, y, "ps.y") == bar(50)
    c = Circuit("jr")
    c.add("j1", Inertia(J=0.1, w0=3.0))
    c.add("s", ShaftSpringDamper(k=100.0, d=0.3))
    c.add("j2", Inertia(J=0.2))
    c.add("tq", TorqueInput())
    c.add("u", Constant(k=2.0))
    c.connect("j1.shaft", "s.a", "tq.shaft")
    c.connect("s.b", "j2.shaft")
    c.connect("u.y", "tq.u")
    assert jacobian_fd_error(c.compile()) < 1e-6
    with pytest.raises(ParameterError, match="J"):
        Inertia(J=0.0)


@requires_solver
@pytest.mark.parametrize("i, eta", [(4.0, 1.0), (4.0, 0.9), (-2.5, 0.95)])
def test_gear_between_two_inertias_reflects_the_inertia(i, eta):
    """Torque T on J_a, gear i = w_a/w_b, J_b on the output: J_a a + tau_a = T,
    J_b a / i = i eta tau_a, so a = T / (J_a + J_b / (i^2 eta)), w_b = w_a / i (two inertias
    joined rigidly: index two, reduced by the compiler)."""
    from pvgraph.components.mechanical import Gear
    J_a, J_b, T = 0.01, 0.5, 2.0
    c = Circuit("gear")
    c.add("ja", Inertia(J=J_a))
    c.add("jb", Inertia(J=J_b))
    c.add("drive", TorqueSource(T=T))
    c.add("g", Gear(i=i, eta=eta))
    c.connect("drive.shaft", "ja.shaft", "g.a")
    c.connect("g.b", "jb.shaft")
    t = np.array([0.5, 0.75, 1.0])
    sol = simulate(c, 1.0, rtol=1e-10, atol=1e-10, t_eval=t)
    alpha = T / (J_a + J_b / (i * i * eta))
    # from rest the loss fades in over the first watt (P_eps); past it the acceleration is
    # the closed form's
    np.testing.assert_allclose(np.diff(sol["ja.w"]) / 0.25, alpha, rtol=1e-8)
    np.testing.assert_allclose(sol["jb.w"], sol["ja.w"] / i, rtol=1e-10)
    if eta == 1.0:
        np.testing.assert_allclose(sol["ja.w"], alpha * t, rtol=1e-8)
    # power into b is eta times the power through a
    p_a = sol["g.a.tau"] * sol["ja.w"]
    p_b = -sol["g.b.tau"] * sol["jb.w"]
    np.testing.assert_allclose(p_b, eta * p_a, rtol=1e-8)


@pytest.mark.parametrize("driven", ["a", "b"])
def test_gear_loses_power_whichever_way_it_flows(driven):
    """10 N m on one shaft, a damper of 0.5 N m s/rad on shaft a. Driven at b (an overrunning
    load turning the input back) the gear passes eta of the power to a: a.tau = -eta b.tau / i,
    so w_a = eta * 10 / (i * 0.5) = 4.5 rad/s and the damper takes 0.9 of what goes in."""
    from pvgraph.analysis import steady_state
    from pvgraph.components.mechanical import Gear
    i, eta, b, T = 4.0, 0.9, 0.5, 10.0
    c = Circuit("g")
    c.add("T", TorqueSource(T=T))
    c.add("gear", Gear(i=i, eta=eta))
    c.add("ja", Inertia(J=0.01, b=b))
    c.add("jb", Inertia(J=0.1))
    c.connect("gear.a", "ja.shaft", *(["T.shaft"] if driven == "a" else []))
    c.connect("gear.b", "jb.shaft", *(["T.shaft"] if driven == "b" else []))
    op = steady_state(c.compile())
    if driven == "a":   # nothing takes power at b: it all goes into the damper
        assert op["ja.w"] == pytest.approx(T / b, rel=1e-9)
    else:
        assert op["ja.w"] == pytest.approx(eta * T / (i * b), rel=1e-9)
        P_in = T * op["jb.w"]
        assert b * op["ja.w"] ** 2 == pytest.approx(eta * P_in, rel=1e-9)


@requires_solver
def test_compliant_gear_oscillates_at_the_reflected_frequency():
    """Gear mesh stiffness k at a, J_a free, J_b on b: with T = k (phi_a - i phi_b),
    J_a phi_a'' = -T and J_b phi_b'' = i T, so the twist oscillates at
    w_n = sqrt(k (1/J_a + i^2/J_b)) and J_a w_a + J_b w_b / i is conserved."""
    from pvgraph.components.mechanical import Gear
    J_a, J_b, i, k = 0.02, 0.8, 3.0, 500.0
    c = Circuit("gear")
    c.add("ja", Inertia(J=J_a, w0=10.0))
    c.add("jb", Inertia(J=J_b))
    c.add("g", Gear(i=i, k=k))
    c.connect("ja.shaft", "g.a")
    c.connect("g.b", "jb.shaft")
    t = np.linspace(0.0, 0.5, 101)
    sol = simulate(c, 0.5, rtol=1e-10, atol=1e-10, t_eval=t)
    wn = math.sqrt(k * (1 / J_a + i * i / J_b))
    rel = sol["ja.w"] - sol["jb.w"] * i
    np.testing.assert_allclose(rel, 10.0 * np.cos(wn * t), atol=1e-5)
    np.testing.assert_allclose(J_a * sol["ja.w"] + J_b * sol["jb.w"] / i, J_a * 10.0, rtol=1e-7)


def test_gear_ratio_zero_is_refused_by_name():
    from pvgraph.components.mechanical import Gear
    with pytest.raises(ParameterError, match="i"):
        Gear(i=0.0)


def test_a_lossy_gear_never_makes_energy_and_passes_the_ideal_torque_at_rest():
    """Two inertias and a spring with a 50 % gear as the only loss, swinging at well under the
    1 W of P_eps: the stored energy never grows (it grew 12 % with a loss blended above 1 at
    low power). At rest under a 2 N m torque, i = 3, the spring holds the ideal 6 N m."""
    from pvgraph.analysis import steady_state
    from pvgraph.components.mechanical import Gear
    c = Circuit("e")
    c.add("ja", Inertia(J=1.0, w0=0.05))
    c.add("g", Gear(i=1.0, eta=0.5))
    c.add("jb", Inertia(J=1.0))
    c.add("s", ShaftSpringDamper(k=1.0))
    c.add("gnd", RotationalFixed())
    c.connect("ja.shaft", "g.a")
    c.connect("g.b", "jb.shaft", "s.a")
    c.connect("s.b", "gnd.shaft")
    sol = simulate(c, 60.0, rtol=1e-9, atol=1e-14, t_eval=np.linspace(0.0, 60.0, 121))
    stored = 0.5 * (sol["ja.w"] ** 2 + sol["jb.w"] ** 2) + 0.5 * sol["jb.shaft.phi"] ** 2
    assert np.all(np.diff(stored) <= 1e-12 * stored[0])
    assert stored[-1] < stored[0]
    c = Circuit("gs")
    c.add("T", TorqueSource(T=2.0))
    c.add("ja", Inertia(J=0.01))
    c.add("g", Gear(i=3.0, eta=0.9))
    c.add("jb", Inertia(J=0.1))
    c.add("s", ShaftSpringDamper(k=100.0, d=0.5))
    c.add("gnd", RotationalFixed())
    c.connect("T.shaft", "ja.shaft", "g.a")
    c.connect("g.b", "jb.shaft", "s.a")
    c.connect("s.b", "gnd.shaft")
    assert steady_state(c.compile())["s.a.tau"] == pytest.approx(6.0, rel=1e-9)


def test_lever_ratio_zero_is_refused_by_name():
    with pytest.raises(ParameterError, match=r"i = 0.*must not be 0"):
        Lever(i=0.0)


@pytest.mark.parametrize("make", [lambda d: __import__("pvgraph.components.mechanical",
                                                       fromlist=["Gear"]).Gear(i=2.0, d=d),
                                  lambda d: Lever(i=2.0, d=d),
                                  lambda d: RackPinion(r=0.05, d=d)])
def test_a_mesh_damping_without_a_stiffness_is_refused(make):
    with pytest.raises(ParameterError, match=r"d = 1.0 damps the mesh's deflection, but k is "
                                             r"None"):
        make(1.0)
    make(0.0)


def test_a_rack_position_expressed_in_the_pinion_angle_keeps_its_own_unit():
    """Rack and pinion (r = 0.05 m) join a 1 kg mass and a 0.1 kg m^2 inertia; 10 N pushes.
    x(t) = x0 + F t^2 / (2 (m + J / r^2)); the rack position is a length and the pinion
    torque a torque whichever of them the compiler keeps as the unknown, in results, CSV
    headers and start values with units."""
    from pvgraph.components import Constant, ForceInput, Inertia, Mass, RackPinion
    from pvgraph.simulate import simulate
    c = Circuit("rack")
    m = c.add("M", Mass(m=1.0, x0=0.02))
    inertia = c.add("I", Inertia(J=0.1))
    rack = c.add("R", RackPinion(r=0.05))
    force = c.add("k", Constant(k=10.0))
    push = c.add("f", ForceInput())
    c.connect(m.flange, rack.flange, push.flange)
    c.connect(rack.shaft, inertia.shaft)
    c.connect(force.y, push.u)
    sol = simulate(c, 0.1, rtol=1e-8)
    want = 0.02 + 10.0 * 0.1 ** 2 / (2.0 * (1.0 + 0.1 / 0.05 ** 2))
    assert abs(sol.final("M.flange.x") - want) < 1e-9
    assert sol.unit("M.flange.x") == sol.unit("R.flange.x") == "m"
    assert sol.unit("I.shaft.phi") == "rad"
    assert sol.unit("I.shaft.tau") == sol.unit("R.shaft.tau") == "N m"
    assert sol.unit("M.flange.f") == "N"
    # a start value in a length unit on the rack position is taken (was refused as rad)
    moved = simulate(c, 0.1, rtol=1e-8, start={"M.flange.x": "30 mm"})
    assert abs(moved["M.flange.x"][0] - 0.03) < 1e-12
    assert abs(moved["I.shaft.phi"][0] - 0.03 / 0.05) < 1e-12


@pytest.mark.parametrize("r", [0.1, 0.02])
def test_a_given_rack_position_holds_when_the_radius_changes_at_run_time(r):
    """Mass(x0 = 0.02 m) on a rack, pinion radius changed as a runtime parameter: the rack
    starts at its given 0.02 m (the pinion angle moves to x0 / r), and x(1) = x0 + F / (2 (m
    + J / r^2)), as the circuit compiled with that radius gives."""
    from pvgraph.components import Constant, ForceInput, Inertia, Mass, RackPinion

    def build(radius=0.05):
        c = Circuit("rack")
        m = c.add("M", Mass(m=1.0, x0=0.02))
        inertia = c.add("I", Inertia(J=0.1))
        rack = c.add("R", RackPinion(r=radius))
        force = c.add("k", Constant(k=10.0))
        push = c.add("f", ForceInput())
        c.connect(m.flange, rack.flange, push.flange)
        c.connect(rack.shaft, inertia.shaft)
        c.connect(force.y, push.u)
        return c
    sol = simulate(build().compile(), 1.0, rtol=1e-9, params={"R.r": r})
    assert abs(sol["M.flange.x"][0] - 0.02) < 1e-12
    assert abs(sol["I.shaft.phi"][0] - 0.02 / r) < 1e-10
    assert abs(sol.final("M.flange.x") - (0.02 + 10.0 / (2.0 * (1.0 + 0.1 / r ** 2)))) < 1e-8


def test_two_rigid_gears_in_parallel_are_refused_naming_the_way_out():
    """Two gears i = 4 between the same shafts: the torque each carries is undetermined, a
    StructureError when compiling names the redundant constraint and the mesh stiffness; with
    one mesh compliant the pair runs at dw/dt = T / (J_a + J_b / i^2)."""
    from pvgraph.components import Gear, Inertia, TorqueSource
    from pvgraph.errors import StructureError

    def pair(**second):
        c = Circuit("gears")
        a = c.add("I", Inertia(J=0.1))
        b = c.add("J2", Inertia(J=2.0))
        torque = c.add("T", TorqueSource(T=1.0))
        g1 = c.add("G1", Gear(i=4.0))
        g2 = c.add("G2", Gear(i=4.0, **second))
        c.connect(a.shaft, g1.a, g2.a, torque.shaft)
        c.connect(g1.b, g2.b, b.shaft)
        return c
    with pytest.raises(StructureError, match=r"redundant constraint.*mesh stiffness \(k\)"):
        pair().compile()
    sol = simulate(pair(k=1e6, d=1e2), 1.0, rtol=1e-8)
    assert abs(sol.final("I.w") - 1.0 / (0.1 + 2.0 / 16.0)) < 1e-3 * 4.444
