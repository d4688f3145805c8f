"""The installed layout: every package folder of the checkout installs under pvgraph."""

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _config():
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_folder_is_installed_under_the_pvgraph_namespace():
    config = _config()
    found = set()
    for prefix, folder in config["package-dir"].items():
        for init in (ROOT / folder).rglob("__init__.py"):
            found.add(".".join((prefix, *init.parent.relative_to(ROOT / folder).parts)))
    assert not (ROOT / "pvgraph" / "components").exists()
    assert not (ROOT / "pvgraph" / "circuits").exists()
    assert found == set(config["packages"]), (
        f"pyproject.toml [tool.setuptools] packages misses {sorted(found - set(config['packages']))}"
        f" and lists {sorted(set(config['packages']) - found)} that do not exist")


def test_the_checkout_imports_the_library_under_the_installed_names():
    import pvgraph.circuits.lab_data as lab
    import pvgraph.components.hydraulic as hyd

    assert Path(hyd.__file__).resolve().parent == ROOT / "components" / "hydraulic"
    assert len(lab.load_voltage_sweep()) == 7
