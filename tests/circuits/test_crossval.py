"""Roles of the lab values, the identification procedure and the cross-validation."""

import numpy as np
import pytest

from pvgraph.circuits import crossval as X
from pvgraph.circuits.scenarios import all_scenarios, get_scenario
from pvgraph.circuits.pvg32.parameters import report_tuned
from pvgraph.units import bar, to_bar, to_lpm


def test_tuned_roles_mark_what_the_report_fitted():
    roles = X.tuned_roles()
    # the 12 A_H anchors' flows and the saturated flow (the pump's 16.3 L/min) are fitted; the
    # opening tests' flows are not
    fit_flows = sorted(n for (n, q), r in roles.items() if q == "Q_total" and r == "fit")
    assert len(fit_flows) == 13 and "sweep-7" in fit_flows
    held_flows = sorted(n for (n, q), r in roles.items() if q == "Q_total" and r == "held-out")
    assert held_flows == ["test-11", "test-2", "test-5", "test-8"]
    # neutral flows and Q_branch with L2 closed are trivial
    assert roles[("sweep-1", "Q_total")] == roles[("sweep-2", "Q_total")] == "trivial"
    assert roles[("test-1", "Q_branch")] == "trivial"
    # the return line came from Pb of tests 1, 4, 7, 10; K_L1, K_L3 from tests 2 and 8 and
    # K_L2 from Q against Pf - Pm of the four opening tests (figure 4.32)
    assert [roles[(f"test-{k}", "Pb")] for k in (1, 4, 7, 10)] == ["fit"] * 4
    assert roles[("test-2", "Pf")] == roles[("test-8", "Pm")] == "fit"
    assert roles[("test-5", "Pf")] == roles[("test-11", "Pm")] == "fit"
    assert roles[("test-5", "Pb")] == "held-out"
    assert set(roles.values()) == set(X.ROLES)


def test_roles_are_per_model_configuration():
    """The closing tests 3, 6, 9, 12 end in the configuration of the fitted closed-L2 tests 1,
    4, 7, 10: their Pb is the fitted number again, not a prediction; with L2 closed the
    model's Pm is its Pb."""
    roles = X.tuned_roles()
    for fitted, closing in ((1, 3), (4, 6), (7, 9), (10, 12)):
        a, b = get_scenario(f"test-{fitted}"), get_scenario(f"test-{closing}")
        assert X.configuration(a) == X.configuration(b)
        assert roles[(b.name, "Pb")] == "repeat"
        assert roles[(a.name, "Pm")] == roles[(b.name, "Pm")] == "repeat"
        # Pf of that configuration was not fitted anywhere: held-out in both
        assert roles[(a.name, "Pf")] == roles[(b.name, "Pf")] == "held-out"
    # the opening tests 5 and 11 are configurations of their own; their Pf and Pm went into
    # K_L2 (figure 4.32 fits Q_L2 against Pf - Pm over the opening tests), their Pb did not
    assert {roles[(f"test-{k}", q)] for k in (5, 11) for q in ("Pf", "Pm")} == {"fit"}
    assert {roles[(f"test-{k}", "Pb")] for k in (5, 11)} == {"held-out"}
    # no "held-out" value shares its configuration and quantity with a fitted one
    fitted = {(X.configuration(get_scenario(n)), q) for (n, q), r in roles.items() if r == "fit"}
    assert not [(n, q) for (n, q), r in roles.items() if r == "held-out"
                and (X.configuration(get_scenario(n)), q) in fitted]


def test_the_saturated_flow_is_held_out_unless_the_pump_flow_came_from_it():
    s = get_scenario("sweep-7")
    assert X.role(s, "Q_total", {("sweep-7", "Q_total")}) == "fit"
    assert X.role(s, "Q_total", set()) == "held-out"


def test_a_miss_is_never_printed_as_the_tolerance():
    assert X.shown_against(1.0019, 1.0) == "1.002"
    assert X.shown_against(1.00004, 1.0) == "1.00004"
    assert X.shown_against(0.9996, 1.0) == "1.00"                # a pass at the boundary
    assert X.shown_against(0.6789, 1.0) == "0.68"
    cv = X.CrossValidation(
        [{"grouping": "voltage", "fold": "U = 4.21 V", "scenario": "sweep-6", "quantity": q,
          "error": e, "role": "held-out" if q != "Q_branch" else "trivial"}
         for q, e in (("Q_total", -1.0019), ("Q_branch", 0.0), ("Pf", 0.5), ("Pm", 0.1),
                      ("Pb", 0.1))], [{}], 1.0, 1)
    text = X.format_cross_validation(cv)
    assert "held-out flow within 1 L/min (non-neutral points): 0/1 (worst 1.002 at sweep-6" \
        in text
    assert "miss  held-out flow" in text
    row = next(ln for ln in text.splitlines() if ln.startswith("sweep-6"))
    assert row.split("|")[1].split() == ["-1.002h", "+0.00t"]         # the cell reads as a miss


def test_table_4_8_constants_are_single_tests_q_over_dp():
    """The provenance claimed for the tuned preset: K_L1 and K_L3 (small) are test 2's Q/dp."""
    m = get_scenario("test-2").measured
    k1 = to_lpm(m.Q_branch) / to_bar(m.Pm - m.Pb)
    k3 = to_lpm(m.Q_total - m.Q_branch) / to_bar(m.Pf - m.Pb)
    assert k1 == pytest.approx(0.2105, abs=5e-4)
    assert k3 == pytest.approx(0.2203, abs=5e-4)
    m8 = get_scenario("test-8").measured
    assert to_lpm(m8.Q_branch) / to_bar(m8.Pm - m8.Pb) == pytest.approx(0.3544, abs=5e-4)


def test_load_law_fit_recovers_a_known_law():
    dp = np.array([10.0, 20.0, 35.0, 60.0])
    q = 0.2 * dp + 0.001 * dp**2
    k, b, law = X._fit_load_law([(d, v, "s", ()) for d, v in zip(dp, q)])
    assert (k, b) == pytest.approx((0.2, 0.001), rel=1e-9)
    assert law == "K dp + b dp^2"
    # one pressure level: laminar through the origin
    k, b, law = X._fit_load_law([(30.0, 6.0, "s", ()), (31.0, 6.2, "s", ())])
    assert (b, law) == (0.0, "laminar") and k == pytest.approx(0.2, rel=1e-3)


def test_pvp_margin_reachable_from_the_spring():
    m = X.pvp_margin_reachable(report_tuned())
    # 300 N / 254.5 mm^2 and (300 + 15000 * 2 mm) N / 254.5 mm^2 (eq 4.17-4.19, C.1.2)
    assert to_bar(m["preload_only"]) == pytest.approx(11.79, abs=0.01)
    assert to_bar(m["at_A3_opening"]) == pytest.approx(12.97, abs=0.01)


def test_judge_counts_held_out_points_with_absolute_tolerances():
    def rec(s, q, err, role="held-out"):
        return {"grouping": "g", "scenario": s, "quantity": q, "error": err, "role": role}
    records = [rec("test-1", "Q_total", 0.9), rec("test-1", "Pf", 1.9), rec("test-1", "Pm", 0.1),
               rec("test-1", "Pb", -2.1),                       # one pressure 0.1 bar over
               rec("test-4", "Q_total", -1.2), rec("test-4", "Pf", 0.0),
               rec("test-4", "Pm", 0.0), rec("test-4", "Pb", 0.0, "fit"),    # not judged
               rec("sweep-1", "Q_total", 0.0, "trivial"),                    # neutral: skipped
               rec("sweep-5", "Q_total", 0.5), rec("sweep-5", "Pf", 1.0),
               rec("sweep-5", "Pm", 1.0), rec("sweep-5", "Pb", 1.0)]
    t = X.judge(records)
    ok, total, _ = t["flow within 1 L/min (non-neutral points)"]
    assert (ok, total) == (2, 3)
    ok, total, rows = t["Pf, Pm, Pb within 2 bar (step tests)"]
    assert (ok, total) == (0, 1) and rows[0][1] == pytest.approx(2.1)
    assert t["Pf, Pm, Pb within 2 bar (non-neutral sweep points)"][:2] == (1, 1)


@pytest.mark.slow
def test_one_voltage_fold_predicts_the_held_out_tests():
    """Identify without U = 4.62 V, predict tests 4-6 and compare with the lab (B.7)."""
    held = [get_scenario(f"test-{k}") for k in (4, 5, 6)]
    train = [s for s in all_scenarios() if s.U_input != 4.62]
    ident = X.identify(train)
    assert 10.5 <= ident.params.rig.supply_voltage <= 12.5
    assert not ({("test-4", "Q_total"), ("test-5", "Pf")} & ident.fitted)
    pred = X.steady_values(ident.params, held, sweep_load=ident.sweep_load)
    for s in held:
        v = pred[s.name]
        assert abs(to_lpm(v["Q_total"] - s.measured.Q_total)) <= 1.0, s.name
        assert abs(v["Pb"] - s.measured.Pb) <= bar(1.0), s.name
        assert abs(v["Pf"] - s.measured.Pf) <= bar(2.0), s.name
        # the compensator holds about 5 bar across the main spool (2.2, 4.7.3)
        assert 4.0 < to_bar(v["drop"]) < 6.0


@pytest.mark.slow
def test_identification_does_not_hang_on_the_base_values_tuned_on_all_data():
    """The return line and the pump flow of the base preset were tuned on all 19 scenarios,
    the held-out group's too; identify() corrects them from the training points until they
    stop moving, so a fold's result is the same from a base with other values of them (one
    pass moved test-10's held-out Pb by 0.19 bar and sweep-6's flow by 0.05 L/min)."""
    from pvgraph.circuits.pvg32.parameters import report_tuned, with_values
    train = [s for s in all_scenarios() if s.U_input != 4.60]
    base = report_tuned()
    other = with_values(base, {"rig.pump_flow": base.rig.pump_flow * 1.05,
                               "rig.return_line_K": base.rig.return_line_K * 1.3})
    a, b = X.identify(train, base).params, X.identify(train, other).params
    assert a.rig.return_line_K == pytest.approx(b.rig.return_line_K, rel=1e-3)
    assert a.rig.pump_flow == pytest.approx(b.rig.pump_flow, rel=1e-4)
    assert a.rig.supply_voltage == pytest.approx(b.rig.supply_voltage, rel=1e-4)


@pytest.mark.slow
def test_cross_validation_held_out_targets():
    cv = X.cross_validate(workers=2)
    assert len(cv.folds) == 11 + 3
    assert not [r for r in cv.records if r["error"] is None]
    t = X.judge(cv.records, "voltage")
    # the flow target (>= 15 of 17 held-out points within the meter's 1 L/min) is met; the
    # pressure target (>= 10 of 12) is met with the return hose and the Pb transducer offset
    # identified per fold and the shared load-law curvature (9 without the latter, 7 without
    # either); tests 10 and 12 miss: the load's own scatter between sessions (Q/dp of one
    # setting 10 % apart in tests 7-9 and 10-12) (docs/pvg32_model.md, 8b)
    assert t["flow within 1 L/min (non-neutral points)"][0] >= 15
    assert t["Pf, Pm, Pb within 2 bar (step tests)"][0] >= 10
    assert t["Pf, Pm, Pb within 2 bar (non-neutral sweep points)"][0] >= 4
    # every held-out record was predicted without its scenario's data
    for fold in cv.folds:
        assert "error" not in fold["sources"]


def test_identify_rejects_an_unknown_load_law():
    from pvgraph.errors import PvgraphError
    with pytest.raises(PvgraphError, match="load_law"):
        X.identify(all_scenarios(), load_law="turbulent")


def test_cross_validate_runs_only_the_folds_asked_for():
    cv = X.cross_validate(("voltage", "load"), workers=1, folds=["no such fold"])
    assert cv.folds == [] and cv.records == []


def test_one_level_setting_takes_the_shared_curvature():
    """load_law="shared": a setting seen at one pressure level gets Q = K dp (1 + beta dp) with
    beta from the others; K then reproduces a point of that law exactly."""
    beta = 0.005                                   # [1/bar]
    pts = [(d, 0.2 * d * (1 + beta * d), "s", ()) for d in (30.0, 31.0)]
    k, b, law = X._fit_with_curvature(pts, beta)
    assert k == pytest.approx(0.2, rel=1e-12) and b == pytest.approx(0.2 * beta, rel=1e-12)
    # the laminar fit of the same points over-predicts the pressure at twice the drop
    k_lam, _, _ = X._fit_load_law(pts, quadratic=False)
    q60 = 0.2 * 60 * (1 + beta * 60)
    assert q60 / k_lam > 60.0 + 2.0                # laminar: > 2 bar high at 60 bar
    assert k * 60 * (1 + beta * 60) == pytest.approx(q60, rel=1e-12)


def test_flows_at_4_6_v_lie_above_every_convex_opening_through_the_training_points():
    """Tests 10-12 (4.60 V) against the chord of their nearest training points, sweep 5
    (4.45 V) and tests 4-6 (4.62 V): a flow convex in the input voltage (an opening that widens
    with travel, travel linear in U, eq. 4.110) lies below that chord, so no such opening
    identified without tests 10-12 predicts them within 0.44 L/min (B.7)."""
    q462 = np.mean([to_lpm(get_scenario(f"test-{k}").measured.Q_total) for k in (4, 5, 6)])
    s5 = get_scenario("sweep-5")
    q445 = to_lpm(s5.measured.Q_total)
    chord = q462 + (q445 - q462) * (4.62 - 4.60) / (4.62 - s5.U_input)
    assert chord == pytest.approx(7.55, abs=0.01)
    gaps = [to_lpm(get_scenario(f"test-{k}").measured.Q_total) - chord for k in (10, 11, 12)]
    assert min(gaps) > 0.44 and max(gaps) < 0.66


def test_identify_rejects_an_unknown_meter_out_law():
    from pvgraph.errors import PvgraphError
    with pytest.raises(PvgraphError, match="meter_out"):
        X.identify(all_scenarios(), meter_out="larger")


def test_held_out_targets_are_the_stated_shares():
    """15 of 17 flows, 10 of 12 step tests, every sweep point, 7 of 8 step tests settled;
    subsets round up."""
    from pvgraph.circuits.crossval import held_out_target
    assert held_out_target("flow within 1 L/min (non-neutral points)", 17) == 15
    assert held_out_target("Pf, Pm, Pb within 2 bar (step tests)", 12) == 10
    assert held_out_target("Pf, Pm, Pb within 2 bar (step tests)", 3) == 3
    assert held_out_target("Pf, Pm, Pb within 2 bar (non-neutral sweep points)", 5) == 5
    assert held_out_target(X.SETTLED_STEP, 8) == 7
