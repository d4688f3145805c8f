"""The FMU of a circuit passes FMPy's model-description validation and, run by FMPy, gives what
pvgraph's own simulation gives, inputs changed between communication steps included."""

import numpy as np
import pytest

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit, ParameterError, PvgraphError
from pvgraph.simulate import simulate

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
from fmpy.validation import validate_fmu  # noqa: E402

from pvgraph.fmi import FmiError, export_fmu  # noqa: E402

Q1, Q2 = 10 / 60e3, 5 / 60e3    # [m^3/s] pump flow before and after t = 0.5 s


def demo(Q=Q1, A=2e-6):
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V="0.5 L"))
    orifice = c.add("orifice", Orifice(A=A))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    return c


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    path = tmp_path_factory.mktemp("fmu") / "demo.fmu"
    return export_fmu(demo(), path, inputs=["pump.Q"], outputs=["node.port.p", "orifice.q"],
                      parameters=["orifice.A"])


def test_the_model_description_is_valid(fmu):
    assert validate_fmu(fmu) == []
    md = fmpy.read_model_description(fmu)
    causality = {v.name: v.causality for v in md.modelVariables}
    assert causality == {"pump.Q": "input", "orifice.A": "parameter", "node.port.p": "output",
                         "orifice.q": "output"}
    assert md.coSimulation is not None
    # SI units on every variable, each defined by its exponents of the SI base units
    assert {v.name: v.unit for v in md.modelVariables} == {
        "pump.Q": "m^3/s", "orifice.A": "m^2", "node.port.p": "Pa", "orifice.q": "m^3/s"}
    base = {u.name: (u.baseUnit.kg, u.baseUnit.m, u.baseUnit.s) for u in md.unitDefinitions}
    assert base == {"Pa": (1, -1, -2), "m^2": (0, 2, 0), "m^3/s": (0, 3, -1)}


def test_fmu_with_an_input_step_matches_simulate(fmu):
    t = np.linspace(0.0, 1.5, 31)
    inputs = np.array([(0.0, Q1), (0.5, Q1), (0.5, Q2), (1.5, Q2)],
                      dtype=[("time", float), ("pump.Q", float)])
    res = fmpy.simulate_fmu(fmu, stop_time=1.5, output_interval=0.05, input=inputs,
                            output=["node.port.p", "orifice.q"])
    assert np.allclose(res["time"], t)
    # the same run in pvgraph: Q1 up to 0.5 s, then Q2 from the state reached
    first = simulate(demo(Q1), 0.5, rtol=1e-8, t_eval=t[:11])
    second = simulate(demo(Q2).compile(), 1.5, t_start=0.5, rtol=1e-8, t_eval=t[10:],
                      y0=first.y[-1], yp0=first.yp[-1])
    expected = np.concatenate([first["node.port.p"], second["node.port.p"][1:]])
    scale = expected.max()
    assert np.max(np.abs(res["node.port.p"] - expected)) < 2e-4 * scale
    # steady states: p = rho/2 (Q / (Cd A))^2, a quarter after halving the flow
    assert res["node.port.p"][10] == pytest.approx(870 / 2 * (Q1 / 1.2e-6) ** 2, rel=2e-3)
    assert res["node.port.p"][-1] == pytest.approx(870 / 2 * (Q2 / 1.2e-6) ** 2, rel=2e-3)
    assert res["orifice.q"][-1] == pytest.approx(Q2, rel=2e-3)


def test_a_parameter_set_before_the_run(fmu):
    res = fmpy.simulate_fmu(fmu, stop_time=1.0, output_interval=0.1,
                            start_values={"orifice.A": 4e-6}, output=["node.port.p"])
    assert res["node.port.p"][-1] == pytest.approx(870 / 2 * (Q1 / 2.4e-6) ** 2, rel=2e-3)


def test_export_refuses_unknown_names(tmp_path):
    with pytest.raises(ParameterError, match="Did you mean 'pump.Q'"):
        export_fmu(demo(), tmp_path / "x.fmu", inputs=["pump.QQ"], outputs=["node.port.p"])
    with pytest.raises(PvgraphError, match="'node.port.pp' is not a variable"):
        export_fmu(demo(), tmp_path / "x.fmu", outputs=["node.port.pp"])
    with pytest.raises(FmiError, match="ends in .fmu"):
        export_fmu(demo(), tmp_path / "x.zip", outputs=["node.port.p"])


def test_one_name_is_one_input_or_output(tmp_path):
    """outputs="node.port.p" is that variable, not its letters."""
    path = export_fmu(demo(), tmp_path / "one.fmu", inputs="pump.Q", outputs="node.port.p")
    md = fmpy.read_model_description(path)
    assert {v.name: v.causality for v in md.modelVariables} == {"pump.Q": "input",
                                                                "node.port.p": "output"}


def test_a_start_value_parameter_set_before_the_run_starts_the_fmu_there(tmp_path):
    """node.p0 = 50 bar set before the run: the node starts at 50 bar (it was copied back from
    the exported start, 0), and the outputs read before the first step show it."""
    c = demo()
    c["node"].params = c["node"].params.model_copy(update={"p0": 0.0})
    path = export_fmu(c, tmp_path / "p0.fmu", outputs=["node.port.p"], parameters=["node.p0"])
    res = fmpy.simulate_fmu(path, stop_time=0.02, output_interval=0.01,
                            start_values={"node.p0": 50e5}, output=["node.port.p"])
    assert res["node.port.p"][0] == pytest.approx(50e5, rel=1e-9)
    c["node"].params = c["node"].params.model_copy(update={"p0": 50e5})
    ref = simulate(c, 0.02, t_eval=[0.01, 0.02])
    np.testing.assert_allclose(res["node.port.p"][1:], ref["node.port.p"], rtol=1e-5)


def test_a_value_the_component_refuses_is_refused_when_set(fmu):
    """A negative area fails at fmi2SetReal, where it is given, not at the next step."""
    with pytest.raises(Exception, match="fmi2SetReal failed"):
        fmpy.simulate_fmu(fmu, stop_time=0.1, output_interval=0.05,
                          start_values={"orifice.A": -1e-6}, output=["node.port.p"])
