"""Model files: a circuit saved as TOML or JSON loads back to the same equations."""

import json

import numpy as np
import pytest

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.modelfile import ModelFileError, dumps, load, loads, save, schema, to_dict
from pvgraph.simulate import simulate

TEXT = '''# a pump, a volume and an orifice to tank
format = 1
name = "demo"
connections = [["pump.port", "node.port", "orifice.a"], ["orifice.b", "tank.port"]]

[components.pump]
type = "FlowSource"
params = { Q = "10 L/min" }

[components.node]
type = "VolumeNode"
params = { V = "0.5 L" }
start = { "port.p" = 1e5 }

[components.orifice]
type = "Orifice"
params = { A = "2 mm^2" }

[components.tank]
type = "Tank"
'''


def _nested():
    inner = Circuit("bench")
    pump = inner.add("pump", FlowSource(Q="10 L/min"))
    node = inner.add("node", VolumeNode(V="0.5 L", start={"port.p": 2e5}))
    orifice = inner.add("orifice", Orifice(A="2 mm^2"))
    inner.connect(pump.port, node.port, orifice.a)
    inner.expose("out", orifice.b, "to the tank")
    outer = Circuit("outer")
    outer.add("bench", inner)
    tank = outer.add("tank", Tank())
    outer.connect("bench.out", tank.port)
    return outer


def _same_system(a, b):
    sa, sb = a.compile(), b.compile()
    assert sa.names == sb.names and sa.units == sb.units
    assert np.array_equal(sa.y0, sb.y0)
    rng = np.random.default_rng(0)
    for _ in range(3):
        y = sa.y0 + rng.normal(size=sa.n) * sa.nominal
        yp = rng.normal(size=sa.n) * sa.nominal
        assert np.array_equal(sa.residual(0.1, y, yp), sb.residual(0.1, y, yp))


def test_a_hand_written_file_reaches_the_orifice_law(tmp_path):
    path = tmp_path / "demo.toml"
    path.write_text(TEXT)
    c = load(path)
    assert c["node"].params.V == pytest.approx(5e-4, rel=1e-15)
    sol = simulate(c, 1.0)
    q = 10 / 60e3
    assert sol.final("node.port.p") == pytest.approx(870 / 2 * (q / (0.6 * 2e-6)) ** 2, rel=1e-3)


@pytest.mark.parametrize("fmt", ["toml", "json"])
def test_round_trip_keeps_every_float_and_the_hierarchy(fmt, tmp_path):
    c = _nested()
    path = save(c, tmp_path / f"c.{fmt}")
    back = load(path)
    assert to_dict(back) == to_dict(c)
    assert back["bench.node"]._start == {"port.p": 2e5}
    _same_system(c, back)
    with open(path) as f:
        assert dumps(back, fmt) == f.read()


def test_the_schema_describes_the_format():
    s = schema()
    assert set(s["properties"]) == {"format", "name", "components", "connections", "expose",
                                    "fluid"}
    assert "ComponentEntry" in s["$defs"] and "CircuitEntry" in s["$defs"]
    json.dumps(s)


@pytest.mark.parametrize("change, message", [
    (('"10 L/min"', '"10 bar"'), "line 8 (components.pump.params): invalid parameters for "
                                 "FlowSource:\n  Q = '10 bar' is a pressure"),
    (('"Orifice"', '"Orifce"'), "line 16 (components.orifice.type): unknown component type "
                                "'Orifce'; did you mean 'Orifice'"),
    (('"tank.port"]]', '"tank.prt"]]'), "line 4 (connections.1): Tank 'tank' has no port 'prt'"),
    (("params = { A", "parms = { A"), "line 17 (components.orifice.parms): unknown key 'parms'"),
    (("[components.tank]", "[components.tank"), "line 19: not valid TOML"),
    (("format = 1", "format = 2"), "line 2 (format): Input should be 1"),
    (('"port.p" = 1e5', '"port.pp" = 1e5'), "line 13 (components.node.start)"),
    (("[components.tank]", '[components."tank\\n"]'),
     'line 19 (components."tank\\n"): circuit \'demo\': component name \'tank\\n\' is not'),
])
def test_errors_name_the_line(change, message):
    with pytest.raises(ModelFileError) as exc:
        loads(TEXT.replace(*change), source="demo.toml")
    assert f"demo.toml, {message}" in str(exc.value)


def test_json_errors_name_the_line():
    text = json.dumps({"format": 1, "name": "x", "components": {
        "tank": {"type": "Tank", "params": {"p0": "1 m"}}}}, indent=1)
    with pytest.raises(ModelFileError, match=r"x.json, line 7 \(components.tank.params\)"):
        loads(text, "json", source="x.json")
    with pytest.raises(ModelFileError, match=r"x.json, line 1: not valid JSON"):
        loads("{", "json", source="x.json")


def test_no_code_runs_from_a_file():
    """A type is looked up among library classes; a module the file names is not imported."""
    text = TEXT.replace('"Tank"', '"os:system"')
    with pytest.raises(ModelFileError, match="'os:system' is not in the library"):
        loads(text)
    with pytest.raises(ModelFileError, match="a model file is .toml or .json"):
        load("circuit.pickle")


def test_a_bad_port_in_a_connection_list_of_many_lines_names_its_own_line():
    """Exported files write one connection per line: the error names the line of the
    connection that holds the bad port, not the line of ``connections = [``."""
    text = dumps(loads(TEXT), "toml")
    bad = text.replace('"tank.port"', '"tank.prt"')
    line = next(k + 1 for k, row in enumerate(bad.splitlines()) if '"tank.prt"' in row)
    assert line > next(k + 1 for k, row in enumerate(bad.splitlines())
                       if row.startswith("connections"))
    with pytest.raises(ModelFileError, match=rf"demo.toml, line {line} \(connections.1\): "
                                             rf"Tank 'tank' has no port 'prt'"):
        loads(bad, source="demo.toml")


def test_a_key_given_twice_in_a_json_file_is_refused_with_its_line():
    """JSON keeps the last of two equal keys silently (TOML refuses them): two "pump"
    components, or A given twice, are named at the line of the second."""
    text = json.dumps({"format": 1, "name": "x", "components": {
        "tank": {"type": "Tank", "params": {"p0": 0.0}}}}, indent=1)
    twice = text.replace('"p0": 0.0', '"p0": 0.0,\n    "p0": 1.0')
    line = next(k + 1 for k, row in enumerate(twice.splitlines()) if '"p0": 1.0' in row)
    with pytest.raises(ModelFileError, match=rf'x.json, line {line}: the key "p0" is given twice'):
        loads(twice, "json", source="x.json")


def test_an_unconnected_port_of_a_file_names_the_file_and_the_component_line():
    from pvgraph.errors import CircuitError
    text = dumps(loads(TEXT), "toml")
    cut = "\n".join(row for row in text.splitlines() if '"tank.port"' not in row)
    line = next(k + 1 for k, row in enumerate(cut.splitlines())
                if row.startswith("[components.orifice]"))
    circuit = loads(cut, source="demo.toml")
    with pytest.raises(CircuitError, match=rf"demo.toml, line {line} \(components.orifice\): "
                                           rf"port 'orifice.b' \(hydraulic\) is not connected"):
        circuit.compile()


def test_a_component_defined_in_a_function_cannot_be_saved_and_says_why(tmp_path):
    """A model file names types by module; a class no module can give back (defined in a
    script or a function) is refused, naming it, and no file is written."""
    from pydantic import Field

    from pvgraph import Component, Hydraulic, Params
    from pvgraph.components import FlowSource, Tank
    from pvgraph.modelfile import ModelFileError, save

    class LeakParams(Params):
        K: float = Field(..., gt=0, description="Leakage coefficient [m^3/(s Pa)]")

    class Leak(Component):
        Params = LeakParams
        ports = {"a": Hydraulic("high side"), "b": Hydraulic("low side")}

        def equations(self, v, p):
            return [v.a.q - p.K * (v.a.p - v.b.p), v.a.q + v.b.q]
    c = Circuit("leaky")
    c.add("src", FlowSource(Q="1 L/min"))
    c.add("leak", Leak(K=1e-11))
    c.add("t", Tank())
    c.connect("src.port", "leak.a")
    c.connect("leak.b", "t.port")
    path = tmp_path / "leaky.toml"
    with pytest.raises(ModelFileError, match=r"Leak is defined in .*, not in a module a model "
                                             r"file can name"):
        save(c, path)
    assert not path.exists()


@pytest.mark.parametrize("text, message", [
    ('format = 1\nname = "m"\nconnections = []\n\n[components.tank]\ntype = "Tank"\n\n'
     '[components.orifice]\nparams = { A = "2 mm^2" }\n\n[components.t2]\ntype = "Tank"\n',
     r"m.toml, line 8 \(components.orifice.type\): no type: give the component's class"),
    ('format = 1\nname = "m"\nconnections = []\nexpose = { P = "tank.port" }\n\n'
     '[components.tank]\ntype = "Tank"\n',
     r"line 4 \(expose.P\): an exposed port is written P = \{ port = \"component.port\" \}"),
])
def test_model_file_mistakes_are_told_at_their_line_in_plain_words(text, message, tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(text)
    with pytest.raises(ModelFileError, match=message):
        load(path)


def test_a_fluid_in_the_file_reaches_the_parts_not_given_their_own(tmp_path):
    """fluid = { rho = 1000 } at the top: the orifice's drop rho/2 (Q/(Cd A))^2 is that of
    water; a sub-circuit's own fluid wins in it; saved and read back, the same; a fluid a part
    refuses is told at the fluid's line."""
    text = TEXT.replace('name = "demo"', 'name = "demo"\nfluid = { rho = 1000, beta = "15000 bar" }')
    path = tmp_path / "water.toml"
    path.write_text(text)
    c = load(path)
    assert c["orifice"].params.rho == 1000.0 and c["node"].params.beta == pytest.approx(1.5e9)
    sol = simulate(c, 1.0)
    q = 10 / 60e3
    assert sol.final("node.port.p") == pytest.approx(1000 / 2 * (q / (0.6 * 2e-6)) ** 2, rel=1e-3)
    back = load(save(c, tmp_path / "again.toml"))
    assert to_dict(back) == to_dict(c)
    # the fluid's values are written once, in its table: an edit there reaches the parts
    again = (tmp_path / "again.toml").read_text()
    assert "rho = 1000" in again and again.count("rho") == 1
    edited = again.replace("rho = 1000", "rho = 500")
    assert loads(edited)["orifice"].params.rho == 500.0
    # a Fluid with every property and numpy numbers save and load
    import numpy as np
    from pvgraph.components import Fluid
    full = load(path)
    full.use_fluid(Fluid(rho=np.float64(950.0)))
    assert load(save(full, tmp_path / "full.toml"))["orifice"].params.rho == 950.0
    typo = TEXT.replace('name = "demo"', 'name = "demo"\nfluid = { density = 1000 }')
    with pytest.raises(ModelFileError, match=r"line 4 \(fluid\): 'density': not a fluid "
                                             r"property"):
        loads(typo, source="typo.toml")
    bad = TEXT.replace('name = "demo"', 'name = "demo"\nfluid = { rho = 5 }')
    with pytest.raises(ModelFileError, match=r"(?s)bad.toml, line 4 \(fluid\): orifice: .*rho = 5"):
        loads(bad, source="bad.toml")


def test_every_mistake_of_a_file_is_told_at_once_by_line():
    """A misspelt unit, a misspelt type and a connection to a misspelt component: one
    error tells all three, each with its line, in file order. The connections that name a
    component left out (the misspelt type's) are not told again."""
    text = "\n".join([
        'format = 1',
        'name = "demo"',
        'connections = [["pump.port", "node.port", "orifice.a"], ["orifice.b", "tank.port"],',
        '               ["node.port", "tnk.port"]]',
        '[components.pump]',
        'type = "FlowSource"',
        'params = { Q = "10 L/mn" }',
        '[components.node]',
        'type = "VolumeNode"',
        'params = { V = "0.5 L" }',
        '[components.orifice]',
        'type = "Orifise"',
        '[components.tank]',
        'type = "Tank"'])
    with pytest.raises(ModelFileError) as info:
        loads(text, source="demo.toml")
    lines = str(info.value).splitlines()
    assert lines[0] == "3 mistakes in demo.toml:"
    told = [line.strip() for line in lines[1:] if line.startswith("  demo.toml")]
    assert [t.split(" (")[0] for t in told] == ["demo.toml, line 3", "demo.toml, line 7",
                                               "demo.toml, line 12"]
    assert "'tnk'" in told[0] and "Did you mean 'tank'" in told[0]
    assert "unknown unit 'mn'" in str(info.value) and "'Orifise'" in told[2]
    # one mistake keeps the one-line message
    with pytest.raises(ModelFileError, match=r"^demo.toml, line 12 \(components.orifice.type\)"):
        loads(text.replace("10 L/mn", "10 L/min").replace('"tnk.port"', '"tank.port"'),
              source="demo.toml")


@pytest.mark.parametrize("start, message", [
    ('{ "port.p" = "5 barr" }', r"m.toml, line 13 \(components.node.start\): VolumeNode start "
                                r"value 'port.p' = '5 barr': unknown unit 'barr'"),
    ('{ "port.p" = "5 L" }', r"m.toml, line 13 \(components.node.start\): .* is a volume"),
])
def test_a_bad_start_value_is_told_at_its_own_line(start, message, tmp_path):
    text = TEXT.replace('start = { "port.p" = 1e5 }', f"start = {start}")
    lines = text.splitlines()
    assert lines[12].startswith("start") and lines[11].startswith("params")
    path = tmp_path / "m.toml"
    path.write_text(text)
    with pytest.raises(ModelFileError, match=message):
        load(path)


def test_an_empty_model_file_is_named(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text('format = 1\nname = "nothing"\n')
    with pytest.raises(ModelFileError, match=r"empty.toml \(top level\): the model file holds "
                                             r"no components"):
        load(path)


def test_a_circuit_without_components_is_not_saved(tmp_path):
    path = tmp_path / "e.toml"
    with pytest.raises(ModelFileError, match=r"circuit 'empty' has no components: a model file "
                                             r"of it could not be loaded"):
        save(Circuit("empty"), path)
    assert not path.exists()


def test_a_files_fluid_is_checked_though_every_part_gives_its_own():
    """fluid = { rho = "1000 bar" } in a file whose parts all give their own rho was kept,
    run and saved again; it is refused at its line, as Circuit.use_fluid refuses it."""
    text = "\n".join([
        'format = 1', 'name = "demo"', 'fluid = { rho = "1000 bar" }',
        'connections = [["pump.port", "node.port", "o.a"], ["o.b", "tank.port"]]',
        '[components.pump]', 'type = "FlowSource"', 'params = { Q = "10 L/min" }',
        '[components.node]', 'type = "VolumeNode"', 'params = { V = "0.5 L", beta = "7000 bar" }',
        '[components.o]', 'type = "Orifice"', 'params = { A = "2 mm^2", rho = 870, nu = 3.2e-5 }',
        '[components.tank]', 'type = "Tank"'])
    with pytest.raises(ModelFileError, match=r"(?s)^demo.toml, line 3 \(fluid\): .*rho = .1000 bar. "
                                             r"is a pressure, but rho is a density"):
        loads(text, source="demo.toml")
    assert loads(text.replace('"1000 bar"', '"1000 kg/m^3"'), source="demo.toml")
