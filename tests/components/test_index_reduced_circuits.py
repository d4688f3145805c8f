"""Circuits users build that need index reduction, each against a closed-form answer.

A cylinder rod rigidly joined to two masses, a gas accumulator written with its gas volume as the
state on a line volume fed by a pump, and the PVG 32 main spool and its hand lever as two rigidly
joined bodies (report section 4.4.3, eqs. 4.67, 4.82) against the merged ``SpoolMass``.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import Field
from scipy.optimize import brentq

from pvgraph.circuits.pvg32.modules import FRICTION_V_EPS, STOP_ROUNDING
from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.components.hydraulic import Cylinder, FlowSource, Pump, Tank, VolumeNode
from pvgraph.components.hydraulic.volumes import P_ATM
from pvgraph.components.mechanical import (CenteringSpring, Damper, EndStop, ForceInput, Friction,
                                   SpoolMass)
from pvgraph.components.signal import Constant, Step
from pvgraph import Circuit, Component, Hydraulic, Params, Variable, der
from pvgraph.simulate import simulate


# cylinder rod + spool mass + load mass, fed by a flow source --------------------------------

A_A, A_ROD = 2e-3, 1e-3
Q, F_LOAD, D = 2e-4, 2000.0, 4e4       # [m^3/s], [N], [N s/m]


def cylinder_rig(masses):
    c = Circuit("cyl")
    cyl = c.add("cyl", Cylinder(A_A=A_A, A_rod=A_ROD, stroke=1.0, V_dead_A=2e-4, V_dead_B=2e-4))
    src = c.add("src", FlowSource(Q=Q))
    tank = c.add("tank", Tank())
    c.connect(src.port, cyl.A)
    c.connect(cyl.B, tank.port)
    bodies = [c.add(name, SpoolMass(m=m)) for name, m in masses.items()]
    damper = c.add("damper", Damper(d=D))
    load = c.add("load_force", ForceInput())
    k = c.add("k", Constant(k=-F_LOAD))
    c.connect(cyl.flange, *[b.flange for b in bodies], damper.flange, load.flange)
    c.connect(k.y, load.u)
    return c


def test_cylinder_rod_joined_to_spool_and_load_reaches_q_over_a_and_force_balance():
    s = cylinder_rig({"spool": 0.5, "load": 20.0}).compile()
    report = s.index_report()
    assert "spool equation 1 (SpoolMass): once" in report
    assert "load equation 1 (SpoolMass): once" in report
    sol = simulate(s, 0.5, rtol=1e-8, t_eval=np.linspace(0.0, 0.5, 51))
    v = Q / A_A
    assert sol["spool.v"][-1] == pytest.approx(v, rel=1e-6)
    assert np.allclose(sol["spool.v"], sol["load.v"], rtol=0, atol=1e-12)
    # force balance at steady velocity: p_A A_A = F_load + d v (B at tank pressure)
    assert sol["cyl.A.p"][-1] == pytest.approx((F_LOAD + D * v) / A_A, rel=1e-6)
    # the rod drives both masses with the same acceleration: f_k = m_k a
    a = sol.der("cyl.flange.x")
    assert np.allclose(sol["load.flange.f"] / 20.0, sol["spool.flange.f"] / 0.5, rtol=0,
                       atol=1e-6 * np.max(np.abs(sol["load.flange.f"] / 20.0)))
    assert a[-1] == pytest.approx(v, rel=1e-6)


def test_cylinder_with_joined_masses_matches_one_mass_of_the_sum():
    t = np.linspace(0.0, 0.05, 26)
    joined = simulate(cylinder_rig({"spool": 0.5, "load": 20.0}), 0.05, rtol=1e-9, t_eval=t)
    merged = simulate(cylinder_rig({"body": 20.5}), 0.05, rtol=1e-9, t_eval=t)
    assert np.allclose(joined["cyl.A.p"], merged["cyl.A.p"], rtol=1e-5, atol=1.0)
    assert np.allclose(joined["cyl.flange.x"], merged["cyl.flange.x"], rtol=0, atol=1e-9)


# a gas accumulator whose state is the gas volume --------------------------------------------

class GasVolumeParams(Params):
    p_pre: float = Field(..., gt=0.0, description="Precharge (gauge) pressure [Pa]")
    V_gas: float = Field(..., gt=0.0, description="Gas volume at the precharge pressure [m^3]")
    n: float = Field(1.4, ge=1.0, le=1.4, description="Polytropic exponent [-]")


class GasVolume(Component):
    """Gas-charged accumulator with the gas volume ``V`` as its state::

        (port.p + p_atm) * V^n = (p_pre + p_atm) * V_gas^n
        port.q = -der(V)                  (oil flowing in shrinks the gas)
    """

    Params = GasVolumeParams
    ports = {"port": Hydraulic("oil side")}
    variables = {"V": Variable("m^3", lambda p: p.V_gas, 1e-4, "gas volume")}

    def equations(self, v, p):
        return [(v.port.p + P_ATM) * v.V ** p.n - (p.p_pre + P_ATM) * p.V_gas ** p.n,
                v.port.q + der(v.V)]


def test_gas_accumulator_on_a_pumped_line_stores_the_pumped_volume():
    p_pre, V_gas, n, V_line, beta, Q_p = 20e5, 1e-3, 1.4, 2e-4, 1.2e9, 1e-4
    c = Circuit("acc")
    tank = c.add("tank", Tank())
    pump = c.add("pump", Pump(Q0=Q_p))
    line = c.add("line", VolumeNode(V=V_line, beta=beta, p0=p_pre))
    acc = c.add("acc", GasVolume(p_pre=p_pre, V_gas=V_gas, n=n))
    c.connect(tank.port, pump.a)
    c.connect(pump.b, line.port, acc.port)
    s = c.compile()
    report = s.index_report()
    assert "acc equation 1 (GasVolume): once" in report
    assert s.differential[s.index["acc.V"]]   # the gas volume is the state, as written
    t = np.linspace(0.0, 4.0, 9)
    sol = simulate(s, 4.0, rtol=1e-9, t_eval=t)

    def gas(p):
        return V_gas * ((p_pre + P_ATM) / (p + P_ATM)) ** (1.0 / n)

    # pumped volume = oil compressed in the line + gas volume given up
    def stored(p, tk):
        return V_line / beta * (p - p_pre) + V_gas - gas(p) - Q_p * tk
    p_exact = np.array([brentq(stored, p_pre - 1.0, 1e9, args=(tk,), xtol=1e-6) for tk in t])
    assert np.allclose(sol["line.port.p"], p_exact, rtol=1e-6)
    assert np.allclose(sol["acc.V"], gas(p_exact), rtol=1e-7)


# the PVG 32 main spool and its hand lever as two rigidly joined bodies ----------------------

def main_spool_bench(split: bool):
    """Main spool on its centring spring, friction and stops, pushed by a pilot-force step.

    The force step is the 13.5 bar pilot pressure on the spool end area A_m (report eq. 4.86,
    4.92); spring (eq. 4.88), viscous friction c_vm = 25 N s/m (table 4.14) and the +-7 mm stops
    (4.4.2) are those of the PVG 32 model (``pvgraph.circuits.pvg32.modules.build_pvb``).
    """
    m = report_tuned().main_spool
    c = Circuit("main_spool")
    if split:
        spool = c.add("main_spool", SpoolMass(m=m.spool_mass))
        lever = c.add("lever", SpoolMass(m=m.lever_equivalent_mass))
        bodies = [spool.flange, lever.flange]
    else:
        spool = c.add("main_spool", SpoolMass(m=m.spool_mass, m_lever=m.lever_equivalent_mass))
        bodies = [spool.flange]
    spring = c.add("main_spring", CenteringSpring(k=m.spring_rate, F0=m.spring_preload))
    friction = c.add("main_friction", Friction(F_c=m.coulomb_friction, b=m.viscous_friction,
                                               v_eps=FRICTION_V_EPS))
    stop = c.add("main_stop", EndStop(x_min=-m.stroke_max, x_max=m.stroke_max,
                                      eps=STOP_ROUNDING))
    push = c.add("pilot_force", ForceInput())
    step = c.add("step", Step(height=13.5e5 * m.spool_area, t_step=0.01))
    c.connect(*bodies, spring.flange, friction.flange, stop.flange, push.flange)
    c.connect(step.y, push.u)
    return c


def test_pvg32_spool_and_lever_joined_match_the_merged_spool_mass():
    t = np.linspace(0.0, 0.3, 301)
    merged = simulate(main_spool_bench(split=False), 0.3, rtol=1e-8, t_eval=t)
    s = main_spool_bench(split=True).compile()
    report = s.index_report()
    assert "lever equation 1 (SpoolMass): once" in report
    joined = simulate(s, 0.3, rtol=1e-8, t_eval=t)
    x_m, x_j = merged["main_spool.flange.x"], joined["main_spool.flange.x"]
    assert np.max(np.abs(x_m)) > 1e-3     # the spool moves millimetres
    assert np.allclose(x_j, x_m, rtol=0, atol=1e-6 * np.max(np.abs(x_m)) + 1e-9)
    assert np.allclose(joined["lever.v"], merged["main_spool.v"], rtol=0,
                       atol=1e-5 * np.max(np.abs(merged["main_spool.v"])))
    # the lever carries m_lever / (m + m_lever) of the net force on the pair
    m = report_tuned().main_spool
    f_lever, f_spool = joined["lever.flange.f"], joined["main_spool.flange.f"]
    moving = np.abs(f_lever) > 1e-3
    assert moving.sum() > 20
    share = f_lever[moving] / (f_lever[moving] + f_spool[moving])
    assert np.allclose(share, m.lever_equivalent_mass / m.total_mass, rtol=1e-6)


def _spool_and_lever(m, m_lever=0.0, **kwargs):
    """The main spool as two bodies on one flange: spool (eq. 4.67) and lever (eq. 4.82)."""
    if m_lever == 0.0:
        return SpoolMass(m=m, **kwargs)
    c = Circuit("main_spool")
    spool = c.add("spool", SpoolMass(m=m, **kwargs))
    lever = c.add("lever", SpoolMass(m=m_lever))
    c.connect(spool.flange, lever.flange)
    c.expose("flange", spool.flange)
    return c


def test_pvg32_rig_with_spool_and_lever_joined_matches_the_merged_model(monkeypatch):
    """Report 4.9 / figure 4.62: the closed-loop step to 3.5 mm of the full rig, once with the
    merged ``SpoolMass(m, m_lever)`` of ``build_pvb`` and once with the lever as its own body."""
    import pvgraph.circuits.pvg32.modules as modules
    from pvgraph.circuits.rig import build_rig
    from pvgraph.units import mm

    p = report_tuned()
    u = 11.5 * (-mm(3.5) + 0.014) / 0.028      # the input voltage that commands -3.5 mm
    t = np.linspace(0.0, 0.5, 51)
    merged = simulate(build_rig(p, U_input=u), 0.5, rtol=1e-6, t_eval=t)
    monkeypatch.setattr(modules, "SpoolMass", _spool_and_lever)
    s = build_rig(p, U_input=u).compile()
    assert "pvg.pvb.main_spool.lever equation 1 (SpoolMass): once" in s.index_report()
    joined = simulate(s, 0.5, rtol=1e-6, t_eval=t)
    x_m = merged["pvg.pvb.main_spool.flange.x"]
    x_j = joined["pvg.pvb.main_spool.spool.flange.x"]
    assert x_m[-1] == pytest.approx(-mm(3.5), rel=0.05)
    assert np.max(np.abs(x_j - x_m)) < 1e-4 * mm(3.5)
    for name in ("pvg.pve.V4.port.p", "pvg.pve.V5.port.p"):
        assert np.allclose(joined[name], merged[name], rtol=0, atol=1e-4 * np.ptp(merged[name]))
