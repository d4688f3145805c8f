"""Plots write real PNG files of the data asked for; bad names fail before anything is written."""

import matplotlib.image as mpimg
import numpy as np
import pytest

from circuits.pvg32.modules import build_pvb, opening_areas
from circuits.pvg32.parameters import report_tuned
from pvgraph.plotting import (draw_circuit, plot_bode, plot_opening_areas, plot_solution,
                              plot_step_response)
from pvgraph.simulate import simulate
from components import FlowSource, Orifice, Tank, VolumeNode
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


def test_opening_areas_are_the_ones_the_model_uses(tmp_path):
    p = report_tuned()
    areas = opening_areas(p)
    assert set(areas) == {"A1", "A2", "A3", "A_H"}
    pvb = build_pvb(p)
    pa = pvb["PA"].params                                  # P -> A edge, x > 0 half of A_H
    a_h = areas["A_H"]
    x = np.asarray(pa.x_table)                             # resampled every TABLE_STEP
    assert np.allclose(pa.A_table, np.where(x > 0, a_h(x), 0.0))
    # A2 = pi D x_k (eq. 4.38)
    a2 = areas["A2"]
    assert np.allclose(a2.area, np.pi * p.compensator.opening_diameter * a2.x)
    _png(plot_opening_areas(areas.values(), tmp_path / "areas.png"))


def test_bode_step_and_circuit_drawings(tmp_path):
    f = np.logspace(-1, 2, 50)
    h = 1.0 / (1j * 2 * np.pi * f + 1.0)
    _png(plot_bode(f, [20 * np.log10(abs(h))], [np.degrees(np.angle(h))], tmp_path / "b.png"))
    t = np.linspace(0, 1, 50)
    _png(plot_step_response([(t, 1 - np.exp(-5 * t), "first order")], tmp_path / "s.png"))
    _png(draw_circuit(_demo(), tmp_path / "c.png"))
    dot = draw_circuit(_demo(), tmp_path / "c.dot", fmt="dot")
    text = open(dot).read()
    assert "digraph" in text or "graph" in text
    assert "orifice" in text and "tank" in text
