"""Rows of one shape evaluated as arrays over their instances (``compile(array_rows=...)``).

The array path must give the residual, the Jacobian values, dF/dp and events of the straight-line
code bit for bit (the same floating-point operations in the same order, the same ``math``
functions), keep runtime parameters working, and give NaN where an equation cannot be evaluated.
"""

from __future__ import annotations

import numpy as np
import pytest

from pvgraph import Circuit
from pvgraph import system as S
from pvgraph.components import FlowSource, LaminarOrifice, Orifice, Tank, VolumeNode
from pvgraph.simulate import simulate
from pvgraph.units import bar, litre, lpm, lpm_per_bar, mm2



def chain(n: int, q=lpm(10)) -> Circuit:
    """A pump feeding n volume + orifice pairs in series into the tank."""
    c = Circuit(f"chain{n}")
    pump = c.add("pump", FlowSource(Q=q))
    prev = pump.port
    for k in range(n):
        v = c.add(f"v{k}", VolumeNode(V=litre(0.01 * (1 + k % 3))))
        o = c.add(f"o{k}", Orifice(A=mm2(20.0 + k)))
        c.connect(prev, v.port, o.a)
        prev = o.b
    tank = c.add("tank", Tank())
    c.connect(prev, tank.port)
    return c


def wide(m: int) -> Circuit:
    """A pump into one volume joining m turbulent and m laminar restrictions to the tank."""
    c = Circuit(f"wide{m}")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    tank = c.add("tank", Tank())
    ors = [c.add(f"o{k}", Orifice(A=mm2(1.0 + 0.01 * k))) for k in range(m)]
    lams = [c.add(f"l{k}", LaminarOrifice(K=lpm_per_bar(0.1 + 0.01 * k))) for k in range(m)]
    c.connect(pump.port, node.port, *[o.a for o in ors], *[r.a for r in lams])
    c.connect(tank.port, *[o.b for o in ors], *[r.b for r in lams])
    return c


def rig() -> Circuit:
    from pvgraph.circuits.rig import build_rig
    return build_rig()


def machine() -> Circuit:
    from pvgraph.circuits.machine import build_machine
    return build_machine()


def _points(system, rng, k=3):
    for _ in range(k):
        y = system.y0 + system.nominal * rng.uniform(-0.2, 1.0, system.n)
        yp = system.nominal * rng.normal(size=system.n)
        yield y, yp


def _close(a, b):
    """Equal bit for bit (NaN where the other is NaN)."""
    return np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)


@pytest.mark.filterwarnings("ignore::pvgraph.errors.PlausibilityWarning")  # machine: by design
@pytest.mark.parametrize("build", [lambda: chain(40), lambda: wide(30), rig, machine],
                         ids=["chain", "wide", "pvg32_rig", "machine"])
def test_array_rows_give_the_residual_and_jacobian_of_straight_line_code(build):
    circuit = build()
    plain = circuit.compile(array_rows=False)
    arrays = circuit.compile(array_rows=True)
    assert plain._vector is None
    assert arrays._vector is not None and arrays._vector.groups
    assert arrays.names == plain.names
    np.testing.assert_array_equal(arrays._rows, plain._rows)
    np.testing.assert_array_equal(arrays._cols, plain._cols)
    np.testing.assert_array_equal(arrays.differential, plain.differential)
    rng = np.random.default_rng(7)
    for y, yp in _points(plain, rng):
        for t in (0.0, 0.37):
            assert _close(arrays.residual(t, y, yp), plain.residual(t, y, yp))
            for c in (0.0, 1e3):
                assert _close(arrays.jacobian_values(t, y, yp, c),
                              plain.jacobian_values(t, y, yp, c))
        assert _close(arrays.event_values(0.1, y, yp), plain.event_values(0.1, y, yp))


def test_array_rows_keep_runtime_parameters_and_dF_dp():
    circuit = chain(40)
    plain = circuit.compile(array_rows=False)
    arrays = circuit.compile(array_rows=True)
    new = {"o7.A": mm2(3.0), "v3.V": litre(0.2), "pump.Q": lpm(12)}
    p2, a2 = plain.with_params(new), arrays.with_params(new)
    rng = np.random.default_rng(3)
    for y, yp in _points(plain, rng, 2):
        ra, rp = a2.residual(0.0, y, yp), p2.residual(0.0, y, yp)
        assert _close(ra, rp)
        # the change reaches the rows: the orifice row o7 differs from the unchanged system
        assert not np.allclose(ra, arrays.residual(0.0, y, yp))
        assert _close(a2.jacobian_values(0.0, y, yp, 50.0), p2.jacobian_values(0.0, y, yp, 50.0))
        assert _close(a2.parameter_jacobian(0.0, y, yp), p2.parameter_jacobian(0.0, y, yp))
    # the original system keeps its values
    y, yp = plain.y0 + 1.0, np.zeros(plain.n)
    assert _close(arrays.residual(0.0, y, yp), plain.residual(0.0, y, yp))


@pytest.mark.parametrize("solver", ["pvgraph", "ida"])
def test_chain_with_array_rows_carries_the_pump_flow_through_every_orifice(solver):
    """Steady flow through the series chain: every orifice passes the pump flow (continuity)."""
    if solver == "ida":
        pytest.importorskip("sksundae")
    q = lpm(10)
    circuit = chain(40, q)
    arrays = circuit.compile(array_rows=True)
    plain = circuit.compile(array_rows=False)
    ra = simulate(arrays, 0.5, rtol=1e-7, solver=solver)
    rp = simulate(plain, 0.5, rtol=1e-7, solver=solver)
    assert len(ra.t) == len(rp.t)
    for k in (0, 17, 39):
        flows = ra[f"o{k}.q"]
        assert abs(flows[-1] - q) < 1e-6 * q
        np.testing.assert_allclose(flows, rp[f"o{k}.q"], rtol=1e-9, atol=1e-12 * q)
    # pressures fall along the chain (each orifice needs a positive drop for positive flow)
    p = [ra[f"v{k}.port.p"][-1] for k in range(40)]
    assert all(a > b for a, b in zip(p, p[1:]))
    assert p[-1] > 0.0


def test_rows_that_cannot_be_evaluated_are_nan_in_both_paths():
    circuit = chain(40)
    plain = circuit.compile(array_rows=False)
    arrays = circuit.compile(array_rows=True)
    y, yp = plain.y0 + bar(1.0), np.zeros(plain.n)
    y[plain.index["v5.port.p"]] = np.nan
    rp, ra = plain.residual(0.0, y, yp), arrays.residual(0.0, y, yp)
    bad = np.isnan(rp)
    # the volume itself and the orifices on both sides of it read the pressure
    assert 2 <= bad.sum() <= 4
    np.testing.assert_array_equal(np.isnan(ra), bad)
    assert _close(ra[~bad], rp[~bad])
    jp, ja = plain.jacobian_values(0.0, y, yp, 10.0), arrays.jacobian_values(0.0, y, yp, 10.0)
    np.testing.assert_array_equal(np.isnan(ja), np.isnan(jp))


def test_array_rows_are_chosen_only_for_big_systems(monkeypatch):
    small = chain(5).compile()
    assert small._vector is None
    monkeypatch.setattr(S, "ARRAY_MIN_ROWS", 10)
    monkeypatch.setattr(S, "ARRAY_MIN_GROUP", 4)
    big = chain(5).compile()
    assert big._vector is not None
    # five volumes and five orifices: groups of at least four rows of one shape
    assert all(len(g.rows) >= 4 for g in big._vector.groups)
    assert "rows of shape 0" in big.source()


@pytest.mark.filterwarnings("ignore::UserWarning")   # the cavitation warning is the point here
def test_an_event_of_an_array_group_fires_as_in_straight_line_code():
    """A pump sucking from the chain drains the first volume to the vapour pressure: its
    cavitation event switches its mode, at the same time in both paths."""
    from pvgraph.components.hydraulic.volumes import P_ATM
    circuit = chain(40, q=-lpm(60))
    arrays = circuit.compile(array_rows=True)
    plain = circuit.compile(array_rows=False)
    assert arrays._ev_vector is not None
    ra, rp = simulate(arrays, 0.2), simulate(plain, 0.2)
    switched = [(t, modes.index(1.0)) for t, modes in arrays.mode_log[1:] if 1.0 in modes]
    assert switched and switched[0][1] == arrays.mode_names.index("v0.#cavitated")
    assert [t for t, _ in arrays.mode_log] == [t for t, _ in plain.mode_log]
    p0 = ra["v0.port.p"][-1]
    # at the vapour pressure (absolute ~ 0), less what the cavity takes at the limit's level
    # compliance (1.4e-3 /Pa): the pump has drawn some 19 chamber volumes by then
    assert -1.2 * P_ATM < p0 < -0.9 * P_ATM
    assert abs(p0 - rp["v0.port.p"][-1]) <= 1e-9 * P_ATM


def test_rows_flavour_computes_the_scalar_flavour_element_by_element():
    """Generated array code over instances gives each instance the scalar code's number."""
    import math

    from pvgraph import codegen
    from pvgraph import expr as E
    y0, y1 = E.Expr("y", (), 0), E.Expr("y", (), 1)
    roots = [E.tanh(y0) * E.exp(y1) - E.atan(y0 / y1) + E.cos(y1) ** 2.0,
             E.where(y0 > 0.0, E.log(y0), E.sin(y1))]
    scalar = codegen.compile_function("f", *codegen.generate("f", roots))
    rows = codegen.compile_function("f", *codegen.generate("f", roots, flavour="rows"))
    rng = np.random.default_rng(11)
    a, b = rng.normal(scale=3.0, size=500), rng.normal(scale=3.0, size=500)
    got = rows(0.0, [a, b], [], ())
    want = np.array([scalar(0.0, [x, z], [], ()) for x, z in zip(a, b)]).T
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])   # log of the negative half not selected
    # where the math function raises (log of a negative number), the instance is NaN
    bad = codegen.compile_function("g", *codegen.generate("g", [E.log(y0)], flavour="rows"))
    out = bad(0.0, [np.array([math.e, -1.0])], [], ())[0]
    assert out[0] == 1.0 and math.isnan(out[1])


def manifold(m: int, q=lpm(40)) -> Circuit:
    """A pump into one volume joining ``m`` turbulent orifices to the tank (two connection sets
    of m + 2 and m + 1 ports)."""
    c = Circuit(f"manifold{m}")
    pump = c.add("pump", FlowSource(Q=q))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    tank = c.add("tank", Tank())
    ors = [c.add(f"o{k}", Orifice(A=mm2(1.0 + 0.05 * k))) for k in range(m)]
    c.connect(pump.port, node.port, *[o.a for o in ors])
    c.connect(tank.port, *[o.b for o in ors])
    return c


def test_a_node_of_many_ports_sums_its_flows_as_a_sparse_matrix():
    """The flow balance of a node joining more than S.LINEAR_MIN_TERMS ports is a sparse
    matrix product: the residual equals the straight-line sum to rounding, the Jacobian,
    its pattern and dF/dp exactly, and a run conserves the pump's flow."""
    q = lpm(40)
    m = S.LINEAR_MIN_TERMS + 8
    circuit = manifold(m, q)
    plain = circuit.compile(array_rows=False)
    arrays = circuit.compile(array_rows=True)
    assert "sums evaluated as sparse matrices" in arrays.source()
    assert "sums evaluated as sparse matrices" not in plain.source()
    assert arrays.names == plain.names
    np.testing.assert_array_equal(arrays._rows, plain._rows)
    np.testing.assert_array_equal(arrays._cols, plain._cols)
    np.testing.assert_array_equal(arrays.differential, plain.differential)
    rng = np.random.default_rng(5)
    for y, yp in _points(plain, rng):
        # the sums add the same terms in another order: equal to a few ulps of the terms
        scale = np.abs(y).max() + np.abs(yp).max()
        np.testing.assert_allclose(arrays.residual(0.0, y, yp), plain.residual(0.0, y, yp),
                                   rtol=0, atol=1e-14 * scale)
        for c in (0.0, 1e3):
            assert _close(arrays.jacobian_values(0.0, y, yp, c),
                          plain.jacobian_values(0.0, y, yp, c))
        assert _close(arrays.parameter_jacobian(0.0, y, yp), plain.parameter_jacobian(0.0, y, yp))
    ra, rp = simulate(arrays, 0.3, rtol=1e-8), simulate(plain, 0.3, rtol=1e-8)
    total = sum(ra[f"o{k}.q"][-1] for k in range(m))
    assert abs(total - q) < 1e-7 * q          # continuity at the node, settled
    np.testing.assert_allclose(ra["node.port.p"][-1], rp["node.port.p"][-1], rtol=1e-8)
    # a parameter changed at run time reaches the summed rows' neighbours as in plain code
    new = {"o3.A": mm2(7.0), "pump.Q": lpm(30)}
    y, yp = plain.y0 + bar(2.0), np.zeros(plain.n)
    np.testing.assert_allclose(arrays.with_params(new).residual(0.0, y, yp),
                               plain.with_params(new).residual(0.0, y, yp), rtol=0,
                               atol=1e-14 * np.abs(y).max())


def test_sums_below_the_threshold_and_parametric_terms_stay_straight_line_code():
    """A node of fewer ports, or one whose flows are parametric in the pressures (laminar
    restrictions eliminated into the node), keeps its sum as generated code."""
    few = manifold(S.LINEAR_MIN_TERMS - 4).compile(array_rows=True)
    assert "sums evaluated as sparse matrices" not in few.source()
    laminar = wide(20).compile(array_rows=True)    # 20 of the 42 flows are K (p_a - p_b)
    assert "sums evaluated as sparse matrices" not in laminar.source()
