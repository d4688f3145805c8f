"""Traced equations reused across instances of a class (``pvgraph._templates``).

The compiled system must be the one of tracing every instance: the same generated code,
unknowns, parameters and values, whichever instances share a template, and components outside
the parameter contract (structure from a parameter's value, instance state, reads of
``self.params``, a trace that changes from instance to instance) must still compile right.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from pydantic import Field

from pvgraph import Circuit
from pvgraph import _templates as T
from pvgraph import compiler as K
from pvgraph.component import Component, Hydraulic, Params
from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph.components.hydraulic.fluid import CavitationWarning
from pvgraph.units import bar, litre, lpm, mm2


def _traced_one_by_one(monkeypatch):
    monkeypatch.setattr(T.Templates, "trace",
                        lambda self, comp, path, registry, trace: T._plain(comp, path, registry))


def _fingerprint(system):
    rng = np.random.default_rng(3)
    y = system.y0 * (1.0 + 0.01 * rng.standard_normal(system.n)) + 1e-3
    yp = 1e-3 * rng.standard_normal(system.n)
    return {"names": list(system.names), "y0": system.y0.tolist(), "source": system.source(),
            "parameters": [(k, i.value, i.structural, i.in_equations, i.in_starts)
                           for k, i in system.parameters.items()],
            "residual": system.residual(0.0, y, yp).tolist(),
            "jacobian": system.jacobian_values(0.0, y, yp, 3.0).tolist(),
            "events": np.asarray(system.event_values(0.0, y, yp)).tolist(),
            "dFdp": system.parameter_jacobian(0.0, y, yp).tolist()}


def _same_as_traced_one_by_one(build, monkeypatch):
    shared = _fingerprint(build().compile())
    with monkeypatch.context() as m:
        _traced_one_by_one(m)
        alone = _fingerprint(build().compile())
    assert shared == alone
    return shared


class _ScaledParams(Params):
    K: float = Field(1e-9, gt=0.0, description="Flow coefficient [m^3/(s Pa)]")
    n: float = Field(1.0, gt=0.0, description="Exponent, read structurally [-]")
    baked: float = Field(1.0, gt=0.0, description="Factor made a number by float() [-]")


class _Scaled(Component):
    """``q = K * baked * dp`` (``n == 1``) or ``q = K * baked * dp**3`` (else).

    ``n`` is compared with ``==`` and ``baked`` converted with ``float()``: both are structural,
    so their values are part of the equations' structure."""

    Params = _ScaledParams
    ports = {"a": Hydraulic(), "b": Hydraulic()}

    def equations(self, v, p):
        dp = v.a.p - v.b.p
        law = dp if p.n == 1.0 else dp * dp * dp
        return [v.a.q - p.K * float(p.baked) * law, v.a.q + v.b.q]


def _ladder(parts):
    """A pump into a volume; each part joins that volume to the tank."""
    c = Circuit("ladder")
    pump = c.add("pump", FlowSource(Q=lpm(1)))
    vol = c.add("vol", VolumeNode(V=litre(1), p0=bar(10)))
    tank = c.add("tank", Tank())
    c.connect(pump.port, vol.port, *[c.add(f"r{k}", part).a for k, part in enumerate(parts)])
    c.connect(tank.port, *[c[f"r{k}"].b for k in range(len(parts))])
    return c


def _flow(s, k, p):
    """Flow into part ``r<k>`` with the volume at ``p`` (the tank at zero), as compiled: its
    law's residual where it stays an equation, else the alias it was eliminated into."""
    y = s.y0.copy()
    y[s.index["vol.port.p"]] = p
    for end in ("a", "b"):
        if f"r{k}.{end}.q" in s.index:
            y[s.index[f"r{k}.{end}.q"]] = 0.0
    rows = [i for i, lab in enumerate(s.equations) if lab.startswith(f"r{k} equation 1 ")]
    if rows:
        return -s.residual(0.0, y, np.zeros(s.n))[rows[0]]
    coef, idx, off = s.resolve(f"r{k}.a.q")
    return coef * y[idx] + off


def test_a_structurally_read_parameter_that_differs_gets_a_template_of_its_own(monkeypatch):
    values = [(1.0, 1.0), (2.0, 1.0), (1.0, 3.0), (1.0, 1.0), (2.0, 1.0), (1.0, 3.0)]

    def build():
        return _ladder([_Scaled(K=1e-9 * (k + 1), n=n, baked=b)
                        for k, (n, b) in enumerate(values)])
    _same_as_traced_one_by_one(build, monkeypatch)
    s = build().compile()
    assert "r1.n" in s.parameters and s.parameters["r1.n"].structural
    assert s.parameters["r2.baked"].structural and not s.parameters["r2.K"].structural
    # each part's own law: q = K * baked * dp (n == 1) or K * baked * dp^3
    for k, (n, b) in enumerate(values):
        dp = 2.0
        expected = 1e-9 * (k + 1) * b * (dp if n == 1.0 else dp ** 3)
        assert _flow(s, k, dp) == pytest.approx(expected, rel=1e-12)


class _SelfReading(Component):
    """Reads ``self.params`` inside its equations (outside the parameter contract): the
    factor is baked in from the instance's own model."""

    Params = _ScaledParams
    ports = {"a": Hydraulic(), "b": Hydraulic()}

    def equations(self, v, p):
        return [v.a.q - p.K * self.params.baked * (v.a.p - v.b.p), v.a.q + v.b.q]


def test_a_component_reading_its_own_model_is_traced_instance_by_instance(monkeypatch):
    def build():
        # the first two alike: a template checked against the second would pass
        return _ladder([_SelfReading(baked=1.0 + max(k - 1, 0)) for k in range(5)])
    _same_as_traced_one_by_one(build, monkeypatch)
    s = build().compile()
    for k in range(5):
        assert _flow(s, k, 1e5) == pytest.approx(1e-9 * (1.0 + max(k - 1, 0)) * 1e5,
                                                 rel=1e-12)


class _Drifting(Component):
    """A trace that changes from one call to the next (a count of calls): the template
    renamed does not reproduce the second instance, so its class is traced one by one."""

    Params = _ScaledParams
    ports = {"a": Hydraulic(), "b": Hydraulic()}
    calls = [0]

    def equations(self, v, p):
        extra = self.calls[0] % 2
        self.calls[0] += 1
        q = p.K * (v.a.p - v.b.p) * (1.0 + extra)
        return [v.a.q - q, v.a.q + v.b.q]


def test_a_trace_that_differs_from_the_template_turns_templates_off(monkeypatch):
    def build():
        _Drifting.calls[0] = 0
        return _ladder([_Drifting() for _ in range(6)])
    _same_as_traced_one_by_one(build, monkeypatch)
    s = build().compile()
    for k in range(6):     # every instance traced: the factor alternates 1, 2, 1, 2, ...
        assert _flow(s, k, 1e5) == pytest.approx(1e-9 * (1 + k % 2) * 1e5, rel=1e-12)


def test_orifices_of_different_areas_share_a_template(monkeypatch):
    def build():
        return _ladder([Orifice(A=mm2(1.0 + 0.1 * k)) for k in range(8)])
    _same_as_traced_one_by_one(build, monkeypatch)
    templates = T.Templates()
    from pvgraph import expr as E
    c = build()
    trace = E.ParameterTrace({})
    registry: dict = {}
    n_traced = 0
    original = T._record

    def counting(*a):
        nonlocal n_traced
        n_traced += 1
        return original(*a)
    with monkeypatch.context() as m:
        m.setattr(T, "_record", counting)
        for k in range(8):
            with trace:
                templates.trace(c[f"r{k}"], f"r{k}", registry, trace)
    assert n_traced == 2       # the template and the instance that verifies it
    assert registry["r7.A"].value == c["r7"].params.A and registry["r7.A"].in_equations
    assert registry["r7.A"].value == pytest.approx(mm2(1.7), rel=1e-15)


def test_an_event_action_of_an_instance_built_from_a_template_names_it():
    c = Circuit("vols")
    pump = c.add("pump", FlowSource(Q=lpm(1)))
    tank = c.add("tank", Tank())
    prev = pump.port
    for k in range(4):
        v = c.add(f"v{k}", VolumeNode(V=litre(0.1)))
        o = c.add(f"o{k}", Orifice(A=mm2(5)))
        c.connect(prev, v.port, o.a)
        prev = o.b
    c.connect(prev, tank.port)
    s = c.compile()
    path, spec = [(p, ev) for p, ev in s.event_specs
                  if p == "v3" and ev.name == "cavitation"][0]
    assert isinstance(spec.action, T._LazyAction)
    modes = {"cavitated": 0.0}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        spec.action(modes)
    assert modes["cavitated"] == 1.0
    assert len(caught) == 1 and issubclass(caught[0].category, CavitationWarning)
    assert str(caught[0].message).startswith("v3: the pressure in the volume")


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")
def test_rig_and_machine_compile_as_when_traced_one_by_one(monkeypatch):
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    for build in (build_rig, build_machine):
        _same_as_traced_one_by_one(build, monkeypatch)


class _NoProvenance(K._Provenance):
    """Records nothing: every row shape, affine test and substitution computed row by row."""

    def add(self, *args, **kwargs):
        pass


def _same_without_provenance(build, monkeypatch, **options):
    shared = _fingerprint(build().compile(**options))
    with monkeypatch.context() as m:
        m.setattr(K, "_Provenance", _NoProvenance)
        alone = _fingerprint(build().compile(**options))
    assert shared == alone
    return shared


def _chain(n, areas):
    c = Circuit("chain")
    prev = c.add("pump", FlowSource(Q=lpm(5))).port
    for k in range(n):
        v = c.add(f"v{k}", VolumeNode(V=litre(0.05)))
        o = c.add(f"o{k}", Orifice(A=mm2(areas(k))))
        c.connect(prev, v.port, o.a)
        prev = o.b
    c.connect(prev, c.add("tank", Tank()).port)
    return c


@pytest.mark.parametrize("array_rows", [True, None])
def test_rows_of_one_provenance_compile_as_row_by_row(monkeypatch, array_rows):
    """Row shapes, affine tests and substitutions shared by rows of one template and one
    substitution pattern give the system of doing each row by itself."""
    _same_without_provenance(lambda: _chain(40, lambda k: 2.0 + 0.1 * k), monkeypatch,
                             array_rows=array_rows)
    values = [(1.0, 1.0), (2.0, 1.0), (1.0, 3.0)] * 4
    _same_without_provenance(
        lambda: _ladder([_Scaled(K=1e-9 * (k + 1), n=n, baked=b)
                         for k, (n, b) in enumerate(values)]), monkeypatch,
        array_rows=array_rows)


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")
def test_rig_and_machine_with_array_rows_compile_as_row_by_row(monkeypatch):
    from pvgraph.circuits.machine import build_machine
    from pvgraph.circuits.rig import build_rig
    for build in (build_rig, build_machine):
        _same_without_provenance(build, monkeypatch, array_rows=True)


def test_a_substitution_builder_rebuilds_rows_of_its_key_and_only_those():
    from pvgraph import expr as E

    def row(tag):
        a, b, c = (E.Expr("sym", (), f"{tag}.{n}") for n in ("a", "b", "c"))
        k = E.Expr("param", (), f"{tag}.k")
        shared = k * (a - b)
        return shared * shared + E.sqrt(c) * 2.0

    def renamed(node, tag, target):
        # a -> target (kept name), b -> -2 * target (fixed coefficient), c kept
        if node.op != "sym":
            return None
        if node.value.endswith(".a"):
            return E.Expr("sym", (), target)
        if node.value.endswith(".b"):
            return -2.0 * E.Expr("sym", (), target)
        return None

    rows = {tag: row(tag) for tag in ("r1", "r2", "r3")}
    new = {tag: E.substitute([r], lambda n, t=tag: renamed(n, t, f"{t}.x"))[0]
           for tag, r in rows.items()}
    names = {tag: (f"{tag}.x", f"{tag}.c", f"{tag}.k") for tag in rows}
    build = K._derived_builder(E.postorder([rows["r1"]]), new["r1"], names["r1"], [])
    old2 = E.postorder([rows["r2"]])
    assert K._built_alike(build, names["r2"], old2, new["r2"], [])
    got, nodes = build(names["r3"], E.postorder([rows["r3"]]))
    assert E.to_text(got) == E.to_text(new["r3"])
    assert nodes[-1] is got and len(nodes) == len(E.postorder([new["r3"]]))
    # the unchanged parameter leaf is the row's own node, the changed ones are new
    assert [n for n in nodes if n.op == "param"][0] is \
        [n for n in E.postorder([rows["r3"]]) if n.op == "param"][0]
    # a row whose substitution folds differently is not rebuilt alike
    other = E.substitute([rows["r2"]], lambda n: E.const(0.0) if n.op == "sym" and
                         n.value.endswith(".b") else None)[0]
    assert not K._built_alike(build, names["r2"], old2, other, [])
