"""Applications register circuits, commands and plots from above; the framework imports none."""

import os
import subprocess
import sys
import textwrap

import pytest

from pvgraph.registry import ENV_VAR, Registry, RegistryError


def _build():
    from pvgraph.components import Tank
    from pvgraph import Circuit
    c = Circuit("t")
    c.add("tank", Tank())
    return c


def test_registering_and_clashes():
    reg = Registry()
    reg.circuit("bench", _build, description="a tank", variables=["tank.port.p"], t_end=2.0)
    assert reg.circuits["bench"].t_end == 2.0 and reg.circuits["bench"].build().name == "t"
    with pytest.raises(RegistryError, match="a circuit named 'bench' is already registered"):
        reg.circuit("bench", _build)
    with pytest.raises(RegistryError, match="must be callable"):
        reg.circuit("other", 3)
    with pytest.raises(RegistryError, match="without surrounding spaces"):
        reg.circuit("bench\n", _build)
    reg.extension("sweep", lambda p: None, run=lambda args: 0)
    with pytest.raises(RegistryError, match="already has a handler"):
        reg.extension("sweep", lambda p: None, run=lambda args: 0)


PLUGIN = '''
def register(registry):
    from pvgraph import Circuit
    from pvgraph.components import FlowSource, Orifice, Tank

    def press(Q=1e-4):
        c = Circuit("press")
        pump = c.add("pump", FlowSource(Q=Q))
        orf = c.add("orf", Orifice(A=1e-6))
        tank = c.add("tank", Tank())
        c.connect(pump.port, orf.a)
        c.connect(orf.b, tank.port)
        return c
    registry.circuit("press", press, description="the test press", variables=["pump.port.p"],
                     t_end=0.1, options=("Q",), group="my machines")

    def configure(parser):
        parser.add_argument("--tons", type=float, default=40.0)

    def run(args):
        print(f"press rated {args.tons:g} t")
        return 0
    registry.command("rating", configure, run, help="print the rating")
'''


@pytest.fixture
def fresh_registry():
    from pvgraph.registry import registry
    registry.reset()
    yield registry
    registry.reset()          # the next lookup loads the test session's plugins again


def test_a_plugin_named_in_the_environment_reaches_the_command_line(tmp_path, monkeypatch,
                                                                    capsys, fresh_registry):
    from pvgraph.cli import main
    (tmp_path / "my_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv(ENV_VAR, "my_plugin")
    assert main(["circuits"]) == 0
    out = capsys.readouterr().out
    assert "my machines:" in out and "press        the test press" in out
    assert main(["simulate", "press", "--option", "Q=2e-4"]) == 0
    # orifice law with the option's flow: p = rho/2 (Q / (Cd A))^2 = 48.3 bar
    p = float(capsys.readouterr().out.split()[2])
    assert p == pytest.approx(870 / 2 * (2e-4 / 0.6e-6) ** 2 / 1e5, rel=2e-3)
    assert main(["rating", "--tons", "63"]) == 0
    assert "press rated 63 t" in capsys.readouterr().out
    assert "validate" not in fresh_registry.commands      # only what the plugin registered


def test_a_plugin_that_cannot_be_loaded_is_named(tmp_path):
    env = {**os.environ, ENV_VAR: "no_such_plugin_xyz:register"}
    proc = subprocess.run([sys.executable, "-m", "pvgraph.cli", "circuits"], env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "PVGRAPH_PLUGINS names 'no_such_plugin_xyz:register', which cannot be loaded" \
        in proc.stderr


def test_the_framework_imports_no_application():
    code = textwrap.dedent("""
        import sys
        import pvgraph, pvgraph.cli, pvgraph.plotting, pvgraph.analysis, pvgraph.modelfile
        import pvgraph.registry, pvgraph.fmi, pvgraph.units
        pvgraph.cli.build_parser()
        print(sorted(m for m in sys.modules if m.split('.')[0] in ('circuits', 'components')))
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, ENV_VAR: ""}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


def test_an_installed_entry_point_registers(tmp_path, monkeypatch, fresh_registry):
    """What ``pip install`` of a package declaring the pvgraph.circuits entry point leaves."""
    (tmp_path / "my_plugin.py").write_text(PLUGIN)
    info = tmp_path / "my_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[pvgraph.circuits]\nmine = my_plugin:register\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv(ENV_VAR, "")
    fresh_registry.load()
    assert "press" in fresh_registry.circuits and "rating" in fresh_registry.commands
