"""Fluid description and the cavitation limit of volumes and chambers."""

import warnings

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from pvgraph.components.hydraulic import CheckValve, FlowSource, Orifice, VolumeNode
from pvgraph.components.hydraulic.fluid import (MINERAL_OIL, P_ATM, CavitationWarning, Fluid,
                                        cavitation_compliance)
from hydraulic_helpers import jacobian_fd_error, requires_solver
from pvgraph.circuit import Circuit
from pvgraph.errors import ParameterError
from pvgraph.simulate import simulate

V, BETA, P_VAP, DP_CAV = 1e-4, 7e8, 2e3, 3e3


def test_one_default_density_and_fluid_applies_to_any_part():
    assert Orifice(A=1e-6).params.rho == CheckValve(A=1e-6).params.rho == MINERAL_OIL.rho == 870.0
    oil = Fluid(rho=900.0, beta=1.5e9, air=0.01)
    assert oil.args_for(Orifice) == {"rho": 900.0, "nu": oil.nu}
    assert VolumeNode(V=1e-3, **oil.args_for(VolumeNode)).params.beta == 1.5e9
    assert oil.speed_of_sound == pytest.approx(np.sqrt(1.5e9 / 900.0))
    with pytest.raises(ParameterError, match="p_vap"):
        VolumeNode(V=1e-3, p_vap=-1.0)


def _compliance_law(p):
    """The documented cavitation term, written out independently: zero above p_vap + 10 dp_cav,
    ``s`` the smooth maximum of p_abs - p_vap and the floor 0.01 dp_cav (rounded within it)."""
    depth, floor = p + P_ATM - P_VAP, 0.01 * DP_CAV
    s = 0.5 * (depth + floor + np.hypot(depth - floor, floor))
    return max(DP_CAV / s - 0.1, 0.0) ** 3 / BETA if depth < 10 * DP_CAV else 0.0


def test_cavitation_term_is_zero_in_normal_operation_and_levels_off_at_the_vapour_pressure():
    fp = MINERAL_OIL
    assert cavitation_compliance(0.0, fp) == 0.0
    assert cavitation_compliance(-P_ATM + P_VAP + 10 * DP_CAV + 1.0, fp) == 0.0
    for s in (3e4 * 0.5, 3e3, 1.5e3):  # the floor (30 Pa) rounds s by < 1e-4 here
        p = s - P_ATM + P_VAP
        assert cavitation_compliance(p, fp) == pytest.approx(_compliance_law(p), rel=5e-4)
    # at and below the vapour pressure: (1/0.01 - 1/10)^3 / beta, rounded within the floor
    level = (100.0 - 0.1) ** 3 / BETA
    for depth in (1.0, -50.0, -1e3):
        got = cavitation_compliance(-P_ATM + P_VAP + depth, fp)
        assert 0.3 * level < got < 1.01 * level
        assert got == pytest.approx(_compliance_law(-P_ATM + P_VAP + depth), rel=1e-12)


def test_the_void_fraction_is_the_integral_of_the_cavitation_compliance():
    """d(void fraction)/dp = -compliance at every depth (so a chamber's oil balance holds as
    its wall moves), zero above p_vap + 10 dp_cav, the integral of the law from there."""
    from pvgraph.components.hydraulic.fluid import void_fraction
    fp = MINERAL_OIL
    assert void_fraction(0.0, fp) == 0.0
    for depth in (2e4, 3e3, 200.0, 31.0, 29.0, 1.0, -500.0):
        p, h = -P_ATM + P_VAP + depth, 1e-3
        slope = (void_fraction(p + h, fp) - void_fraction(p - h, fp)) / (2 * h)
        assert -slope == pytest.approx(cavitation_compliance(p, fp), rel=1e-6)
        top = -P_ATM + P_VAP + 10 * DP_CAV
        law = quad(_compliance_law, p, top, points=[-P_ATM + P_VAP + 0.01 * DP_CAV]
                   if depth < 0.01 * DP_CAV else None, limit=400, epsabs=1e-16,
                   epsrel=1e-12)[0]
        assert void_fraction(p, fp) == pytest.approx(law, rel=1e-7, abs=1e-13)


@requires_solver
def test_volume_drained_below_vacuum_stops_at_the_vapour_pressure_and_warns():
    Q, p0, T = 1e-6, 5e5, 1.6    # draws 1.6e-6 m^3 = 1.6 % of the volume
    c = Circuit("drain")
    c.add("vol", VolumeNode(V=V, p0=p0))
    c.add("sink", FlowSource(Q=-Q))
    c.connect("vol.port", "sink.port")
    t_linear = 0.9 * (p0 + P_ATM - 0.32e5) * V / (BETA * Q)     # still above the onset
    with pytest.warns(CavitationWarning, match=r"vol: .* at t = ([\d.e+-]+) s") as told:
        sol = simulate(c, T, rtol=1e-8, atol=1e-10, t_eval=[0.0, t_linear, T])
    # told at the user's call, with the time the pressure reached p_vap + dp_cav: after the
    # linear fall to the onset of the cavitation compliance, p_vap + 10 dp_cav
    warned = [w for w in told if issubclass(w.category, CavitationWarning)][0]
    assert warned.filename == __file__
    import re
    t_warn = float(re.search(r"at t = ([\d.e+-]+) s", str(warned.message)).group(1))
    assert (p0 + P_ATM - P_VAP - 10 * DP_CAV) * V / (BETA * Q) < t_warn < T
    assert sol["vol.port.p"][1] == pytest.approx(p0 - BETA * Q * t_linear / V, rel=1e-8)
    p_end = sol.final("vol.port.p")
    # the drawn volume equals the integral of V * compliance from p_end to p0
    drawn = quad(lambda p: V * (1.0 / BETA + _compliance_law(p)), p_end, p0,
                 points=[-P_ATM + P_VAP + 10 * DP_CAV], limit=200)[0]
    assert drawn == pytest.approx(Q * T, rel=1e-3)
    assert P_VAP < p_end + P_ATM < P_VAP + 100.0   # about 40 Pa above, as documented


@requires_solver
def test_no_warning_while_the_pressure_stays_above_the_limit():
    c = Circuit("fill")
    c.add("vol", VolumeNode(V=V))
    c.add("src", FlowSource(Q=1e-6))
    c.connect("vol.port", "src.port")
    with warnings.catch_warnings():
        warnings.simplefilter("error", CavitationWarning)
        sol = simulate(c, 0.01, rtol=1e-8)
    assert sol.final("vol.port.p") == pytest.approx(BETA * 1e-6 * 0.01 / V, rel=1e-8)


def test_jacobian_near_the_vapour_pressure():
    c = Circuit("j")
    c.add("vol", VolumeNode(V=V, p0=-P_ATM + P_VAP + 500.0))
    c.add("orf", Orifice(A=1e-6))
    c.add("tank", VolumeNode(V=V, p0=1e5))
    c.connect("vol.port", "orf.a")
    c.connect("orf.b", "tank.port")
    assert jacobian_fd_error(c.compile()) < 1e-5


def _orifice_circuit(fluid=None, **orifice):
    from pvgraph import Circuit
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
    c = Circuit("demo")
    if fluid is not None:
        c.use_fluid(fluid)
    c.add("pump", FlowSource(Q="6 L/min"))
    c.add("node", VolumeNode(V="0.5 L"))
    c.add("o", Orifice(A="2 mm^2", **orifice))
    c.add("tank", Tank())
    c.connect("pump.port", "node.port", "o.a")
    c.connect("o.b", "tank.port")
    return c


def test_a_circuit_fluid_reaches_every_part_that_was_not_given_its_own():
    """use_fluid(Fluid(rho=1000)): the orifice's drop rho/2 (Q/(Cd A))^2 grows by 1000/870;
    a part given its own density keeps it; a mapping works too, parts added later and parts
    of sub-circuits take it; a value the part refuses is told with the part's name."""
    from pvgraph import Circuit, ParameterError
    from pvgraph.analysis import steady_state
    from pvgraph.components import Fluid, Orifice
    base = steady_state(_orifice_circuit().compile())["node.port.p"]
    water = _orifice_circuit(Fluid(rho=1000.0, beta="22000 bar"))
    assert steady_state(water.compile())["node.port.p"] == pytest.approx(base * 1000.0 / 870.0,
                                                                         rel=1e-9)
    assert water["node"].params.beta == pytest.approx(2.2e9)
    own = _orifice_circuit(Fluid(rho=1000.0), rho=870.0)
    assert steady_state(own.compile())["node.port.p"] == pytest.approx(base, rel=1e-12)
    again = _orifice_circuit(Fluid(rho=1000.0)).use_fluid({"rho": 900.0})
    assert again["o"].params.rho == 900.0          # a later fluid replaces the earlier one
    outer = Circuit("outer").use_fluid({"rho": 950.0})
    inner = Circuit("inner")
    inner.add("o", Orifice(A="1 mm^2"))
    outer.add("sub", inner)
    assert inner["o"].params.rho == 950.0
    with pytest.raises(ParameterError, match=r"(?s)o: the circuit.s fluid does not fit.*Orifice.*"
                                             r"rho = 5.0"):
        _orifice_circuit().use_fluid({"rho": 5.0})


def test_a_sub_circuits_own_fluid_wins_for_its_properties_and_inherits_the_rest():
    """A sub-circuit given its own density keeps it and follows its parent's bulk modulus,
    also when the parent's changes later (it kept the parent's earlier one); a sub-circuit
    added to a circuit with a fluid takes the properties it does not give."""
    from pvgraph import Circuit
    from pvgraph.components import Orifice, VolumeNode
    top = Circuit("top")
    top_node = top.add("tn", VolumeNode(V=1e-4))
    sub = Circuit("sub")
    node, orf = sub.add("n", VolumeNode(V=1e-4)), sub.add("o", Orifice(A=1e-6))
    top.add("sub", sub)
    top.use_fluid({"beta": "15000 bar", "rho": 900.0})
    sub.use_fluid({"rho": 1000.0})
    assert (orf.params.rho, node.params.beta) == (1000.0, 1.5e9)
    top.use_fluid({"beta": "10000 bar", "rho": 850.0})
    assert (top_node.params.beta, node.params.beta, orf.params.rho) == (1e9, 1e9, 1000.0)
    later = Circuit("later").use_fluid({"rho": 800.0})
    late_orf, late_node = later.add("o", Orifice(A=1e-6)), later.add("n", VolumeNode(V=1e-4))
    top.add("later", later)
    assert (late_orf.params.rho, late_node.params.beta) == (800.0, 1e9)


def test_use_fluid_overrides_builders_values_when_asked_and_refuses_unknown_properties():
    """The PVG 32 builders give their parts the report's oil: use_fluid leaves those, and
    override=True replaces them (beta of a chamber, 7000 -> 10000 bar); a mapping adds to the
    circuit's fluid; a name that is not a fluid property is refused."""
    from pvgraph import Circuit, CircuitError
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig
    from pvgraph.components import Fluid, Orifice
    rig = build_rig(report_tuned())
    before = rig["pvg.pvb.V2"].params.beta
    rig.use_fluid(Fluid(beta=1e9))
    assert rig["pvg.pvb.V2"].params.beta == before
    rig.use_fluid(Fluid(beta=1e9), override=True)
    assert rig["pvg.pvb.V2"].params.beta == 1e9
    c = Circuit("x")
    c.add("o", Orifice(A="1 mm^2"))
    c.use_fluid({"rho": 900.0}).use_fluid({"nu": 1e-6})
    assert (c["o"].params.rho, c["o"].params.nu) == (900.0, 1e-6)
    with pytest.raises(CircuitError, match=r"'density' is not a fluid property; a fluid has "
                                           r"air, beta"):
        c.use_fluid({"density": 900.0})


def test_a_fluid_a_part_refuses_changes_nothing():
    """{"rho": 900, "beta": 1e3}: the orifice would take rho, the volume refuses beta: the
    error names the volume, and no part nor the circuit's fluid has changed; a part added to a
    circuit whose fluid it refuses is not added."""
    from pvgraph import Circuit, CircuitError, ParameterError
    from pvgraph.components import Orifice, VolumeNode
    c = Circuit("x")
    c.add("o", Orifice(A="1 mm^2"))
    c.add("node", VolumeNode(V="1 L"))
    with pytest.raises(ParameterError, match=r"node: the circuit's fluid does not fit"):
        c.use_fluid({"rho": 900.0, "beta": 1e3})
    assert c["o"].params.rho == 870.0 and c._fluid is None
    with pytest.raises(CircuitError, match=r"override=\.\.\.\) takes True or False"):
        c.use_fluid({"rho": 900.0}, override="yes")
    d = Circuit("y")
    # no part yet: the fluid's own model refuses it (it was kept, and saved, where no part
    # took it), and the circuit keeps none
    with pytest.raises(ParameterError, match=r"circuit 'y': its fluid: .*\n  beta = 1000.0: "
                                             r"Input should be greater than 1000000"):
        d.use_fluid({"beta": 1e3})
    assert d._fluid is None
    d.add("node", VolumeNode(V="1 L"))
    assert d["node"].params.beta == VolumeNode(V="1 L").params.beta


def test_use_fluid_takes_fluid_properties_only_and_checks_each_value():
    """A misspelt or non-fluid key (rhoo, Cd, an orifice's parameters) is refused, on an empty
    circuit too; a value no part could take is refused at once, though every part has its own
    (beta "5 bar" on the PVG 32 rig, below the 10 bar a bulk modulus takes)."""
    from pvgraph import Circuit, CircuitError, ParameterError
    from pvgraph.circuits.pvg32.parameters import report_tuned
    from pvgraph.circuits.rig import build_rig
    from pvgraph.components import Orifice
    for bad in ({"rhoo": 900.0}, {"Cd": 0.7}):
        with pytest.raises(CircuitError, match="not a fluid property; a fluid has air, beta"):
            Circuit("e").use_fluid(bad)
    with pytest.raises(CircuitError, match="are not fluid properties"):
        Circuit("e").use_fluid(Orifice(A=5e-6).params)
    with pytest.raises(ParameterError, match=r"(?s)pvg.pvp.Vp: the circuit's fluid does not "
                                             r"fit.*beta = '5 bar'"):
        build_rig(report_tuned()).use_fluid({"beta": "5 bar"})
    # a Fluid itself is checked as a part's parameters are: the field, the bound in units
    from pvgraph.components import Fluid
    with pytest.raises(ParameterError, match=r"invalid parameters for Fluid:\n  rho = -1: Input "
                                             r"should be greater than 100 \[kg/m\^3\]"):
        Fluid(rho=-1)
    with pytest.raises(ParameterError, match=r"beta = '5 bar' \(500000 Pa\): must be greater "
                                             r"than 1e\+06 Pa \(10 bar\)"):
        Fluid(beta="5 bar")
    with pytest.raises(ParameterError, match=r"rhoo = 5: not a parameter of Fluid; did you mean 'rho'\? it accepts"):
        Fluid(rhoo=5)


def test_a_chamber_cannot_start_below_the_vapour_pressure():
    """p0_A = -1 bar (1325 Pa absolute) lies below p_vap (2000 Pa): the chamber would start with
    a cavity larger than itself (void fraction 1.025, -5.5 cm^3 of oil), and compressing it
    lowered its pressure. Refused by name with the lowest start; the vapour pressure itself
    is a valid start."""
    from pvgraph import ParameterError
    from pvgraph.components import Cylinder, VolumeNode
    with pytest.raises(ParameterError, match=r"p0_A = -100000 Pa \(gauge\) is below the vapour "
                                             r"pressure .* p0_A=-99325"):
        Cylinder(A_A=1e-3, A_rod=5e-4, stroke=0.3, V_dead_A=1e-5, V_dead_B=1e-5, p0_A="-1 bar")
    with pytest.raises(ParameterError, match=r"p0 = -100000 Pa"):
        VolumeNode(V=1e-3, p0=-1e5)
    assert VolumeNode(V=1e-3, p0=-P_ATM + P_VAP).params.p0 == -P_ATM + P_VAP


def test_a_circuits_fluid_no_part_takes_is_checked_by_the_fluid_model():
    """{"rho": "1000 bar", "nu": -1, "beta": "abc"} on a circuit with no part that takes
    them (yet) was kept and saved without a word; every property is now checked by the
    library's Fluid (units, bounds), and nothing changes on a refusal."""
    from pvgraph import Circuit, ParameterError
    from pvgraph.components import FlowSource
    c = Circuit("demo")
    c.add("pump", FlowSource(Q="1 L/min"))
    with pytest.raises(ParameterError) as info:
        c.use_fluid({"rho": "1000 bar", "nu": -1, "beta": "abc"})
    text = str(info.value)
    assert "rho = '1000 bar' is a pressure, but rho is a density" in text
    assert "nu = -1: Input should be greater than 0" in text and "beta = 'abc'" in text
    assert c._fluid is None
    c.use_fluid({"rho": "1000 kg/m^3"})
    assert c._fluid == {"rho": "1000 kg/m^3"}
