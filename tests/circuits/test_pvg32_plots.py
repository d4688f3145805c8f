"""The PVG 32 figures draw the data the model uses."""

import matplotlib.image as mpimg
import numpy as np

from pvgraph.circuits.pvg32.modules import build_pvb, opening_areas
from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.plotting import plot_opening_areas


def _png(path):
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300
    assert img[..., :3].std() > 0.01                    # not a blank canvas
    return img


def test_opening_areas_are_the_ones_the_model_uses(tmp_path):
    p = report_tuned()
    areas = opening_areas(p)
    assert set(areas) == {"A1", "A2", "A3", "A_H"}
    pvb = build_pvb(p)
    pa = pvb["PA"].params                                  # P -> A edge, x > 0 half of A_H
    a_h = areas["A_H"]
    assert np.allclose(pa.A_table, np.where(a_h.x > 0, a_h.area, 0.0))
    # A2 = pi D x_k (eq. 4.38)
    a2 = areas["A2"]
    assert np.allclose(a2.area, np.pi * p.compensator.opening_diameter * a2.x)
    _png(plot_opening_areas(areas.values(), tmp_path / "areas.png"))
