"""PVG 32 parameters (circuits.pvg32.parameters) and tables (circuits.pvg32.tables).

Values are checked against the report (sections 4.2-4.7, tables 4.7-4.9, 4.14).
"""

import math

import numpy as np
import pytest
from pydantic import ValidationError

from pvgraph.circuits.pvg32.parameters import (
    CompensatorParams,
    FluidParams,
    MainSpoolParams,
    PVEParams,
    PVG32Params,
    PVPParams,
    RigParams,
    SolenoidValveParams,
    report_initial,
    report_tuned,
)
from pvgraph.circuits.pvg32 import tables
from pvgraph.units import bar, cm3, lpm, lpm_per_bar, mm, mm2, to_bar, to_mm2

PARAM_MODELS = [FluidParams, PVPParams, CompensatorParams, MainSpoolParams, PVEParams, RigParams,
                PVG32Params]


# ---------------------------------------------------------------- presets
@pytest.mark.parametrize("preset", [report_initial, report_tuned])
def test_presets_validate_and_round_trip(preset):
    p = preset()
    assert isinstance(p, PVG32Params)
    again = PVG32Params.model_validate(p.model_dump())
    assert again == p


def test_initial_preset_is_table_4_9():
    p = report_initial()
    assert p.rig.pump_flow == pytest.approx(lpm(17.0))
    assert p.rig.supply_voltage == 12.0
    assert p.fluid.bulk_modulus == bar(7000)
    assert (p.pvp.viscous_friction, p.compensator.viscous_friction,
            p.main_spool.viscous_friction) == (9000, 9000, 25)
    assert p.pvp.coulomb_friction == 0 and p.compensator.coulomb_friction == 0
    assert p.pvp.pressure_chamber_orifice_diameter is None
    assert p.pvp.pressure_chamber_orifice_area is None


def test_tuned_preset_is_table_4_14():
    p = report_tuned()
    assert p.rig.pump_flow == pytest.approx(16.3e-3 / 60)
    assert p.rig.supply_voltage == 11.5
    assert (p.pvp.viscous_friction, p.compensator.viscous_friction,
            p.main_spool.viscous_friction) == (35000, 20000, 25)
    assert (p.pvp.coulomb_friction, p.compensator.coulomb_friction) == (0, 50)
    assert p.pvp.pressure_chamber_orifice_diameter == pytest.approx(0.3e-3)
    assert to_mm2(p.pvp.pressure_chamber_orifice_area) == pytest.approx(math.pi * 0.3**2 / 4)


def test_presets_differ_only_in_tuned_quantities():
    a, b = report_initial().model_dump(), report_tuned().model_dump()
    for section in ("fluid", "main_spool", "pve"):
        assert a[section] == b[section]
    assert a["discharge_coefficient"] == b["discharge_coefficient"] == 0.6


def test_report_values():
    p = report_tuned()
    assert p.fluid.density == 900 and p.discharge_coefficient == 0.6
    assert p.pvp.spool_mass == 0.070 and p.pvp.spring_rate == 15000 and p.pvp.spring_preload == 300
    assert p.pvp.spool_area == pytest.approx(2.54e-4, rel=0.01)
    assert p.pvp.pump_volume == pytest.approx(2.7e-3) and p.pvp.spring_chamber_volume == cm3(8)
    assert p.pvp.tank_area_dead_band == mm(2) and p.pvp.flow_angle == pytest.approx(math.radians(69))
    c = p.compensator
    assert (c.spool_mass, c.spring_rate_1, c.spring_rate_2, c.spring_preload) == (0.066, 9945, 35000, 105.12)
    assert c.second_stage_start == mm(5.2) and c.inlet_orifice_area == mm2(3.5)
    assert c.ls_orifice_area == p.pvp.ls_orifice_area == mm2(1.0)  # A5 = A6 (eq 4.37)
    m = p.main_spool
    assert m.total_mass == pytest.approx(0.185 + 1.569)          # table 4.15: 1.754 kg
    assert m.spring_rate == 3596 and m.spring_preload == 65.05
    assert m.dead_band == mm(1.5) and m.area_at_full_stroke == mm2(69.549)
    assert math.degrees(m.flow_angle) == pytest.approx(27.73)
    slot_angle = math.degrees(math.atan((3.115 - 0.15) / 5.64))  # eq 4.69
    assert math.degrees(m.flow_angle) == pytest.approx(slot_angle, abs=0.01)
    e = p.pve
    assert e.pilot_pressure == bar(13.5)
    assert to_mm2(e.supply_orifice_area) == pytest.approx(12.6, abs=0.05)
    assert to_mm2(e.drain_orifice_area) == pytest.approx(0.79, abs=0.01)
    assert to_mm2(e.check_valve_area) == pytest.approx(2.3, abs=0.05)
    assert (e.port_a_volume, e.port_b_volume) == (cm3(13), cm3(27))
    assert (e.nc1.kind, e.nc1.chamber, e.nc1.switching_delay) == ("NC", "B", 0.020)
    assert (e.no2.kind, e.no2.chamber, e.no2.switching_delay) == ("NO", "B", 0.003)
    assert (e.nc3.kind, e.nc3.chamber, e.no4.kind, e.no4.chamber) == ("NC", "A", "NO", "A")
    assert (e.lvdt_gain, e.lvdt_time_constant) == (0.945, 0.0059)
    assert (e.input_gain, e.input_offset, e.duty_offset) == (0.028, -0.014, 0.284)
    assert e.duty_gain * mm(1) == pytest.approx(0.70)  # 70 % per mm (eq 4.115)
    r = p.rig
    assert r.L1.laminar("small") == pytest.approx(lpm_per_bar(0.2105))
    assert r.L3.laminar("large") == pytest.approx(lpm_per_bar(0.4533))
    assert r.L2.laminar_open == pytest.approx(lpm_per_bar(1.6111))
    assert r.L1.area("small") == mm2(2.174) and r.L3.area("large") == mm2(4.635)
    assert r.load_flow_model == "laminar"


def test_controller_maps_input_range_to_stroke():
    """Eq 4.110: V_rel 0.25 -> -7 mm, 0.5 -> 0, 0.75 -> +7 mm."""
    e = report_tuned().pve
    for v_rel, x in ((0.25, -7e-3), (0.5, 0.0), (0.75, 7e-3)):
        assert e.input_gain * v_rel + e.input_offset == pytest.approx(x, abs=1e-12)


def test_compensator_spring_is_continuous_at_second_stage():
    c = report_tuned().compensator
    x2 = c.second_stage_start
    assert c.spring_rate_1 * x2 + c.spring_preload == pytest.approx(c.spring_rate_2 * x2 + c.preload_stage_2)
    assert c.preload_stage_2 == pytest.approx(-25.166, abs=1e-3)
    assert c.stroke_max == pytest.approx(3.93e-3, rel=1e-3)


def test_steady_margins_from_springs():
    """Sec 2.2: PVP holds ~15 bar, compensator ~5 bar over P_LS; the springs give 11.8 bar at
    x_p = 0 (13.0 bar at the 2 mm dead band edge) and 4.13 bar at x_k = 0."""
    p = report_tuned()
    pvp, c = p.pvp, p.compensator
    assert to_bar(pvp.spring_preload / pvp.spool_area) == pytest.approx(11.79, abs=0.01)
    edge = (pvp.spring_preload + pvp.spring_rate * pvp.tank_area_dead_band) / pvp.spool_area
    assert to_bar(edge) == pytest.approx(12.97, abs=0.01)
    assert to_bar(c.spring_preload / c.spool_area) == pytest.approx(4.13, abs=0.01)


# ---------------------------------------------------------------- bounds
@pytest.mark.parametrize("model, field, bad", [
    (FluidParams, "density", -900.0),
    (FluidParams, "bulk_modulus", 7000.0),            # bar given instead of Pa
    (PVPParams, "spool_mass", 0.0),
    (PVPParams, "spring_rate", -1.0),
    (PVPParams, "pressure_chamber_orifice_diameter", 0.0),
    (PVPParams, "flow_angle", 69.0),                  # degrees given instead of rad
    (CompensatorParams, "inlet_orifice_area", 3.5),   # mm^2 given instead of m^2
    (CompensatorParams, "coulomb_friction", -50.0),
    (MainSpoolParams, "dead_band", -1e-3),
    (MainSpoolParams, "viscous_friction", -25.0),
    (PVEParams, "pilot_pressure", 13.5),              # bar given instead of Pa
    (PVEParams, "duty_offset", 28.4),                 # percent given instead of fraction
    (RigParams, "pump_flow", 0.0),
    (RigParams, "load_flow_model", "quadratic"),
    (PVG32Params, "discharge_coefficient", 1.5),
])
def test_bounds_reject_bad_values_naming_the_field(model, field, bad):
    with pytest.raises(ValidationError) as info:
        model(**{field: bad})
    assert field in str(info.value)


def test_nested_bad_value_names_the_path():
    with pytest.raises(ValidationError) as info:
        PVG32Params(pvp={"spool_mass": -1.0})
    assert "pvp.spool_mass" in str(info.value)


def test_solenoid_valve_params_validate():
    with pytest.raises(ValidationError, match="kind"):
        SolenoidValveParams(kind="NX", chamber="A", switching_delay=0.003)
    with pytest.raises(ValidationError, match="switching_delay"):
        SolenoidValveParams(kind="NO", chamber="A", switching_delay=0.0)


@pytest.mark.parametrize("model", PARAM_MODELS)
def test_models_frozen_and_forbid_extra(model):
    with pytest.raises(ValidationError, match="extra"):
        model(not_a_parameter=1.0)
    instance = model()
    name = next(iter(model.model_fields))
    with pytest.raises(ValidationError):
        setattr(instance, name, getattr(instance, name))


@pytest.mark.parametrize("model", PARAM_MODELS + [SolenoidValveParams])
def test_every_field_documented_with_unit_and_source(model):
    for name, field in model.model_fields.items():
        d = field.description or ""
        assert d, f"{model.__name__}.{name} has no description"
        if model not in (PVG32Params,) and field.annotation in (float, float | None):
            assert "[" in d and "]" in d, f"{model.__name__}.{name}: no unit in {d!r}"
            has_bound = any(hasattr(m, a) for m in field.metadata for a in ("gt", "ge", "lt", "le"))
            assert has_bound, f"{model.__name__}.{name} has no bounds"


# ---------------------------------------------------------------- area tables
def _monotone(values, increasing=True):
    d = np.diff(values)
    return bool(np.all(d >= -1e-15)) if increasing else bool(np.all(d <= 1e-15))


def test_pvp_tank_area():
    a3 = tables.pvp_tank_area()
    assert _monotone(a3.area)
    assert a3(mm(1.0)) == 0.0 and a3(mm(2.0)) == 0.0
    assert a3(mm(2.0) + 1e-6) > 0.0
    assert to_mm2(a3(mm(3.5))) == pytest.approx(90.0)
    assert to_mm2(a3(mm(5.0))) == pytest.approx(180.0) and to_mm2(a3(mm(9.0))) == pytest.approx(180.0)


def test_compensator_areas():
    a1, a2 = tables.compensator_closing_area(), tables.compensator_opening_area()
    assert _monotone(a1.area, increasing=False) and _monotone(a2.area)
    assert a1(mm(2.7)) == 0.0 and a1(mm(4.0)) == 0.0 and a1(0.0) > 0.0
    assert a2(0.0) == 0.0
    assert a2(mm(2.0)) == pytest.approx(math.pi * 18e-3 * 2e-3)  # eq 4.38


def test_main_spool_area_anchor_points():
    ah = tables.main_spool_area()
    assert to_mm2(ah(mm(7.0))) == pytest.approx(69.549, rel=0.005)
    assert to_mm2(ah(mm(-7.0))) == pytest.approx(69.549, rel=0.005)
    inside = np.linspace(-1.5e-3, 1.5e-3, 61)
    assert np.all(ah(inside) == 0.0)
    assert ah(mm(1.6)) > 0.0
    pos = ah.x >= 0
    assert _monotone(ah.area[pos]) and _monotone(ah.area[~pos], increasing=False)
    assert np.allclose(ah.area, ah.area[::-1])  # symmetric


def test_main_spool_area_matches_lab_flows():
    """A_H reproduces the lab flows at 5 bar, 11.5 V (4.7.3): mean |error| < 10 %."""
    ah = tables.main_spool_area()
    errors = []
    for volts, q_lpm, _ in tables.MAIN_SPOOL_LAB_ANCHORS:
        x = 0.028 * volts / 11.5 - 0.014
        q = 0.6 * ah(x) * math.sqrt(2 * 5e5 / 900) * 60000
        errors.append(q / q_lpm - 1)
    assert np.mean(np.abs(errors)) < 0.10
    assert max(abs(e) for e in errors) < 0.45


def test_user_supplied_area_table():
    t = tables.AreaTable(name="custom", x=[0.0, 1e-3], area=[0.0, 1e-6], source="test")
    assert t(0.5e-3) == pytest.approx(0.5e-6)
    with pytest.raises(ValueError, match="increasing"):
        tables.AreaTable(name="bad", x=[0.0, 0.0], area=[0.0, 1.0], source="test")
    with pytest.raises(ValueError, match=">= 0"):
        tables.AreaTable(name="bad", x=[0.0, 1.0], area=[0.0, -1.0], source="test")
    with pytest.raises(ValueError):
        t.area[0] = 1.0  # read-only


def test_pilot_orifice_areas():
    areas = tables.pilot_orifice_areas(report_tuned())
    assert areas["A4"] == mm2(3.5) and areas["A5"] == areas["A6"] == mm2(1.0)
    assert to_mm2(areas["A7"]) == pytest.approx(0.0707, abs=1e-4)
    assert tables.pilot_orifice_areas(report_initial())["A7"] is None


def test_documented_parameter_table_is_the_code_s():
    """docs/pvg32_model.md section 12 is generated from the parameter models; no drift."""
    from pathlib import Path

    from pvgraph.circuits.pvg32.parameters import parameter_table
    doc = (Path(__file__).parents[2] / "docs" / "pvg32_model.md").read_text()
    assert parameter_table() in doc


def test_documented_tables_are_linear_as_evaluated():
    """A3 and A1 are documented as linear edges (C.1.2, tables.py); the model's orifices must
    evaluate them so: A3 at 2.1 mm is 60 mm^2/mm x 0.1 mm = 6.0 mm^2 (a 4-point pchip gave
    0.59), A1 at 2.6 mm is 20 mm^2/mm x 0.1 mm = 2.0 mm^2."""
    from pvgraph.circuits.pvg32.modules import TABLE_STEP, _table, opening_areas
    from pvgraph import expr as E
    areas = opening_areas(report_tuned())
    for name, x, expected in (("A3", mm(2.1), mm2(6.0)), ("A3", mm(3.5), mm2(90.0)),
                              ("A1", mm(2.6), mm2(2.0)), ("A1", mm(1.0), mm2(34.0))):
        kw = _table(areas[name])
        table = E.Table(kw["x_table"], kw["A_table"], method="pchip")
        assert table.value(x) == pytest.approx(expected, rel=1e-9), name
    # the rounding at a kink is confined to one resampling step
    kw = _table(areas["A3"])
    table = E.Table(kw["x_table"], kw["A_table"], method="pchip")
    assert table.value(mm(2.0) + TABLE_STEP) == pytest.approx(mm2(60.0) * TABLE_STEP / mm(1.0))


# ---------------------------------------------------------------- the PVE valves' one map
def test_pve_valves_run_on_one_map_with_the_reports_delays():
    """One flow map for NC1-NO4: the library's PWMValve with figure 4.55's lines, the
    switching delays of 4.5.5 (NC 20 ms, NO 3 ms; the NO shuts 17 ms before the NC opens)."""
    from pvgraph.circuits.pvg32.modules import build_pve
    from pvgraph.components.hydraulic.solenoid import PWMValve

    pve = build_pve(report_tuned())
    valves = {n: c for n, c in pve.components.items() if n[:2] in ("NC", "NO")}
    assert sorted(valves) == ["NC1", "NC3", "NO2", "NO4"]
    for name, valve in valves.items():
        assert type(valve) is PWMValve
        assert valve.params.kind == name[:2]
        assert valve.params.setting("tau") == (0.020 if name[:2] == "NC" else 0.003)
    nc, no = valves["NC1"].params, valves["NO2"].params
    # figure 4.55's lines at the linearisation pressures (4.8): NC 13.5 bar, NO 4 bar
    for dt in (0.3, 0.5, 0.7, 0.9):
        assert float(nc.flow(dt, bar(13.5))) == pytest.approx(3.0e-7 * 100 * dt - 3.7e-6,
                                                              rel=0.02)
        assert float(no.flow(dt - 0.2, bar(4.0))) == pytest.approx(
            -1.8e-7 * 100 * (dt - 0.2) + 1.6e-5, rel=0.02)


def test_rig_operating_point_of_the_pve_valves():
    """Where the maps are used (docs/pvg32_model.md section 6): at a lab operating point (test
    1, 4.24 V) one pair of valves holds its chamber at the NC's zero-flow end of the map
    (fig. 4.55's 13.5 bar line is zero at 12.3 %), the NO valves see less than the 4 bar of
    their linearisation, the NC valves less than the 13.5 bar pilot."""
    from pvgraph.analysis import steady_state
    from pvgraph.circuits.rig import build_rig, laminar_load

    p = report_tuned()
    op = steady_state(build_rig(p, load=laminar_load(p), U_input=4.24).compile(), tol=1e-10)
    duty = sorted(op[f"pvg.pve.{v}.d"] for v in ("NC1", "NC3"))
    assert duty[0] < 0.15 < 0.40 < duty[1]
    for v in ("NO2", "NO4"):
        assert 0.0 <= op[f"pvg.pve.{v}.dp"] < bar(4.0)
    for v in ("NC1", "NC3"):
        assert 0.0 < op[f"pvg.pve.{v}.dp"] < bar(13.5)


@pytest.mark.parametrize("stages", [1, 4])
def test_switching_delay_as_a_chain_of_lags(stages):
    """pve.delay_stages = n: the duty cycle reaches the valve through n lags of delay / n (an
    Erlang delay: mean delay 20 ms for the NC, 4.5.5). A duty-cycle step from 28.4 % follows
    1 - exp(-t/theta) sum_{k<n} (t/theta)^k / k!, theta = delay / n."""
    from pvgraph import Circuit
    from pvgraph.circuits.pvg32.modules import _delay_chain, build_pve
    from pvgraph.components.hydraulic import Tank
    from pvgraph.components.hydraulic.solenoid import PWMValve
    from pvgraph.components.signal.sources import Constant
    from pvgraph.simulate import simulate

    delay, d0, d1 = 0.020, 0.284, 0.6
    c = Circuit("chain")
    valve = c.add("NC1", PWMValve(kind="NC", tau=delay / stages, DT0=d0))
    hi, lo = c.add("hi", Tank(p0=bar(13.5))), c.add("lo", Tank(p0=bar(5.0)))
    c.connect(hi.port, valve.a)
    c.connect(lo.port, valve.b)
    u = c.add("u", Constant(k=d1))
    c.connect(u.y, _delay_chain(c, "NC1", delay, stages, d0, valve.DT))
    t = np.array([0.005, 0.020, 0.060])
    sol = simulate(c.compile(), t[-1], rtol=1e-9, atol=1e-12, t_eval=t)
    theta = delay / stages
    erlang = 1.0 - np.exp(-t / theta) * sum((t / theta) ** k / math.factorial(k)
                                            for k in range(stages))
    assert np.asarray(sol["NC1.d"]) == pytest.approx(d0 + (d1 - d0) * erlang, abs=2e-5)
    # in the PVE: n - 1 lags in front of each of the four valves, none for one stage
    p = report_tuned()
    pve = build_pve(p.model_copy(update={"pve": p.pve.model_copy(
        update={"delay_stages": stages})}))
    lags = [n for n in pve.components if "_delay" in n]
    assert len(lags) == 4 * (stages - 1)
