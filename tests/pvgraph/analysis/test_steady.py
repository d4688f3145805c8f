"""Steady operating points: Newton, continuation, and errors that name the culprits."""

import sys
from pathlib import Path

import numpy as np
import pytest

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit, Component, Variable, der
from pvgraph.analysis import steady_state
from pvgraph.analysis.steady import _newton, _Scaled
from pvgraph.errors import InitializationError
from pvgraph.units import bar, mm2

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_compiler import K, Q, V, demo  # noqa: E402


def test_laminar_demo_is_exact():
    s = demo().compile()
    op = steady_state(s)
    assert op.method == "newton"
    assert op["node.port.p"] == pytest.approx(Q / K, rel=1e-12)
    assert op["orifice.b.p"] == 0.0 and np.all(op.yp == 0.0)


def test_turbulent_orifice():
    Cd, A, rho = 0.6, mm2(2.0), 870.0
    s = demo(Orifice(A=A, Cd=Cd, rho=rho, dp_t=bar(0.05))).compile()
    op = steady_state(s)
    p_ss = rho / 2 * (Q / (Cd * A)) ** 2
    assert op["node.port.p"] == pytest.approx(p_ss, rel=5e-3)  # regularisation error
    assert op["orifice.a.q"] == pytest.approx(Q, rel=1e-9)
    assert op.residual_norm <= 1e-9


class Cubic(Component):
    """x' = -(x^3 - 2x + 2): Newton from 0 cycles/stalls, the dynamics reach x = -1.769."""

    variables = {"x": Variable("1", 0.0, 1.0, "state")}

    def equations(self, v, p):
        return [der(v.x) + v.x * v.x * v.x - 2.0 * v.x + 2.0]


def test_continuation_rescues_newton():
    c = Circuit("cubic")
    c.add("c", Cubic())
    s = c.compile()
    sc = _Scaled(s, 0.0, s.y0)
    assert not _newton(sc, s.y0.copy(), 1e-9, 50)[3]  # plain (damped) Newton stalls
    op = steady_state(s)
    assert op.method == "continuation"
    root = np.roots([1.0, 0.0, -2.0, 2.0])
    assert op["c.x"] == pytest.approx(root[np.isreal(root)].real[0], rel=1e-9)


def test_no_steady_state_names_the_volume():
    c = Circuit("closed")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V=V))
    c.connect(pump.port, node.port)
    with pytest.raises(InitializationError) as err:
        steady_state(c.compile())
    msg = str(err.value)
    assert "node" in msg and "node.port.p" in msg and "VolumeNode" in msg


def test_pvg32_rig_needs_continuation_from_rest():
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig
    s = build_rig(report_tuned(), U_input=4.29).compile()
    op = steady_state(s)
    r = s.residual(0.0, op.y, op.yp)
    assert np.all(np.isfinite(r)) and op.residual_norm <= 1e-9
    assert op["pvg.pvb.main_spool.flange.x"] == pytest.approx(-3.46e-3, rel=0.02)


def test_operating_point_gives_derived_outputs():
    """``op[name]`` also reads outputs declared with ``v.observe`` (here the rig's L3 flow), which
    must equal the laminar law K_L3 (Pf - Pb) at the same point."""
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig
    p = report_tuned()
    op = steady_state(build_rig(p, U_input=4.29).compile())
    assert "load.L3.q" in op.system.observed
    dp = op["load.f.port.p"] - op["load.b.port.p"]
    assert op["load.L3.q"] == pytest.approx(p.rig.L3.laminar_small * dp, rel=1e-9)


def test_a_long_chain_solves_sparse_to_the_orifice_law():
    # 400 volume + orifice pairs (800 unknowns, above the dense limit): each orifice drops
    # rho/2 (Q / (Cd A))^2, so node k sits at (N - k) times that; a dense Newton took seconds
    from pvgraph import Circuit
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    N, Q, A = 400, 1e-4, 20e-6
    c = Circuit("chain")
    prev = c.add("pump", FlowSource(Q=Q)).port
    for k in range(N):
        v = c.add(f"v{k}", VolumeNode(V=1e-4))
        o = c.add(f"o{k}", Orifice(A=A, dp_t=100.0))
        c.connect(prev, v.port, o.a)
        prev = o.b
    c.connect(prev, c.add("tank", Tank()).port)
    system = c.compile()
    assert system.n > system.DENSE_MAX
    op = steady_state(system)
    o0 = c["o0"].params
    dp = o0.rho / 2.0 * (Q / (o0.Cd * A)) ** 2            # turbulent: dp >> dp_t
    p = np.array([op[f"v{k}.port.p"] for k in range(N)])
    # the law's smooth laminar-turbulent transition (dp_t = 100 Pa) shifts it by 5.5e-6
    assert np.allclose(p, (N - np.arange(N)) * dp, rtol=2e-5, atol=0)
    assert np.allclose(np.diff(p), np.diff(p).mean(), rtol=1e-9)     # every drop the same


@pytest.mark.parametrize("kwargs, match", [
    ({"tol": -1.0}, r"tol must lie in \(0, 1\)"), ({"tol": float("nan")}, "tol must lie"),
    ({"max_iter": 0}, "max_iter must be a positive integer"),
    ({"t": float("nan")}, "t must be a finite time"),
    ({"params": ["orifice.A"]}, "params must be a mapping"),
])
def test_bad_options_of_steady_state_are_named(kwargs, match):
    from pvgraph.errors import PvgraphError
    from pvgraph.analysis import steady_state
    c = Circuit("demo")
    pump, node = c.add("pump", FlowSource(Q=1e-4)), c.add("node", VolumeNode(V=5e-4))
    orifice, tank = c.add("orifice", Orifice(A=2e-6)), c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    with pytest.raises(PvgraphError, match=match):
        steady_state(c.compile(), **kwargs)


def test_unknowns_no_steady_equation_reads_are_named():
    """A free 10 kg mass at rest: v = 0 is steady at every x, so x keeps its start value and
    the operating point says it is undetermined; a mass on a spring is determined."""
    from pvgraph.components import Free, LinearSpring, Mass
    c = Circuit("free")
    mass = c.add("m", Mass(m=10.0, x0=0.3))
    free = c.add("free", Free())
    c.connect(mass.flange, free.flange)
    op = steady_state(c.compile())
    assert op["m.flange.x"] == 0.3 and op["m.v"] == 0.0
    assert op.info["undetermined"] == ["m.flange.x"]
    c = Circuit("sprung")
    mass = c.add("m", Mass(m=10.0, x0=0.3))
    spring = c.add("k", LinearSpring(k=100.0, F0=5.0))
    c.connect(mass.flange, spring.flange)
    op = steady_state(c.compile())
    assert "undetermined" not in op.info


@pytest.mark.parametrize("back", [20e5, 50e5, 100e5])
def test_a_row_scaled_at_a_closed_valve_is_scaled_again_where_newton_stops(back):
    """A flow source into a check valve against a back-pressure, no volume: at the start the
    valve is closed and its flow row is scaled by the leakage's slope, 1e7 times smaller than
    at the answer, so the residual's rounding read as 8e-9 > tol. Scaled again at the answer
    it converges: dp = rho/2 (Q/(Cd A))^2 = 3.3565 bar for 10 L/min through 10 mm^2."""
    from pvgraph.components import CheckValve, PressureSource
    Q, A = 10 / 60000, 10e-6
    c = Circuit("ck")
    src = c.add("src", FlowSource(Q=Q))
    ck = c.add("ck", CheckValve(A=A, p_crack=1e5))
    end = c.add("end", PressureSource(p0=back))
    c.connect(src.port, ck.a)
    c.connect(ck.b, end.port)
    op = steady_state(c.compile())
    assert op["ck.a.p"] - back == pytest.approx(870.0 / 2 * (Q / (0.6 * A)) ** 2, rel=1e-4)


@pytest.mark.parametrize("g", [2.0, -2.0])
def test_an_unstable_steady_state_is_told_with_its_pole(g):
    """y' = k g y (an integrator, k = 1.5, fed back through a gain g): the steady state y = 0
    has the pole k g; at +3 1/s a simulation runs away from it, and steady_state says so."""
    import warnings as w

    from pvgraph.components.signal import Gain, Integrator
    from pvgraph.errors import PlausibilityWarning
    c = Circuit("loop")
    integ = c.add("i", Integrator(k=1.5))
    gain = c.add("g", Gain(k=g))
    c.connect(integ.y, gain.u)
    c.connect(gain.y, integ.u)
    with w.catch_warnings(record=True) as seen:
        w.simplefilter("always")
        op = steady_state(c.compile())
    told = [str(x.message) for x in seen if issubclass(x.category, PlausibilityWarning)]
    assert abs(op["i.y"]) < 1e-12
    np.testing.assert_allclose(op.poles(), [1.5 * g], rtol=1e-12)
    if g > 0:
        assert len(told) == 1 and "unstable (pole 3 1/s: a departure that grows with time " \
            "constant 0.333 s" in told[0]
    else:
        assert not told


def test_a_circuit_without_states_has_no_poles():
    """A pressure source through an orifice to the tank: every unknown fixed, no pole."""
    from pvgraph.components import PressureSource
    c = Circuit("fixed")
    src = c.add("src", PressureSource(p0=bar(10)))
    ori = c.add("o", Orifice(A=mm2(1.0)))
    tank = c.add("tank", Tank())
    c.connect(src.port, ori.a)
    c.connect(ori.b, tank.port)
    op = steady_state(c.compile())
    assert op.poles().shape == (0,)


def test_sensitivity_holds_an_undetermined_position_where_it_is():
    """A 50 kg mass pressed with 10 kN onto a closed oil column (10 cm^2): its position is
    free (steady_state names it), the pressure F / A is not: dp/dA = -F / A^2 and dp/dF =
    1 / A exactly, where the singular F_y raised numpy's 'Singular matrix'."""
    import warnings

    from pvgraph import Circuit
    from pvgraph.analysis import steady_state
    from pvgraph.components import Constant, ForceInput, Mass, PistonChamber, Plug
    A, F = 1e-3, 1e4
    c = Circuit("held")
    c.add("ch", PistonChamber(A=A, V0=1e-4, p0=F / A))
    c.add("plug", Plug())
    c.add("mass", Mass(m=50.0, b=2000.0))
    c.add("force", ForceInput())
    c.add("k", Constant(k=-F))
    c.connect("ch.port", "plug.port")
    c.connect("ch.flange", "mass.flange", "force.flange")
    c.connect("k.y", "force.u")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        op = steady_state(c.compile())
    assert op.info["undetermined"] == ["mass.flange.x"]
    got = op.sensitivity(["ch.port.p"], ["ch.A", "k.k"])[0]
    assert got == pytest.approx([-F / A ** 2, -1.0 / A], rel=1e-9)
