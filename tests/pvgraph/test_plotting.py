"""Plots write real PNG files of the data asked for; bad names fail before anything is written."""

import os

import matplotlib.image as mpimg
import numpy as np
import pytest

from pvgraph.plotting import draw_circuit, plot_bode, plot_solution, plot_step_response
from pvgraph.simulate import simulate
from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit
from pvgraph.units import litre, lpm, mm2


def _png(path):
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300
    assert img[..., :3].std() > 0.01                    # not a blank canvas
    return img


def _demo():
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    return c


def test_time_series_in_engineering_units(tmp_path):
    sol = simulate(_demo(), 0.2)
    path = plot_solution(sol, ["node.port.p", "orifice.a.q"], tmp_path / "ts.png")
    img = _png(path)
    assert img.shape[0] > 400                              # two panels: bar and L/min


def test_misspelled_variable_fails_before_writing(tmp_path):
    sol = simulate(_demo(), 0.05)
    with pytest.raises(KeyError, match="node.port.p"):
        plot_solution(sol, ["node.port.pp"], tmp_path / "bad.png")
    assert not (tmp_path / "bad.png").exists()


def test_empty_names_and_a_directory_as_path_are_named(tmp_path):
    """plot_solution with no names or a directory for the file says so (matplotlib's
    'Number of rows must be a positive integer' / IsADirectoryError before)."""
    sol = simulate(_demo(), 0.05)
    with pytest.raises(ValueError, match="plot_solution: names is empty"):
        plot_solution(sol, [], tmp_path / "e.png")
    with pytest.raises(IsADirectoryError, match="is a directory; give a file name in it"):
        plot_solution(sol, ["node.port.p"], tmp_path)
    with pytest.raises(TypeError, match="plot_solution: names: names are strings"):
        plot_solution(sol, [1], tmp_path / "i.png")
    assert list(tmp_path.iterdir()) == []


def test_bode_step_and_circuit_drawings(tmp_path):
    f = np.logspace(-1, 2, 50)
    h = 1.0 / (1j * 2 * np.pi * f + 1.0)
    _png(plot_bode(f, [20 * np.log10(abs(h))], [np.degrees(np.angle(h))], tmp_path / "b.png"))
    t = np.linspace(0, 1, 50)
    _png(plot_step_response([(t, 1 - np.exp(-5 * t), "first order")], tmp_path / "s.png"))
    _png(draw_circuit(_demo(), tmp_path / "c.png"))
    dot = draw_circuit(_demo(), tmp_path / "c.dot", fmt="dot")
    with open(dot) as f:
        text = f.read()
    assert "digraph" in text or "graph" in text
    assert "orifice" in text and "tank" in text


def test_schematic_groups_sub_circuits_and_styles_domains(tmp_path):
    from pvgraph.components.mechanical import Fixed, SpoolMass
    from pvgraph.plotting import _schematic

    outer = Circuit("outer")
    inner = outer.add("bench", _demo())
    inner.expose("P", inner["node"].port)
    mass = outer.add("mass", SpoolMass(m=0.1))
    wall = outer.add("wall", Fixed())
    outer.connect(mass.flange, wall.flange)
    nodes, edges, groups = _schematic(outer)
    assert groups == ["", "bench"]
    assert nodes["bench.orifice"] == ("orifice", "Orifice", "bench")
    junctions = [n for n, v in nodes.items() if v[1] == "junction"]
    assert len(junctions) == 1                       # pump, node and orifice meet at one node
    # each end names the port it joins (a junction's side none)
    assert sorted((a, pa) for a, b, d, pa, pb in edges if b == junctions[0]) == \
        [("bench.node", "port"), ("bench.orifice", "a"), ("bench.pump", "port")]
    assert ("mass", "wall", "mechanical", "flange", "flange") in edges
    assert {e[2] for e in edges} == {"hydraulic", "mechanical"}
    dot = draw_circuit(outer, tmp_path / "o.dot")
    with open(dot) as f:
        text = f.read()
    assert 'subgraph "cluster_bench"' in text and "style=dashed" in text
    assert 'taillabel="flange", headlabel="flange"' in text
    svg = draw_circuit(outer, tmp_path / "o.svg")
    with open(svg) as f:
        assert "<svg" in f.read()
    _png(draw_circuit(outer, tmp_path / "o.png"))


def test_every_part_of_a_sub_circuit_lies_inside_its_band():
    """The band drawn for a sub-circuit spans [-(y0 + height) + 0.1, -y0 - 0.1]: each member's
    centre lies inside it, with half a row to spare from its edges."""
    from pvgraph.plotting import _layered_positions, _schematic
    outer = Circuit("outer")
    outer.add("bench", _demo())
    outer.add("rig", _demo())
    nodes, edges, groups = _schematic(outer)
    pos, spans = _layered_positions(nodes, edges, groups)
    for n, (_, _, grp) in nodes.items():
        top, bottom = spans[grp]
        assert -bottom + 0.5 - 1e-12 <= pos[n][1] <= -top - 0.5 + 1e-12, (n, pos[n], spans[grp])


def test_a_schematic_into_a_folder_is_refused_and_a_dot_file_makes_its_folder(tmp_path):
    from pvgraph import PvgraphError
    c = _demo()
    with pytest.raises(PvgraphError, match="is a folder; give the file to write"):
        draw_circuit(c, tmp_path)
    out = draw_circuit(c, tmp_path / "new" / "c.dot")
    assert os.path.exists(out)
