"""Lab data loaders (circuits.lab_data) and validation scenarios (circuits.scenarios).

Known values are from the report, appendix B.7 and tables 4.5, 4.10-4.13.
"""

import math

import pytest

from pvgraph.circuits.lab_data import (
    FLOW_ACCURACY,
    PRESSURE_ACCURACY,
    LabDataError,
    SolenoidStepRecord,
    load_solenoid_steps,
    load_voltage_sweep,
)
from pvgraph.circuits.scenarios import UnknownScenarioError, all_scenarios, get_scenario, scenario_names
from pvgraph.errors import PvgraphError
from pvgraph.units import bar, lpm, lpm_per_bar, to_bar, to_lpm, to_mm2

CD, RHO = 0.6, 900.0


def _by_test(records):
    return {r.test: r for r in records}


# ---------------------------------------------------------------- loaders
def test_record_counts():
    assert len(load_solenoid_steps()) == 12
    assert len(load_voltage_sweep()) == 7


def test_test2_values_converted_to_si_and_originals_kept():
    r = _by_test(load_solenoid_steps())[2]
    assert isinstance(r, SolenoidStepRecord)
    assert r.Pf_bar == 43.01
    assert r.Pf == pytest.approx(bar(43.01), rel=1e-12)
    assert r.Pf == pytest.approx(4.301e6, rel=1e-12)
    assert r.Q_total == pytest.approx(14.19e-3 / 60, rel=1e-12)
    assert r.Q_branch == pytest.approx(lpm(6.47), rel=1e-12)
    assert r.U_input == 4.24
    assert (r.orifice_L1, r.orifice_L3, r.solenoid_event) == ("small", "small", "opening")
    assert r.solenoid_open_after


def test_sweep_values():
    s = _by_test(load_voltage_sweep())
    assert s[1].U_input == 6 and s[1].Q_total == 0.0
    assert s[7].Q_total_lpm == 16.30 and s[7].Q_total == pytest.approx(lpm(16.3))
    assert s[6].Pf == pytest.approx(bar(38.680))
    assert [r.U_input for r in s.values()] == sorted((r.U_input for r in s.values()), reverse=True)


def test_records_are_frozen():
    r = load_solenoid_steps()[0]
    with pytest.raises(AttributeError):
        r.Pf = 0.0  # type: ignore[misc]


def test_readme_check_test2_gives_A_L1():
    """README / table 4.5: A_L1 = Q_branch / (Cd sqrt(2 (Pm - Pb)/rho)) = 2.174 mm^2."""
    r = _by_test(load_solenoid_steps())[2]
    area = r.Q_branch / (CD * math.sqrt(2.0 * (r.Pm - r.Pb) / RHO))
    assert to_mm2(area) == pytest.approx(2.174, rel=0.02)


@pytest.mark.parametrize("test, a_l1, a_l2, a_l3", [
    (2, 2.174, 5.800, 2.429), (5, 1.553, 3.879, 1.565), (8, 2.585, 5.623, 3.629),
    (11, 1.933, 3.626, 2.637),
])
def test_table_4_5_areas_from_data(test, a_l1, a_l2, a_l3):
    """Eq 4.123-4.125 applied to the data reproduce table 4.5 (so Q_total is Qv, Q_branch QL2)."""
    r = _by_test(load_solenoid_steps())[test]
    k = CD * math.sqrt(2.0 / RHO)
    assert to_mm2(r.Q_branch / (k * math.sqrt(r.Pm - r.Pb))) == pytest.approx(a_l1, rel=0.01)
    assert to_mm2(r.Q_branch / (k * math.sqrt(r.Pf - r.Pm))) == pytest.approx(a_l2, rel=0.01)
    assert to_mm2((r.Q_total - r.Q_branch) / (k * math.sqrt(r.Pf - r.Pb))) == pytest.approx(a_l3, rel=0.01)


def test_accuracies():
    assert PRESSURE_ACCURACY == bar(1.0)
    assert FLOW_ACCURACY == lpm(1.0)


def test_missing_file_raises(tmp_path):
    with pytest.raises(LabDataError, match="not found"):
        load_solenoid_steps(tmp_path / "nope.csv")


def test_lab_data_error_is_pvgraph_error():
    assert issubclass(LabDataError, PvgraphError)


_HEADER = ("test,orifice_L1,orifice_L3,solenoid_event,Q_total_lpm,Q_branch_lpm,U_input_V,"
           "Pf_bar,Pm_bar,Pb_bar\n")


@pytest.mark.parametrize("content, match", [
    ("test,foo\n1,2\n", "header"),
    (_HEADER, "no data rows"),
    (_HEADER + "1,small,small,closed_steady,13.67,0,4.24,abc,8.67,7.42\n", "Pf_bar"),
    (_HEADER + "1,medium,small,closed_steady,13.67,0,4.24,66.32,8.67,7.42\n", "orifice_L1"),
    (_HEADER + "1,small,small,open,13.67,0,4.24,66.32,8.67,7.42\n", "solenoid_event"),
    (_HEADER + "1,small,small,closed_steady,-1,0,4.24,66.32,8.67,7.42\n", "Q_total_lpm"),
    (_HEADER + "1,small,small,closed_steady,13.67,0,4.24,66.32,8.67\n", "fields"),
    (_HEADER + "1,small,small,closed_steady,13.67,0,4.24,66.32,8.67,7.42,9\n", "fields"),
    (_HEADER + "1,small,small,closed_steady,13.67,0,4.24,66.32,8.67,7.42\n"
               "1,small,small,closed_steady,13.67,0,4.24,66.32,8.67,7.42\n", "duplicate"),
])
def test_malformed_solenoid_file(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(LabDataError, match=match):
        load_solenoid_steps(path)


def test_malformed_sweep_file(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("test,Pf_bar,Pm_bar,Pb_bar,Q_total_lpm,U_input_V\n1,9.1,9.2,8.7,x,6\n")
    with pytest.raises(LabDataError, match="line 2, column 'Q_total_lpm'"):
        load_voltage_sweep(path)


def test_user_file_same_as_packaged(tmp_path):
    from importlib import resources
    text = resources.files("pvgraph.circuits.data").joinpath("rig_voltage_sweep.csv").read_text()
    path = tmp_path / "copy.csv"
    path.write_text(text)
    assert load_voltage_sweep(path) == load_voltage_sweep()


# ---------------------------------------------------------------- scenarios
def test_scenario_names_and_count():
    names = scenario_names()
    assert names == [f"test-{i}" for i in range(1, 13)] + [f"sweep-{i}" for i in range(1, 8)]
    assert len(all_scenarios()) == 19


def test_unknown_scenario_lists_valid_names():
    with pytest.raises(UnknownScenarioError) as info:
        get_scenario("test-13")
    assert "test-1" in str(info.value) and "sweep-7" in str(info.value)
    assert isinstance(info.value, LookupError)


@pytest.mark.parametrize("record", load_solenoid_steps(), ids=lambda r: f"test-{r.test}")
def test_step_scenario_fields(record):
    s = get_scenario(f"test-{record.test}")
    assert s.kind == "solenoid_step" and s.test == record.test
    assert (s.orifice_L1, s.orifice_L3) == (record.orifice_L1, record.orifice_L3)
    assert s.solenoid_event == record.solenoid_event
    assert s.U_input == record.U_input
    m = s.measured
    assert (m.Q_total, m.Q_branch, m.Pf, m.Pm, m.Pb) == (
        record.Q_total, record.Q_branch, record.Pf, record.Pm, record.Pb)
    event = record.solenoid_event
    assert s.l2_open_finally == (event == "opening")
    assert s.l2_open_initially == (event == "closing")
    if event == "closed_steady":
        assert s.preceded_by is None and s.report_dynamic_error_bound is None
        assert m.Q_branch == 0.0
    else:
        prev = get_scenario(s.preceded_by)
        assert prev.test == s.test - 1 and prev.orifice_L3 == s.orifice_L3
        assert s.report_dynamic_error_bound == (0.10 if s.test in (8, 9) else 0.30)
    assert (s.test <= 6) == (s.orifice_L1 == "small")


def test_step_scenario_pattern():
    events = [get_scenario(f"test-{i}").solenoid_event for i in range(1, 13)]
    assert events == ["closed_steady", "opening", "closing"] * 4


@pytest.mark.parametrize("test, dp_sim, dp_test, q_sim, q_test", [
    (6, 31.720, 34.07, 6.988, 7.23), (9, 30.599, 30.08, 13.944, 13.75),
    (12, 16.210, 19.25, 7.354, 8.00),
])
def test_table_4_10(test, dp_sim, dp_test, q_sim, q_test):
    s = get_scenario(f"test-{test}")
    assert to_bar(s.measured.dp_L3) == pytest.approx(dp_test, abs=0.006)
    assert to_lpm(s.measured.Q_total) == pytest.approx(q_test, abs=1e-9)
    sim = s.report_simulated
    assert to_bar(sim.dp_L3) == pytest.approx(dp_sim)
    assert to_lpm(sim.Q_total) == pytest.approx(q_sim)
    assert sim.K_L3 == pytest.approx(sim.Q_total / sim.dp_L3, rel=0.01)  # table 4.11 = Q/dp
    assert sim.dp_L1 is None and sim.dp_L2 is None


@pytest.mark.parametrize("test, dp1_sim, dp1_test, dp2_sim, dp2_test", [
    (5, 15.201, 17.530, 1.986, 2.81), (8, 15.355, 15.32, 3.371, 3.23),
    (11, 8.110, 9.22, 1.784, 2.62),
])
def test_table_4_12(test, dp1_sim, dp1_test, dp2_sim, dp2_test):
    s = get_scenario(f"test-{test}")
    assert to_bar(s.measured.dp_L1) == pytest.approx(dp1_test, abs=0.006)
    assert to_bar(s.measured.dp_L2) == pytest.approx(dp2_test, abs=0.006)
    sim = s.report_simulated
    assert to_bar(sim.dp_L1) == pytest.approx(dp1_sim)
    assert to_bar(sim.dp_L2) == pytest.approx(dp2_sim)
    assert sim.K_L1 > 0 and sim.K_L2 > 0 and sim.dp_L3 is None


def test_only_tabulated_tests_have_report_values():
    with_sim = {s.name for s in all_scenarios() if s.report_simulated is not None}
    assert with_sim == {f"test-{i}" for i in (5, 6, 8, 9, 11, 12)}


@pytest.mark.parametrize("record", load_voltage_sweep(), ids=lambda r: f"sweep-{r.test}")
def test_sweep_scenario_fields(record):
    s = get_scenario(f"sweep-{record.test}")
    assert s.kind == "voltage_sweep" and s.solenoid_event == "closed_steady"
    assert not s.l2_open_initially and not s.l2_open_finally
    assert s.orifice_L1 is None and s.orifice_L3 == "large"
    assert s.U_input == record.U_input
    assert s.measured.Q_total == record.Q_total and s.measured.Q_branch == 0.0
    assert s.measured.Pf == record.Pf
    assert s.report_simulated is None and s.preceded_by is None


def test_sweep_orifice_inference_large_L3():
    """Q / (Pf - Pb) of the flowing, unsaturated sweep points is near table 4.8's large L3."""
    k_large = lpm_per_bar(0.4533)
    for i in (4, 5, 6):
        m = get_scenario(f"sweep-{i}").measured
        assert m.Q_total / m.dp_L3 == pytest.approx(k_large, rel=0.12)


def test_scenarios_are_frozen():
    s = get_scenario("test-2")
    with pytest.raises(Exception):
        s.U_input = 5.0
