"""The graph compiler: assembly, alias elimination, structural checks and their messages."""

import numpy as np
import pytest

from pvgraph.components import FlowSource, LaminarOrifice, Orifice, Plug, Tank, VolumeNode
from pvgraph import Circuit, Component, Hydraulic, Mechanical, SignalIn, SignalOut, Variable
from pvgraph.errors import (CircuitError, ConnectionError_, ParameterError, PvgraphError,
                            StructureError)
from pvgraph.units import bar, litre, lpm, lpm_per_bar, mm2

Q = lpm(10.0)
K = lpm_per_bar(0.5)
V = litre(0.5)
BETA = 7e8


def demo(orifice=None):
    """The README circuit: a pump feeding a volume node that drains to tank through an orifice."""
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V=V))
    orf = c.add("orifice", orifice or LaminarOrifice(K=K))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    return c


def fd_jacobian(system, t, y, yp, c, h=1e-7):
    n = system.n
    J = np.zeros((n, n))
    for j in range(n):
        for vec, weight in ((y, 1.0), (yp, c)):
            step = h * max(1.0, abs(vec[j]))
            up, dn = vec.copy(), vec.copy()
            up[j] += step
            dn[j] -= step
            if vec is y:
                col = (system.residual(t, up, yp) - system.residual(t, dn, yp)) / (2 * step)
            else:
                col = (system.residual(t, y, up) - system.residual(t, y, dn)) / (2 * step)
            J[:, j] += weight * col
    return J


def set_value(system, y, name, value):
    """Write ``value`` of variable ``name`` into ``y``, whichever alias survived."""
    coef, idx, off = system.resolve(name)
    if idx is not None:
        y[idx] = (value - off) / coef


def test_demo_laminar_reduces_to_one_state():
    s = demo().compile()
    # the laminar law is affine, so alias elimination leaves only the node pressure
    assert s.names == ["node.port.p"]
    y = np.array([Q / K])  # analytic steady state of a laminar drain
    assert abs(s.residual(0.0, y, np.zeros(1))[0]) < 1e-12 * V / BETA * 1e6
    # away from steady state the pressure rises at beta*(Q - K p)/V
    y = np.array([0.5 * Q / K])
    yp = np.array([BETA * (Q - 0.5 * Q) / V])
    assert abs(s.residual(0.0, y, yp)[0]) < 1e-18


def test_demo_turbulent_residual_and_jacobian():
    Cd, A, rho = 0.6, mm2(2.0), 870.0
    s = demo(Orifice(A=A, Cd=Cd, rho=rho, dp_t=bar(0.05))).compile()
    assert s.n == 2 and int(s.differential.sum()) == 1
    p_ss = rho / 2 * (Q / (Cd * A)) ** 2  # turbulent steady state, far above dp_t
    y = s.y0.copy()
    set_value(s, y, "node.port.p", p_ss)
    set_value(s, y, "orifice.a.q", Q)
    r = s.residual(0.0, y, np.zeros(s.n))
    assert abs(r[0]) < 1e-12 and abs(r[1]) < 2e-3 * Q  # 0.3 % regularisation error at 50 dp_t
    rng = np.random.default_rng(1)
    for _ in range(5):
        y = rng.normal(size=s.n) * s.nominal
        yp = rng.normal(size=s.n) * s.nominal
        J = s.jacobian_dense(0.0, y, yp, 3e3)
        assert np.allclose(J, fd_jacobian(s, 0.0, y, yp, 3e3), rtol=1e-5, atol=1e-14)


def test_every_variable_is_addressable_after_alias_elimination():
    s = demo().compile()
    for name in ("pump.port.p", "orifice.a.p", "orifice.b.p", "tank.port.p", "orifice.b.q",
                 "pump.port.q", "node.port.q"):
        coef, idx, off = s.resolve(name)
        assert np.isfinite(coef) and np.isfinite(off)
    assert s.resolve("tank.port.p") == (0.0, None, 0.0)
    assert s.resolve("pump.port.q") == (0.0, None, pytest.approx(-Q))
    with pytest.raises(KeyError, match="orifice.a.p"):
        s.resolve("orifice.a.pp")


def test_jacobian_pattern_and_sparse_form_agree():
    s = demo(Orifice(A=mm2(2))).compile()
    y = np.array([bar(12.0), 1e-4])[: s.n]
    yp = np.zeros(s.n)
    dense = s.jacobian_dense(0.0, y, yp, 10.0)
    assert np.allclose(s.jacobian(0.0, y, yp, 10.0).toarray(), dense)
    assert s.jac_sparsity.nnz == len(s._rows)


def test_generated_source_is_readable():
    system = demo(Orifice(A=mm2(2))).compile()
    src = system.source()
    assert "def residual(t, y, yp, d, P):" in src
    k = system.parameter_names.index("orifice.A")
    assert f"# P[{k}] = orifice.A [m^2]" in src
    # parametric subexpressions are computed once per parameter set, in derive()
    assert f"P[{k}]" in src.split("def derive")[1].split("def residual")[0]
    assert "orifice equation 1 (Orifice)" in src


# errors --------------------------------------------------------------------------------------

def test_unconnected_port_is_named():
    c = Circuit("c")
    a = c.add("a", LaminarOrifice(K=K))
    t = c.add("tank", Tank())
    c.connect(a.a, t.port)
    with pytest.raises(CircuitError, match=r"port 'a\.b' \(hydraulic\) is not connected"):
        c.compile()


def test_misspelled_port_suggests_the_right_one():
    c = Circuit("c")
    a = c.add("orifice", LaminarOrifice(K=K))
    with pytest.raises(AttributeError, match="did you mean 'a'|Did you mean 'a'"):
        a.aa  # noqa: B018


def test_incompatible_domains_are_refused():
    class Rod(Component):
        ports = {"flange": Mechanical("rod end")}

        def equations(self, v, p):
            return [v.flange.f]

    c = Circuit("c")
    a = c.add("orifice", LaminarOrifice(K=K))
    r = c.add("rod", Rod())
    t = c.add("tank", Tank())
    c.connect(a.b, t.port)
    with pytest.raises(ConnectionError_, match=r"orifice\.a \(hydraulic\).*rod\.flange "
                                               r"\(mechanical\)"):
        c.connect(a.a, r.flange)



class Source(Component):
    ports = {"y": SignalOut("value")}

    def equations(self, v, p):
        return [v.y - 1.0]


class Sink(Component):
    ports = {"u": SignalIn("value")}
    variables = {"z": Variable()}

    def equations(self, v, p):
        return [v.z - v.u]


def test_two_outputs_driving_one_input():
    c = Circuit("c")
    s1, s2, k = c.add("s1", Source()), c.add("s2", Source()), c.add("k", Sink())
    c.connect(s1.y, s2.y, k.u)
    with pytest.raises(ConnectionError_, match=r"\['s1\.y', 's2\.y'\] drive one connection"):
        c.compile()


def test_undriven_input():
    c = Circuit("c")
    c.add("k", Sink())
    with pytest.raises(CircuitError, match=r"\['k\.u'\] are not driven"):
        c.compile()


def test_duplicate_names_and_reuse():
    c = Circuit("c")
    orf = c.add("a", LaminarOrifice(K=K))
    with pytest.raises(CircuitError, match="already has a component named 'a'"):
        c.add("a", LaminarOrifice(K=K))
    with pytest.raises(CircuitError, match="already part of a circuit"):
        Circuit("d").add("x", orf)
    with pytest.raises(CircuitError, match="not a valid identifier"):
        c.add("my orifice", LaminarOrifice(K=K))


def test_bad_parameters_name_the_field():
    with pytest.raises(ParameterError, match=r"K = nan"):
        LaminarOrifice(K=float("nan"))
    with pytest.raises(ParameterError, match=r"A = -1e-06.*greater than 0"):
        Orifice(A=-mm2(1))
    with pytest.raises(ParameterError, match=r"Kx = 1.0: not a parameter of LaminarOrifice; "
                                             r"did you mean 'K'\? it accepts K"):
        LaminarOrifice(Kx=1.0)
    with pytest.raises(ParameterError, match=r"\bK: required parameter not given"):
        LaminarOrifice()


def test_unbalanced_system_names_the_surplus():
    class Floating(Component):
        """A component with a variable no equation determines."""
        ports = {"port": Hydraulic()}
        variables = {"lost": Variable(description="a forgotten variable")}

        def equations(self, v, p):
            return [v.port.q]

    c = demo()
    c.add("floating", Floating())
    c.connect("floating.port", "tank.port")
    with pytest.raises(StructureError, match=r"(?s)equations for .* unknowns.*floating\.lost"):
        c.compile()


def test_flow_sources_in_series_are_refused_with_names():
    c = Circuit("c")
    s1 = c.add("pump1", FlowSource(Q=Q))
    s2 = c.add("pump2", FlowSource(Q=-Q))
    c.connect(s1.port, s2.port)
    with pytest.raises(StructureError, match=r"pump1\.port, pump2\.port.*(repeats|contradicts)"):
        c.compile()


def test_two_tanks_on_one_node_are_refused():
    c = Circuit("c")
    t1, t2 = c.add("t1", Tank()), c.add("t2", Tank(p0=bar(1)))
    c.connect(t1.port, t2.port)
    with pytest.raises(StructureError, match="contradicts"):
        c.compile()


def test_structurally_singular_block_is_named():
    class TwoEquationsOneVariable(Component):
        ports = {"a": Hydraulic(), "b": Hydraulic()}
        variables = {"s": Variable()}

        def equations(self, v, p):
            # both equations fix the pressure drop; none fixes the flow
            return [v.a.p - v.b.p - v.s * v.s, (v.a.p - v.b.p) * 2.0 - v.s * v.s * 2.0 + 0.0 * v.a.q,
                    v.a.q + v.b.q]

    c = Circuit("c")
    src = c.add("src", FlowSource(Q=Q))
    x = c.add("x", TwoEquationsOneVariable())
    node = c.add("node", VolumeNode(V=V))
    t = c.add("tank", Tank())
    c.connect(src.port, node.port, x.a)
    c.connect(x.b, t.port)
    with pytest.raises(StructureError) as info:
        c.compile()
    assert "x equation" in str(info.value) or "node" in str(info.value)


def test_errors_share_one_base_class():
    for cls in (CircuitError, ConnectionError_, ParameterError, StructureError):
        assert issubclass(cls, PvgraphError)


# hierarchy -----------------------------------------------------------------------------------

def restriction_module(name):
    """Two laminar orifices in series with a volume between them, exposed as ports a and b."""
    m = Circuit(name)
    r1 = m.add("r1", LaminarOrifice(K=2 * K))
    r2 = m.add("r2", LaminarOrifice(K=2 * K))
    mid = m.add("mid", VolumeNode(V=litre(0.01)))
    m.connect(r1.b, r2.a, mid.port)
    m.expose("a", r1.a)
    m.expose("b", r2.b)
    return m


def test_four_level_hierarchy_compiles_with_dotted_names():
    inner = restriction_module("compensator")
    pvb = Circuit("pvb")
    pvb.add("compensator", inner)
    pvb.expose("P", inner.a)
    pvb.expose("T", inner.b)
    pvg = Circuit("pvg")
    pvg.add("pvb", pvb)
    pvg.expose("P", pvb.P)
    pvg.expose("T", pvb.T)
    rig = Circuit("rig")
    pump = rig.add("pump", FlowSource(Q=Q))
    node = rig.add("supply", VolumeNode(V=V))
    rig.add("pvg", pvg)
    tank = rig.add("tank", Tank())
    rig.connect(pump.port, node.port, pvg.P)
    rig.connect(pvg.T, tank.port)
    s = rig.compile()
    assert "pvg.pvb.compensator.mid.port.p" in s.names
    assert rig["pvg.pvb.compensator.r1"].path == "pvg.pvb.compensator.r1"
    # steady state: series conductance K, the midpoint at half the supply pressure
    y = s.y0.copy()
    set_value(s, y, "supply.port.p", Q / K)
    set_value(s, y, "pvg.pvb.compensator.mid.port.p", Q / K / 2)
    assert np.max(np.abs(s.residual(0.0, y, np.zeros(s.n)))) < 1e-12


def test_exposed_port_left_unconnected_outside_is_named():
    m = restriction_module("m")
    top = Circuit("top")
    top.add("m", m)
    t = top.add("tank", Tank())
    top.connect(m.b, t.port)
    with pytest.raises(CircuitError, match=r"m\.r1\.a.*exposed as m\.a"):
        top.compile()


def test_parallel_volumes_share_one_pressure_state():
    c = demo()
    extra = c.add("extra", VolumeNode(V=V))
    c.connect(extra.port, "node.port")
    s = c.compile()
    assert int(s.differential.sum()) == 1  # one pressure state for the node, index one


def test_plug_closes_a_port():
    c = Circuit("c")
    n = c.add("node", VolumeNode(V=V))
    p = c.add("plug", Plug())
    c.connect(n.port, p.port)
    s = c.compile()
    assert s.n == 1
