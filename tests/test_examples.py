"""Every examples/*.py runs (main(tmp_path)) and its numbers make physical sense."""

import importlib.util
import math
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
CHECKS = {}


def check(name):
    def register(fn):
        CHECKS[name] = fn
        return fn
    return register


def _load(path: Path):
    spec = importlib.util.spec_from_file_location(f"example_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@check("build_circuit")
def _build_circuit(r, tmp_path):
    assert r["x_final"] > r["x_start"] + 0.05              # the cylinder extended
    assert r["p_supply_bar"] == pytest.approx(r["p_relief_bar"], abs=5)   # relief holds it
    assert r["p_cap_bar"] == pytest.approx(r["p_supply_bar"], abs=0.5)    # no flow, no drop
    assert r["q_relief_lpm"] == pytest.approx(10.0, rel=0.02)              # all pump flow
    assert r["x_final"] == pytest.approx(r["x_expected"], rel=0.03)        # statics
    assert (tmp_path / "build_circuit.png").exists()


@check("position_servo")
def _position_servo(r, tmp_path):
    assert r["x_steady"] == pytest.approx(0.1, abs=1e-9)      # the integral: no steady error
    assert r["dc_gain"] == pytest.approx(1.0, abs=1e-6)
    assert r["max_pole_real"] < 0.0 and r["n_poles"] == 8      # stable closed loop
    assert r["command_max"] <= 1.0 + 1e-7                      # the output limit holds
    assert r["command_in_window"] == pytest.approx(1.0, abs=1e-7)
    # full command, pump-limited: the carriage moves at 20 L/min over the cap area
    assert r["speed_saturated"] == pytest.approx(r["speed_pump_limited"], rel=1e-3)
    assert 0.0 < r["overshoot_mm"] < 2.0
    assert r["x_final"] == pytest.approx(0.1, abs=1e-3)
    assert (tmp_path / "position_servo.png").exists()


@check("shaker_table")
def _shaker_table(r, tmp_path):
    # base-excited oscillator: steady amplitude Y * transmissibility
    assert r["x_payload"] == pytest.approx(r["x_expected"], rel=2e-3)
    # the position drive supplies the rigidly joined masses' inertia plus the mount force
    assert r["force_error"] < 1e-6 * r["force_scale"]
    assert "table equation 1 (SpoolMass): once" in r["report"]
    assert "fixture equation 1 (SpoolMass): once" in r["report"]
    assert r["states"] == ["payload.flange.x", "payload.v"]


@check("swap_load")
def _swap_load(r, tmp_path):
    lam, cyl = r["laminar"], r["cylinder"]
    for res in (lam, cyl):
        assert res["LS"] == pytest.approx(res["port_B"], abs=0.5)   # LS picks up the fed port
        assert res["pump"] > res["LS"] + 3.0                          # load sensing margin
        assert res["x_spool_mm"] < -1.5                               # 4.24 V feeds port B
        assert res["q_B_lpm"] > 10.0
    assert cyl["x_rod_final"] > cyl["x_rod_start"] + 0.1             # the cylinder extends
    q_rod = cyl["v_rod"] * cyl["A_cap"] * 60000.0
    assert q_rod == pytest.approx(cyl["q_B_lpm"], rel=0.05)         # flow = A * velocity
    assert cyl["LS"] < lam["LS"]                                      # lighter load here
    # settled, the laminar load is at its operating point: the PVP spring's margin (12.97 bar
    # where A3 opens) within 1 bar, as pvgraph validate checks it
    assert r["laminar, 8 s"]["margin"] == pytest.approx(12.97, abs=1.0)
    assert (tmp_path / "swap_load.png").exists()


@check("new_component")
def _new_component(r, tmp_path):
    assert r["residual"] < 1e-12
    assert r["max_rel_error"] < 1e-6
    assert r["p_final_bar"] == pytest.approx(35.0, rel=1e-6)
    assert r["p_final_bar"] == pytest.approx(r["p_final_analytic_bar"], rel=1e-6)
    assert r["x_final"] == pytest.approx(0.2e-3 / 20e-4, rel=1e-6)   # 0.2 L over 20 cm^2


@check("pvg32_stack")
def _pvg32_stack(r, tmp_path):
    assert r["sec1_ls_bar"] > r["sec2_ls_bar"] + 10.0                 # different loads
    assert r["p_ls_common_bar"] == pytest.approx(r["ls_max_bar"], abs=1.0)   # max-select
    assert 10.0 <= r["margin_bar"] <= 16.0                             # pump follows the max
    assert r["sec1_q_lpm"] > r["sec2_q_lpm"] > 0.0
    assert (tmp_path / "pvg32_stack.png").exists()


@check("pve_linear_model")
def _pve_linear_model(r, tmp_path):
    # report 4.8.4 / figures 4.60-4.61: table 4.15 with c_vm = 25 has one conjugate pair in the
    # right half plane; c_vm = 2500 makes it stable
    rhp = r["table_poles"]["evaluated_c25"]
    rhp = rhp[rhp.real > 0]
    assert len(rhp) == 2 and rhp[0] == pytest.approx(rhp[1].conjugate(), rel=1e-9)
    assert r["table_rhp"]["evaluated_c2500"] == 0
    # with the duty slope and the NC/NO signs made consistent the loop is still unstable at
    # c_vm = 25; adding the flow the moving spool displaces (A_m dx_m/dt, dropped in eq.
    # 4.147) damps it without any spool friction, as the nonlinear model is damped
    assert r["table_rhp"]["corrected_c25"] == 2 and r["table_rhp"]["complete_c25"] == 0
    # ... and that complete hand model has the report's margins (4.9: GM 9.91 dB at 214 rad/s)
    hand = r["margins"]["hand_complete"]
    assert hand["w_gm"] == pytest.approx(214.0, rel=0.05)
    assert hand["gm_db"] == pytest.approx(9.91, abs=1.0)
    # the automatic model with the NC valves' lag at the linear model's 3 ms (4.8.2) instead
    # of 20 ms (4.5.5) has the report's crossovers and phase margin too
    nc3 = r["margins"]["automatic_nc3ms"]
    assert nc3["w_gm"] == pytest.approx(214.0, rel=0.05)
    assert nc3["w_pm"] == pytest.approx(87.5, rel=0.1)
    assert nc3["pm"] == pytest.approx(49.7, abs=5.0)
    # the table's poles put the phase crossover below 214 rad/s for any c_vm: at 214 rad/s
    # the PVE (330, 27 rad/s) and LVDT (169 rad/s) poles alone lag 167 deg and the spool,
    # past its 46 rad/s natural frequency, more than 90 deg
    assert r["margins"]["table_4_15"]["w_gm"] < 214.0
    # root locus and Bode agree: the loop goes unstable at the gain margin
    for model in ("table_4_15", "hand_complete", "automatic"):
        gm = 10.0 ** (r["margins"][model]["gm_db"] / 20.0)
        assert r["k_crit"][model] == pytest.approx(gm, rel=0.01)
    # the automatic linear model is stable, and predicts a small step of the nonlinear circuit
    assert max(r["auto_poles"].real) < 0.0
    assert r["small_step_error"] < 0.05                       # within 5 % of the step
    # the fastest pair is the spool on the oil springs of V4 and V5 (eq. 4.93-4.94, 4.103):
    # w = sqrt(beta A_m^2 (1/V4 + 1/V5) / M_m) with the report's 7000 bar, 254.5 mm^2,
    # 13 + A_m x_m and 27 - A_m x_m cm^3, 1.754 kg
    a_m, x_m = math.pi / 4 * 0.018 ** 2, r["x_op_mm"] * 1e-3
    w_oil = math.sqrt(7e8 * a_m ** 2 * (1 / (13e-6 + a_m * x_m) + 1 / (27e-6 - a_m * x_m))
                      / 1.754)
    fast = [w for w, p in zip(r["auto_wn"], r["auto_poles"]) if p.imag > 0 and w > 1000.0]
    assert len(fast) == 1 and fast[0] == pytest.approx(w_oil, rel=0.03)
    # a P loop under-reading by the LVDT gain 0.945 settles below x_set / 0.945
    assert 0.9 < r["auto_dc_gain"] < 1.0 / 0.945
    assert 0.9 * 3.5 < r["x_nonlinear_final_mm"] < 3.5 / 0.945
    # report 4.8.4 (figure 4.62): the duty-cycle limits make the nonlinear step slower
    assert r["metrics"]["nonlinear"]["rise_time"] > 1.5 * r["metrics"]["automatic"]["rise_time"]
    # report 4.9: its overshoot 27.8 % is a dominant pair with zeta = 0.38; the automatic
    # model's dominant complex pair is damped alike (within 0.1)
    zeta_report = 1.0 / math.sqrt(1.0 + (math.pi / math.log(100.0 / 27.7916)) ** 2)
    pair = [z for z, p in zip(r["auto_zeta"], r["auto_poles"]) if p.imag > 1.0][0]
    assert pair == pytest.approx(zeta_report, abs=0.1)
    # report 4.9 / figure 4.64: a lower P gain raises both margins, cuts the overshoot and
    # slows the rise, for the report's models and for the automatic one
    low = r["gains"]["report_0.3"]
    for model in ("table_4_15", "hand_complete", "automatic"):
        base_m, base_s = r["margins"][model], r["metrics"][model]
        assert low[model]["pm"] > base_m["pm"] and low[model]["gm_db"] > base_m["gm_db"]
        assert low[model]["overshoot"] < base_s["overshoot"]
        assert low[model]["rise_time"] > base_s["rise_time"]
    assert low["automatic"]["gm_db"] == pytest.approx(
        r["margins"]["automatic"]["gm_db"] - 20.0 * math.log10(0.3), abs=0.05)
    # the tuned gain meets its phase margin and the nonlinear circuit with the PVE's duty
    # slope scaled by it follows the linear prediction
    design = r["gains"]["design"]
    assert 0.0 < r["k_design"] < 1.0
    assert design["automatic"]["pm"] == pytest.approx(60.0, abs=0.5)
    assert r["design_small_step_error"] < 0.05
    assert design["nonlinear_3p5mm"]["overshoot"] < r["metrics"]["nonlinear"]["overshoot"]
    # ... at a price: holding the spool against its spring takes a pressure difference, i.e. a
    # duty-cycle offset, which a flatter slope makes out of a larger position error
    assert design["nonlinear_3p5mm"]["ess"] > 2.0 * r["metrics"]["nonlinear"]["ess"]
    for name in ("step", "gain", "bode", "poles"):
        assert Path(r["paths"][name]).stat().st_size > 10_000


@check("pvp_bypass_loss")
def _pvp_bypass_loss(r, tmp_path):
    rows = r["rows"]
    q_load = [x["q_load"] for x in rows]
    for x in rows:
        assert abs(x["imbalance"]) < 1e-9 * x["pump"]                 # power is conserved
        assert 11.0 <= x["margin"] <= 17.0                            # pump follows LS + margin
        # the rest (~0.1 L/min) feeds the PVE pilot supply and the LS drain
        assert x["q_pump"] == pytest.approx(x["q_load"] + x["q_bypass"], abs=0.2)
        assert x["bypass"] < x["bypass_fixed"]                        # load sensing saves power
        assert x["load"] == pytest.approx(x["p_load"] * 1e5 * x["q_load"] / 60000, rel=1e-9)
    assert max(q_load) - min(q_load) < 0.02 * max(q_load)             # compensated flow
    # bypass loss = Q_bypass (p_L + margin): linear in p_L with slope Q_bypass [W/bar]
    q_byp = sum(x["q_bypass"] for x in rows) / len(rows) / 60000
    assert r["bypass_slope_W_per_bar"] == pytest.approx(q_byp * 1e5, rel=0.02)
    assert r["bypass_intercept_W"] == pytest.approx(q_byp * 1e5 * rows[0]["margin"], rel=0.1)
    assert (tmp_path / "pvp_bypass_loss.png").exists()


@check("linearize_pvg32")
def _linearize_pvg32(r, tmp_path):
    import numpy as np
    assert np.all(r["poles"].real < 0)                                # a stable operating point
    lin, nl = r["dx_linear"], r["dx_nonlinear"]
    assert abs(lin[-1]) > 1e-6                                        # the step moves the spool
    # 0.01 V is small: the linear and nonlinear responses agree within 2 % of the final change
    assert np.max(np.abs(lin - nl)) < 0.02 * abs(nl[-1])
    # the spool moves by K_input / (U_s K_lvdt) per volt in steady state (eq. 4.110, 4.113)
    assert r["model"].dc_gain()[0, 0] == pytest.approx(0.028 / (11.5 * 0.945), rel=0.1)


@check("machine_cycle")
def _machine_cycle(r, tmp_path):
    assert 14.0 <= r["margin_min_bar"] and r["margin_max_bar"] <= 21.0   # LS margin 20 bar
    assert r["x_max"] < 0.25 + 1e-3 and r["F_stop_hold"] > 0.0        # held by the end stop
    assert r["q_shock_max"] > 0.0 and 150.0 < r["p_swing_peak_bar"] < 210.0   # shock valves
    assert r["v_lower"] < 0.0 and r["x_end"] < r["x_top"] - 0.01       # lowered, metered
    useful = r["E_pot"] + r["E_kin_end"] + r["E_stop"]
    assert r["E_cyl"] == pytest.approx(useful, rel=0.01, abs=20.0)    # boom energy balance
    assert r["E_shaft"] > r["E_hyd"] > 0.0
    assert (tmp_path / "machine_cycle.png").exists()


SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))
SLOW = {"machine_cycle"}   # a 6 s cycle of a 180-unknown circuit: about a minute


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW
                                  else p for p in SCRIPTS], ids=[p.stem for p in SCRIPTS])
def test_example_runs(path, tmp_path):
    module = _load(path)
    assert hasattr(module, "main"), f"{path.name} has no main(outdir)"
    out = tmp_path / "output"           # a folder that does not exist yet: main creates it
    result = module.main(out)
    if path.stem in CHECKS:
        CHECKS[path.stem](result, out)
    if isinstance(result, dict):
        for key, value in result.items():
            if isinstance(value, float):
                assert math.isfinite(value), key


def test_every_example_has_physics_checks():
    missing = {p.stem for p in SCRIPTS} - set(CHECKS)
    assert not missing, f"examples without checks in tests/test_examples.py: {missing}"
