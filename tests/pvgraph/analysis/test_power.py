"""Hydraulic power and the energy balance of the demo circuit."""

import sys
from pathlib import Path

import numpy as np
import pytest

from pvgraph.analysis import energy_balance, hydraulic_power
from pvgraph.simulate import simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_compiler import BETA, K, Q, V, demo  # noqa: E402


def test_power_signs_and_values():
    tau = V / (BETA * K)
    sol = simulate(demo(), 3 * tau, rtol=1e-8, t_eval=np.linspace(0, 3 * tau, 31))
    p = sol["node.port.p"]
    assert np.allclose(hydraulic_power(sol, "pump"), -Q * p, rtol=1e-12, atol=0)
    assert np.allclose(hydraulic_power(sol, "orifice"), K * p * p, rtol=1e-6, atol=1e-9)
    with pytest.raises(KeyError):
        hydraulic_power(sol, "nothing")


def test_energy_balance_closes():
    tau = V / (BETA * K)
    t = np.linspace(0, 4 * tau, 401)
    sol = simulate(demo(), 4 * tau, rtol=1e-8, t_eval=t)
    eb = energy_balance(sol, "pump", losses=("orifice",), volumes={"node": (V, BETA)})
    scale = np.max(eb["P_pump"])
    assert np.max(np.abs(eb["imbalance"])) < 1e-5 * scale
    # integral form, independent of the stored derivatives
    work = np.trapezoid(eb["P_pump"] - eb["P_loss"], t)
    assert work == pytest.approx(eb["E_stored"][-1] - eb["E_stored"][0], rel=1e-4)
    # at the end almost all delivered power is dissipated (steady state p = Q/K)
    assert eb["P_loss"][-1] == pytest.approx(Q * Q / K, rel=0.05)


def test_misnamed_components_and_volumes_are_named():
    """A misspelt component gets close matches, one loss name as a string is one name (it was
    read letter by letter), and a volume without (V, beta) is named."""
    tau = V / (BETA * K)
    t = np.linspace(0, 4 * tau, 101)
    sol = simulate(demo(), 4 * tau, rtol=1e-8, t_eval=t)
    with pytest.raises(KeyError, match="no component 'orifce' in this result; did you mean "
                                       "'orifice'"):
        hydraulic_power(sol, "orifce")
    with pytest.raises(TypeError, match="a component is named by its path"):
        hydraulic_power(sol, 3)
    one = energy_balance(sol, "pump", losses="orifice", volumes={"node": (V, BETA)})
    listed = energy_balance(sol, "pump", losses=["orifice"], volumes={"node": (V, BETA)})
    np.testing.assert_array_equal(one["P_loss"], listed["P_loss"])
    assert one["P_loss"][-1] == pytest.approx(Q * Q / K, rel=0.05)
    for bad in (1, "12", (V, -BETA)):
        with pytest.raises(ValueError, match=r"volumes\['node'\] must be \(V \[m\^3\], beta"):
            energy_balance(sol, "pump", volumes={"node": bad})
