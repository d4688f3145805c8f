"""User mistakes on the ``pvgraph`` command line: each is refused with exit 2 and a message
naming the option, before anything runs and without writing anything."""

import json

import pytest

from pvgraph.cli import main

RIG = '''
from pvgraph import Circuit
from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode


def build(Q="10 L/min"):
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q=Q))
    node = c.add("node", VolumeNode(V="0.5 L"))
    orifice = c.add("orifice", Orifice(A="2 mm^2"))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    return c
'''


@pytest.fixture
def rig(tmp_path):
    path = tmp_path / "my_rig.py"
    path.write_text(RIG)
    return f"{path}:build"


def _sweep(rig, out, *param_args):
    return main(["sweep", rig, *param_args, "--var", "node.port.p", "--t-end", "0.1",
                 "--backend", "serial", "--out", str(out)])


# --------------------------------------------------------------------------------------------
# sweep --param: a plain number beside a quantity is SI, not in the quantity's unit

@pytest.mark.parametrize("spec, bare, fixed, si", [
    ("orifice.A=1:2 mm^2:3", "'1'", "'orifice.A=1 mm^2:2 mm^2:3'", "'orifice.A=1e-06:2e-06:3'"),
    ("orifice.A=log:1:4 mm^2:3", "'1'", "'orifice.A=log:1 mm^2:4 mm^2:3'",
     "'orifice.A=log:1e-06:4e-06:3'"),
    ("orifice.A=0.5,1 mm^2", "'0.5'", "'orifice.A=0.5 mm^2,1 mm^2'", "'orifice.A=5e-07,1e-06'"),
    ("pump.Q=5:20 L/min:4", "'5'", "'pump.Q=5 L/min:20 L/min:4'", None),
])
def test_sweep_refuses_a_spec_mixing_plain_numbers_and_units(spec, bare, fixed, si, rig, tmp_path,
                                                             capsys):
    out = tmp_path / "s"
    assert _sweep(rig, out, "--param", spec) == 2
    err = capsys.readouterr().err
    name = spec.partition("=")[0]
    assert f"pvgraph sweep: error: --param {name}: {bare} has no unit" in err
    assert fixed in err
    if si:
        assert si in err
    assert not out.exists()


def test_random_sweep_mixing_units_or_an_empty_range_names_the_option(rig, tmp_path, capsys):
    out = tmp_path / "s"
    assert _sweep(rig, out, "--param", "orifice.A=1:2 mm^2", "--random", "3") == 2
    err = capsys.readouterr().err
    assert "--param orifice.A: '1' has no unit but '2 mm^2' has one" in err
    assert "'orifice.A=1 mm^2:2 mm^2'" in err
    assert _sweep(rig, out, "--param", "orifice.A=2 mm^2:1 mm^2", "--random", "3") == 2
    err = capsys.readouterr().err
    assert "--param orifice.A: a random range LO:HI needs LO < HI" in err
    assert "random_sample" not in err
    assert not out.exists()


def test_an_out_of_bound_value_is_hinted_in_the_spelling_of_param(rig, tmp_path, capsys):
    out = tmp_path / "s"
    # plain numbers: the unit they were likely meant in, written as a --param spec
    assert _sweep(rig, out, "--param", "pump.Q=5:20:4") == 2
    err = capsys.readouterr().err
    assert "give the unit with the numbers, e.g. --param 'pump.Q=5 L/min:20 L/min:4'" in err
    assert 'Q="10 L/min"' not in err and 'Q="15 L/min"' not in err
    # quantities: their SI value is not offered in another unit
    assert _sweep(rig, out, "--param", "pump.Q=2 m^3/s,3 m^3/s") == 2
    err = capsys.readouterr().err
    assert "less than or equal to 1 [m^3/s]" in err
    assert "L/min" not in err
    assert not out.exists()


# --------------------------------------------------------------------------------------------
# sweep --resume: only the run that made the record

@pytest.mark.parametrize("changed, recorded, now", [
    (["--t-end", "0.1"], "t_end 0.5", "t_end 0.1"),
    (["--t-end", "0.5", "--rtol", "1e-8"], "rtol 1e-06", "rtol 1e-08"),
    (["--t-end", "0.5", "--var", "orifice.q"], "outputs ['node.port.p']", "outputs ['orifice.q']"),
])
def test_resume_of_another_run_exits_2_and_keeps_the_record(changed, recorded, now, rig,
                                                            tmp_path, capsys):
    out = tmp_path / "s"
    first = ["sweep", rig, "--param", "orifice.A=1 mm^2,2 mm^2", "--backend", "serial",
             "--out", str(out)]
    assert main(first + ["--var", "node.port.p", "--t-end", "0.5"]) == 0
    log = out / "cases.jsonl"
    before = log.read_text()
    table = (out / "sweep.json").read_text()
    capsys.readouterr()
    var = [] if "--var" in changed else ["--var", "node.port.p"]
    assert main(first + var + changed + ["--resume"]) == 2
    err = capsys.readouterr().err
    assert f"pvgraph sweep: error: resume: {log} was recorded by another run (recorded: " \
           f"{recorded}; now: {now})" in err
    assert "--overwrite" in err and "overwrite=True" not in err
    assert log.read_text() == before and (out / "sweep.json").read_text() == table
    # the same command resumes (nothing left to run)
    assert main(first + ["--var", "node.port.p", "--t-end", "0.5", "--resume"]) == 0
    assert json.loads(log.read_text().splitlines()[0]) == json.loads(before.splitlines()[0])


# --------------------------------------------------------------------------------------------
# linearize: a repeated --input or --output

@pytest.mark.parametrize("args, message", [
    (["--input", "pump.Q", "--input", "pump.Q", "--output", "node.port.p"],
     "--input pump.Q is given twice"),
    (["--input", "pump.Q", "--output", "node.port.p", "--output", "node.port.p"],
     "--output node.port.p is given twice"),
])
def test_linearize_refuses_a_name_given_twice(args, message, rig, tmp_path, capsys):
    path = tmp_path / "lin.json"
    assert main(["linearize", rig, *args, "--json", str(path)]) == 2
    captured = capsys.readouterr()
    assert f"pvgraph linearize: error: {message}" in captured.err
    assert "DC gain" not in captured.out and not path.exists()


# --------------------------------------------------------------------------------------------
# graph: the format asked for is the format written, under the name printed

def test_graph_format_svg_writes_svg_under_the_name_printed(rig, tmp_path, capsys):
    out = tmp_path / "gg"
    assert main(["graph", rig, "--format", "svg", "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out}"
    assert out.read_text().lstrip().startswith("<?xml") and "<svg" in out.read_text()
    assert not (tmp_path / "gg.png").exists()


@pytest.mark.parametrize("args, message", [
    (["--format", "svg", "--out", "{dir}/g2.png"],
     "--format svg but --out '{dir}/g2.png' is named .png; name it '{dir}/g2.svg'"),
    (["--format", "png", "--out", "{dir}/g2.dot"], "--format png but --out '{dir}/g2.dot'"),
    (["--out", "{dir}/g5"], "--out '{dir}/g5': the format comes from the extension"),
])
def test_graph_refuses_a_name_that_disagrees_with_the_format(args, message, rig, tmp_path,
                                                              capsys):
    args = [a.format(dir=tmp_path) for a in args]
    assert main(["graph", rig, *args]) == 2
    assert f"pvgraph graph: error: {message.format(dir=tmp_path)}" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == [tmp_path / "my_rig.py"]


def test_draw_circuit_writes_the_format_asked_for(tmp_path):
    import importlib.util
    spec = importlib.util.spec_from_file_location("rig_for_drawing", tmp_path / "r.py")
    (tmp_path / "r.py").write_text(RIG)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    from pvgraph.plotting import draw_circuit
    path = tmp_path / "noext"
    assert draw_circuit(module.build(), path, fmt="svg") == str(path)
    assert "<svg" in path.read_text()
    plain = tmp_path / "plain"
    assert draw_circuit(module.build(), plain) == str(plain)      # PNG under the very name
    assert plain.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match=r"fmt='svg' but the file .* is named \.png"):
        draw_circuit(module.build(), tmp_path / "g4.png", fmt="svg")
    assert not (tmp_path / "g4.png").exists()


# --------------------------------------------------------------------------------------------
# export: an FMU names each variable once

@pytest.mark.parametrize("args, message", [
    (["--var", "node.port.p", "--var", "node.port.p"], "--var node.port.p is given twice"),
    (["--var", "node.port.p", "--input", "pump.Q", "--input", "pump.Q"],
     "--input pump.Q is given twice"),
    (["--var", "node.port.p", "--input", "pump.Q", "--parameter", "pump.Q"],
     "pump.Q is given as --input and as --parameter"),
])
def test_export_fmu_refuses_a_name_given_twice(args, message, rig, tmp_path, capsys):
    path = tmp_path / "d.fmu"
    assert main(["export", rig, "--out", str(path), *args]) == 2
    assert f"pvgraph export: error: {message}" in capsys.readouterr().err
    assert not path.exists()


def test_export_fmu_in_python_refuses_an_output_given_twice(tmp_path):
    pytest.importorskip("pythonfmu")
    from pvgraph.fmi import FmiError, export_fmu
    (tmp_path / "r.py").write_text(RIG)
    import importlib.util
    spec = importlib.util.spec_from_file_location("rig_for_fmu", tmp_path / "r.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = tmp_path / "d.fmu"
    with pytest.raises(FmiError, match="'node.port.p' is given twice among the outputs"):
        export_fmu(module.build(), path, outputs=["node.port.p", "node.port.p"])
    assert not path.exists()


def test_export_to_a_model_file_refuses_the_fmu_options(rig, tmp_path, capsys):
    path = tmp_path / "m.toml"
    assert main(["export", rig, "--out", str(path), "--var", "node.port.p"]) == 2
    assert "--var applies to an FMU (--out NAME.fmu)" in capsys.readouterr().err
    assert not path.exists()


# --------------------------------------------------------------------------------------------
# validate: --json and --out must not clash

@pytest.mark.parametrize("out, json_name, message", [
    ("vv", "vv", "--json '{dir}/vv' is the --out folder; give a file name, e.g. "
                 "'{dir}/vv/validation.json'"),
    ("vv3/sub", "vv3", "--json '{dir}/vv3' is a folder above --out '{dir}/vv3/sub'"),
    ("vv", "vv/validation_targets.json", "--json '{dir}/vv/validation_targets.json' is the "
                                         "file validation_targets.json the command writes "
                                         "into --out"),
])
def test_validate_json_clashing_with_out_exits_2_before_any_run(out, json_name, message,
                                                                tmp_path, capsys):
    code = main(["validate", "--scenario", "test-1", "--no-plots", "--out",
                 str(tmp_path / out), "--json", str(tmp_path / json_name)])
    assert code == 2
    captured = capsys.readouterr()
    assert f"pvgraph validate: error: {message.format(dir=tmp_path)}" in captured.err
    assert "PVG 32 on the lab rig" not in captured.out
    assert list(tmp_path.iterdir()) == []


def test_json_naming_an_existing_folder_is_hinted_a_json_name(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["validate", "--json", str(tmp_path)])
    assert exc.value.code == 2
    assert f"argument --json: '{tmp_path}' is a directory; give a file name, e.g. " \
           f"'{tmp_path / 'result.json'}'" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# sweep: a backend that cannot start leaves no record

def test_sweep_whose_backend_is_missing_leaves_no_record(rig, tmp_path, monkeypatch, capsys):
    import sys
    out = tmp_path / "m_study"
    args = ["sweep", rig, "--param", "orifice.A=1 mm^2,2 mm^2", "--var", "node.port.p",
            "--t-end", "0.1", "--out", str(out)]
    monkeypatch.setitem(sys.modules, "distributed", None)     # dask not installed
    assert main(args + ["--backend", "dask"]) == 2
    assert 'backend "dask" needs dask.distributed' in capsys.readouterr().err
    assert not (out / "cases.jsonl").exists()
    monkeypatch.delitem(sys.modules, "distributed")
    assert main(args + ["--backend", "serial"]) == 0       # the corrected command just runs
    assert len((out / "cases.jsonl").read_text().splitlines()) == 3


def test_sweep_whose_scheduler_is_out_of_reach_leaves_no_record(rig, tmp_path, capsys):
    dask = pytest.importorskip("dask")
    pytest.importorskip("distributed")
    out = tmp_path / "sch"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        code = main(["sweep", rig, "--param", "orifice.A=1 mm^2,2 mm^2", "--var",
                     "node.port.p", "--t-end", "0.1", "--scheduler", "tcp://127.0.0.1:1",
                     "--out", str(out)])
    assert code == 2
    assert "cannot connect to the Dask scheduler at 'tcp://127.0.0.1:1'" in \
        capsys.readouterr().err
    assert not (out / "cases.jsonl").exists()


def test_sweep_refusing_an_earlier_record_gives_the_option_spelling(rig, tmp_path, capsys):
    out = tmp_path / "s"
    args = ["sweep", rig, "--param", "orifice.A=1 mm^2", "--var", "node.port.p", "--t-end",
            "0.1", "--backend", "serial", "--out", str(out)]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "holds the record of an earlier sweep (1 case, 1 finished): resume it (--resume), " \
           "replace it (--overwrite) or give another folder" in err
    assert "resume=True" not in err and "overwrite=True" not in err


# --------------------------------------------------------------------------------------------
# scenario sweeps and simulate: times of the PVG 32 scenarios

@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "abc"])
def test_scenario_sweep_checks_after_before_running(value, tmp_path, capsys):
    out = tmp_path / "p9"
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--scenario", "test-2", "--param", "U_input=4.2", "--after", value,
              "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "pvgraph sweep: error: argument --after:" in err and value in err
    assert not out.exists()


@pytest.mark.parametrize("option, value", [("--settle", "nan"), ("--settle", "-1"),
                                           ("--t-end", "nan")])
def test_scenario_sweep_checks_settle_before_running(option, value, tmp_path, capsys):
    out = tmp_path / "p9"
    assert main(["sweep", "--scenario", "test-2", "--param", "U_input=4.2", option, value,
                 "--out", str(out)]) == 2
    assert f"pvgraph sweep: error: {option} must be a finite time > 0 s" in \
        capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("value", ["-1", "nan"])
def test_simulate_names_t_switch(value, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "test-2", "--t-switch", value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"pvgraph simulate: error: argument --t-switch: must be a finite time > 0 s, got " \
           f"{value}" in err
    assert "TimedOnOffValve" not in err


# --------------------------------------------------------------------------------------------
# PVGRAPH_BACKEND

def test_a_misspelt_pvgraph_backend_exits_2_naming_the_variable(rig, monkeypatch, capsys):
    monkeypatch.setenv("PVGRAPH_BACKEND", "cc")
    assert main(["simulate", rig, "--t-end", "0.1"]) == 2
    captured = capsys.readouterr()
    assert "pvgraph simulate: error: PVGRAPH_BACKEND='cc': choose python, c or auto" in \
        captured.err
    assert "Traceback" not in captured.err and "final" not in captured.out


def test_pvgraph_backend_in_capitals_is_read_as_written_in_lower_case(rig, monkeypatch,
                                                                     capsys):
    monkeypatch.setenv("PVGRAPH_BACKEND", " Python ")
    assert main(["simulate", rig, "--t-end", "0.1", "--var", "node.port.p"]) == 0
    assert "node.port.p  final" in capsys.readouterr().out
    import os
    assert os.environ["PVGRAPH_BACKEND"] == " Python "     # the caller's value, as it was


# --------------------------------------------------------------------------------------------
# model files with a user's own component type

LEAK_MODULE = '''
from pydantic import Field

from pvgraph import Circuit, Component, Hydraulic, Params
from pvgraph.components import FlowSource, Tank, VolumeNode


class LeakParams(Params):
    K: float = Field(..., gt=0, description="Leakage coefficient [m^3/(s Pa)]")


class Leak(Component):
    """Laminar leakage q = K (a.p - b.p)."""
    Params = LeakParams
    ports = {"a": Hydraulic("high side"), "b": Hydraulic("low side")}

    def equations(self, v, p):
        q = v.observe("q", p.K * (v.a.p - v.b.p), "m^3/s")
        return [v.a.q - q, v.a.q + v.b.q]


def build():
    c = Circuit("leaky")
    pump = c.add("pump", FlowSource(Q="1 L/min"))
    node = c.add("node", VolumeNode(V="0.5 L"))
    leak = c.add("leak", Leak(K=1e-11))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, leak.a)
    c.connect(leak.b, tank.port)
    return c
'''


def test_a_model_file_of_a_users_component_loads_with_module(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / "leakmod.py").write_text(LEAK_MODULE)
    assert main(["export", "leakmod:build", "--out", "cust.toml"]) == 0
    captured = capsys.readouterr()
    assert 'type = "leakmod:Leak"' in (tmp_path / "cust.toml").read_text()
    assert "pvgraph export: note: cust.toml names component types of leakmod" in captured.err
    assert "loading it needs --module leakmod" in captured.err
    # without the module: the error names the command-line way
    assert main(["simulate", "cust.toml", "--t-end", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "component type 'leakmod:Leak' is not in the library or in the allowed modules; " \
           "allow its module: --module leakmod on the command line" in err
    # with it: the steady state of the leak, p = Q / K
    assert main(["simulate", "cust.toml", "--module", "leakmod", "--t-end", "2", "--si",
                 "--var", "node.port.p"]) == 0
    p = float(capsys.readouterr().out.split("final")[1].split()[0])
    assert p == pytest.approx(1 / 60e3 / 1e-11, rel=1e-3)
    assert main(["simulate", "cust.toml", "--module", "no_such_module"]) == 2
    assert "--module no_such_module: cannot import it" in capsys.readouterr().err


def test_module_on_a_python_target_is_refused(rig, capsys):
    assert main(["simulate", rig, "--module", "json"]) == 2
    assert "--module applies to a model file target" in capsys.readouterr().err


def test_a_circuit_of_the_checkout_components_package_round_trips(tmp_path):
    """In a source checkout ``components`` is importable as itself and as
    ``pvgraph.components`` (the same files): a circuit of ``components.*`` classes is written
    with the library's names and loads back."""
    pytest.importorskip("components.hydraulic.sources")
    from components.hydraulic import Orifice, Tank, VolumeNode
    from components.hydraulic.sources import FlowSource

    import pvgraph.components as library
    from pvgraph import Circuit
    from pvgraph.modelfile import dumps, loads
    assert FlowSource is not library.FlowSource        # two imports of one file
    c = Circuit("demo")
    pump = c.add("pump", FlowSource(Q="10 L/min"))
    node = c.add("node", VolumeNode(V="0.5 L"))
    orifice = c.add("orifice", Orifice(A="2 mm^2"))
    tank = c.add("tank", Tank())
    c.connect(pump.port, node.port, orifice.a)
    c.connect(orifice.b, tank.port)
    text = dumps(c)
    assert 'type = "FlowSource"' in text and "components.hydraulic" not in text
    again = loads(text)
    assert type(again["pump"]) is library.FlowSource
    assert again.parameters()["pump.Q"][0] == pytest.approx(10 / 60e3)
    # a file written before with the checkout's module name loads too
    old = text.replace('type = "FlowSource"', 'type = "components.hydraulic.sources:FlowSource"')
    assert type(loads(old)["pump"]) is library.FlowSource


# --------------------------------------------------------------------------------------------
# module entry points: python -m pvgraph, pvgraph.docgen, pvgraph.circuits.figures

def test_python_m_pvgraph_is_the_pvgraph_command(rig, tmp_path):
    import os
    import subprocess
    import sys
    env = {**os.environ, "PYTHONPATH": os.getcwd()}
    ok = subprocess.run([sys.executable, "-m", "pvgraph", "simulate", rig, "--t-end", "0.1",
                         "--var", "node.port.p"], capture_output=True, text=True, env=env,
                        timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "node.port.p  final" in ok.stdout
    bad = subprocess.run([sys.executable, "-m", "pvgraph", "simulate", rig, "--var", "nope"],
                         capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2
    assert "pvgraph simulate: error: --var 'nope' is not a variable" in bad.stderr


def test_docgen_parses_its_arguments(tmp_path, monkeypatch, capsys):
    from pvgraph import docgen
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        docgen.main(["--help"])
    assert exc.value.code == 0
    assert "usage: python -m pvgraph.docgen [-h] [output]" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        docgen.main(["--bogus"])
    assert exc.value.code == 2
    assert list(tmp_path.iterdir()) == []                  # no file named after an option
    assert docgen.main([str(tmp_path / "ref.md")]) == 0
    assert (tmp_path / "ref.md").read_text().startswith(docgen.TITLE)


def test_docgen_outside_a_source_checkout_needs_a_file(tmp_path, monkeypatch, capsys):
    from pvgraph import docgen
    installed = tmp_path / "site-packages" / "docs" / "components.md"
    monkeypatch.setattr(docgen, "DEFAULT_OUTPUT", installed)
    monkeypatch.setattr(docgen, "_in_checkout", lambda output=installed: False)
    with pytest.raises(SystemExit) as exc:
        docgen.main([])
    assert exc.value.code == 2
    assert "pvgraph is installed, not a source checkout" in capsys.readouterr().err
    assert not (tmp_path / "site-packages").exists()


def test_in_checkout_tells_a_checkout_from_an_installed_package(tmp_path):
    from pvgraph.docgen import _in_checkout
    (tmp_path / "site-packages" / "pvgraph").mkdir(parents=True)
    assert not _in_checkout(tmp_path / "site-packages" / "docs" / "components.md")
    (tmp_path / "repo" / "docs").mkdir(parents=True)
    (tmp_path / "repo" / "pyproject.toml").write_text("[project]\n")
    assert _in_checkout(tmp_path / "repo" / "docs" / "components.md")


def test_figures_module_parses_its_arguments(tmp_path, monkeypatch, capsys):
    figures = pytest.importorskip("pvgraph.circuits.figures")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        figures.main(["--help"])
    assert exc.value.code == 0
    assert "usage: python -m pvgraph.circuits.figures" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        figures.main(["--bogus"])
    assert exc.value.code == 2
    assert list(tmp_path.iterdir()) == []


def test_linearize_json_and_bode_naming_one_file_exit_2(rig, tmp_path, capsys):
    path = tmp_path / "lin.png"
    assert main(["linearize", rig, "--input", "pump.Q", "--output", "node.port.p", "--json",
                 str(path), "--bode", str(path)]) == 2
    captured = capsys.readouterr()
    assert f"--json and --bode name the same file '{path}'" in captured.err
    assert f"'{tmp_path / 'lin.json'}'" in captured.err
    assert "DC gain" not in captured.out and not path.exists()


# --------------------------------------------------------------------------------------------
# validate: options that only apply together, names given twice

@pytest.mark.parametrize("args, message", [
    (["--fit", "rig.supply_voltage"], "--fit only applies with --calibrate"),
    (["--calibrate", "--fit", "rig.nonexistent"], "--fit rig.nonexistent: 'rig.nonexistent' "
                                                  "cannot be calibrated"),
    (["--calibrate", "--fit", "rig.pump_flow", "--fit", "rig.pump_flow"],
     "--fit rig.pump_flow is given twice"),
    (["--calibrate", "--law", "turbulent"], "--calibrate fits the laminar load constants"),
    (["--scenario", "test-2", "--scenario", "test-2"], "--scenario test-2 is given twice"),
    (["--fold", "U = 4.6 V", "--meter-out", "ratio"],
     "--fold and --meter-out only apply with --cross-validate"),
])
def test_validate_option_mistakes_exit_2_before_the_out_folder_is_made(args, message, tmp_path,
                                                                       capsys):
    out = tmp_path / "v5"
    assert main(["validate", "--no-plots", "--out", str(out), *args]) == 2
    captured = capsys.readouterr()
    assert f"pvgraph validate: error: {message}" in captured.err
    assert "PVG 32 on the lab rig" not in captured.out and not out.exists()


def test_export_fmu_without_var_names_the_option(rig, tmp_path, capsys):
    path = tmp_path / "m.fmu"
    assert main(["export", rig, "--out", str(path)]) == 2
    err = capsys.readouterr().err
    assert "pvgraph export: error: an FMU needs at least one output: give --var NAME" in err
    assert "export_fmu needs" not in err and not path.exists()


def test_pvgraphs_own_user_warnings_print_as_one_plain_line(rig, monkeypatch, capsys):
    """A warning pvgraph issues (here: an input without first-order effect) is one line
    naming the command, not Python's format with a source line of pvgraph."""
    import sys
    monkeypatch.setattr(sys, "argv", ["pvgraph", "linearize", rig, "--input", "node.V",
                                      "--output", "node.port.p"])
    main()
    err = capsys.readouterr().err
    assert "pvgraph linearize: warning: linearize_circuit: input(s) ['node.V']" in err
    assert "UserWarning" not in err and "cli.py" not in err


def test_t_end_takes_a_time_with_its_unit(rig, capsys):
    assert main(["simulate", rig, "--t-end", "100 ms", "--var", "node.port.p", "--si"]) == 0
    with_unit = capsys.readouterr().out
    assert main(["simulate", rig, "--t-end", "0.1", "--var", "node.port.p", "--si"]) == 0
    assert capsys.readouterr().out == with_unit
    with pytest.raises(SystemExit) as exc:
        main(["simulate", rig, "--t-end", "1 bar"])
    assert exc.value.code == 2
    assert "argument --t-end: '1 bar' is not a time" in capsys.readouterr().err


def test_without_matplotlib_figures_are_refused_up_front_and_dot_still_works(rig, tmp_path):
    import os
    import subprocess
    import sys
    code = (
        "import sys; sys.modules['matplotlib'] = None\n"
        "from pvgraph.cli import main\n"
        f"rig, d = {rig!r}, {str(tmp_path)!r}\n"
        "assert main(['graph', rig, '--out', d + '/c.dot']) == 0\n"
        "assert main(['graph', rig, '--out', d + '/c.png']) == 2\n"
        "assert main(['simulate', rig, '--plot', d + '/p.png']) == 2\n"
        "assert main(['linearize', rig, '--input', 'pump.Q', '--output', 'node.port.p',\n"
        "             '--bode', d + '/b.png']) == 2\n"
        "print('checked')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": os.getcwd()}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "checked" in proc.stdout and "Traceback" not in proc.stderr
    assert "pvgraph graph: error: --out " in proc.stderr
    assert "pvgraph simulate: error: --plot draws with matplotlib, which is not installed" in \
        proc.stderr
    assert "pvgraph linearize: error: --bode draws with matplotlib" in proc.stderr
    assert "final" not in proc.stdout                  # refused before simulating
    assert (tmp_path / "c.dot").read_text().startswith("graph")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.dot", "my_rig.py"]


def test_resume_with_other_builder_options_exits_2(rig, tmp_path, capsys):
    out = tmp_path / "s"
    args = ["sweep", rig, "--param", "orifice.A=1 mm^2,2 mm^2", "--var", "node.port.p",
            "--t-end", "0.2", "--backend", "serial", "--out", str(out)]
    assert main(args + ["--option", 'Q="10 L/min"']) == 0
    before = (out / "cases.jsonl").read_text()
    capsys.readouterr()
    assert main(args + ["--option", 'Q="20 L/min"', "--resume"]) == 2
    err = capsys.readouterr().err
    assert "was recorded by another run (recorded: " in err and "10 L/min" in err \
        and "20 L/min" in err
    assert (out / "cases.jsonl").read_text() == before
    assert main(args + ["--option", 'Q="10 L/min"', "--resume"]) == 0


# --------------------------------------------------------------------------------------------
# legitimate uses the up-front checks must let through

def test_a_zero_bound_beside_a_quantity_is_zero_in_any_unit(rig, tmp_path, capsys):
    # "0:10 L/min:3" was refused as mixing units; 0 is 0 in L/min as in m^3/s
    out = tmp_path / "z"
    assert _sweep(rig, out, "--param", "pump.Q=0:10 L/min:3") == 0
    rows = json.loads((out / "sweep.json").read_text())
    cases = rows["cases"] if "cases" in rows else rows["records"]
    values = [c["params"]["pump.Q"] if "params" in c else c["pump.Q"] for c in cases]
    assert values == pytest.approx([0.0, 5 / 60000, 10 / 60000], rel=1e-12)


def test_resume_takes_the_same_file_however_it_is_spelled(rig, tmp_path, monkeypatch):
    # ./my_rig.py:build and its absolute path were "another run"
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "study"
    assert _sweep(rig, out, "--param", "orifice.A=1e-6:2e-6:2") == 0
    assert _sweep("./my_rig.py:build", out, "--param", "orifice.A=1e-6:2e-6:2",
                  "--resume") == 0


@pytest.mark.parametrize("args, written", [
    (["--out", "c.gv", "--format", "dot"], "c.gv"), (["--out", "c.gv"], "c.gv"),
    (["--format", "svg"], "circuit.svg"), (["--format", "dot"], "circuit.dot")])
def test_graph_writes_dot_as_gv_and_names_the_default_by_the_format(args, written, rig,
                                                                   tmp_path, monkeypatch,
                                                                   capsys):
    # --format dot --out c.gv was refused; --format svg alone was refused over the default
    # name circuit.png it never typed
    monkeypatch.chdir(tmp_path)
    assert main(["graph", rig, *args]) == 0
    text = (tmp_path / written).read_text()
    assert text.lstrip().startswith("<?xml" if written.endswith("svg") else "graph")


def test_a_listing_command_runs_whatever_pvgraph_backend_says(monkeypatch, capsys):
    monkeypatch.setenv("PVGRAPH_BACKEND", "numba")
    assert main(["components", "Orifice"]) == 0
    assert main(["simulate", "nothing.py:build"]) == 2


def test_validate_refuses_only_the_files_this_run_writes(tmp_path):
    import argparse
    from pvgraph.circuits.cli import _check_json_beside_out
    from pvgraph.errors import PvgraphError
    out = tmp_path / "rep"

    def args(json_name, **options):
        given = {"no_plots": False, "calibrate": False, "cross_validate": False, **options}
        return argparse.Namespace(json=str(out / json_name), out=str(out), **given)
    _check_json_beside_out(args("calibration.json"))         # not written without --calibrate
    with pytest.raises(PvgraphError, match="calibration.json the command writes"):
        _check_json_beside_out(args("calibration.json", calibrate=True))
    with pytest.raises(PvgraphError, match="cross_validation.png the command writes"):
        _check_json_beside_out(args("cross_validation.png", cross_validate=True))


def test_a_plain_number_beside_the_parameters_own_si_unit_is_not_mixing(rig, tmp_path):
    # "1e-6:2e-6 m^2:2" reads the same either way; it was refused as mixing units
    out = tmp_path / "si"
    assert _sweep(rig, out, "--param", "orifice.A=1e-6:2e-6 m^2:2") == 0


def test_the_difference_of_two_runs_is_told_by_whole_items():
    # a changed output inside a list was cut mid-list: "(recorded: 'orifice.q']; ..."
    from pvgraph.analysis.sweep import _identity_difference
    run = ("pvgraph.cli._noted_case with (CompiledRun of pvgraph.cli._target_circuit with "
           "('/x/my_rig.py:build', {}, ()), outputs ['node.port.p', 'orifice.q'], t_end 1.0, "
           "rtol 1e-06)")
    assert _identity_difference(run, run.replace("'orifice.q'", "'orifice.a.q'")) == (
        "recorded: outputs ['node.port.p', 'orifice.q']; "
        "now: outputs ['node.port.p', 'orifice.a.q']")
    assert _identity_difference(run, run.replace("t_end 1.0", "t_end 0.1").replace(
        "1e-06", "1e-08")) == "recorded: t_end 1.0, rtol 1e-06; now: t_end 0.1, rtol 1e-08"
