"""The no-pressure-reference check on the compiler's templates (:mod:`pvgraph._roles`).

Instances built from a component template take their port roles from the template's symbolic
graph wherever tracing them with numbers keeps the same leaves. These tests hold the result to
that of tracing every instance with numbers, and check the fall-backs: a ``where`` branch
picked by a parameter, and a parameter value (0, +-1) at which tracing with numbers folds a
variable away.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from pvgraph import Circuit
from pvgraph import _roles as R
from pvgraph import circuit as C
from pvgraph import compiler as K
from pvgraph import expr as E
from pvgraph.component import Component, Hydraulic, Params
from pvgraph.components import Orifice, Tank, VolumeNode
from pvgraph.errors import PlausibilityWarning
from pvgraph.units import litre, mm2

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


def _summary(islands):
    return sorted((sorted(i["components"]), sorted(i["volumes"])) for i in islands)


def _compile_with_known_roles(circuit, monkeypatch):
    """Compile ``circuit``; the port roles the compiler read from its templates."""
    got = {}
    original = K.template_roles

    def spy(*args):
        got["roles"] = original(*args)
        return got["roles"]
    with monkeypatch.context() as m:
        m.setattr(K, "template_roles", spy)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PlausibilityWarning)
            circuit.compile()
    return got["roles"]


def _one_by_one(circuit, monkeypatch):
    """The islands with every component traced with numbers by itself."""
    with monkeypatch.context() as m:
        m.setattr(C, "_alike", lambda comp: None)
        return C._pressure_islands(circuit)


class _GateParams(Params):
    s: float = 1.0      # open where s > 0 [-]
    g: float = 1e-9     # conductance when open [m^3/(s Pa)]


class _Gate(Component):
    """A two-port that a parameter opens or closes: ``where(s > 0, ...)`` picks the branch.
    Open, one flow path from a to b; closed, no flow at either port (the ports unjoined)."""

    Params = _GateParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        is_open = p.s > 0.0
        return [E.where(is_open, v.a.q + v.b.q, v.b.q),
                E.where(is_open, v.a.q - p.g * (v.a.p - v.b.p), v.a.q)]


class _CouplerParams(Params):
    c: float = 2.0      # coupling of the flows [-]
    g: float = 1e-9     # conductance [m^3/(s Pa)]


class _Coupler(Component):
    """``c*a.q - a.q + b.q = 0`` and ``a.q = g (a.p - b.p)``: with c = 1 the first equation,
    traced with numbers, folds to ``b.q = 0`` (``1*a.q - a.q`` is zero) and the ports are
    not joined by a flow path."""

    Params = _CouplerParams
    ports = {"a": Hydraulic("inlet"), "b": Hydraulic("outlet")}

    def equations(self, v, p):
        return [p.c * v.a.q - v.a.q + v.b.q, v.a.q - p.g * (v.a.p - v.b.p)]


def _bays(cls, values):
    """Per value, a node of two volumes and the inlet of a ``cls`` instance, whose outlet is
    on a tank: the node floats where the instance joins no flow path."""
    c = Circuit("bays")
    for k, (name, value) in enumerate(values):
        v1 = c.add(f"v{k}a", VolumeNode(V=litre(1)))
        v2 = c.add(f"v{k}b", VolumeNode(V=litre(1)))
        x = c.add(f"x{k}", cls(**{name: value}))
        t = c.add(f"t{k}", Tank())
        c.connect(v1.port, v2.port, x.a)
        c.connect(x.b, t.port)
    return c


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")
@pytest.mark.parametrize("build", ["rig", "machine", "wide", "chain", "rings"])
def test_roles_from_templates_are_those_of_tracing_with_numbers(build, monkeypatch):
    from bench_scaling import chain, wide
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    from tests.pvgraph.test_compile_checks import rings
    c = {"rig": build_rig, "machine": build_machine, "wide": lambda: wide(40),
         "chain": lambda: chain(30), "rings": lambda: rings(3, 2)}[build]()
    known = _compile_with_known_roles(c, monkeypatch)
    assert known
    for path, roles in known.items():
        comp = c[path]
        assert roles == C._port_roles(comp, path, C._hydraulic_ports(comp)), path
    assert _summary(C._pressure_islands(c, known)) == _summary(_one_by_one(c, monkeypatch))
    if build == "wide":
        # every orifice but the second (traced to check the template) is built from it
        assert sorted(k for k in known if k.startswith("o")) == sorted(
            f"o{k}" for k in range(40) if k != 1)


def test_a_branch_picked_by_a_parameter_is_traced_with_numbers(monkeypatch):
    c = _bays(_Gate, [("s", 1.0), ("s", -1.0), ("s", -1.0), ("s", 1.0)])
    with E.ParameterTrace({}):
        graph = c["x0"].trace("x0", {})[0]
    assert R._operands(graph) is None       # no instance takes the template's roles
    known = _compile_with_known_roles(c, monkeypatch)
    assert not any(path.startswith("x") for path in known)
    islands = _summary(C._pressure_islands(c, known))
    assert islands == _summary(_one_by_one(c, monkeypatch))
    # the closed gates (s = -1) leave their nodes floating, each with its two volumes
    assert islands == [(["v1a", "v1b", "x1"], [("v1a", "port"), ("v1b", "port")]),
                       (["v2a", "v2b", "x2"], [("v2a", "port"), ("v2b", "port")])]
    with pytest.warns(PlausibilityWarning, match=r"network of v1a, v1b, x1; v2a, v2b, x2 has no"):
        c.compile()


@pytest.mark.parametrize("special", [1.0, 0.0])
def test_a_parameter_value_that_folds_a_flow_away_is_traced_with_numbers(special, monkeypatch):
    c = _bays(_Coupler, [("c", 2.0), ("c", 2.5), ("c", special), ("c", 3.0)])
    known = _compile_with_known_roles(c, monkeypatch)
    assert "x3" in known and "x2" not in known    # x2 takes no roles from the template
    islands = _summary(C._pressure_islands(c, known))
    assert islands == _summary(_one_by_one(c, monkeypatch))
    if special == 1.0:      # 1*a.q - a.q folds to zero: no flow path through x2
        assert islands == [(["v2a", "v2b", "x2"], [("v2a", "port"), ("v2b", "port")])]
    else:                   # 0*a.q - a.q is -a.q: the flow path stays
        assert islands == []


def test_instances_kept_by_their_parameter_values():
    """The mask of :func:`pvgraph._roles._kept`: special or non-finite operands drop an
    instance, and so does a non-finite value inside an operand made of parameters."""
    a, b, x = (E.Expr("param", (), "t.a"), E.Expr("param", (), "t.b"),
               E.Expr("sym", (), "t.x"))
    residual = E.sqrt(a - b) * x + b * x     # operands sqrt(a - b) and b
    order, checked = R._operands([residual])
    assert {id(n) for n in order if id(n) in checked} and id(b) in checked
    cols = {"t.a": np.array([5.0, 2.0, 1.0, 3.0, 9.0, 4.0]),
            "t.b": np.array([1.0, 1.5, 2.0, 2.0, 0.0, 1e308 * 10])}
    ok = R._kept(order, checked, cols, 6)
    # sqrt(4)=2 and 1: b = 1 is special; sqrt(0.5) and 1.5 fine; sqrt(-1) is NaN;
    # sqrt(1) = 1 special; b = 0 special; b = inf
    assert ok.tolist() == [False, True, False, False, False, False]


@pytest.mark.parametrize("build", ["rig", "machine", "wide"])
def test_connection_provenance_is_read_off_the_equations(build):
    """The provenance ``_connection_equations`` records with each equation is what
    ``_connection_key`` reads off the equation: the same key, names and nodes."""
    from bench_scaling import wide
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    c = {"rig": build_rig, "machine": build_machine, "wide": lambda: wide(12)}[build]()
    leaves = K._flatten(c)
    infos: dict = {}
    for path, comp in leaves:
        K._declare_variables(path, comp, infos, {})
    keys: list = []
    equations = K._connection_equations(c, leaves, infos, keys)
    assert len(keys) == len(equations) > 10
    for eq, got in zip(equations, keys):
        want = K._connection_key(eq.expr)
        assert (got is None) == (want is None), eq.label
        if got is not None:
            assert got[:2] == want[:2], eq.label
            assert len(got[2]) == len(want[2]) and all(
                a is b for a, b in zip(got[2], want[2])), eq.label


def test_class_start_values_are_those_of_the_traced_view():
    """Where a class's start values read no parameters, the compiler takes them from the
    class: they are what ``start_values_traced`` gives, user overrides included."""
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    from pvgraph.components import FlowSource
    checked = 0
    for c in (build_rig(), build_machine()):
        for path, comp in K._flatten(c):
            fixed = K._class_starts(type(comp))
            if fixed is None:
                continue
            assert {**fixed, **comp._start} == comp.start_values_traced(path, {}), path
            checked += 1
    assert checked > 10
    assert K._class_starts(VolumeNode) is None      # its port pressure starts at p0
    assert K._class_starts(FlowSource) is not None
