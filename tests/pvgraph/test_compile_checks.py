"""The no-pressure-reference check of ``Circuit.compile`` (``_pressure_islands``).

Instances of one component class with equal parameters trace alike, so the check traces one of
them and gives the others the same port roles; its result must be that of tracing every
instance, and an instance with state of its own must be traced by itself.
"""

from __future__ import annotations

import warnings

import pytest

from pvgraph import Circuit
from pvgraph import circuit as C
from pvgraph.component import Component, Hydraulic, Params
from pvgraph.components import Orifice, Tank, VolumeNode
from pvgraph.errors import PlausibilityWarning, StructureError
from pvgraph.units import litre, mm2


def _summary(islands):
    return sorted((sorted(i["components"]), sorted(i["volumes"])) for i in islands)


def _islands_traced_one_by_one(circuit, monkeypatch):
    with monkeypatch.context() as m:
        m.setattr(C, "_alike", lambda comp: None)
        return C._pressure_islands(circuit)


def rings(n_floating: int, n_tanked: int) -> Circuit:
    """Rings of two equal volumes and two equal orifices; the last ``n_tanked`` have a tank."""
    c = Circuit("rings")
    for k in range(n_floating + n_tanked):
        v1 = c.add(f"v{k}a", VolumeNode(V=litre(1)))
        v2 = c.add(f"v{k}b", VolumeNode(V=litre(1)))
        o1 = c.add(f"o{k}a", Orifice(A=mm2(1)))
        o2 = c.add(f"o{k}b", Orifice(A=mm2(1)))
        ends = [v1.port, o1.a, o2.b]
        if k >= n_floating:
            ends.append(c.add(f"t{k}", Tank()).port)
        c.connect(*ends)
        c.connect(o1.b, v2.port, o2.a)
    return c


def test_shared_tracing_finds_the_islands_of_tracing_every_instance(monkeypatch):
    c = rings(3, 2)
    shared = _summary(C._pressure_islands(c))
    assert shared == _summary(_islands_traced_one_by_one(c, monkeypatch))
    # the three rings without a tank float, each with its two volumes; the tanked ones do not
    assert [names for names, _ in shared] == [
        [f"o{k}a", f"o{k}b", f"v{k}a", f"v{k}b"] for k in range(3)]
    assert all(len(vols) == 2 for _, vols in shared)
    with pytest.warns(PlausibilityWarning, match=r"'rings': the hydraulic network of o0a, o0b, "
                                                 r"v0a, v0b; o1a, o1b, v1a, v1b; o2a"):
        c.compile()


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")
def test_machine_and_rig_islands_are_those_of_tracing_every_instance(monkeypatch):
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    for build in (build_rig, build_machine):
        c = build()
        assert _summary(C._pressure_islands(c)) == \
            _summary(_islands_traced_one_by_one(c, monkeypatch))


class _NoParams(Params):
    pass


class _End(Component):
    """Closes a port: a plug (no flow), or, with ``fixes`` set on the instance, a pressure
    reference (the pressure fixed at zero, like a tank)."""

    Params = _NoParams
    ports = {"port": Hydraulic("the closed port")}

    def equations(self, v, p):
        if getattr(self, "fixes", False):
            return [v.port.p - 0.0]
        return [v.port.q]


def test_an_instance_with_state_of_its_own_is_traced_by_itself():
    c = Circuit("ends")
    for k, fixes in enumerate((False, True)):
        vol = c.add(f"v{k}", VolumeNode(V=litre(1)))
        end = c.add(f"e{k}", _End())
        if fixes:
            end.fixes = True
        c.connect(vol.port, end.port)
    assert C._alike(c["e0"]) is not None and C._alike(c["e1"]) is None
    # only the plugged volume floats; the other has its reference
    assert _summary(C._pressure_islands(c)) == [(["e0", "v0"], [("v0", "port")])]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert C._alike(c["v0"]) == C._alike(c["v1"])   # equal volumes share their tracing


def _incidence_of_alias_elimination(circuit):
    """Run the compiler's stages up to alias elimination; its equations and the incidence it
    hands to the index check."""
    from pvgraph import compiler as K
    from pvgraph import expr as E
    captured = {}
    original = K._eliminate_aliases

    def spy(equations, infos, subs, values, found=None, incidence=None, prov=None, why=None,
            held=None):
        out = original(equations, infos, subs, values, found, incidence, prov, why, held)
        captured["equations"], captured["incidence"] = out, incidence
        return out

    K._eliminate_aliases = spy
    try:
        circuit.compile()
    finally:
        K._eliminate_aliases = original
    read = []
    for eq in captured["equations"]:
        lv = E.leaves(eq.expr, ("sym", "der"))
        read.append(({n for op, n in lv if op == "sym"}, {n for op, n in lv if op == "der"}))
    return captured["incidence"], read


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")
@pytest.mark.parametrize("build", ["rings", "rig", "machine"])
def test_alias_elimination_hands_on_the_exact_incidence(build):
    """The values and derivatives each equation reads after elimination, as kept while
    eliminating (fixed pressures fold terms away), equal those read from the expressions."""
    if build == "rings":
        circuit = rings(2, 3)
    else:
        from pvgraph.circuits.machine import build_machine
        from pvgraph.circuits.rig import build_rig
        circuit = {"rig": build_rig, "machine": build_machine}[build]()
    kept, read = _incidence_of_alias_elimination(circuit)
    assert len(kept) == len(read) > 0
    assert kept == read


def test_flow_sources_in_series_are_told_as_such_not_as_a_missing_tank():
    """Two ideal pumps in series (tank -> p1 -> p2 -> tank) and a pump into a plug: the tank
    is there; the message leads with the node whose flows contradict and says what to put
    between them."""
    from pvgraph.components import Plug, Pump, Tank
    c = Circuit("x")
    p1, p2, t = c.add("p1", Pump(Q0="10 L/min")), c.add("p2", Pump(Q0="5 L/min")), c.add("t", Tank())
    c.connect(t.port, p1.a)
    c.connect(p1.b, p2.a)
    c.connect(p2.b, t.port)
    with pytest.raises(StructureError, match=r"^circuit 'x': node\{p1.b, p2.a\}: sum of q is zero "
                                             r"contradicts the others.*\n.*network of p1, p2.*"
                                             r"VolumeNode and a relief valve") as info:
        c.compile()
    assert "Connect a Tank" not in str(info.value)
    d = Circuit("y")
    p, t, plug = d.add("p", Pump(Q0="10 L/min")), d.add("t", Tank()), d.add("pl", Plug())
    d.connect(t.port, p.a)
    d.connect(p.b, plug.port)
    with pytest.raises(StructureError, match=r"(?s)node\{p.b, pl.port\}.*contradicts.*closed end"):
        d.compile()


def test_a_signal_joining_ports_of_different_units_is_refused():
    """A pressure sensor's y [Pa] wired into a flow input's u [m^3/s] ran: it asked for
    1e6 m^3/s and the only hint was a 7e10 bar warning on the hydraulics. Ports without a
    unit (a Gain) take any signal, so a Gain between them is the way."""
    from pvgraph import ConnectionError_
    from pvgraph.components.hydraulic import (FlowInput, Orifice, PressureSensor,
                                              PressureSource, VolumeNode)
    from pvgraph.components.signal import Gain

    def build(gain):
        c = Circuit("wire")
        c.add("src", PressureSource(p0="10 bar"))
        c.add("o", Orifice(A="1 mm^2"))
        c.add("n", VolumeNode(V="1 L"))
        c.add("ps", PressureSensor())
        c.add("fi", FlowInput())
        c.connect("src.port", "o.a")
        c.connect("o.b", "n.port", "ps.port", "fi.port")
        if gain:
            c.add("g", Gain(k=-1e-10))
            c.connect("ps.y", "g.u")
            c.connect("g.y", "fi.u")
        else:
            c.connect("ps.y", "fi.u")
        return c
    with pytest.raises(ConnectionError_, match=r"signal 'ps.y' \[Pa\] is joined to 'fi.u' "
                                               r"\[m\^3/s\]: .* Put a Gain between them"):
        build(False).compile()
    build(True).compile()
