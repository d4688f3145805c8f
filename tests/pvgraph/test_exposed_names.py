"""Names through exposed ports: ``valve.P.p`` where the sub-circuit ``valve`` exposes an inner
port as ``P`` is a valid name in every lookup, with exactly the values of the inner variable.

The bench: a flow source feeds ``valve.P``; inside ``valve`` a sub-circuit ``core`` holds a
volume and an orifice to ``T`` (exposed twice: ``core.a`` -> ``valve.P``), and a mass on a
preloaded spring exposed as the mechanical port ``spool``. Steady state: the orifice law
``p = rho/2 (Q / (Cd A))^2`` and the spring balance ``x = -F0 / k``.
"""

import numpy as np
import pytest

from pvgraph import Circuit
from pvgraph.simulate import simulate
from pvgraph.analysis import linearize_circuit, steady_state
from pvgraph.analysis.power import hydraulic_ports
from pvgraph.analysis.sweep import CompiledRun, grid, sweep
from pvgraph.components import FlowSource, LinearSpring, Mass, Orifice, Tank, VolumeNode

RHO, CD, BETA = 870.0, 0.6, 7e8          # the default oil and discharge coefficient; the orifice law is
                                          # regularised near zero flow (1e-7 relative here)
Q, A, V = 10 / 60e3, 2e-6, 0.5e-3         # [m^3/s], [m^2], [m^3]
K, F0 = 2e4, -100.0                       # [N/m], [N] (negative: tension, pulls to +x)


def _p_steady(q=Q):
    return RHO / 2 * (q / (CD * A)) ** 2


def build(q=Q) -> Circuit:
    core = Circuit("core")
    node = core.add("node", VolumeNode(V=V))
    edge = core.add("edge", Orifice(A=A))
    core.connect(node.port, edge.a)
    core.expose("a", edge.a, "inlet")
    core.expose("b", edge.b, "outlet")
    valve = Circuit("valve")
    inner = valve.add("core", core)
    body = valve.add("body", Mass(m=0.05, b=40.0))
    spring = valve.add("spring", LinearSpring(k=K, F0=F0))
    valve.connect(body.flange, spring.flange)
    valve.expose("P", inner.a, "pressure port")
    valve.expose("T", inner.b, "tank port")
    valve.expose("spool", body.flange, "the moving body")
    rig = Circuit("rig")
    pump = rig.add("pump", FlowSource(Q=q))
    v = rig.add("valve", valve)
    tank = rig.add("tank", Tank())
    rig.connect(pump.port, v.P)
    rig.connect(v.T, tank.port)
    return rig


EXPOSED = {"valve.P.p": "valve.core.edge.a.p", "valve.core.a.p": "valve.core.edge.a.p",
           "valve.T.q": "valve.core.edge.b.q", "valve.spool.x": "valve.body.flange.x"}


@pytest.fixture(scope="module")
def system():
    return build().compile()


@pytest.fixture(scope="module")
def sol(system):
    return simulate(system, 0.5, rtol=1e-7)


def test_exposed_names_resolve_to_the_inner_variables(system):
    names = system.exposed_names()
    for alias, real in EXPOSED.items():
        assert names[alias] == real
        assert system.resolve_name(alias) == real
        assert system.unit(alias) == system.unit(real)
    assert system.resolve_name("valve.core.edge.a.p") == "valve.core.edge.a.p"
    # all_names() lists each variable once, by its canonical name
    canonical = system.all_names()
    assert len(canonical) == len(set(canonical))
    assert not set(names) & set(canonical)


def test_solution_lookups_through_exposed_names_are_exact(sol):
    for alias, real in EXPOSED.items():
        assert np.array_equal(sol[alias], sol[real])
        assert np.array_equal(sol.der(alias), sol.der(real))
        assert alias in sol
    assert sol.final("valve.P.p") == pytest.approx(_p_steady(), rel=2e-3)
    # the spool, released at x = 0, settles at the spring balance x = -F0/k
    assert sol.final("valve.spool.x") == pytest.approx(-F0 / K, rel=1e-3)
    assert sol.final("valve.spool.f") == pytest.approx(0.0, abs=1e-3 * abs(F0))


def test_the_flow_through_an_exposed_port_is_the_flow_across_the_boundary(system, sol):
    # valve.P stands for a node of two inner ports (the volume and the orifice's inlet): its
    # flow is their sum, what the pump delivers into the valve, not the inlet's alone
    assert "valve.P.q" not in system.exposed_names() and "valve.P.q" in system.observed
    for name in ("valve.P.q", "valve.core.a.q"):
        assert np.allclose(sol[name], sol["valve.core.node.port.q"] + sol["valve.core.edge.a.q"],
                           rtol=1e-12, atol=0)
        assert np.allclose(sol[name], -sol["pump.port.q"], rtol=1e-9, atol=1e-15)
        assert system.unit(name) == "m^3/s"
    # valve.T is one inner port, an alias: -Q once the volume has charged (t = 0.5 s: 3.5e-4)
    assert sol.final("valve.T.q") == pytest.approx(-Q, rel=1e-3)
    # valve.spool joins the body and the spring: no force across its boundary
    assert np.allclose(sol["valve.spool.f"], 0.0, atol=1e-9 * abs(F0))


def test_power_accounting_lists_each_port_once(sol):
    """The walk over all_names() sees the orifice's own ports, not the exposed ones again."""
    assert hydraulic_ports(sol, "valve.core.edge") == ["a", "b"]
    with pytest.raises(KeyError):
        hydraulic_ports(sol, "valve")         # a sub-circuit is not a component with ports


def test_misspelled_exposed_name_suggests_it(system, sol):
    with pytest.raises(KeyError, match=r"valve\.P\.p'"):
        sol["valve.P.pp"]
    assert "valve.spool.x" in system.close_names("valve.spool.xx")
    with pytest.raises(KeyError, match=r"valve\.spool\.x'"):
        system.resolve_name("valve.spool.xx")
    # a port (exposed or not) named without its variable lists the variables under it
    with pytest.raises(KeyError, match=r"'valve\.P' is a component or a port, not a variable; "
                                       r"the names under it: valve\.P\.p, valve\.P\.q\."):
        sol["valve.P"]


def test_steady_state_start_values_and_sensitivities_take_exposed_names(system):
    op = steady_state(system)
    assert op["valve.P.p"] == op["valve.core.edge.a.p"] == pytest.approx(_p_steady(), rel=1e-6)
    assert op["valve.spool.x"] == pytest.approx(-F0 / K, rel=1e-9)
    # d p / d A of the orifice law: -2 p / A
    sens = op.sensitivity(["valve.P.p"], ["valve.core.edge.A"])
    assert sens[0, 0] == pytest.approx(-2 * _p_steady() / A, rel=1e-6)
    sol = simulate(system, 1e-3, start={"valve.spool.x": 2e-3})
    assert sol["valve.body.flange.x"][0] == 2e-3


def test_linearize_with_exposed_output_names(system):
    def bench(u):
        return build(q=u["pump.Q"])
    op = steady_state(system)
    lm = linearize_circuit(bench, {"pump.Q": Q}, ["valve.P.p", "valve.spool.x"], op=op)
    ref = linearize_circuit(bench, {"pump.Q": Q}, ["valve.core.edge.a.p",
                                                   "valve.body.flange.x"], op=op)
    assert np.array_equal(lm.C, ref.C) and np.array_equal(lm.D, ref.D)
    p = _p_steady()
    gain = lm.dc_gain()
    assert gain[0, 0] == pytest.approx(2 * p / Q, rel=1e-4)          # orifice law
    assert gain[1, 0] == pytest.approx(0.0, abs=1e-12)               # the spool ignores Q
    # the node's pole: -(beta / V) dq/dp = -(beta / V) Q / (2 p)
    poles = lm.poles()
    node_pole = -(BETA / V) * Q / (2 * p)
    assert min(abs(poles - node_pole)) == pytest.approx(0.0, abs=1e-4 * abs(node_pole))
    # the model answers to either name of an output
    assert lm.tf("valve.core.edge.a.p")[0] == pytest.approx(lm.tf("valve.P.p")[0])
    with pytest.raises(KeyError, match="no output named"):
        lm.tf("valve.T.p")


def test_sweep_outputs_through_exposed_names():
    run = CompiledRun(build, outputs={"p": "valve.P.p", "p_inner": "valve.core.edge.a.p"},
                      steady=True)
    result = sweep(run, grid({"pump.Q": [Q, 2 * Q]}), backend="serial")
    assert all(r.ok for r in result)
    assert np.array_equal(result.column("p"), result.column("p_inner"))
    assert result.column("p") == pytest.approx([_p_steady(Q), _p_steady(2 * Q)], rel=1e-6)


def test_a_system_without_a_circuit_has_no_exposed_names(system):
    bare = system._copy()
    bare._circuit = None
    bare._lazy = {}
    assert bare.exposed_names() == {}
    with pytest.raises(KeyError):
        bare.resolve_name("valve.P.p")
