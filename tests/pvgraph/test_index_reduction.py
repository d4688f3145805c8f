"""Index reduction (Pantelides, dummy derivatives) on circuits with closed-form answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import Field
from scipy.special import ellipk

from pvgraph.components.hydraulic import FlowSource, Tank, VolumeNode
from pvgraph.components.mechanical import ForceInput, Inertia, Mass, PositionInput, SpoolMass
from pvgraph.components.mechanical.rotational import Rotational
from pvgraph.components.signal import Constant, Ramp, Sine, Step, TimeTable
from pvgraph import (Circuit, Component, Hydraulic, InitializationError, Mechanical, Params,
                     PvgraphError, SolverError, StructureError, Variable, der)
from pvgraph import expr as E
from pvgraph.index_reduction import derivative_name, time_derivative
from pvgraph.simulate import simulate

G = 9.81


# the total time derivative ---------------------------------------------------------------------

def test_time_derivative_follows_product_chain_and_explicit_time():
    x, y = E.Expr("sym", (), "x"), E.Expr("sym", (), "y")
    t = E.Expr("time")
    e = x * y + E.sin(3.0 * t) + E.exp(x) + 2.0 * E.Expr("sym", (), "m.#mode")

    def d(node):
        if node.op == "sym" and "#" not in node.value:
            return E.Expr("sym", (), derivative_name(node.value, 1))
        return None  # the mode is constant in time
    de = time_derivative(e, d)
    vals = {"x": 0.7, "y": -1.3, "der(x)": 2.0, "der(y)": 0.5}
    tv = 0.4
    leaves = {("sym", k): v for k, v in vals.items()}
    got = _eval(de, leaves, tv)
    want = 2.0 * -1.3 + 0.7 * 0.5 + 3.0 * math.cos(3.0 * tv) + math.exp(0.7) * 2.0
    assert got == pytest.approx(want, rel=1e-14)


def _eval(e, leaves, t):
    src = E.substitute([e], lambda n: E.const(leaves[(n.op, n.value)]) if n.op == "sym" else
                       (E.const(t) if n.op == "time" else None))[0]
    assert src.op == "const"
    return src.value


# circuits ---------------------------------------------------------------------------------------

def masses_under_force(masses, force, *, start=None):
    c = Circuit("masses")
    parts = [c.add(f"m{k + 1}", SpoolMass(m=m, **(start or {}).get(k, {})))
             for k, m in enumerate(masses)]
    push = c.add("push", ForceInput())
    k = c.add("k", Constant(k=force))
    c.connect(*[p.flange for p in parts], push.flange)
    c.connect(k.y, push.u)
    return c


def test_index_one_circuit_compiles_unchanged():
    c = masses_under_force([2.0], 4.0)
    s = c.compile()
    assert s.names == ["m1.flange.x", "m1.v"]
    assert "no index reduction" in s.index_report()


def test_masses_on_one_flange_move_as_one_mass():
    masses, F = [1.0, 2.0, 3.0], 6.0
    s = masses_under_force(masses, F).compile()
    report = s.index_report()
    for k in (1, 2, 3):
        assert f"m{k} equation 1 (SpoolMass)" in report
    assert int(s.differential.sum()) == 2  # one position, one velocity
    t = np.linspace(0.0, 1.0, 11)
    sol = simulate(s, 1.0, t_eval=t, rtol=1e-8)
    a = F / sum(masses)
    assert np.allclose(sol["m3.flange.x"], 0.5 * a * t ** 2, rtol=0, atol=1e-9)
    for k in (1, 2, 3):
        assert np.allclose(sol[f"m{k}.v"], a * t, rtol=0, atol=1e-9)
        # each mass takes its share of the force: m_k * a
        assert np.allclose(sol[f"m{k}.flange.f"], masses[k - 1] * a, rtol=1e-9)


def test_report_names_dummies_and_states_by_component():
    s = masses_under_force([1.0, 2.0], 3.0).compile()
    report = s.index_report()
    dummies = report.split("dummy derivatives (")[1].split("states chosen")[0]
    states = report.split("states chosen")[1].split("made algebraic")[0]
    # the position's second derivative and one velocity's derivative are dummies; the position
    # and the other velocity stay states; each line names the component it belongs to
    assert "der(m1.flange.x, 2)  [m1]" in dummies
    assert "m1.flange.x  [m1]" in states
    assert ("m1.v  [m1]" in states) != ("m2.v  [m2]" in states)
    assert s.names.count("der(m1.flange.x, 2)") == 1
    assert s.unit("der(m1.flange.x, 2)") == "m/s^2"
    dummy_v = [n for n in ("der(m1.v)", "der(m2.v)") if n in s.names]
    assert len(dummy_v) == 1 and s.unit(dummy_v[0]) == "m/s^2"


def test_connection_equations_kept_are_differentiated_too():
    """Without alias elimination the node's position equality is the constraint (index three)."""
    s = masses_under_force([1.0, 2.0], 3.0).compile(eliminate_aliases=False)
    assert "x equal at m2.flange: twice" in s.index_report()
    sol = simulate(s, 1.0, t_eval=np.array([0.0, 1.0]), rtol=1e-8)
    assert sol["m1.flange.x"][-1] == pytest.approx(0.5, rel=1e-8)
    assert sol["m2.v"][-1] == pytest.approx(1.0, rel=1e-8)


def test_joined_masses_on_a_spring_linearise_to_one_mass_of_the_sum():
    from pvgraph.components.mechanical import LinearSpring
    from pvgraph.analysis import linearize, steady_state
    k, F = 4e3, 20.0
    c = masses_under_force([1.0, 3.0], F)
    spring = c.add("spring", LinearSpring(k=k))
    c.connect(spring.flange, c["m1"].flange)
    s = c.compile()
    op = steady_state(s)
    assert op["m2.flange.x"] == pytest.approx(F / k, rel=1e-9)
    lin = linearize(s, op, None, ["m2.flange.x"])
    assert lin.A.shape == (2, 2)
    assert sorted(np.abs(lin.poles().imag)) == pytest.approx([math.sqrt(k / 4.0)] * 2, rel=1e-9)


def test_given_start_velocity_keeps_that_mass_a_state():
    c = masses_under_force([1.0, 3.0], 8.0, start={1: {"v0": 0.5}})
    s = c.compile()
    assert s.differential[s.index["m2.v"]]
    sol = simulate(s, 1.0, t_eval=np.array([0.0, 1.0]), rtol=1e-8)
    assert sol["m1.v"][-1] == pytest.approx(0.5 + 2.0 * 1.0, rel=1e-9)
    assert sol["m1.flange.x"][-1] == pytest.approx(0.5 + 0.5 * 2.0, rel=1e-8)


def test_conflicting_start_positions_are_named():
    c = masses_under_force([1.0, 1.0], 1.0, start={0: {"x0": 0.01}, 1: {"x0": 0.02}})
    with pytest.raises(InitializationError) as info:
        c.compile()
    msg = str(info.value)
    assert ("m1.flange.x = 0.01 given, the constraints force 0.02" in msg
            or "m2.flange.x = 0.02 given, the constraints force 0.01" in msg)


def test_conflicting_start_velocities_are_named():
    c = masses_under_force([1.0, 1.0], 1.0, start={0: {"v0": 1.0}, 1: {"v0": 2.0}})
    with pytest.raises(InitializationError, match=r"m\d\.v = [12] given, the constraints force"):
        c.compile()


def test_position_input_force_is_mass_times_acceleration():
    m, A, f = 2.0, 0.01, 5.0
    c = Circuit("drive")
    mass = c.add("mass", SpoolMass(m=m))
    pos = c.add("pos", PositionInput())
    sine = c.add("sine", Sine(amplitude=A, f=f))
    c.connect(mass.flange, pos.flange)
    c.connect(sine.y, pos.u)
    s = c.compile()
    report = s.index_report()
    assert "sine equation 1 (Sine): twice" in report
    assert "der(mass.flange.x, 2)" in report
    # purely algebraic: with the step fixed by max_step and the algebraic variables out of the
    # error test, every step solves the linear equations exactly
    sol = simulate(s, 0.4, max_step=1e-2, suppress_alg=True)
    t = sol.t
    assert len(t) > 40
    w = 2.0 * math.pi * f
    # the source pushes the mass with -pos.flange.f = m x''  (x = A sin(w t))
    assert np.allclose(-sol["pos.flange.f"], -m * A * w * w * np.sin(w * t), rtol=0,
                       atol=1e-6 * m * A * w * w)
    assert np.allclose(sol["mass.v"], A * w * np.cos(w * t), rtol=0, atol=1e-9)
    assert np.allclose(sol["mass.a"], -A * w * w * np.sin(w * t), rtol=0, atol=1e-6 * A * w * w)


def test_a_pchip_position_table_that_would_need_a_second_derivative_is_named():
    c = Circuit("drive")
    mass = c.add("mass", SpoolMass(m=2.0))
    pos = c.add("pos", PositionInput())
    table = c.add("table", TimeTable(t=(0.0, 1.0, 2.0), y=(0.0, 1e-3, 0.0), method="pchip"))
    c.connect(mass.flange, pos.flange)
    c.connect(table.y, pos.u)
    with pytest.raises(StructureError, match=r"slope of table .*pchip.*method='linear'"):
        c.compile()


def test_start_values_a_position_source_overrides_are_named():
    A, f = 0.01, 5.0
    c = Circuit("drive")
    mass = c.add("mass", SpoolMass(m=2.0, x0=0.004, v0=A * 2.0 * math.pi * f))
    pos = c.add("pos", PositionInput())
    sine = c.add("sine", Sine(amplitude=A, f=f))
    c.connect(mass.flange, pos.flange)
    c.connect(sine.y, pos.u)
    with pytest.raises(InitializationError) as info:
        c.compile()
    msg = str(info.value)
    # x(0) = A sin(0) = 0 contradicts x0; v0 = A w is what the sine gives, so it is not named
    assert "mass.flange.x = 0.004 given, the constraints force 0" in msg
    assert "mass.v" not in msg.split("With the states")[0]


def test_structurally_singular_circuit_is_still_refused_by_name():
    class TwoLawsForOnePressureDrop(Component):
        ports = {"a": Hydraulic(), "b": Hydraulic()}

        def equations(self, v, p):  # both fix the pressure drop, none the flow
            return [E.exp((v.a.p - v.b.p) / 1e5) - 2.0, E.sqrt(1.0 + (v.a.p - v.b.p) ** 2) - 3.0]

    c = masses_under_force([1.0, 2.0], 1.0)   # needs reduction ...
    src = c.add("src", FlowSource(Q=1e-5))
    bad = c.add("bad", TwoLawsForOnePressureDrop())  # ... and is singular here
    node = c.add("node", VolumeNode(V=1e-4))
    tank = c.add("tank", Tank())
    c.connect(src.port, node.port, bad.a)
    c.connect(bad.b, tank.port)
    with pytest.raises(StructureError) as info:
        c.compile()
    msg = str(info.value)
    assert "structurally singular" in msg
    assert "Over-determined" in msg and "bad equation" in msg


# an index-3 system: the pendulum on a rigid link --------------------------------------------

class PendulumParams(Params):
    m: float = Field(1.0, gt=0.0, description="Mass [kg]")
    L: float = Field(1.0, gt=0.0, description="Link length [m]")
    theta0: float = Field(0.5, ge=-3.2, le=3.2, description="Start angle from below [rad]")


class Pendulum(Component):
    """Point mass on a rigid link in the vertical plane (Cartesian, index 3)."""

    Params = PendulumParams
    variables = {"x": Variable("m", lambda p: p.L * math.sin(p.theta0)),
                 "y": Variable("m", lambda p: -p.L * math.cos(p.theta0)),
                 "vx": Variable("m/s"), "vy": Variable("m/s"),
                 "lam": Variable("N/m", 0.0, 10.0, "link tension per length")}

    def equations(self, v, p):
        return [der(v.x) - v.vx, der(v.y) - v.vy,
                p.m * der(v.vx) + v.lam * v.x,
                p.m * der(v.vy) + v.lam * v.y + p.m * G,
                v.x * v.x + v.y * v.y - p.L ** 2]


@pytest.mark.parametrize("solver", ["pvgraph", "ida"])
def test_pendulum_period_matches_the_elliptic_integral_on_both_backends(solver):
    theta0, L = 0.5, 1.0
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=theta0, L=L))
    s = c.compile()
    assert "p equation 5 (Pendulum): twice" in s.index_report()
    # well-conditioned pivot at the start: |y| > |x|, so y's derivatives are the dummies and the
    # horizontal coordinate and its velocity are the states
    assert [n for n, d in zip(s.names, s.differential) if d] == ["p.x", "p.vx"]
    T = 4.0 * math.sqrt(L / G) * ellipk(math.sin(theta0 / 2.0) ** 2)
    sol = simulate(s, T, solver=solver, rtol=1e-8, t_eval=np.array([0.0, T / 2.0, T]))
    x0 = L * math.sin(theta0)
    # IDA keeps the algebraic variables (the dummy derivatives, the tension) in its error test
    # (scikit-sundae has no suppressalg): 10x the steps, and a phase error after one period of
    # 1.5e-6 m at rtol 1e-8 (7.7e-7 at 1e-9), against pvgraph's 1.5e-7
    assert sol["p.x"] == pytest.approx([x0, -x0, x0], abs=1e-6 if solver == "pvgraph" else 3e-6)
    assert np.allclose(sol["p.x"] ** 2 + sol["p.y"] ** 2, L * L, rtol=1e-9)
    # energy: speed at the turning points is zero, tension there is m g cos(theta0) / L
    assert np.allclose(sol["p.lam"], G * math.cos(theta0) / L, rtol=1e-5)


class ScaledPendulum(Pendulum):
    """The same pendulum with its link written ``(x/L)^2 + (y/L)^2 = 1``: the parameter L is
    in the constraint's Jacobian."""

    def equations(self, v, p):
        return [der(v.x) - v.vx, der(v.y) - v.vy,
                p.m * der(v.vx) + v.lam * v.x,
                p.m * der(v.vy) + v.lam * v.y + p.m * G,
                (v.x / p.L) * (v.x / p.L) + (v.y / p.L) * (v.y / p.L) - 1.0]


def test_a_parameter_in_a_constraint_does_not_change_the_choice_of_states():
    """The constraint's Jacobian is evaluated with the parameter's value, so the states are
    those of the plain form (x, vx at a small angle) and the pivot is watched: the period is
    the elliptic integral's and the energy stays (a structural choice of y, singular at the
    bottom, lost most of the swing energy at each pass)."""
    theta0, L = 0.05, 1.0
    c = Circuit("pendulum")
    c.add("p", ScaledPendulum(theta0=theta0, L=L))
    s = c.compile()
    assert [n for n, d in zip(s.names, s.differential) if d] == ["p.vx", "p.x"] or \
        [n for n, d in zip(s.names, s.differential) if d] == ["p.x", "p.vx"]
    assert "watched during the run" in s.index_report()
    T = 4.0 * math.sqrt(L / G) * ellipk(math.sin(theta0 / 2.0) ** 2)
    sol = simulate(s, 2.0 * T, rtol=1e-9, atol=1e-10, t_eval=np.array([0.0, T / 2.0, T, 2 * T]))
    x0 = L * math.sin(theta0)
    assert sol["p.x"] == pytest.approx([x0, -x0, x0, x0], abs=1e-6)
    energy = 0.5 * (sol["p.vx"] ** 2 + sol["p.vy"] ** 2) + G * sol["p.y"]
    assert np.allclose(energy, -G * L * math.cos(theta0), rtol=0.0, atol=1e-7)


def test_pendulum_stops_by_name_where_the_state_choice_would_have_to_change():
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=1.8))  # above horizontal: x is the large coordinate at the start
    s = c.compile()
    assert "watched during the run" in s.index_report()
    T = 4.0 * math.sqrt(1.0 / G) * ellipk(math.sin(0.9) ** 2)
    with pytest.raises(SolverError, match=r"at t = 0\.\d+ s the dummy derivatives .*der\(p\.x, 2\)"
                                          r".*choice of states \(p\.vy, p\.y\)") as info:
        simulate(s, T, switch_states=False)
    # x passes through a tenth of its start value shortly before the bottom (T/4)
    assert 0.1 * T < info.value.t < 0.25 * T


@pytest.mark.parametrize("solver, theta0, tol", [("pvgraph", 1.8, 2e-5), ("ida", 1.8, 2e-5),
                                                 ("pvgraph", 3.0, 3e-3)])
def test_a_cartesian_pendulum_swinging_past_the_horizontal_changes_its_states(solver, theta0,
                                                                              tol):
    """Released above the horizontal, y and vy are the states at the start (x is the larger
    coordinate); the choice is made again where it becomes ill-conditioned, near the bottom
    (x, vx) and near the horizontal (y, vy), four times a period. x at the quarter periods is
    that of the elliptic integral's period (a phase error of 6e-6 m after three periods at
    rtol 1e-8 from 1.8 rad; 6.5e-4 from 3.0 rad, 0.14 rad from the top, where the period
    grows without bound with the amplitude), the link keeps its length, energy is conserved."""
    L = 1.0
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=theta0, L=L))
    s = c.compile()
    T = 4.0 * math.sqrt(L / G) * ellipk(math.sin(theta0 / 2.0) ** 2)
    t_eval = np.linspace(0.0, 3.0 * T, 13)
    sol = simulate(s, 3.0 * T, rtol=1e-8, t_eval=t_eval, solver=solver)
    x0 = L * math.sin(theta0)
    assert sol.t == pytest.approx(t_eval, abs=0.0)
    assert sol["p.x"] == pytest.approx(np.tile([x0, 0.0, -x0, 0.0], 4)[:13], abs=tol)
    assert np.allclose(sol["p.x"] ** 2 + sol["p.y"] ** 2, L * L, rtol=1e-8)
    energy = 0.5 * (sol["p.vx"] ** 2 + sol["p.vy"] ** 2) + G * sol["p.y"]
    assert np.ptp(energy) < 5e-4
    switches = sol.stats["state_switches"]
    assert len(switches) in (12, 13) if theta0 < 2.0 else len(switches) >= 12
    first = ("p.vy", "p.y") if theta0 < 2.0 else ("p.vx", "p.x")   # the larger coordinate's
    assert switches[0][1] == first == tuple(sorted(n for n, d in zip(s.names, s.differential)
                                                   if d))
    assert all(a[2] == b[1] for a, b in zip(switches, switches[1:]))
    # the solution is in the layout of the system the run started with
    assert sol.system is s and sol.y.shape == (13, s.n)


def test_state_switches_keep_runtime_parameters_and_the_derivatives():
    """The circuit compiled again at a switch has the run's parameter values (a 2 m link:
    the period of a 2 m pendulum); every output time of a dense run is in order, and the
    derivative of x read from the solution is vx (to 1e-4 m/s of 6 m/s: where x is algebraic
    its rate is the solver's, outside the error test)."""
    theta0, L = 1.8, 2.0
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=theta0, L=1.0))
    s = c.compile()
    T = 4.0 * math.sqrt(L / G) * ellipk(math.sin(theta0 / 2.0) ** 2)
    sol = simulate(s, T, rtol=1e-8, params={"p.L": L})
    switches = [t for t, before, after in sol.stats["state_switches"] if before != after]
    assert len(switches) >= 3
    # in order; a switch's instant twice (before and after, as at an event)
    assert np.all(np.diff(sol.t) >= 0.0)
    assert set(sol.t[1:][np.diff(sol.t) == 0.0]) == {t for t in switches if t > 0.0}
    assert sol.final("p.x") == pytest.approx(L * math.sin(theta0), abs=2e-5)
    assert np.max(np.abs(sol.der("p.x") - sol["p.vx"])) < 1e-4
    assert np.allclose(sol["p.x"] ** 2 + sol["p.y"] ** 2, L * L, rtol=1e-8)


def test_switch_states_is_a_flag():
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=0.5))
    with pytest.raises(PvgraphError, match="switch_states takes True or False"):
        simulate(c, 0.1, switch_states="yes")


def test_a_position_driven_mass_runs_on_both_backends_without_max_step():
    # every unknown is algebraic after index reduction: the error test must keep them all
    # (otherwise the step grows unchecked over the sine), and the start needs consistent rates
    # of the algebraic variables (x' = A w at t = 0), without which SUNDIALS IDA fails its
    # first error tests down to h ~ 1e-9 and gives up
    m, A, f = 3.0, 0.01, 5.0
    w = 2.0 * math.pi * f
    c = Circuit("shaker")
    sine = c.add("sig", Sine(amplitude=A, f=f))
    pos = c.add("pos", PositionInput())
    mass = c.add("m", Mass(m=m))
    c.connect(sine.y, pos.u)
    c.connect(pos.flange, mass.flange)
    s = c.compile()
    assert not np.any(s.differential)
    t = np.linspace(0.01, 0.4, 40)
    for solver in ("pvgraph", "ida"):
        sol = simulate(s, 0.4, t_eval=t, rtol=1e-8, solver=solver)
        assert np.allclose(sol["m.flange.x"], A * np.sin(w * t), rtol=0, atol=1e-8 * A), solver
        assert np.allclose(sol["m.v"], A * w * np.cos(w * t), rtol=0, atol=1e-6 * A * w), solver
        assert np.allclose(-sol["pos.flange.f"], -m * A * w * w * np.sin(w * t), rtol=0,
                           atol=1e-5 * m * A * w * w), solver


@pytest.mark.parametrize("drive, warned", [
    (lambda: Step(height=0.01, t_step=0.1), "the event-switched mode sig.#after"),
    (lambda: Ramp(height=0.02, duration=0.2, t_start=0.1), "the event-switched modes sig.#ended, sig.#started"),
    (lambda: TimeTable(t=(0.0, 0.1, 0.3), y=(0.0, 0.0, 0.02), method="linear"),
     "the linear table 'sig"),
    (lambda: Sine(amplitude=0.01, f=5.0), None),
])
def test_a_position_source_driven_by_a_jumping_signal_warns_of_the_lost_impulse(drive, warned):
    """A step or a ramp on a position source makes the mass's position or velocity jump at the
    switch; index reduction takes the source's derivatives with the switch held, so the run
    re-initialises there and the force shows no impulse. The compiler says so; a smooth drive
    compiles without a word."""
    import warnings
    from pvgraph.errors import StructureWarning
    c = Circuit("drive")
    mass = c.add("mass", Mass(m=5.0))
    pos = c.add("pos", PositionInput())
    sig = c.add("sig", drive())
    c.connect(mass.flange, pos.flange)
    c.connect(sig.y, pos.u)
    if warned is None:
        with warnings.catch_warnings():
            warnings.simplefilter("error", StructureWarning)
            c.compile()
        return
    with pytest.warns(StructureWarning, match=rf"differentiates sig equation 1 .* twice, and it "
                                              rf"reads {warned}.*impulse"):
        c.compile()


@pytest.mark.parametrize("theta0", [0.1, 0.0])
def test_a_start_on_the_constrained_coordinate_moves_the_state_far_and_off_the_bottom(theta0):
    """Pendulum L = 1 m with x, vx as states: y0 = -0.5 given moves x to sqrt(1 - 0.25) (a
    move of 0.77 m from theta0 = 0.1, and from the bottom, where y does not move with x at
    first), energy from there on as for a release at 60 degrees."""
    c = Circuit("pendulum")
    c.add("p", Pendulum(theta0=theta0, L=1.0))
    s = c.compile()
    sol = simulate(s, 0.2, rtol=1e-9, start={"p.y": -0.5},
                   t_eval=np.array([0.0, 0.1, 0.2]))
    assert sol["p.y"][0] == pytest.approx(-0.5, abs=1e-9)
    assert sol["p.x"][0] == pytest.approx(math.sqrt(0.75), abs=1e-9)
    energy = 0.5 * (sol["p.vx"] ** 2 + sol["p.vy"] ** 2) + G * sol["p.y"]
    assert np.allclose(energy, -0.5 * G, atol=1e-6)


def test_calc_initial_all_moving_a_given_state_is_told():
    """calc_initial="all" computes every unknown from y' = 0, the states too: a pendulum
    started at x = 0.3 hangs at the bottom instead, and the user is told so."""
    from pvgraph.errors import StartValueWarning

    class Hanging(Pendulum):   # the link's tension starts at its value at rest, m g / L
        variables = {**Pendulum.variables,
                     "lam": Variable("N/m", lambda p: p.m * G / p.L, 10.0, "link tension")}
    c = Circuit("pendulum")
    c.add("p", Hanging(theta0=0.1))
    with pytest.warns(StartValueWarning, match=r"'p.x' \(0.3\) was not kept.*calc_initial='all'"):
        sol = simulate(c, 0.1, calc_initial="all", start={"p.x": 0.3})
    assert abs(sol["p.x"][0]) < 1e-6        # the rest position, as told
    kept = simulate(c, 0.1, start={"p.x": 0.3})
    assert kept["p.x"][0] == pytest.approx(0.3, abs=1e-12)


class LinkParams(Params):
    L: float = Field(1.0, gt=0.0, description="Link length [m]")


class Link(Component):
    """A pendulum written in its angle: bob coordinates x = L sin(phi), y = -L cos(phi)."""

    Params = LinkParams
    ports = {"shaft": Rotational("pivot"), "x": Mechanical("bob x"), "y": Mechanical("bob y")}

    def equations(self, v, p):
        phi = v.shaft.phi
        return [v.x.x - p.L * E.sin(phi), v.y.x + p.L * E.cos(phi),
                v.shaft.tau + v.x.f * p.L * E.cos(phi) + v.y.f * p.L * E.sin(phi)]


def _angle_pendulum(**bx):
    c = Circuit("pend")
    link = c.add("link", Link(L=1.0))
    bob_x = c.add("bx", Mass(m=1.0, **bx))
    bob_y = c.add("by", Mass(m=1.0, g=-G))
    hub = c.add("hub", Inertia(J=0.01))
    c.connect(link.shaft, hub.shaft)
    c.connect(link.x, bob_x.flange)
    c.connect(link.y, bob_y.flange)
    return c


def test_a_height_and_a_speed_given_together_at_the_bottom_are_met():
    """From phi = 0 (where the height does not move with the angle), y = -0.5 and vx = 1 give
    phi = pi/3 and w = vx / (L cos phi) = 2."""
    sol = simulate(_angle_pendulum(), 1e-4, start={"by.flange.x": -0.5, "bx.v": 1.0},
                   t_eval=np.array([0.0, 1e-4]))
    assert sol["hub.shaft.phi"][0] == pytest.approx(math.pi / 3, abs=1e-8)
    assert sol["hub.w"][0] == pytest.approx(2.0, abs=1e-8)


def test_a_speed_given_where_the_constraints_allow_none_is_refused():
    """Bob at x = L (horizontal): vx = L cos(phi) w = 0 whatever w; vx = 1 is met only by a
    speed growing without bound, and is refused instead of starting at thousands of rad/s."""
    with pytest.raises(InitializationError, match="can be met together only where the "
                                                  "constraints are singular"):
        simulate(_angle_pendulum(), 1e-4, start={"bx.flange.x": 1.0, "bx.v": 1.0})
    # 1 mrad below horizontal, swinging at 5 rad/s: consistent, and met
    phi = math.pi / 2 - 1e-3
    sol = simulate(_angle_pendulum(), 1e-4, t_eval=np.array([0.0, 1e-4]),
                   start={"bx.flange.x": math.sin(phi), "bx.v": 5.0 * math.cos(phi)})
    assert sol["hub.shaft.phi"][0] == pytest.approx(phi, abs=1e-8)
    assert sol["hub.w"][0] == pytest.approx(5.0, rel=1e-6)


def test_a_build_time_start_moved_by_simulate_start_is_told():
    """Lever i = 2 with Mass(v0=0.5) on A and start={"B.v": 3}: start= wins, A.v becomes 1.5,
    and a StartValueWarning names the build-time value it moved."""
    from pvgraph.components import Lever, LinearSpring
    from pvgraph.errors import StartValueWarning
    c = Circuit("lev")
    a = c.add("A", Mass(m=4.0, v0=0.5))
    lever = c.add("lev", Lever(i=2.0))
    b = c.add("B", Mass(m=2.0))
    spring = c.add("k", LinearSpring(k=1000.0))
    c.connect(a.flange, lever.a)
    c.connect(lever.b, b.flange, spring.flange)
    with pytest.warns(StartValueWarning, match=r"A.v from 0.5 to 1.5"):
        sol = simulate(c, 1e-3, start={"B.v": 3.0})
    assert sol["A.v"][0] == pytest.approx(1.5, abs=1e-9)


@pytest.mark.parametrize("how", ["start", "params"])
def test_a_run_starting_away_from_the_compiled_configuration_chooses_its_states_there(how):
    """The pivot watches are relative to the configuration where the states were chosen: a
    pendulum compiled hanging at 0.1 rad and started above the horizontal (y = 0.3, 1.875 rad:
    the pivot of the other sign, where no watch could fire), or compiled with a 20 m link and
    run with 1 m, first chooses its states at its start, then swings with the elliptic
    integral's period (x at the quarter periods to 2e-5), energy conserved."""
    if how == "start":
        c = Circuit("pendulum")
        c.add("p", Pendulum(theta0=0.1))
        y0 = 0.3
        th = math.atan2(math.sqrt(1.0 - y0 * y0), -y0)
        run = dict(start={"p.y": y0})
    else:
        c = Circuit("pendulum")
        c.add("p", Pendulum(theta0=1.8, L=20.0))
        th = 1.8
        run = dict(params={"p.L": 1.0})
    T = 4.0 * math.sqrt(1.0 / G) * ellipk(math.sin(th / 2.0) ** 2)
    t_eval = np.linspace(0.0, 2.0 * T, 9)
    sol = simulate(c.compile(), 2.0 * T, rtol=1e-8, t_eval=t_eval, **run)
    x0 = math.sin(th)
    assert sol["p.x"] == pytest.approx(np.tile([x0, 0.0, -x0, 0.0], 3)[:9], abs=2e-5)
    energy = 0.5 * (sol["p.vx"] ** 2 + sol["p.vy"] ** 2) + G * sol["p.y"]
    assert np.ptp(energy) < 2e-4


def test_events_after_the_last_output_time_still_fire_across_switches():
    """t_eval = [0, 0.1] on a pendulum from 1.8 rad that switches its states: the run goes on
    to t_end, and an event counting the passes through the bottom (x = 0) fires at
    T/4 + k T/2 as without t_eval."""
    class Counted(Pendulum):
        def equations(self, v, p):
            v.event("bottom", v.x)
            return super().equations(v, p)
    c = Circuit("pendulum")
    c.add("p", Counted(theta0=1.8))
    T = 4.0 * math.sqrt(1.0 / G) * ellipk(math.sin(0.9) ** 2)
    sol = simulate(c, 1.6 * T, rtol=1e-8, t_eval=[0.0, 0.1])
    crossings = [r.t for r in sol.events if r.name.endswith("bottom")]
    assert crossings == pytest.approx([T / 4, 3 * T / 4, 5 * T / 4], abs=1e-4)
    assert not any(r.name.startswith("index_reduction.") for r in sol.events)
    assert list(sol.t) == [0.0, 0.1]


def test_a_slider_crank_with_angles_in_radians_chooses_its_states():
    """Crank (J = 1, angle phi in rad), rod (Jb = 0.01, angle beta in rad) and slider
    (m = 1, x in m), joined by r cos phi + l cos beta = x and r sin phi = l sin beta with
    multipliers (index 3), coasting from phi = pi/2 at 10 rad/s. The preferences that keep
    angles as states spread the columns of the hidden constraints over ten decades, and the
    regular block they chose was refused as singular. Reference: the one-degree-of-freedom
    energy equation phi' = sqrt(2 E / M(phi)), M = J + Jb beta_phi^2 + m x_phi^2, by
    DOP853 at rtol 1e-13, through two dead centres."""
    from scipy.integrate import solve_ivp
    from pvgraph import expr as E
    J, Jb, m, r, l, w0, phi0 = 1.0, 0.01, 1.0, 0.5, 1.0, 10.0, math.pi / 2

    def kin(phi):
        beta = math.asin(r * math.sin(phi) / l)
        db = r * math.cos(phi) / (l * math.cos(beta))
        return beta, db, -r * math.sin(phi) - l * math.sin(beta) * db
    b0, db0, dx0 = kin(phi0)
    energy = 0.5 * (J + Jb * db0 ** 2 + m * dx0 ** 2) * w0 ** 2

    class SliderCrank(Component):
        Params = Params
        variables = {"phi": Variable("rad", phi0), "beta": Variable("rad", b0),
                     "x": Variable("m", r * math.cos(phi0) + l * math.cos(b0)),
                     "w": Variable("rad/s", w0), "wb": Variable("rad/s", db0 * w0),
                     "vx": Variable("m/s", dx0 * w0), "lam1": Variable("N", 0.0),
                     "lam2": Variable("N", 0.0)}

        def equations(self, v, p):
            return [der(v.phi) - v.w, der(v.beta) - v.wb, der(v.x) - v.vx,
                    J * der(v.w) - r * E.sin(v.phi) * v.lam1 + r * E.cos(v.phi) * v.lam2,
                    Jb * der(v.wb) - l * E.sin(v.beta) * v.lam1 - l * E.cos(v.beta) * v.lam2,
                    m * der(v.vx) - v.lam1,
                    r * E.cos(v.phi) + l * E.cos(v.beta) - v.x,
                    r * E.sin(v.phi) - l * E.sin(v.beta)]
    c = Circuit("crank")
    c.add("s", SliderCrank())
    system = c.compile()
    assert [n for n, d in zip(system.names, system.differential) if d] == ["s.phi", "s.w"]
    ref = solve_ivp(lambda t, s: [math.sqrt(2 * energy / (J + Jb * kin(s[0])[1] ** 2 +
                                                           m * kin(s[0])[2] ** 2))],
                    (0.0, 1.0), [phi0], rtol=1e-13, atol=1e-13, method="DOP853")
    sol = simulate(system, 1.0, rtol=1e-8, atol=1e-8)
    assert sol["s.phi"][-1] > 2 * math.pi + phi0      # past two dead centres
    assert sol["s.phi"][-1] == pytest.approx(ref.y[0, -1], abs=1e-4)
    kinetic = 0.5 * (J * sol["s.w"] ** 2 + Jb * sol["s.wb"] ** 2 + m * sol["s.vx"] ** 2)
    assert np.max(np.abs(kinetic - energy)) < 1e-4 * energy


def test_a_quadruple_pendulum_chooses_its_states_again_through_the_bottom():
    """Four unit masses on four unit rigid links in Cartesian coordinates (index 3), released
    at rest with every link at 1.2 rad. Its position-level pivot block is 4 x 4, and blocks
    above 3 were not watched: the start's states (the heights) were kept where a link
    passes the vertical, and the run lost 26 J of its 35.5 with success. The block is
    watched now: the states are chosen again there and the energy holds to the tolerance."""
    n, g, th0 = 4, 9.81, 1.2
    xs = np.cumsum(np.full(n, math.sin(th0)))
    ys = -np.cumsum(np.full(n, math.cos(th0)))

    class Chain(Component):
        Params = Params
        variables = {**{f"x{i}": Variable("m", float(xs[i])) for i in range(n)},
                     **{f"y{i}": Variable("m", float(ys[i])) for i in range(n)},
                     **{f"u{i}": Variable("m/s", 0.0) for i in range(n)},
                     **{f"v{i}": Variable("m/s", 0.0) for i in range(n)},
                     **{f"l{i}": Variable("", 10.0) for i in range(n)}}

        def equations(self, v, p):
            x, y, u, w, lam = ([getattr(v, f"{k}{i}") for i in range(n)]
                               for k in ("x", "y", "u", "v", "l"))
            dx = [x[0]] + [x[i] - x[i - 1] for i in range(1, n)]
            dy = [y[0]] + [y[i] - y[i - 1] for i in range(1, n)]
            eqs = [der(x[i]) - u[i] for i in range(n)] + [der(y[i]) - w[i] for i in range(n)]
            for i in range(n):
                fx = -lam[i] * dx[i] + (lam[i + 1] * dx[i + 1] if i + 1 < n else 0.0)
                fy = -lam[i] * dy[i] + (lam[i + 1] * dy[i + 1] if i + 1 < n else 0.0)
                eqs += [der(u[i]) - fx, der(w[i]) - fy + g]
            return eqs + [dx[i] * dx[i] + dy[i] * dy[i] - 1.0 for i in range(n)]
    c = Circuit("chain")
    c.add("p", Chain())
    sol = simulate(c.compile(), 3.0, rtol=1e-6)
    assert sol.t[-1] == pytest.approx(3.0)
    assert len(sol.stats.get("state_switches", [])) >= 2
    energy = sum(0.5 * (sol[f"p.u{i}"] ** 2 + sol[f"p.v{i}"] ** 2) + g * sol[f"p.y{i}"]
                 for i in range(n))
    assert np.max(np.abs(energy - g * ys.sum())) < 0.02       # of |E0| = 35.5 J
