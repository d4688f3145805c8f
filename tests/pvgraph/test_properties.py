"""Property tests: random series/parallel networks compile, balance and solve by hand."""

import numpy as np
from hypothesis import HealthCheck, example, given, settings, strategies as st

from pvgraph.components import FlowSource, LaminarOrifice, Orifice, Pump, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.units import litre, lpm, lpm_per_bar, mm2

from test_compiler import fd_jacobian, set_value

# a network is ("R", K) | ("S", [networks]) | ("P", [networks]); volumes sit on series joints
networks = st.recursive(
    st.tuples(st.just("R"), st.floats(0.05, 2.0)),
    lambda sub: st.tuples(st.sampled_from(["S", "P"]), st.lists(sub, min_size=2, max_size=3),
                          st.booleans()),
    max_leaves=8)


def conductance(net):
    if net[0] == "R":
        return lpm_per_bar(net[1])
    g = [conductance(n) for n in net[1]]
    return 1.0 / sum(1.0 / x for x in g) if net[0] == "S" else sum(g)


class Builder:
    """Adds a network's components between two nodes, and records the hand-solved values."""

    def __init__(self, circuit, turbulent=False):
        self.c = circuit
        self.turbulent = turbulent
        self.count = 0
        self.nodes = []        # lists of ports to connect
        self.values = {}       # variable name -> steady-state value

    def name(self, prefix):
        self.count += 1
        return f"{prefix}{self.count}"

    def build(self, net, node_in, node_out, p_in, p_out):
        q = conductance(net) * (p_in - p_out)
        if net[0] == "R":
            nm = self.name("r")
            if self.turbulent:
                comp = self.c.add(nm, Orifice(A=mm2(net[1] * 2)))
            else:
                comp = self.c.add(nm, LaminarOrifice(K=lpm_per_bar(net[1])))
            node_in.append(comp.a)
            node_out.append(comp.b)
            self.values[f"{nm}.a.p"], self.values[f"{nm}.b.p"] = p_in, p_out
            self.values[f"{nm}.a.q"], self.values[f"{nm}.b.q"] = q, -q
            return
        if net[0] == "P":
            for sub in net[1]:
                self.build(sub, node_in, node_out, p_in, p_out)
            return
        p = p_in
        current = node_in
        for k, sub in enumerate(net[1]):
            last = k == len(net[1]) - 1
            p_next = p_out if last else p - q / conductance(sub)
            nxt = node_out if last else []
            self.build(sub, current, nxt, p, p_next)
            if not last:
                if net[2]:
                    vol = self.c.add(self.name("v"), VolumeNode(V=litre(0.01)))
                    nxt.append(vol.port)
                    self.values[f"{vol._name}.port.q"] = 0.0
                self.nodes.append(nxt)
            current, p = nxt, p_next


def assemble(net, turbulent=False, volume_at_supply=True):
    c = Circuit("random")
    b = Builder(c, turbulent)
    Q = lpm(5.0)
    src = c.add("src", FlowSource(Q=Q))
    tank = c.add("tank", Tank())
    supply, ret = [src.port], [tank.port]
    if volume_at_supply:
        supply.append(c.add("supply", VolumeNode(V=litre(0.1))).port)
        b.values["supply.port.q"] = 0.0
    p_supply = Q / conductance(net)
    b.values["src.port.q"], b.values["tank.port.q"] = -Q, Q  # the source delivers, tank absorbs
    b.build(net, supply, ret, p_supply, 0.0)
    for node in [supply, ret] + b.nodes:
        c.connect(*node)
    return c, b.values


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(networks, st.booleans())
@example(("P", [("R", 1.0), ("S", [("R", 0.0625), ("R", 1.0), ("R", 1.0)], True)], False), False)
def test_random_laminar_network_is_balanced_and_consistent_at_the_hand_solution(net, vol):
    circuit, values = assemble(net, volume_at_supply=vol)
    s = circuit.compile()  # raises on imbalance or structural singularity
    y = s.y0.copy()
    for name, value in values.items():
        set_value(s, y, name, value)
    r = s.residual(0.0, y, np.zeros(s.n))
    # each residual row is a pressure, flow or volume balance; compare with its scale
    assert np.all(np.isfinite(r))
    assert np.all(np.abs(r) < 1e-9 * max(np.max(np.abs(y), initial=0.0), 1.0))
    for name, value in values.items():  # every eliminated alias reproduces the hand value too
        coef, idx, off = s.resolve(name)
        got = off if idx is None else coef * y[idx] + off
        assert abs(got - value) <= 1e-9 * max(abs(value), 1e-3)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(networks, st.integers(0, 2**31 - 1))
def test_random_turbulent_network_jacobian_matches_finite_differences(net, seed):
    circuit, _ = assemble(net, turbulent=True)
    s = circuit.compile()
    rng = np.random.default_rng(seed)
    y = s.nominal * rng.uniform(0.2, 2.0, size=s.n)
    yp = s.nominal * rng.normal(size=s.n)
    J = s.jacobian_dense(0.0, y, yp, 50.0)
    J_fd = fd_jacobian(s, 0.0, y, yp, 50.0)
    scale = np.max(np.abs(J), axis=1, keepdims=True) + 1e-30
    assert np.max(np.abs(J - J_fd) / scale) < 1e-5


def test_pump_between_tank_and_network():
    c = Circuit("pumped")
    tank = c.add("tank", Tank())
    pump = c.add("pump", Pump(Q0=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.2)))
    drain = c.add("drain", LaminarOrifice(K=lpm_per_bar(1.0)))
    c.connect(tank.port, pump.a, drain.b)
    c.connect(pump.b, node.port, drain.a)
    s = c.compile()
    y = s.y0.copy()
    set_value(s, y, "node.port.p", lpm(10) / lpm_per_bar(1.0))
    assert np.max(np.abs(s.residual(0.0, y, np.zeros(s.n)))) < 1e-12
