"""The ``pvgraph sweep`` and ``pvgraph linearize`` commands, run in-process through ``main``.

Sweeps use short settling times (the values are then transient, not the lab steady states),
so the assertions are physics that holds at every instant: the laminar L3 law, the ordering
of flow with spool travel, the return-line pressure against its conductance.
"""

import json
import sys

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


def test_sweep_with_an_invalid_value_exits_2_before_any_case_runs(tmp_path, capsys):
    code = main(["sweep", "--scenario", "sweep-4", "--param", "pve.input_gain=0.028,-1",
                 "--t-end", "0.3", "--backend", "serial", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2
    assert "1 of 2 cases have invalid parameter values; nothing was run" in err
    assert "pve.input_gain = -1.0" in err
    assert not (tmp_path / "sweep.json").exists() and not (tmp_path / "cases.jsonl").exists()


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
        assert main(["linearize", "--voltage", str(U), "--json", str(path), "--poles", "2",
                     "--output", "pvg.pvb.main_spool.flange.x", "--output", "load.f.port.p",
                     "--output", "load.L3.q"]) == 0
        ops[U] = _json(path)
    # a derived output (the load orifice's flow) as well as the variables
    for name in ("pvg.pvb.main_spool.flange.x", "load.f.port.p", "load.L3.q"):
        slope = (ops[U0 + dU]["operating_point"]["values"][name]
                 - ops[U0 - dU]["operating_point"]["values"][name]) / (2 * dU)
        assert ops[U0]["dc_gain"][name] == pytest.approx(slope, rel=2e-2)


@pytest.mark.parametrize("args, message", [
    (["--output", "load.f.port.pp"], "did you mean 'load.f.port.p'"),
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


# --------------------------------------------------------------------------------------------
# the user's own circuit: FILE.py:NAME, MODULE:NAME, model files

RIG_FILE = '''
import sys
import time

from pydantic import Field

from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode
from pvgraph import Circuit, Component, Hydraulic, Params


class SleepyParams(Params):
    delay: float = Field(0.0, ge=0.0, description="Wall time spent tracing [s]")
    exit: float = Field(0.0, ge=0.0, le=1.0, description="1 calls sys.exit while tracing [-]")


class Sleepy(Component):
    """A closed port that takes ``delay`` seconds to trace (a stand-in for a slow case)."""
    Params = SleepyParams
    ports = {"port": Hydraulic("closed end")}

    def equations(self, v, p):
        time.sleep(p.delay)
        if p.exit:
            sys.exit(3)
        return [v.port.q]


def build(Q="10 L/min"):
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V="0.5 L"))
    orifice = c.add("orifice", Orifice(A="2 mm^2"))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    return c


def slow():
    """The demo circuit with a Sleepy part on the node."""
    c = build()
    part = c.add("slow", Sleepy())
    c.connect(part.port, c["tank"].port)
    return c


def nested():
    """The demo circuit inside a 'bench' that exposes the node as port P."""
    inner = build()
    inner.expose("P", inner["node"].port)
    outer = Circuit("outer")
    outer.add("bench", inner)
    return outer
'''
RHO, CD, A_ORF, Q_PUMP, BETA, V_NODE = 870.0, 0.6, 2e-6, 10 / 60e3, 7e8, 0.5e-3


def _p_steady(Q=Q_PUMP, A=A_ORF):
    """Orifice law at steady state: p = rho/2 (Q / (Cd A))^2."""
    return RHO / 2 * (Q / (CD * A)) ** 2


@pytest.fixture
def rig_file(tmp_path):
    path = tmp_path / "my_rig.py"
    path.write_text(RIG_FILE)
    return str(path)


def _final_values(out):
    vals = {}
    for line in out.splitlines():
        cells = line.split()
        if len(cells) >= 4 and cells[1] == "final":
            vals[cells[0]] = (float(cells[2]), cells[3])
    return vals


def test_simulate_a_file_target_prints_bar_and_writes_si(rig_file, tmp_path, capsys):
    csv = tmp_path / "out.csv"
    assert main(["simulate", f"{rig_file}:build", "--t-end", "1", "--var", "node.port.p",
                 "--var", "orifice.q", "--csv", str(csv)]) == 0
    vals = _final_values(capsys.readouterr().out)
    assert vals["node.port.p"][1] == "bar" and vals["orifice.q"][1] == "L/min"
    assert vals["node.port.p"][0] == pytest.approx(_p_steady() / 1e5, rel=2e-3)
    assert vals["orifice.q"][0] == pytest.approx(10.0, rel=2e-3)
    header = csv.read_text().splitlines()[0]
    assert header == "t [s],node.port.p [Pa],orifice.q [m^3/s]"
    assert main(["simulate", f"{rig_file}:build", "--t-end", "1", "--var", "node.port.p",
                 "--si", "--option", 'Q="5 L/min"']) == 0
    p, unit = _final_values(capsys.readouterr().out)["node.port.p"]
    assert unit == "Pa" and p == pytest.approx(_p_steady(Q=Q_PUMP / 2), rel=2e-3)


def test_simulate_a_module_target(rig_file, tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["simulate", "my_rig:build", "--t-end", "1", "--var", "node.port.p"]) == 0
    p, _ = _final_values(capsys.readouterr().out)["node.port.p"]
    assert p == pytest.approx(_p_steady() / 1e5, rel=2e-3)


@pytest.mark.parametrize("target, message", [
    ("{file}:buld", "has no 'buld'. Did you mean 'build'?"),
    ("{dir}/missing.py:build", "no such file"),
    ("rgi", "unknown circuit 'rgi'. Did you mean 'rig'?"),
    ("no_such_module_xyz:build", "cannot import module 'no_such_module_xyz'"),
])
def test_bad_targets_exit_2(target, message, rig_file, tmp_path, capsys):
    spec = target.format(file=rig_file, dir=tmp_path)
    assert main(["simulate", spec]) == 2
    assert message in capsys.readouterr().err


def test_misspelled_var_fails_before_simulating(rig_file, tmp_path, capsys):
    csv = tmp_path / "never.csv"
    code = main(["simulate", f"{rig_file}:build", "--var", "node.port.pp", "--csv", str(csv)])
    err = capsys.readouterr().err
    assert code == 2
    assert "--var 'node.port.pp' is not a variable" in err and "did you mean 'node.port.p'" in err
    assert "steps" not in err and not csv.exists()


@pytest.mark.parametrize("args, message", [
    (["--rtol", "0"], "argument --rtol: '0': a relative tolerance is a number between 0 and 1"),
    (["--rtol", "nan"], "argument --rtol: 'nan': a relative tolerance"),
    (["--rtol", "abc"], "argument --rtol: 'abc' is not a number"),
    (["--plot", "{dir}/out.xyz"], "the figure format comes from the extension; use one of .png"),
    (["--csv", "{dir}/afile/x.csv"], "cannot make a directory there, "),
    (["--plot", "{dir}/afile/sub/x.png"], "is a file"),
    (["--csv", "{dir}"], "is a directory; give a file name"),
])
def test_bad_options_exit_2_before_anything_runs(args, message, rig_file, tmp_path, capsys):
    csv = tmp_path / "never.csv"
    (tmp_path / "afile").write_text("a file where a directory is expected")
    with pytest.raises(SystemExit) as exc:       # argparse's own exit, before the target loads
        main(["simulate", f"{rig_file}:build", "--csv", str(csv)]
             + [a.format(dir=tmp_path) for a in args])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
    assert not csv.exists()
    if args[0] == "--rtol":     # a sweep refuses it too, before any case runs
        with pytest.raises(SystemExit) as exc:
            main(["sweep", f"{rig_file}:build", "--param", "orifice.A=1e-6,2e-6",
                  "--out", str(tmp_path / "sweep")] + args)
        assert exc.value.code == 2 and not (tmp_path / "sweep").exists()


def test_linearize_names_the_option_of_a_misspelled_input(rig_file, capsys):
    assert main(["linearize", f"{rig_file}:build", "--input", "pump.QQ", "--output",
                 "node.port.p"]) == 2
    err = capsys.readouterr().err
    assert "--input: unknown parameter 'pump.QQ'; did you mean 'pump.Q'?" in err
    assert "PVG32" not in err


def test_vars_lists_names_units_and_exposed_ports(rig_file, capsys):
    assert main(["vars", f"{rig_file}:nested"]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines()[1:]}
    assert "[Pa]" in rows["bench.node.port.p"] and "state" in rows["bench.node.port.p"]
    assert "[m^3/s]" in rows["bench.orifice.q"] and "output" in rows["bench.orifice.q"]
    assert "alias of bench.node.port.p (exposed port)" in rows["bench.P.p"]
    # every row is described, eliminated variables by their component's port declaration
    assert rows["bench.orifice.a.p"].endswith("= bench.node.port.p  p at port a (inlet)")
    assert rows["bench.pump.port.q"].endswith("q into port port (node fed by the source)")
    # an exposed port is a valid name everywhere, and close matches include it
    assert main(["simulate", f"{rig_file}:nested", "--t-end", "1", "--var", "bench.P.p"]) == 0
    p, _ = _final_values(capsys.readouterr().out)["bench.P.p"]
    assert p == pytest.approx(_p_steady() / 1e5, rel=2e-3)
    assert main(["simulate", f"{rig_file}:nested", "--var", "bench.P.pp"]) == 2
    assert "'bench.P.p'" in capsys.readouterr().err


def test_sweep_a_file_target_with_units(rig_file, tmp_path, capsys):
    out = tmp_path / "study"
    assert main(["sweep", f"{rig_file}:build", "--param", "orifice.A=1 mm^2,2 mm^2,4 mm^2",
                 "--var", "node.port.p", "--t-end", "4", "--backend", "serial",
                 "--out", str(out)]) == 0
    data = _json(out / "sweep.json")
    A = [c["params"]["orifice.A"] for c in data["cases"]]
    p = [c["outputs"]["node.port.p"] for c in data["cases"]]
    assert A == pytest.approx([1e-6, 2e-6, 4e-6], rel=1e-14)
    assert p == pytest.approx([_p_steady(A=a) for a in A], rel=3e-3)
    assert data["units"] == {"node.port.p": "Pa"}
    assert (out / "sweep.csv").read_text().splitlines()[0] == \
        "index,status,wall_time,orifice.A,node.port.p [Pa],error_type,error_message,warnings"
    printed = capsys.readouterr().out
    assert "orifice.A [mm^2]" in printed and "node.port.p [bar]" in printed
    rows = _table_rows(printed, 3)     # parameters and outputs both in the units people read
    assert [float(rows[k][1]) for k in range(3)] == pytest.approx([1.0, 2.0, 4.0], rel=1e-12)
    assert [float(rows[k][2]) for k in range(3)] == pytest.approx([x / 1e5 for x in p], rel=1e-5)


def test_sweep_steady_states_of_a_file_target(rig_file, tmp_path, capsys):
    """--steady records each case's operating point: the orifice law's pressure, tighter than
    a simulation to a finite time can give."""
    out = tmp_path / "steady"
    assert main(["sweep", f"{rig_file}:build", "--param", "orifice.A=1 mm^2,2 mm^2,4 mm^2",
                 "--var", "node.port.p", "--steady", "--backend", "serial",
                 "--out", str(out)]) == 0
    cases = _json(out / "sweep.json")["cases"]
    for c in cases:
        assert c["status"] == "ok"
        assert c["outputs"]["node.port.p"] == pytest.approx(_p_steady(A=c["params"]["orifice.A"]),
                                                            rel=1e-6)
    assert "steady states" in capsys.readouterr().out


def test_sweep_of_a_file_target_reuses_one_compiled_system(rig_file, tmp_path, capsys):
    """orifice.A and pump.Q are runtime parameters (no note); node.air is structural: its
    other value is compiled once, with a one-line note, and gives the same pressures."""
    out = tmp_path / "reuse"
    assert main(["sweep", f"{rig_file}:build", "--param", "orifice.A=1 mm^2,2 mm^2",
                 "--param", "node.air=0,0.01", "--var", "node.port.p", "--t-end", "4",
                 "--backend", "serial", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "node.air" in notes[0]
    cases = _json(out / "sweep.json")["cases"]
    p = {(c["params"]["orifice.A"], c["params"]["node.air"]): c["outputs"]["node.port.p"]
         for c in cases}
    for (A, air), value in p.items():
        assert value == pytest.approx(_p_steady(A=A), rel=3e-3)
        assert value == pytest.approx(p[(A, 0.0)], rel=1e-3)    # air only slows the rise


@pytest.mark.parametrize("param, message", [
    ("orifice.A=1e-6,-1e-6", "nothing was run"),
    ("orifice.AA=1e-6", "did you mean 'orifice.A'"),
    ("orifice.A=2 bar", "is a pressure, but orifice.A is an area"),
])
def test_sweep_a_file_target_refuses_bad_values_before_running(param, message, rig_file,
                                                                tmp_path, capsys):
    code = main(["sweep", f"{rig_file}:build", "--param", param, "--var", "node.port.p",
                 "--backend", "serial", "--out", str(tmp_path / "s")])
    assert code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "s" / "sweep.json").exists()


def test_linearize_a_file_target_against_the_orifice_law(rig_file, tmp_path):
    """Around p0 = rho/2 (Q/(Cd A))^2: dp/dQ = 2 p0 / Q, one pole at -(beta/V) Q / (2 p0)."""
    path = tmp_path / "lin.json"
    assert main(["linearize", f"{rig_file}:build", "--input", "pump.Q", "--output",
                 "node.port.p", "--json", str(path)]) == 0
    data = _json(path)
    p0 = _p_steady()
    assert data["operating_point"]["node.port.p"] == pytest.approx(p0, rel=1e-6)
    assert data["dc_gain"]["node.port.p"]["pump.Q"] == pytest.approx(2 * p0 / Q_PUMP, rel=1e-4)
    assert data["n_states"] == 1
    assert data["poles"][0]["real"] == pytest.approx(-BETA / V_NODE * Q_PUMP / (2 * p0),
                                                     rel=1e-4)


def test_graph_and_export_of_a_file_target(rig_file, tmp_path, capsys):
    for name in ("c.png", "c.svg", "c.dot"):
        assert main(["graph", f"{rig_file}:build", "--out", str(tmp_path / name)]) == 0
    assert (tmp_path / "c.png").stat().st_size > 5000
    assert "<svg" in (tmp_path / "c.svg").read_text()
    dot = (tmp_path / "c.dot").read_text()
    assert dot.startswith("graph") and '"orifice"' in dot
    model = tmp_path / "demo.toml"
    assert main(["export", f"{rig_file}:build", "--out", str(model)]) == 0
    capsys.readouterr()
    assert main(["simulate", str(model), "--t-end", "1", "--var", "node.port.p"]) == 0
    p, _ = _final_values(capsys.readouterr().out)["node.port.p"]
    assert p == pytest.approx(_p_steady() / 1e5, rel=2e-3)


def test_pvgraph_runs_without_the_pvg32_application(rig_file, tmp_path):
    """With circuits/ unimportable and no plugins, the framework and its CLI still work."""
    import os
    import subprocess
    import sys
    code = (
        "import sys; sys.modules['pvgraph.circuits'] = None\n"
        "from pvgraph.cli import main\n"
        f"assert main(['simulate', {rig_file + ':build'!r}, '--t-end', '0.5']) == 0\n"
        "try:\n"
        "    main(['validate'])\n"
        "except SystemExit as exc:\n"
        "    assert exc.code == 2\n"
        "else:\n"
        "    raise AssertionError('validate should be unknown')\n"
        "assert main(['simulate', 'rig']) == 2\n"
        "print('standalone ok')\n")
    env = {**os.environ, "PVGRAPH_PLUGINS": "", "PVGRAPH_ENTRY_POINTS": "0"}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "standalone ok" in proc.stdout
    assert "No application has registered circuits" in proc.stderr


@pytest.mark.slow
def test_ctrl_c_during_a_sweep_keeps_what_is_done_and_resume_finishes(rig_file, tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time
    out = tmp_path / "study"
    args = [sys.executable, "-m", "pvgraph.cli", "sweep", f"{rig_file}:slow", "--param",
            "slow.delay=1.0:1.2:8", "--var", "node.port.p", "--t-end", "0.2",
            "--backend", "process", "--workers", "2", "--out", str(out)]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": os.getcwd()})
    log = out / "cases.jsonl"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if log.exists() and len(log.read_text().splitlines()) >= 3:   # header + 2 cases
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "cases finished and kept" in stderr and "--resume" in stderr
    assert "Traceback" not in stderr
    finished = len(log.read_text().splitlines()) - 1
    data = _json(out / "sweep.json")
    assert 2 <= data["n_finished"] == finished < 8 and data["complete"] is False
    resumed = subprocess.run(args + ["--resume"], capture_output=True, text=True, timeout=120,
                             env={**os.environ, "PYTHONPATH": os.getcwd()})
    assert resumed.returncode == 0, resumed.stderr
    data = _json(out / "sweep.json")
    assert data["complete"] is True and data["n_ok"] == 8
    p = [c["outputs"]["node.port.p"] for c in data["cases"]]
    assert max(p) - min(p) < 1e-6 * max(p)           # the delay changes nothing physical


def test_a_broken_user_file_is_named(tmp_path, capsys):
    bad = tmp_path / "broken.py"
    bad.write_text("def build():\n    return 1 +\n")
    assert main(["simulate", f"{bad}:build"]) == 2
    err = capsys.readouterr().err
    assert "broken.py (line 2): importing it failed: SyntaxError" in err
    wrong = tmp_path / "wrong.py"
    wrong.write_text("def build():\n    return 42\n")
    assert main(["simulate", f"{wrong}:build"]) == 2
    assert "returned int, not a pvgraph Circuit" in capsys.readouterr().err


@pytest.mark.slow
def test_validate_cross_validate_writes_held_out_records(tmp_path, capsys):
    code = main(["validate", "--scenario", "test-9", "--out", str(tmp_path), "--no-plots",
                 "--cross-validate"])
    out = capsys.readouterr().out
    assert code == 0
    assert "leave one voltage group out" in out and "leave one load group out" in out
    data = json.loads((tmp_path / "cross_validation.json").read_text())
    assert {r["role"] for r in data["records"]} <= {"fit", "repeat", "held-out", "trivial"}
    held = [r for r in data["records"] if r["grouping"] == "voltage"
            and r["quantity"] == "Q_total" and r["role"] == "held-out"]
    # the 17 non-neutral points; the saturated one's pump flow is then table 4.9's 17 L/min
    assert len(held) == 17
    assert sum(abs(r["error"]) <= 1.0 for r in held) >= 15
    records = json.loads((tmp_path / "validation.json").read_text())
    assert all(r["role"] in ("fit", "repeat", "held-out", "trivial") for r in records)


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


def test_validate_roles_per_configuration_and_model_checks(tmp_path, capsys):
    """Test 6 ends in the configuration of the fitted test 4: its Pb repeats a fit, and with L2
    closed Pm is Pb; test 5's Pf and Pm are fit (K_L2), its Pb held out. The margin and
    settling targets compare the model with itself and are not counted as held-out."""
    code = main(["validate", "--scenario", "test-4", "--scenario", "test-5", "--scenario",
                 "test-6", "--out", str(tmp_path), "--no-plots", "--workers", "2"])
    out = capsys.readouterr().out
    assert code == 0
    records = {(r["scenario"], r["quantity"]): r
               for r in json.loads((tmp_path / "validation.json").read_text())}
    assert records[("test-4", "Pb")]["role"] == "fit"
    assert records[("test-6", "Pb")]["role"] == "repeat"
    assert records[("test-6", "Pb")]["simulated"] == pytest.approx(
        records[("test-4", "Pb")]["simulated"], abs=1e-3)
    assert records[("test-4", "Pm")]["role"] == "repeat"
    assert records[("test-4", "Pm")]["simulated"] == pytest.approx(
        records[("test-4", "Pb")]["simulated"], abs=1e-3)
    # test 5's Pf and Pm went into K_L2 (figure 4.32: Q against Pf - Pm), its Pb did not; a
    # test with a fitted value is not counted as held out
    assert {q: records[("test-5", q)]["role"] for q in ("Pf", "Pm", "Pb")} == {
        "Pf": "fit", "Pm": "fit", "Pb": "held-out"}
    lines = {ln.split(":")[0].strip(): ln for ln in out.splitlines() if ln.startswith("  ")}
    steps = lines["miss  Pf, Pm, Pb within 2 bar (step tests)"]
    assert steps.endswith("(fit 1/2, repeat of a fit 1/1)")  # test 5: Pf -2.45
    margin = next(ln for ln in out.splitlines() if "PVP margin within 1 bar" in ln)
    assert "model check 3/3, nothing measured" in margin and "held-out" not in margin
    settled = next(ln for ln in out.splitlines() if "settled within 0.5 s" in ln)
    assert "of the solenoid step (step tests): 2/2" in settled and "held-out" not in settled
    steady = next(ln for ln in out.splitlines() if "steady at the end" in ln)
    assert ": 1/1 (model check 1/1, nothing measured)" in steady       # test 4: no step
    goals = json.loads((tmp_path / "validation_targets.json").read_text())
    assert goals["PVP margin within 1 bar of its spring's, main spool drop 5 +- 1 bar "
                 "(unsaturated)"]["by_role"] == {"model check": {"passed": 3, "total": 3}}
    step_rows = {r["scenario"]: r for r in goals["Pf, Pm, Pb within 2 bar (step tests)"]["rows"]}
    assert {n: r["role"] for n, r in step_rows.items()} == {
        "test-4": "fit", "test-5": "fit", "test-6": "repeat"}
    assert step_rows["test-5"]["number"] == pytest.approx(2.45, abs=0.05)
    settle = goals["settled within 0.5 s of the solenoid step (step tests)"]
    assert settle["unit"] == "bar"
    # within 0.5 bar (or 2 %) of the final Pf from 0.5 s after the step
    assert all(0.0 <= r["number"] <= 0.5 + 0.02 * 43.0 for r in settle["rows"])


@pytest.mark.parametrize("args, message", [
    (["--fold", "U=4.6"], "--fold ['U=4.6']: no such fold; did you mean 'U = 4.6 V'"),
    (["--fold", "U = 4.6 V"], "--fold only applies with --cross-validate"),
    (["--meter-out", "ratio"], "--meter-out only applies with --cross-validate"),
])
def test_validate_fold_options_are_checked_before_any_run(args, message, tmp_path, capsys):
    import time
    cross = ["--cross-validate"] if "no such fold" in message else []
    t0 = time.perf_counter()
    code = main(["validate", "--out", str(tmp_path), "--no-plots", *cross, *args])
    assert code == 2 and time.perf_counter() - t0 < 5.0
    out, err = capsys.readouterr()
    assert message in err
    assert "PVG 32 on the lab rig" not in out                    # no scenario was run
    assert not (tmp_path / "validation.json").exists()


@pytest.mark.parametrize("args, message", [
    (["--workers", "0"], "argument --workers: '0': give 1 or more processes"),
    (["--workers", "-1"], "argument --workers: '-1': give 1 or more processes"),
    (["--workers", "two"], "argument --workers: 'two' is not a whole number"),
])
def test_validate_workers_must_be_positive(args, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["validate", "--out", str(tmp_path), *args])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_validate_json_to_a_folder_exits_2_before_any_run(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["validate", "--out", str(tmp_path / "report"), "--json", str(tmp_path)])
    assert exc.value.code == 2
    out, err = capsys.readouterr()
    assert f"argument --json: '{tmp_path}' is a directory; give a file name" in err
    assert "PVG 32 on the lab rig" not in out and not (tmp_path / "report").exists()
    (tmp_path / "afile").write_text("x")
    with pytest.raises(SystemExit) as exc:
        main(["validate", "--json", str(tmp_path / "afile" / "v.json")])
    assert exc.value.code == 2
    assert "cannot make a directory there" in capsys.readouterr().err


def test_a_builder_error_names_the_line_of_the_users_file(tmp_path, capsys):
    path = tmp_path / "wrong_unit.py"
    path.write_text("from pvgraph import Circuit\n"
                    "from pvgraph.components import VolumeNode\n"
                    "\n"
                    "\n"
                    "def build():\n"
                    "    c = Circuit('c')\n"
                    "    c.add('node', VolumeNode(V='0.5 bar'))\n"
                    "    return c\n")
    assert main(["simulate", f"{path}:build"]) == 2
    err = capsys.readouterr().err
    assert "wrong_unit.py, line 7 (in build): invalid parameters for VolumeNode" in err
    assert "V = '0.5 bar' is a pressure, but V is a volume [m^3]" in err


def test_the_command_prints_its_warnings_as_one_plain_line(tmp_path, monkeypatch, capsys):
    """A closed loop of volumes floats: the command warns in one line naming the circuit,
    not with Python's file-and-source-line format pointing into pvgraph."""
    path = tmp_path / "ring.py"
    path.write_text("from pvgraph import Circuit\n"
                    "from pvgraph.components import Orifice, VolumeNode\n"
                    "\n"
                    "\n"
                    "def build():\n"
                    "    c = Circuit('ring')\n"
                    "    v1 = c.add('v1', VolumeNode(V='1 L', p0='42 bar'))\n"
                    "    v2 = c.add('v2', VolumeNode(V='1 L'))\n"
                    "    o1 = c.add('o1', Orifice(A='1 mm^2'))\n"
                    "    o2 = c.add('o2', Orifice(A='1 mm^2'))\n"
                    "    c.connect(v1.port, o1.a, o2.b)\n"
                    "    c.connect(o1.b, v2.port, o2.a)\n"
                    "    return c\n")
    monkeypatch.setattr(sys, "argv", ["pvgraph", "simulate", f"{path}:build", "--t-end",
                                      "0.2", "--var", "v2.port.p"])
    assert main() == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("pvgraph simulate: warning: circuit 'ring': the hydraulic "
                                   "network of o1, o2, v1, v2 has no pressure reference")
    assert "cli.py" not in captured.err and "PlausibilityWarning" not in captured.err
    p, unit = _final_values(captured.out)["v2.port.p"]
    assert unit == "bar" and p == pytest.approx(21.0, rel=1e-2)   # 42 bar shared by 2 L


@pytest.mark.skipif(__import__("pvgraph.cbackend").cbackend.c_compiler() is None,
                    reason="no C compiler")
def test_eval_c_gives_the_python_codes_numbers(rig_file, tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("PVGRAPH_BACKEND", raising=False)     # restored after the test
    monkeypatch.setenv("PVGRAPH_CACHE_DIR", str(tmp_path / "cache"))
    args = ["simulate", f"{rig_file}:build", "--t-end", "1", "--var", "node.port.p", "--si"]
    assert main(args) == 0
    py = capsys.readouterr().out
    assert main(["--eval", "c"] + args) == 0
    c = capsys.readouterr().out
    assert _final_values(c) == _final_values(py)     # printed alike: the same number
    assert _final_values(c)["node.port.p"][0] == pytest.approx(_p_steady(), rel=2e-3)
    assert list((tmp_path / "cache").glob("pv_*")), "the library is cached"
    with pytest.raises(SystemExit) as exc:
        main(["--eval", "fortran"] + args)
    assert exc.value.code == 2
    assert "invalid choice: 'fortran'" in capsys.readouterr().err


def test_vars_shows_the_offset_of_an_affine_alias(rig_file, capsys):
    """The node's flow is the pump's 10 L/min minus what leaves through the orifice's other
    side: ``node.port.q = Q - ...``; the listing keeps the constant (1.66667e-4 m^3/s)."""
    assert main(["vars", f"{rig_file}:build"]) == 0
    rows = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[1:]}
    assert "fixed -0.000166667" in rows["pump.port.q"]
    assert "+ 0.000166667" in rows["node.port.q"]


CENTRE_FILE = '''
from pvgraph import Circuit
from pvgraph.components import Constant, DirectionalValve43, FlowSource, Plug, Tank, VolumeNode


def build():
    c = Circuit("centres")
    pump, node = c.add("pump", FlowSource(Q="10 L/min")), c.add("n", VolumeNode(V="0.2 L"))
    valve = c.add("v", DirectionalValve43(A_max="20 mm^2", centre="open"))
    u, tank = c.add("u", Constant(k=0.0)), c.add("t", Tank())
    c.connect(pump.port, node.port, valve.P)
    c.connect(valve.T, tank.port)
    c.connect(u.y, valve.u)
    c.connect(valve.A, c.add("pa", Plug()).port)
    c.connect(valve.B, c.add("pb", Plug()).port)
    return c
'''


def test_sweep_over_a_choice_and_a_misspelled_name_with_a_unit(tmp_path, capsys):
    """A choice parameter (the 4/3 valve's centre) sweeps by its values as written; the
    open centre passes the pump flow through two series edges, the tandem centre bypasses
    P to T. A misspelled name given with a unit is named as unknown, not as a bad number."""
    target = tmp_path / "centres.py"
    target.write_text(CENTRE_FILE)
    out = tmp_path / "sweep"
    assert main(["sweep", f"{target}:build", "--param", "v.centre=open,tandem", "--var",
                 "pump.port.p", "--out", str(out), "--t-end", "0.5"]) == 0
    import json
    cases = json.loads((out / "sweep.json").read_text())
    rows = cases["cases"] if isinstance(cases, dict) else cases
    assert [r["params"]["v.centre"] for r in rows] == ["open", "tandem"]
    p_open, p_tandem = (r["outputs"]["pump.port.p"] for r in rows)
    assert p_open > 100e5 and p_tandem < 2e5
    capsys.readouterr()
    assert main(["sweep", f"{target}:build", "--param", "v.A_mx=20 mm^2", "--var",
                 "pump.port.p", "--out", str(tmp_path / "never")]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'v.A_mx'; did you mean 'v.A_max'" in err
    assert not (tmp_path / "never").exists()


def test_linearize_a_file_target_draws_the_bode_plot(rig_file, tmp_path, capsys, monkeypatch):
    """--bode on a user's circuit writes the plot of each output over each input, over two
    decades either side of the poles; the plotted gain at the lowest frequency is the DC
    gain (the volume and orifice: 1 / G, 220 dB in Pa per m^3/s)."""
    import pvgraph.plotting as plotting
    drawn = {}
    real = plotting.plot_bode

    def spy(freq, mags, phases, path, **kw):
        drawn.update(freq=freq, mags=mags, labels=kw.get("labels"))
        return real(freq, mags, phases, path, **kw)
    monkeypatch.setattr(plotting, "plot_bode", spy)
    png = tmp_path / "bode.png"
    assert main(["linearize", f"{rig_file}:build", "--input", "pump.Q", "--output",
                 "node.port.p", "--bode", str(png)]) == 0
    assert f"wrote {png}" in capsys.readouterr().out
    assert png.stat().st_size > 10_000
    dp_dq = 2.0 * _p_steady() / Q_PUMP        # slope of the orifice law, 1 / G
    assert drawn["mags"][0][0] == pytest.approx(20 * np.log10(dp_dq), abs=1e-3)
    pole_hz = dp_dq ** -1 * BETA / V_NODE / (2 * np.pi)
    assert drawn["freq"][0] < pole_hz / 50 and drawn["freq"][-1] > pole_hz * 50
    assert drawn["labels"] == ["node.port.p / pump.Q [Pa/(m^3/s)]"]


def test_a_circuit_the_equations_fix_entirely(tmp_path, capsys):
    """A flow source straight into tank leaves no unknown: simulate shows the fixed variables,
    linearize gives no state and the direct gain 1."""
    path = tmp_path / "dump.py"
    path.write_text("from pvgraph import Circuit\n"
                    "from pvgraph.components import FlowSource, Tank\n"
                    "def build():\n"
                    "    c = Circuit('dump')\n"
                    "    c.add('pump', FlowSource(Q='10 L/min'))\n"
                    "    c.add('tank', Tank())\n"
                    "    c.connect('pump.port', 'tank.port')\n"
                    "    return c\n")
    assert main(["simulate", f"{path}:build", "--t-end", "1"]) == 0
    out = capsys.readouterr().out
    assert _final_values(out)["tank.port.q"] == (10.0, "L/min")
    assert "no unknown left to integrate" in out
    assert main(["linearize", f"{path}:build", "--input", "pump.Q", "--output",
                 "tank.port.q"]) == 0
    out = capsys.readouterr().out
    assert "0 states" in out and "d tank.port.q / d pump.Q: 1" in out


@pytest.mark.parametrize("command", ["sweep", "validate"])
def test_an_output_folder_that_is_a_file_exits_2_before_anything_runs(command, rig_file,
                                                                        tmp_path, capsys):
    (tmp_path / "afile").write_text("a file where a folder is expected")
    target = [f"{rig_file}:build", "--param", "orifice.A=1e-6"] if command == "sweep" else []
    for out, message in ((tmp_path / "afile", "is a file; give a folder"),
                         (tmp_path / "afile" / "sub", "cannot make a folder there")):
        with pytest.raises(SystemExit) as exc:
            main([command] + target + ["--out", str(out)])
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert f"argument --out: '{out}'" in err and message in err


def test_an_output_that_cannot_be_written_names_the_file(rig_file, tmp_path, capsys,
                                                         monkeypatch):
    """A write that fails after the checks (a device, a full disk) names the file, exit 1."""
    import pvgraph.plotting as plotting
    target = str(tmp_path / "g.svg")

    def fail(*args, **kwargs):
        raise FileNotFoundError(2, "No such file or directory", target)
    monkeypatch.setattr(plotting, "draw_circuit", fail)
    assert main(["graph", f"{rig_file}:build", "--out", target]) == 1
    assert f"cannot write '{target}': No such file or directory" in capsys.readouterr().err


def test_a_module_target_is_found_in_the_working_directory(rig_file, tmp_path, monkeypatch,
                                                          capsys):
    """The installed pvgraph script has no working directory on its path; MODULE:FUNCTION
    still finds ./my_rig.py, as python -m pvgraph.cli does."""
    import os
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "path", [p for p in sys.path
                                      if p not in ("", ".", str(tmp_path), os.getcwd())])
    monkeypatch.delitem(sys.modules, "my_rig", raising=False)
    assert main(["simulate", "my_rig:build", "--t-end", "1", "--var", "node.port.p"]) == 0
    p, _ = _final_values(capsys.readouterr().out)["node.port.p"]
    assert p == pytest.approx(_p_steady() / 1e5, rel=2e-3)


def test_the_ida_solver_without_scikit_sundae_is_told_before_compiling(rig_file, monkeypatch,
                                                                        capsys):
    """--solver ida where scikit-sundae is not installed: one line naming the extra, exit 2,
    before the circuit is built (simulate() says the same)."""
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "sksundae" else real(name, *a))
    built = []
    monkeypatch.setattr("pvgraph.cli._target", lambda args: built.append(1))
    assert main(["simulate", f"{rig_file}:build", "--solver", "ida"]) == 2
    err = capsys.readouterr().err
    assert "--solver ida: solver='ida' needs SUNDIALS through scikit-sundae" in err
    assert 'pip install "pvgraph[sundials]"' in err and "Traceback" not in err
    assert not built


def test_the_command_line_runs_at_the_tolerance_simulate_and_sweep_default_to():
    """`pvgraph simulate` and `pvgraph sweep` without --rtol run at the rtol of simulate() and
    sweep_system() (a circuit whose answer moves with the tolerance gave the command line
    and Python different numbers at 1e-5 and 1e-6)."""
    import inspect

    from pvgraph.analysis.sweep import sweep_system
    from pvgraph.cli import build_parser
    from pvgraph.simulate import simulate
    default = inspect.signature(simulate).parameters["rtol"].default
    assert inspect.signature(sweep_system).parameters["rtol"].default == default
    parser = build_parser()
    assert parser.parse_args(["simulate", "demo"]).rtol == default
    assert parser.parse_args(["sweep", "demo", "--param", "a=1"]).rtol == default


def test_a_swept_parameter_asked_as_a_var_and_a_csv_of_another_format_exit_2(rig_file, tmp_path,
                                                                               capsys):
    # each case used to fail after running ("output 'pump.Q' has the name of a parameter"),
    # and --csv out.xlsx wrote comma-separated text into a workbook's name
    out = tmp_path / "study"
    assert main(["sweep", f"{rig_file}:build", "--param", "pump.Q=6 L/min,12 L/min",
                 "--var", "pump.Q", "--var", "node.port.p", "--steady", "--out",
                 str(out)]) == 2
    assert "--var pump.Q is also a swept --param" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(SystemExit) as stop:
        main(["simulate", f"{rig_file}:build", "--t-end", "1", "--csv",
              str(tmp_path / "out.xlsx")])
    assert stop.value.code == 2
    assert "name the file .csv" in capsys.readouterr().err
    assert not (tmp_path / "out.xlsx").exists()


def test_a_builder_argument_no_option_gives_is_named(tmp_path, capsys):
    # a raw TypeError traceback from the command line's call of build() before
    path = tmp_path / "needs_q.py"
    path.write_text(RIG_FILE.replace('def build(Q="10 L/min"):', "def build(Q):"))
    assert main(["simulate", f"{path}:build", "--t-end", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "the builder needs Q" in err and "--option Q=..." in err
    assert main(["simulate", f"{path}:build", "--t-end", "1", "--var", "node.port.p",
                 "--option", "Q=10 L/min"]) == 0


def test_an_application_option_on_a_users_circuit_exits_2(rig_file, capsys):
    # --law was accepted and ignored on a circuit of one's own (the same 67.76 bar either way)
    assert main(["simulate", f"{rig_file}:build", "--t-end", "0.1", "--law", "turbulent"]) == 2
    assert "--law applies to the registered circuits" in capsys.readouterr().err
    # typed with its default value it did nothing all the same
    assert main(["simulate", f"{rig_file}:build", "--t-end", "0.1", "--preset=tuned"]) == 2
    assert "--preset applies to the registered circuits" in capsys.readouterr().err
    assert main(["simulate", f"{rig_file}:build", "--t-end", "0.1"]) == 0


def test_components_shows_the_named_ones(capsys):
    assert main(["components", "Orifice", "gasaccumulator"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("### Orifice") and "### GasAccumulator" in out
    assert "### VolumeNode" not in out
    assert main(["components", "Orifce"]) == 2
    assert "did you mean 'Orifice'" in capsys.readouterr().err
