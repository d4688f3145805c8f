"""Quantities with units at the parameter boundary, and the display convention."""

import math
import re

import pytest

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph.components.signal.sources import TimeTable
from pvgraph import Circuit, ParameterError
from pvgraph.simulate import simulate
from pvgraph.units import (BAR, LPM, UnitError, angle_power, declared_unit, display,
                           format_value, lpm, litre, mm2, parse_unit, to_si, to_unit)




@pytest.mark.parametrize("text, unit, si", [
    ("150 bar", "Pa", 150e5), ("0.5 L", "m^3", 0.5e-3), ("10 L/min", "m^3/s", 10 / 60e3),
    ("2.2 mm^2", "m^2", 2.2e-6), ("2.2 mm2", "m^2", 2.2e-6), ("8 cm^3", "m^3", 8e-6),
    ("3 MPa", "Pa", 3e6), ("1e5 Pa", "Pa", 1e5), ("-3 mm", "m", -3e-3),
    ("0.45 L/(min bar)", "m^3/(s Pa)", 0.45e-3 / 60 / 1e5), ("100 psi", "Pa", 689475.7293168361),
    ("20 N s/m", "N s/m", 20.0), ("3000 rpm", "rad/s", 100 * math.pi),
])
def test_quantity_strings_convert_to_si(text, unit, si):
    assert to_unit(text, unit) == pytest.approx(si, rel=1e-14)


def test_conversion_to_a_declared_non_si_unit():
    # a field declared in %/mm takes "2 %/m" as 0.002 %/mm
    assert to_unit("2 %/m", "%/mm") == pytest.approx(0.002, rel=1e-14)
    assert parse_unit("L/min")[0] == LPM and parse_unit("bar")[0] == BAR


def test_wrong_dimension_is_refused_by_name():
    with pytest.raises(ParameterError, match=r"V = '0.5 bar' is a pressure, but V is a volume"):
        VolumeNode(V="0.5 bar")
    with pytest.raises(UnitError, match="unknown unit 'furlong'"):
        parse_unit("furlong")


def test_parameters_with_units_give_the_same_model_as_the_helpers():
    assert VolumeNode(V="0.5 L").params.V == litre(0.5)
    assert FlowSource(Q="10 L/min").params.Q == pytest.approx(lpm(10), rel=1e-15)
    assert Orifice(A="2 mm^2").params.A == mm2(2)
    assert Orifice(A=2e-6).params.A == 2e-6          # plain numbers stay SI


def test_a_circuit_in_units_reaches_the_orifice_law():
    """Pump into a volume drained by an orifice: steady p = rho/2 (Q / (Cd A))^2."""
    c = Circuit("units")
    pump = c.add("pump", FlowSource(Q="10 L/min"))
    node = c.add("node", VolumeNode(V="0.5 L"))
    orf = c.add("orifice", Orifice(A="2 mm^2", Cd=0.6, rho="870 kg/m^3"))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orf.a)
    c.connect(orf.b, tank.port)
    sol = simulate(c, 1.0)
    q = 10 / 60e3
    p_expected = 870 / 2 * (q / (0.6 * 2e-6)) ** 2
    assert sol.final("node.port.p") == pytest.approx(p_expected, rel=1e-3)


def test_pint_quantities_convert():
    pint = pytest.importorskip("pint")
    u = pint.UnitRegistry()
    assert VolumeNode(V=u.Quantity(500, "cm^3")).params.V == pytest.approx(5e-4, rel=1e-14)
    assert FlowSource(Q=10 * u.liter / u.minute).params.Q == pytest.approx(lpm(10), rel=1e-14)
    with pytest.raises(ParameterError, match="is a length, but V is a volume"):
        VolumeNode(V=u.Quantity(3, "m"))


def test_sequence_fields_take_units_elementwise():
    t = TimeTable(t=("0 s", "500 ms", "1 s"), y=(0.0, 1.0, 1.0))
    assert t.params.t == (0.0, 0.5, 1.0)


@pytest.mark.parametrize("value, message", [
    (True, "True is a bool, not a number"),
    (5e-324, "outside the magnitudes a model can compute with"),
    (1e305, "outside the magnitudes a model can compute with"),
    ("2 bananas", "unknown unit 'bananas'"),
])
def test_nonsense_values_get_named_errors(value, message):
    with pytest.raises(ParameterError, match=r"A = .*" + message.replace("(", r"\(")):
        Orifice(A=value)


def test_declared_units_and_display():
    assert declared_unit("Opening area [m^2] (report 4.3)") == "m^2"
    assert declared_unit("Gain [unit of y / unit of u]") is None
    assert display(150e5, "Pa") == (150.0, "bar")
    assert display(150e5, "Pa", si=True) == (150e5, "Pa")
    v, u = display(lpm(16.3), "m^3/s")
    assert u == "L/min" and v == pytest.approx(16.3, rel=1e-14)
    assert format_value(7e-3, "m") == "7 mm"
    assert format_value(1.0, "N") == "1 N"
    assert math.isclose(display(2e-3, "m^3")[0], 2.0)


@pytest.mark.parametrize("given, unit, expected", [
    ("1500 min^-1", "rad/s", 1500 * 2 * math.pi / 60),    # a datasheet's rotational speed n
    ("1500 1/min", "rad/s", 1500 * 2 * math.pi / 60),
    ("25 Hz", "rad/s", 50 * math.pi),
    ("1500 rpm", "rad/s", 50 * math.pi),
    ("10 deg/s", "rad/s", math.pi / 18),
    ("31.41592653589793 rad/s", "Hz", 5.0),               # w = 2 pi f
    ("300 rpm", "Hz", 5.0),
    ("2 rev/s", "Hz", 2.0),
    ("28 cm^3/rev", "m^3/rad", 28e-6 / (2 * math.pi)),
    ("100 N m/deg", "N m/rad", 100 * 180 / math.pi),
    ("0.25 rev", "rad", math.pi / 2),
])
def test_angles_are_counted_so_nothing_is_two_pi_off(given, unit, expected):
    assert to_unit(given, unit) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("given, unit, match", [
    ("28 cm^3", "m^3/rad", r"gives no angle, but D is per angle \[m\^3/rad\].*'... /rev'"),
    ("100 N m", "N m/rad", r"gives no angle, but D is per angle"),
    (0.5, "rad", None),
    ("0.5", "rad", r"'0.5' has no unit, and D is dimensionless \[rad\]: write the unit meant "
                   r"\('0.5 rad', or another such as '0.5 deg'\)"),
    ("1 rad", "-", r"counts an angle, but D \[-\] does not"),
])
def test_a_missing_or_extra_angle_is_refused_by_name(given, unit, match):
    if match is None:
        assert to_unit(given, unit, "D") == 0.5         # a plain number is SI, as always
        return
    with pytest.raises(UnitError, match=match):
        to_unit(given, unit, "D")


def test_pint_quantities_count_their_angles_too():
    pint = pytest.importorskip("pint")
    ureg = pint.UnitRegistry()
    assert to_unit(25 * ureg.Hz, "rad/s") == pytest.approx(50 * math.pi, rel=1e-12)
    assert to_unit(300 * ureg.rpm, "Hz") == pytest.approx(5.0, rel=1e-12)
    assert to_unit(28 * ureg("cm**3/turn"), "m^3/rad") == pytest.approx(28e-6 / (2 * math.pi),
                                                                         rel=1e-12)


def test_components_read_speeds_and_frequencies_as_a_designer_means_them():
    from pvgraph.components import FixedDisplacementPump, Sine, SpeedSource
    assert SpeedSource(w0="1500 min^-1").params.w0 == pytest.approx(50 * math.pi, rel=1e-12)
    assert Sine(amplitude=1.0, f="300 rpm").params.f == pytest.approx(5.0, rel=1e-12)
    with pytest.raises(ParameterError, match=r"D = '28 cm\^3' gives no angle"):
        FixedDisplacementPump(D="28 cm^3")


@pytest.mark.parametrize("given, unit, expected", [
    ("32 cSt", "m^2/s", 32e-6), ("1.5 t", "kg", 1500.0), ("30 cP", "Pa s", 0.03),
    ("2 MPa", "Pa", 2e6),
])
def test_viscosities_and_tonnes_as_datasheets_write_them(given, unit, expected):
    assert to_unit(given, unit) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("text, unit, want", [
    # NIST SP 811: 1 lbf = 4.4482216152605 N, 1 ft = 0.3048 m, 1 lb = 0.45359237 kg,
    # 1 kgf = 9.80665 N, 1 hp = 745.69987158227022 W, 1 gal (US) = 3.785411784 L
    ("114 lbf/in", "N/m", 114 * 4.4482216152605 / 0.0254),
    ("30 lbf ft", "N m", 30 * 4.4482216152605 * 0.3048),
    ("10 ft", "m", 3.048),
    ("4400 lb", "kg", 4400 * 0.45359237),
    ("150 kgf/cm^2", "bar", 150 * 9.80665e4 / 1e5),
    ("20 hp", "kW", 20 * 0.74569987158227022),
    ("5 gal", "L", 5 * 3.785411784),
    ("30 Nm", "N m", 30.0),
    ("2 mm²", "m^2", 2e-6),
    ("9.81 m/s²", "m/s^2", 9.81),
    ("50 percent", "-", 0.5),
    ("1800 RPM", "rad/s", 60 * math.pi),
    ("1800 r/min", "rad/s", 60 * math.pi),
    ("30 rps", "rad/s", 60 * math.pi),
    ("90°", "rad", math.pi / 2),
    ("2 hr", "s", 7200.0),
])
def test_us_customary_and_data_sheet_spellings(text, unit, want):
    assert to_unit(text, unit, "x") == pytest.approx(want, rel=1e-13)


def test_the_helpers_agree_with_the_quantity_strings():
    from pvgraph.units import cm, cm2, cm3_per_rev, rpm, to_rpm
    assert cm(5) == pytest.approx(to_unit("5 cm", "m"), rel=1e-15)
    assert cm2(20) == pytest.approx(to_unit("20 cm^2", "m^2"), rel=1e-15)
    assert rpm(1500) == pytest.approx(to_unit("1500 rpm", "rad/s"), rel=1e-15)
    assert to_rpm(rpm(1500)) == pytest.approx(1500.0, rel=1e-15)
    assert cm3_per_rev(28) == pytest.approx(to_unit("28 cm^3/rev", "m^3/rad"), rel=1e-15)
    assert cm3_per_rev(28) == pytest.approx(28e-6 / (2 * math.pi), rel=1e-15)


def test_a_bound_broken_by_a_quantity_is_told_in_its_unit():
    from pvgraph.components import FixedDisplacementPump, ReliefValve
    with pytest.raises(ParameterError, match=r"p_crack = '1500 bar' \(1.5e\+08 Pa\): must be at "
                                             r"most 1e\+08 Pa \(1000 bar\)"):
        ReliefValve(p_crack="1500 bar", A_s="50 mm^2", k=5e4, x_max="2 mm", w="10 mm")
    with pytest.raises(ParameterError, match=r"V = '-0.5 L' \(-0.0005 m\^3\): must be greater "
                                             r"than 0 m\^3 \(0 L\)"):
        VolumeNode(V="-0.5 L")
    with pytest.raises(ParameterError, match=r"eta_v = 95: .* \(a fraction: 95 % is 0.95"):
        FixedDisplacementPump(D="28 cm^3/rev", eta_v=95)


@pytest.mark.parametrize("text, unit, si", [
    ("0.5 inch", "m", 0.0127), ("2 inches", "m", 0.0508), ("3 feet", "m", 0.9144),
    ("1 foot", "m", 0.3048), ("5 USgpm", "m^3/s", 5 * 3.785411784e-3 / 60),
])
def test_spelled_out_customary_units(text, unit, si):
    assert to_unit(text, unit) == pytest.approx(si, rel=1e-14)


def test_component_start_values_take_quantities(tmp_path):
    """start={"port.p": "50 bar"} is 5e6 Pa, for the run, the model file and its export; a
    quantity of another dimension or a non-number is named at construction."""
    from pvgraph.modelfile import load, save
    node = VolumeNode(V="0.5 L", start={"port.p": "50 bar"})
    assert node._start == {"port.p": 5e6}
    c = Circuit("start")
    c.add("node", node)
    c.add("orifice", Orifice(A="2 mm^2"))
    c.add("tank", Tank())
    c.connect("node.port", "orifice.a")
    c.connect("orifice.b", "tank.port")
    sol = simulate(c, 1e-9)
    assert sol["node.port.p"][0] == pytest.approx(5e6, rel=1e-12)
    path = tmp_path / "start.toml"
    save(c, path)
    assert load(path)["node"]._start == {"port.p": 5e6}
    with pytest.raises(UnitError, match=r"start value 'port.p' = '50 L' is a volume"):
        VolumeNode(V="0.5 L", start={"port.p": "50 L"})
    with pytest.raises(ParameterError, match=r"start value 'port.p' = \[1\]: give a number"):
        VolumeNode(V="0.5 L", start={"port.p": [1]})


def test_a_plain_number_too_large_for_si_is_pointed_at_units():
    with pytest.raises(ParameterError, match=r"Q = 5: .* \[m\^3/s\]: a plain number is in m\^3/s; "
                                             r"give the unit with the number, e.g. "
                                             r"Q=\"5 L/min\""):
        FlowSource(Q=5)
    with pytest.raises(ParameterError, match=r"V = -1.0: Input should be greater than 0 "
                                             r"\[m\^3\]$"):
        VolumeNode(V=-1.0)


@pytest.mark.parametrize("text, si", [
    ("3000 PSI", 3000 * 6894.757293168361), ("100 BAR", 1e7), ("3 Bar", 3e5),
    ("10 LPM", 10 / 60000), ("10 GPM", 10 * 3.785411784e-3 / 60), ("69 degrees", 69 * math.pi / 180),
    ("1 degree", math.pi / 180), ("2 turns", 4 * math.pi), ("2 kNm", 2000.0),
])
def test_data_sheet_spellings_are_read(text, si):
    assert to_si(text) == pytest.approx(si, rel=1e-15)


@pytest.mark.parametrize("text, hint", [
    ("10 Lpm", "did you mean 'lpm' or 'LPM'?"), ("5 MPA", "did you mean 'MPa'?"),
    ("3 kpa", "did you mean 'kPa'?"), ("4 MM", "did you mean 'mm' or 'Mm'?"),
    ("1 barr", "did you mean 'bar'?"),
])
def test_a_unit_in_another_case_or_misspelt_is_refused_with_the_close_ones(text, hint):
    with pytest.raises(UnitError, match=re.escape(hint)):
        to_si(text)


def test_an_angle_per_turn_counts_the_angle():
    assert angle_power("cm^3/turn") == -1 and angle_power("degrees") == 1


def test_shaft_speeds_and_displacements_are_shown_in_rpm_and_cm3_per_rev():
    assert display(2.0 * math.pi * 1000.0 / 60.0, "rad/s") == pytest.approx((1000.0, "rpm"))
    assert display(28e-6 / (2.0 * math.pi), "m^3/rad") == pytest.approx((28.0, "cm^3/rev"))
    assert display(1.0, "rad/s", si=True) == (1.0, "rad/s")


@pytest.mark.parametrize("text, hint", [
    ("1 kpsi", "'psi' takes no SI prefix ('k'): write the number in 'psi' ('1000 psi' for "
               "'1 kpsi')"),
    ("1 Krpm", "'rpm' takes no SI prefix ('K')"),
    ("1 hPa", "the prefix 'h' (hecto) is not read: write '100 Pa' for '1 hPa'"),
])
def test_a_prefix_on_a_unit_that_takes_none_is_told_with_the_factor(text, hint):
    with pytest.raises(UnitError, match=re.escape(hint)):
        to_si(text)
    with pytest.raises(UnitError) as info:
        to_si("1 degC")
    assert "did you mean" not in str(info.value)      # not a misspelt 'deg'


def test_a_gauge_or_absolute_mark_is_refused_not_read_as_grams():
    # 'barg', 'psig', 'bara' were told "did you mean 'bar'?" without the reason
    for text in ("10 bar(g)", "10 barg", "150 psig", "1 bara", "5 kPag"):
        with pytest.raises(UnitError, match="a gauge or absolute mark is not read"):
            to_si(text)
    assert to_si("10 bar") == 1e6 and to_si("3 Pa") == 3.0


@pytest.mark.parametrize("text, unit, si", [
    ("1 500 kg", "kg", 1500.0),                 # digit groups (ISO 80000-1)
    ("15 000 N/m", "N/m", 15000.0),
    ("1 000 bar", "Pa", 1e8),
    ("1 200 L/min", "m^3/s", 0.02),
    ("100 000 Pa", "Pa", 1e5),
    ("-2 500.5 N", "N", -2500.5),
    ("1\u202f500 rpm", "rad/s", 1500 * 2 * math.pi / 60),   # a narrow no-break space
    ("10 1/s", "1/s", 10.0),                    # a "1/" numerator is no number in the unit
])
def test_digit_groups_are_one_number(text, unit, si):
    # "1 500 kg" was 1 x 500 kg and "15 000 N/m" was 15 x 0 N/m = 0, silently
    assert to_unit(text, unit) == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("text", ["2 3 bar", "1 5000 kg", "10 2 L/min", "3 bar 2"])
def test_a_number_inside_a_unit_is_refused(text):
    with pytest.raises(UnitError, match="number|unexpected"):
        to_unit(text, "Pa" if "bar" in text else ("kg" if "kg" in text else "m^3/s"))


def test_unit_errors_name_the_field_once_and_suggest_minutes():
    from pvgraph.components import FlowSource, VolumeNode
    with pytest.raises(ParameterError) as got:
        VolumeNode(V=1e-3, p0="10 bars")
    assert str(got.value).count("p0 = '10 bars'") == 1 and "did you mean 'bar'" in str(got.value)
    for text in ("10 L/mn", "10 L/Min"):
        with pytest.raises(ParameterError, match="did you mean 'min'"):
            FlowSource(Q=text)


@pytest.mark.parametrize("text, unit, si", [
    ("1 500/min", "1/s", 25.0), ("1500/min", "1/s", 25.0), ("1 500%", "1", 15.0),
    ("1500 min-1", "1/s", 25.0), ("3 m-2", "1/m^2", 3.0), ("5 N.m-1", "N/m", 5.0),
])
def test_per_units_and_powers_written_without_a_caret(text, unit, si):
    assert to_unit(text, unit) == pytest.approx(si, rel=1e-12)


@pytest.mark.parametrize("build, field", [
    (lambda: VolumeNode(V="0.5"), "V = '0.5' has no unit, and V is a volume"),
    (lambda: Orifice(A="2"), "A = '2' has no unit, and A is an area"),
    (lambda: Tank(p0="150"), "p0 = '150' has no unit, and p0 is a pressure")])
def test_a_quantity_string_without_its_unit_is_refused(build, field):
    """"150" for "150 bar" was read as 150 Pa (and "1500" rpm as 1500 rad/s), inside the
    bounds, without a word; a string is written to carry a unit. A number stays SI."""
    with pytest.raises(ParameterError, match=re.escape(field) + r".* or the number"):
        build()
    assert VolumeNode(V=0.5).params.V == 0.5


@pytest.mark.parametrize("written, told", [
    ("0.5 litre", "unknown unit 'litre'; did you mean 'L'?"),
    ("0,5 L", "write a decimal point, not a comma ('0.5 L' for '0,5 L')"),
    ("150 bar abs", "a gauge or absolute mark is not read; pressures are gauge here")])
def test_units_written_as_on_a_data_sheet_get_a_way_out(written, told):
    # "litre" and a decimal comma had no suggestion; "bar abs" was an unknown unit 'abs'
    unit = "Pa" if "bar" in written else "m^3"
    with pytest.raises(UnitError, match=re.escape(told)):
        to_unit(written, unit, "x")


def test_a_comma_before_three_digits_is_told_as_ambiguous():
    # "1,500 rpm" was told to become "1.500 rpm": 1000 times off if it meant fifteen hundred
    with pytest.raises(UnitError, match=r"neither as a thousands separator nor as a decimal "
                                        r"point: write '1500' or '1 500'"):
        to_unit("1,500 rpm", "rad/s", "w")
