"""Sweeps on one compiled system: the same numbers as building and compiling every case,
the closed-form orifice pressure, and a structural parameter compiled again (once per value)."""

import functools
import math
import re
import warnings

import numpy as np
import pytest

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.analysis import CompiledRun, grid, steady_state, sweep, sweep_system
from pvgraph.analysis.sweep import SweepError
from pvgraph.system import RecompileWarning

RHO, CD = 870.0, 0.6


def orifice_bench(Q=1e-4, A=2e-6, air=0.0):
    """Flow source Q -> volume -> orifice A -> tank: steady p = rho/2 (Q / (Cd A))^2."""
    c = Circuit("orifice_bench")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V=1e-4, air=air))
    orf = c.add("orifice", Orifice(A=A, Cd=CD, rho=RHO))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    return c


def rebuilt(**case):
    """The reference: build and compile every case."""
    c = orifice_bench()
    c.set_parameters(case)
    return {"p": steady_state(c.compile(), tol=1e-12)["node.port.p"]}


CASES = grid({"orifice.A": [1e-6, 2e-6, 4e-6], "pump.Q": [5e-5, 1e-4, 2e-4]})


def analytic(case, Q=None, A=None):
    """Steady orifice drop: Q = Cd A sqrt(2/rho) dp / (dp^2 + dp_t^2)^(1/4) (the turbulent
    law with its smooth laminar transition), i.e. with s = rho/2 (Q/(Cd A))^2:
    dp^2 = (s^2 + sqrt(s^4 + 4 s^2 dp_t^2)) / 2, and dp = s for dp >> dp_t."""
    Q = case["pump.Q"] if Q is None else Q
    A = case["orifice.A"] if A is None else A
    s = RHO / 2.0 * (Q / (CD * A)) ** 2
    dp_t = Orifice(A=A, Cd=CD, rho=RHO).params.transition()
    return math.sqrt((s * s + math.sqrt(s ** 4 + 4.0 * s * s * dp_t * dp_t)) / 2.0)


def test_reused_system_matches_rebuilds_and_the_closed_form():
    run = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    reused = sweep(run, CASES, backend="serial")
    fresh = sweep(rebuilt, CASES, backend="serial")
    assert run.compilations() == 1 and not reused.failed and not fresh.failed
    np.testing.assert_allclose(reused.column("p"), fresh.column("p"), rtol=1e-9, atol=0.0)
    exact = np.array([analytic(c) for c in CASES])
    np.testing.assert_allclose(reused.column("p"), exact, rtol=1e-9)
    # 1.9 ... 483 bar, well above the transition: the plain turbulent law within 1e-4
    turbulent = [RHO / 2 * (c["pump.Q"] / (CD * c["orifice.A"])) ** 2 for c in CASES]
    np.testing.assert_allclose(reused.column("p"), turbulent, rtol=1e-4)


def test_structural_parameter_compiles_once_per_value_and_stays_right():
    """VolumeNode's air content is compared with zero in Python (structural); the steady
    pressure does not depend on it."""
    cases = grid({"node.air": [0.0, 0.01], "orifice.A": [1e-6, 3e-6], "pump.Q": [1e-4]})
    run = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    with pytest.warns(RecompileWarning, match=r"node\.air"):
        res = sweep(run, cases, backend="serial")
    assert not res.failed
    assert run.compilations() == 2       # the base system and one for air = 0.01
    np.testing.assert_allclose(res.column("p"), [analytic(c) for c in cases], rtol=1e-9)
    fresh = sweep(rebuilt, cases, backend="serial")
    np.testing.assert_allclose(res.column("p"), fresh.column("p"), rtol=1e-9, atol=0.0)


def test_builder_arguments_reuse_the_compiled_structure():
    """build= : case names are the builder's arguments; one structure, one compilation."""
    run = CompiledRun(build=orifice_bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    cases = grid({"A": [1e-6, 2e-6], "Q": [1e-4, 2e-4]})
    res = sweep(run, cases, backend="serial")
    assert run.compilations() == 1 and not res.failed
    expected = [analytic({}, Q=c["Q"], A=c["A"]) for c in cases]
    np.testing.assert_allclose(res.column("p"), expected, rtol=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecompileWarning)
        more = sweep(run, grid({"air": [0.02], "A": [1e-6]}), backend="serial")
    assert run.compilations() == 2 and more[0].outputs["p"] == pytest.approx(
        analytic({}, Q=1e-4, A=1e-6), rel=1e-9)


def test_transient_final_values_match_rebuilds_in_worker_processes():
    """Process backend: each worker compiles once; final pressures equal the rebuilt ones."""
    def reference(case):
        c = orifice_bench()
        c.set_parameters(case)
        from pvgraph.simulate import simulate
        return simulate(c.compile(), 0.05, rtol=1e-8).final("node.port.p")

    cases = grid({"orifice.A": [1e-6, 2e-6], "pump.Q": [1e-4, 2e-4]})
    res = sweep_system(functools.partial(orifice_bench, Q=1e-4), cases,
                       outputs=["node.port.p"], t_end=0.05, rtol=1e-8, workers=2)
    assert not res.failed
    np.testing.assert_allclose(res.column("node.port.p"), [reference(c) for c in cases],
                               rtol=1e-9, atol=0.0)


def test_bad_setups_are_named():
    with pytest.raises(SweepError, match="t_end"):
        CompiledRun(orifice_bench, outputs=["node.port.p"])
    with pytest.raises(SweepError, match="not both"):
        CompiledRun(orifice_bench, build=orifice_bench, outputs=["node.port.p"], steady=True)
    run = CompiledRun(orifice_bench, outputs=["node.port.p"], steady=True)
    with pytest.raises(SweepError, match=r"no parameter named 'orifice.area'.*'orifice.A'"):
        sweep(run, [{"orifice.area": 1e-6}], backend="serial")


def test_reuse_compiled_gives_the_built_circuits_values_and_compiles_new_structures():
    """Code that builds and compiles per call (a scenario runner) compiles each structure
    once inside reuse_compiled(); the values are those of the circuit built."""
    from pvgraph.circuit import _REUSE, reuse_compiled
    with reuse_compiled():
        n0, hits0 = _REUSE["compilations"], _REUSE["hits"]
        first = orifice_bench(Q=1e-4, A=1e-6).compile()
        second = orifice_bench(Q=2e-4, A=3e-6).compile()
        assert _REUSE["compilations"] - n0 == 1 and _REUSE["hits"] - hits0 == 1
        for system, Q, A in ((first, 1e-4, 1e-6), (second, 2e-4, 3e-6)):
            assert steady_state(system, tol=1e-12)["node.port.p"] == pytest.approx(
                analytic({}, Q=Q, A=A), rel=1e-9)
        with pytest.warns(RecompileWarning, match=r"node\.air"):
            orifice_bench(air=0.01).compile()
        other = orifice_bench()                 # same parts, the orifice's ends swapped
        other._connections = [other._connections[0][:2] + (other["orifice"].b,),
                              (other["orifice"].a, other["tank"].port)]
        flipped = other.compile()
        assert _REUSE["compilations"] - n0 == 3
        # flow now enters the orifice at b: the same drop, the orifice flow reversed
        op = steady_state(flipped, tol=1e-12)
        assert op["orifice.q"] == pytest.approx(-1e-4, rel=1e-9)
    orifice_bench().compile()                   # outside the block: compiled as usual
    assert _REUSE["compilations"] - n0 == 3


def test_compiled_run_without_a_circuit_or_with_one_output_name():
    """Neither circuit nor build is named as such (the message said "not both"); one output
    name as a string is one output (it was read letter by letter)."""
    with pytest.raises(SweepError, match="neither was given"):
        CompiledRun(outputs=["node.port.p"], steady=True)
    run = CompiledRun(orifice_bench, outputs="node.port.p", steady=True, tol=1e-12)
    p = run(**{"orifice.A": 2e-6})["node.port.p"]
    assert p == pytest.approx(analytic({}, Q=1e-4, A=2e-6), rel=1e-8)


def test_a_case_with_other_connections_is_compiled_not_reused():
    """Two equal orifices in parallel or in series through a second volume: the same parts and
    parameters, another circuit. Reusing the parallel system for the series case would give
    7.55e5 Pa instead of the series closed form 2 rho/2 (Q/(Cd A))^2 = 6.04e6 Pa."""
    from pvgraph import Circuit
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    from pvgraph.errors import ParameterError

    def build(series=0):
        c = Circuit("topo")
        c.add("pump", FlowSource(Q=1e-4))
        c.add("n1", VolumeNode(V=5e-4))
        c.add("n2", VolumeNode(V=5e-4))
        c.add("o1", Orifice(A=2e-6, dp_t=1e3))
        c.add("o2", Orifice(A=2e-6, dp_t=1e3))
        c.add("tank", Tank())
        c.connect("pump.port", "n1.port", "o1.a")
        if series:
            c.connect("o1.b", "n2.port", "o2.a")
            c.connect("o2.b", "tank.port")
        else:
            c.connect("n1.port", "o2.a")
            c.connect("o1.b", "o2.b", "tank.port")
            c.connect("n2.port", "tank.port")
        return c
    with pytest.raises(ParameterError, match="connections or exposed ports differ"):
        build(0).compile().params_from(build(1))
    run = CompiledRun(build=build, outputs={"p": "n1.port.p"}, steady=True, tol=1e-12)
    with pytest.warns(RecompileWarning, match="builds another structure"):
        res = sweep(run, [{"series": 0}, {"series": 1}], backend="serial")
    q = lambda Q: 870.0 / 2 * (Q / (0.6 * 2e-6)) ** 2
    np.testing.assert_allclose(res.column("p"), [q(0.5e-4), 2 * q(1e-4)], rtol=1e-6)


@pytest.mark.parametrize("names, outputs, message", [
    ({"orifice.Area": [1e-6, 2e-6]}, {"p": "node.port.p"},
     r"no parameter named 'orifice.Area'. Close matches: \['orifice.A'"),
    ({"orifice.A": [1e-6, 2e-6]}, {"p": "node.port.pp"},
     r"output 'p': .*no variable or output named 'node.port.pp'"),
    ({"orifice.A": [1e-6, 2e-6]}, {"orifice.A": "orifice.A"},
     r"output 'orifice.A' has the name of a swept parameter"),
])
def test_names_wrong_for_every_case_are_refused_before_any_case_runs(tmp_path, names, outputs,
                                                                      message):
    # each case used to fail in its worker with the good message kept in the case record;
    # the sweep returned "0 ok, 2 failed" without a word
    run = CompiledRun(orifice_bench, outputs=outputs, steady=True)
    with pytest.raises(SweepError, match=message):
        sweep(run, grid(names), backend="serial", out=tmp_path / "study")
    assert not (tmp_path / "study").exists()       # nothing written


def test_an_output_folder_that_cannot_be_made_is_a_sweep_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    run = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, steady=True)
    with pytest.raises(SweepError, match=r"out=.*the folder cannot be made"):
        sweep(run, grid({"orifice.A": [1e-6]}), backend="serial", out=blocker / "study")


def test_structural_fields_and_a_first_case_refused_for_its_value_still_run():
    # the up-front name check refused a valid structural field (orifice.dp_t is not a
    # runtime parameter, yet with_params takes it by compiling again), and a build whose
    # first case raised for its value aborted the whole sweep
    run = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RecompileWarning)
        res = sweep(run, [{"orifice.dp_t": 1e4}, {"orifice.dp_t": 2e4}], backend="serial")
    assert [r.status for r in res] == ["ok", "ok"]

    def bench(A):
        if A <= 0:
            raise ValueError(f"A must be positive, got {A}")
        return orifice_bench(A=A)
    by_build = CompiledRun(build=bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    res = sweep(by_build, [{"A": -1.0}, {"A": 2e-6}], backend="serial")
    assert [r.status for r in res] == ["failed", "ok"]
    assert res[1].outputs["p"] == pytest.approx(analytic({}, Q=1e-4, A=2e-6), rel=1e-9)


@pytest.mark.parametrize("kwargs, message", [
    ({"t_end": 0.5, "rtol": -1}, "CompiledRun: rtol must be a number between 0 and 1"),
    ({"t_end": 0.5, "rtol": float("nan")}, "CompiledRun: rtol must be a number between 0"),
    ({"steady": True, "tol": 0.0}, "CompiledRun: tol must be a number between 0 and 1"),
    ({"t_end": 1.0, "steady": True}, "takes t_end= (simulate) or steady=True (steady "
                                     "states), not both"),
    ({}, "needs either t_end= (simulate) or steady=True"),
])
def test_compiled_run_checks_its_settings_when_made(kwargs, message):
    with pytest.raises(SweepError, match=re.escape(message)):
        CompiledRun(build=orifice_bench, outputs={"p": "node.port.p"}, **kwargs)


def test_random_sample_of_quantities_says_to_convert_them():
    from pvgraph.analysis import random_sample
    with pytest.raises(SweepError, match=r"random_sample: the range of 'orifice.A' takes "
                                         r"numbers \(SI\), got \('1 mm\^2', '2 mm\^2'\); "
                                         r"convert quantities first"):
        random_sample({"orifice.A": ("1 mm^2", "2 mm^2")}, 3)


def test_quantities_in_the_cases_are_recorded_in_si(tmp_path):
    """A case value written with a unit runs converted and is recorded as its SI number, so
    that a column of sweep.csv holds one kind of value."""
    run = CompiledRun(orifice_bench, outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    result = sweep(run, grid({"orifice.A": ["1 mm^2", 2e-6]}), backend="serial", out=tmp_path)
    assert list(result.column("orifice.A")) == [pytest.approx(1e-6), 2e-6]
    assert all(isinstance(r.params["orifice.A"], float) for r in result)
    p = result.column("p")
    assert p[0] == pytest.approx(RHO / 2 * (1e-4 / (CD * 1e-6)) ** 2, rel=1e-6)
    rows = (tmp_path / "sweep.csv").read_text().splitlines()
    assert [float(line.split(",")[3]) for line in rows[1:]] == [pytest.approx(1e-6), 2e-6]
    assert "mm^2" not in (tmp_path / "cases.jsonl").read_text()


def test_a_record_of_quantities_from_an_older_pvgraph_resumes(tmp_path):
    """A record written before the records were SI (its cases as typed, "1 mm^2") and before
    the run identity spelled a compiled run's factory: the same sweep resumed it before; it
    was refused as "another sweep" and "another run". It resumes, telling that the record
    is an older one."""
    import json
    from pvgraph.errors import PlausibilityWarning
    run = CompiledRun(orifice_bench(), outputs={"p": "node.port.p"}, steady=True, tol=1e-12)
    cases = [{"orifice.A": "1 mm^2"}, {"orifice.A": "2 mm^2"}]
    out = tmp_path / "rec"
    sweep(run, cases, backend="serial", out=out)
    log = out / "cases.jsonl"
    lines = log.read_text().splitlines()
    head = json.loads(lines[0])
    head["cases"] = cases                                    # as typed, as it was written
    head["run"] = "pvgraph.cli._noted_case with (CompiledRun of partial, p=node.port.p)"
    log.write_text("\n".join([json.dumps(head), lines[1]]) + "\n")   # one case finished
    with pytest.warns(PlausibilityWarning, match="recorded by an older pvgraph"):
        result = sweep(run, cases, backend="serial", out=out, resume=True)
    expected = [rebuilt(**{"orifice.A": a})["p"] for a in (1e-6, 2e-6)]
    assert [r.outputs["p"] for r in result.records] == pytest.approx(expected, rel=1e-9)
