"""The most likely mistakes of a new user: each error names the culprit and says what to do."""

import math
import warnings

import pytest

from components import FlowSource, Orifice, Tank, VolumeNode
from components.hydraulic import Plug, Pump
from components.hydraulic.variable_orifice import VariableOrifice
from components.mechanical import Fixed, ForceInput, SpoolMass
from pvgraph import Circuit
from pvgraph.errors import (CircuitError, ConnectionError_, ParameterError, PlausibilityWarning,
                            PvgraphError,
                            StructureError)
from pvgraph.simulate import simulate
from pvgraph.units import litre, lpm, mm2


def demo(connect=True):
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.5)))
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    tank = c.add("tank", Tank())
    if connect:
        c.connect(pump.port, node.port, orifice.a)
        c.connect(orifice.b, tank.port)
    return c


def test_misspelled_port_names_the_ports_and_suggests():
    orifice = demo(False)["orifice"]
    with pytest.raises(AttributeError) as exc:
        orifice.aa
    msg = str(exc.value)
    assert "'orifice'" in msg and "'aa'" in msg and "['a', 'b']" in msg
    assert "Did you mean 'a'?" in msg


def test_misspelled_component_in_string_connect():
    c = demo(False)
    with pytest.raises(CircuitError) as exc:
        c.connect("orifce.a", "node.port")
    msg = str(exc.value)
    assert "'orifce'" in msg and "'orifice'" in msg
    assert "Did you mean 'orifice'?" in msg


def test_no_tank_leaves_an_unconnected_port():
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    c.connect(pump.port, orifice.a)
    with pytest.raises(CircuitError) as exc:
        c.compile()
    msg = str(exc.value)
    assert "'orifice.b'" in msg and "not connected" in msg and "Plug" in msg


def test_flow_source_into_a_closed_plug_is_a_structural_contradiction():
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    plug = c.add("plug", Plug())
    c.connect(pump.port, plug.port)
    with pytest.raises(StructureError) as exc:
        c.compile()
    msg = str(exc.value)
    assert "plug.port" in msg and "pump.port" in msg and "Remove one of them" in msg


def test_flow_source_into_a_zero_area_valve_warns_of_the_absurd_pressure():
    """The model is solvable (the ideal source forces its flow through the closed valve's
    regularised law), but the pressure it needs is ~1e14 Pa: the run warns and names the node."""
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    valve = c.add("valve", VariableOrifice(opens="positive", w=0.01, x_dead=1e-3, A_leak=0.0))
    fix = c.add("fix", Fixed(x0=0.0))
    tank = c.add("tank", Tank())
    c.connect(pump.port, valve.a)
    c.connect(valve.b, tank.port)
    c.connect(valve.flange, fix.flange)
    with pytest.warns(PlausibilityWarning) as rec:
        sol = simulate(c, 0.1)
    msg = str(rec[0].message)
    assert "pump.port.p" in msg and "implausible pressure" in msg and "relief valve" in msg
    assert sol.final("pump.port.p") > 1e10          # the result is still returned


def test_pump_into_a_closed_volume_warns_when_pressure_passes_the_limit():
    """dp/dt = beta Q / V: 10 L/min into 0.1 L at 1.4 GPa passes 10 000 bar at 0.43 s and reaches
    14 000 bar at 0.6 s."""
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    node = c.add("node", VolumeNode(V=litre(0.1), beta=1.4e9))
    c.connect(pump.port, node.port)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate(c, 0.3)                            # 8 400 bar: no warning yet
    with pytest.warns(PlausibilityWarning, match=r"node.port.p .*reaches 1.4e\+04 bar .*t = 0.4"):
        simulate(c, 0.6)


def test_nan_parameter():
    with pytest.raises(ParameterError) as exc:
        Orifice(A=math.nan)
    msg = str(exc.value)
    assert "Orifice" in msg and "A = nan" in msg and "finite" in msg


def test_negative_area():
    with pytest.raises(ParameterError) as exc:
        Orifice(A=-1e-6)
    msg = str(exc.value)
    assert "Orifice" in msg and "A = -1e-06" in msg and "greater than 0" in msg


def test_missing_and_unknown_parameters_are_named_with_what_is_accepted():
    """A missing parameter is named as required; an unknown keyword lists the accepted ones."""
    from components.hydraulic import Cylinder
    with pytest.raises(ParameterError) as exc:
        Cylinder(D_piston=0.04, stroke=0.3)
    msg = str(exc.value)
    assert "A_A: required parameter not given" in msg
    assert "D_piston = 0.04: not a parameter of Cylinder; it accepts" in msg
    assert "A_rod" in msg.split("it accepts", 1)[1]


def test_circuit_without_volume_still_simulates():
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    tank = c.add("tank", Tank())
    c.connect(pump.port, orifice.a)
    c.connect(orifice.b, tank.port)
    sol = simulate(c, 1.0)
    assert sol.final("pump.port.p") == pytest.approx(83.9e5, rel=1e-3)   # README's 83.9 bar


def test_hydraulic_port_joined_to_a_mechanical_one():
    """Refused at connect(), where the mistake is made, and nothing is recorded."""
    c = Circuit("c")
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    mass = c.add("mass", SpoolMass(m=1.0))
    with pytest.raises(ConnectionError_) as exc:
        c.connect(orifice.a, mass.flange)
    msg = str(exc.value)
    assert "mass.flange (mechanical)" in msg and "orifice.a (hydraulic)" in msg
    assert "one domain only" in msg and "PistonChamber" in msg
    assert c._connections == []


def test_two_tanks_on_one_node():
    c = Circuit("c")
    pump = c.add("pump", FlowSource(Q=lpm(10)))
    t1, t2 = c.add("tank1", Tank()), c.add("tank2", Tank())
    c.connect(pump.port, t1.port, t2.port)
    with pytest.raises(StructureError) as exc:
        c.compile()
    msg = str(exc.value)
    assert "tank2.port" in msg and "two pressure sources on one node" in msg
    assert "Remove one of them" in msg


def test_signal_input_not_connected():
    c = Circuit("c")
    force = c.add("force", ForceInput())
    mass = c.add("mass", SpoolMass(m=1.0))
    c.connect(force.flange, mass.flange)
    with pytest.raises(CircuitError) as exc:
        c.compile()
    msg = str(exc.value)
    assert "'force.u'" in msg and "not driven" in msg and "Constant" in msg


def test_misspelled_variable_name_in_solution():
    sol = simulate(demo(), 0.1)
    with pytest.raises(KeyError) as exc:
        sol["node.port.pp"]
    msg = str(exc.value)
    assert "'node.port.pp'" in msg and "'node.port.p'" in msg and "Close matches" in msg


def test_start_value_for_a_fixed_variable():
    with pytest.raises(PvgraphError) as exc:
        simulate(demo(), 0.1, start={"tank.port.p": 1e5})
    msg = str(exc.value)
    assert "'tank.port.p'" in msg and "fixed" in msg
    # proposed: a ParameterError/InitializationError subclass, and "remove it from start= or
    # change the Tank's p0"
    assert type(exc.value) is PvgraphError


def test_pump_without_tank_names_the_suction_port():
    c = Circuit("c")
    pump = c.add("pump", Pump(Q0=lpm(10)))
    orifice = c.add("orifice", Orifice(A=mm2(2)))
    c.connect(pump.b, orifice.a)
    with pytest.raises(CircuitError) as exc:
        c.compile()
    assert "'pump.a'" in str(exc.value) and "not connected" in str(exc.value)
