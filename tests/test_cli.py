"""The ``pvgraph sweep`` and ``pvgraph linearize`` commands, run in-process through ``main``.

Sweeps use short settling times (the values are then transient, not the lab steady states),
so the assertions are physics that holds at every instant: the laminar L3 law, the ordering
of flow with spool travel, the return-line pressure against its conductance.
"""

import json

import numpy as np
import pytest

from pvgraph.cli import main
from pvgraph.units import lpm_per_bar

K_L3_LARGE = lpm_per_bar(0.4533)   # table 4.8, the L3 setting of the voltage-sweep scenarios


def _json(path):
    with open(path) as f:
        return json.load(f)


def _table_rows(text, n_cases):
    """The numeric cells of the sweep table rows ``case params... outputs... settled``."""
    rows = {}
    for line in text.splitlines():
        cells = line.split()
        if cells and cells[0].isdigit() and int(cells[0]) < n_cases:
            rows[int(cells[0])] = cells
    return rows


def test_sweep_over_voltage_writes_what_it_prints(tmp_path, capsys):
    code = main(["sweep", "--scenario", "sweep-4", "--param", "U_input=4.3:4.7:3",
                 "--settle", "1", "--workers", "2", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    data = _json(tmp_path / "sweep.json")
    assert data["n_cases"] == 3 and data["n_failed"] == 0
    assert data["param_names"] == ["U_input"] and data["units"]["Pf"] == "Pa"
    cases = data["cases"]
    U = [c["params"]["U_input"] for c in cases]
    q = np.array([c["outputs"]["Q_total"] for c in cases])
    x = np.array([c["outputs"]["main_spool_x"] for c in cases])
    assert U == pytest.approx([4.3, 4.5, 4.7])
    # below the neutral 5.75 V the spool moves negative; nearer neutral: less travel, less flow
    assert np.all(x < 0) and np.all(np.diff(x) > 0) and np.all(np.diff(q) < 0)
    assert q[0] > 10.0 / 6e4 and q[-1] > 1.0 / 6e4
    for c in cases:  # L2 closed: all flow through the laminar L3, Q = K (Pf - Pb)
        o = c["outputs"]
        assert abs(o["Q_branch"]) < 1e-6 * o["Q_total"]  # the closed valve's leak
        assert o["Q_total"] == pytest.approx(K_L3_LARGE * (o["Pf"] - o["Pb"]), rel=1e-6)
    rows = _table_rows(out, 3)
    for c in cases:  # the table: U, Q_total [L/min], Pf, Pm, Pb [bar], margin [bar], x [mm]
        cells, o = rows[c["index"]], c["outputs"]
        assert float(cells[1]) == pytest.approx(c["params"]["U_input"])
        assert float(cells[2]) == pytest.approx(o["Q_total"] * 6e4, abs=1e-3)
        assert float(cells[3]) == pytest.approx(o["Pf"] / 1e5, abs=1e-3)
        assert float(cells[7]) == pytest.approx(o["main_spool_x"] * 1e3, abs=1e-3)
    csv_lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(csv_lines) == 4 and csv_lines[0].startswith("index,status,wall_time,U_input,")


def test_random_sweep_of_the_return_line_conductance(tmp_path):
    args = ["sweep", "--scenario", "sweep-4", "--param", "rig.return_line_K=log:1e-9:1e-8",
            "--random", "3", "--seed", "4", "--settle", "0.5", "--backend", "serial",
            "--out", str(tmp_path)]
    assert main(args) == 0
    cases = _json(tmp_path / "sweep.json")["cases"]
    K = np.array([c["params"]["rig.return_line_K"] for c in cases])
    pb = np.array([c["outputs"]["Pb"] for c in cases])
    assert np.all((K >= 1e-9) & (K <= 1e-8))
    assert sorted(np.floor(3 * np.log10(K / 1e-9)).astype(int)) == [0, 1, 2]  # one per bin
    order = np.argsort(K)
    assert np.all(np.diff(pb[order]) < 0)  # a freer return line: lower return pressure
    assert main(args[:-1] + [str(tmp_path / "again")]) == 0  # same seed, same cases
    again = _json(tmp_path / "again" / "sweep.json")["cases"]
    assert [c["params"] for c in again] == [c["params"] for c in cases]


def test_sweep_with_a_failing_case_keeps_the_others_and_exits_1(tmp_path, capsys):
    code = main(["sweep", "--scenario", "sweep-4", "--param", "pve.input_gain=0.028,-1",
                 "--t-end", "0.3", "--backend", "serial", "--out", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 1
    cases = _json(tmp_path / "sweep.json")["cases"]
    assert [c["status"] for c in cases] == ["ok", "failed"]
    assert cases[0]["outputs"]["Q_total"] > 0
    assert cases[1]["error"]["type"] == "ParameterError"
    assert "pve.input_gain = -1.0" in cases[1]["error"]["message"]
    assert "FAILED: ParameterError" in captured.out and "pve.input_gain" in captured.err
    assert "failed" in (tmp_path / "sweep.csv").read_text().splitlines()[2]


@pytest.mark.parametrize("args, message", [
    (["--param", "rig.retrn_line_K=1e-9"],
     "unknown parameter 'rig.retrn_line_K'; did you mean 'rig.return_line_K'?"),
    (["--param", "rig=1e-9"], "'rig' is a group of parameters"),
    (["--param", "U_input=4:5"], "needs the number of points"),
    (["--param", "U_input=4:5:x"], "positive integer"),
    (["--param", "U_input=a:5:3"], "'a' is not a number"),
    (["--param", "U_input=4,5", "--random", "3"], "not a list"),
    (["--random", "3"], "at least one --param"),
    (["--scenario", "test-99"], "unknown scenario(s) ['test-99']"),
    (["--scheduler", "tcp://127.0.0.1:1", "--backend", "process"], "needs --backend dask"),
])
def test_sweep_bad_arguments_exit_2_naming_the_fault(args, message, capsys, tmp_path):
    base = ["sweep", "--out", str(tmp_path)]
    if "--scenario" not in args:
        base += ["--scenario", "sweep-4"]
    assert main(base + args) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "sweep.json").exists()


def test_sweep_lists_its_parameter_names(capsys):
    assert main(["sweep", "--list-params"]) == 0
    out = capsys.readouterr().out
    assert "U_input" in out and "rig.return_line_K" in out and "pve.nc1.switching_delay" in out


def test_linearize_at_a_scenario(tmp_path, capsys):
    path, png = tmp_path / "lin.json", tmp_path / "bode.png"
    assert main(["linearize", "--scenario", "test-9", "--json", str(path),
                 "--bode", str(png)]) == 0
    out = capsys.readouterr().out
    data = _json(path)
    assert data["U"] == pytest.approx(4.29) and data["stable"] is True
    assert data["n_states"] == len(data["state_names"]) > 10
    assert f"{data['n_states']} states, stable" in out
    poles = np.array([p["real"] + 1j * p["imag"] for p in data["poles"]])
    assert len(poles) == data["n_states"] and np.all(poles.real < 0)
    for p in data["poles"]:
        assert p["natural_frequency"] == pytest.approx(abs(p["real"] + 1j * p["imag"]))
        assert 0 < p["damping_ratio"] <= 1
    lines = out.splitlines()
    head = next(k for k, line in enumerate(lines) if "zeta" in line)
    printed = [line.split() for line in lines[head + 1:head + 1 + len(data["dominant_poles"])]]
    assert len(data["dominant_poles"]) == 6
    for p, cells in zip(data["dominant_poles"], printed):
        assert float(cells[0]) == pytest.approx(p["real"], rel=1e-4)
        assert float(cells[4]) == pytest.approx(p["damping_ratio"], abs=1e-3)
    # spool position per volt: the PVE set point gain K_in / (U_s * LVDT gain), slightly less
    # because the proportional position loop leaves an error
    gain_x = data["dc_gain"]["pvg.pvb.main_spool.flange.x"]
    ideal = 0.028 / (11.5 * 0.945)
    assert 0.9 * ideal < gain_x < ideal
    assert data["dc_gain"]["load.f.port.p"] < 0  # more voltage, nearer neutral, lower pressure
    assert f"{gain_x * 1e3:.6g} mm/V" in out
    assert png.stat().st_size > 10_000


def test_linearize_dc_gain_matches_nonlinear_steady_states(tmp_path):
    U0, dU = 4.29, 0.02
    ops = {}
    for U in (U0 - dU, U0, U0 + dU):
        path = tmp_path / f"{U}.json"
        assert main(["linearize", "--voltage", str(U), "--json", str(path), "--poles", "2"]) == 0
        ops[U] = _json(path)
    for name in ("pvg.pvb.main_spool.flange.x", "load.f.port.p"):
        slope = (ops[U0 + dU]["operating_point"]["values"][name]
                 - ops[U0 - dU]["operating_point"]["values"][name]) / (2 * dU)
        assert ops[U0]["dc_gain"][name] == pytest.approx(slope, rel=2e-2)


@pytest.mark.parametrize("args, message", [
    (["--output", "load.f.port.pp"], "did you mean 'load.f.port.p'"),
    (["--output", "load.L3.q"], "'load.L3.q' is a derived output"),
    (["--scenario", "test-99"], "unknown scenario 'test-99'"),
    (["--voltage", "20"], "outside 0 .. 11.5 V"),
])
def test_linearize_bad_arguments_exit_2(args, message, capsys):
    assert main(["linearize"] + args) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--fit", "rig.pump_flw"], "Did you mean 'rig.pump_flow'"),
    (["--fit", "pvp.spool_mass"], "cannot be calibrated"),
    (["--law", "turbulent"], "laminar load constants"),
])
def test_validate_calibrate_bad_arguments_exit_2(args, message, capsys, tmp_path):
    code = main(["validate", "--calibrate", "--out", str(tmp_path), "--no-plots", *args])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "calibration.json").exists()     # nothing half written


@pytest.mark.slow
def test_validate_calibrate_writes_estimates(tmp_path, capsys):
    code = main(["validate", "--calibrate", "--out", str(tmp_path), "--no-plots",
                 "--fit", "rig.supply_voltage", "--fit", "rig.pump_flow"])
    out = capsys.readouterr().out
    assert code == 0 and "table 4.14" in out and "calibrated parameters" in out
    est = {p["name"]: p for p in _json(tmp_path / "calibration.json")["parameters"]}
    v = est["rig.supply_voltage"]
    assert v["ci_low"] < 11.5 < v["ci_high"]            # the report's identified supply


@pytest.mark.slow
def test_validate_cross_validate_writes_held_out_records(tmp_path, capsys):
    code = main(["validate", "--scenario", "test-9", "--out", str(tmp_path), "--no-plots",
                 "--cross-validate"])
    out = capsys.readouterr().out
    assert code == 0
    assert "leave one voltage group out" in out and "leave one load group out" in out
    data = json.loads((tmp_path / "cross_validation.json").read_text())
    assert {r["role"] for r in data["records"]} <= {"fit", "held-out", "trivial"}
    held = [r for r in data["records"] if r["grouping"] == "voltage"
            and r["quantity"] == "Q_total" and r["role"] == "held-out"]
    assert len(held) == 16                       # 17 non-neutral points less the saturated one
    assert sum(abs(r["error"]) <= 1.0 for r in held) >= 14
    records = json.loads((tmp_path / "validation.json").read_text())
    assert all(r["role"] in ("fit", "held-out", "trivial") for r in records)


def test_validate_records_carry_roles(tmp_path, capsys):
    code = main(["validate", "--scenario", "sweep-5", "--scenario", "sweep-1", "--out",
                 str(tmp_path), "--no-plots", "--workers", "1"])
    out = capsys.readouterr().out
    assert code == 0
    assert "PVP margin: the report's spring" in out and "not reachable" in out
    records = {(r["scenario"], r["quantity"]): r
               for r in json.loads((tmp_path / "validation.json").read_text())}
    assert records[("sweep-5", "Q_total")]["role"] == "fit"          # an A_H anchor
    assert records[("sweep-1", "Q_total")]["role"] == "trivial"      # neutral
    assert records[("sweep-5", "Pf")]["role"] == "held-out"
    r = records[("sweep-5", "Q_total")]
    assert r["error"] == pytest.approx(r["simulated"] - r["measured"], abs=1e-3)
    assert abs(r["error"]) <= 1.0                                      # flow meter +-1 L/min
