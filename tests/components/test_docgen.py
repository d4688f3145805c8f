"""The generated component reference is up to date and lists what the classes declare."""

from pathlib import Path

from pvgraph.docgen import DEFAULT_OUTPUT, component_reference, library_modules

DOC = Path(__file__).resolve().parents[2] / "docs" / "components.md"


def test_docs_components_md_is_up_to_date():
    assert DEFAULT_OUTPUT == DOC
    generated = component_reference(library_modules())
    assert DOC.exists(), "docs/components.md is missing: run `python -m pvgraph.docgen`"
    assert DOC.read_text(encoding="utf-8") == generated, (
        "docs/components.md is out of date with the component classes: run "
        "`python -m pvgraph.docgen` and commit the result")


def test_reference_lists_components_ports_and_parameters():
    text = component_reference(library_modules())
    assert "### Orifice" in text
    assert "| `A` | Opening area [m^2] | required |" in text
    assert "### TwoStageSpring" in text and "| `k1` |" in text and "| 9945 |" in text
    assert "| `flange` | mechanical | `x` [m], `f` [N] |" in text
    assert "| `DT_A` | signal output | `DT_A` [1] |" in text
    assert "Discrete modes (switched by events): `after` (start 0)" in text


def test_reference_of_a_single_module():
    import pvgraph.components.signal.lvdt as lvdt
    text = component_reference([lvdt])
    assert "### LVDT" in text and "### Orifice" not in text
    assert "| `tau` | Time constant [s] (report eq. 4.113) | 0.0059 | > 0, <= 10 |" in text


def test_package_not_written_yet_is_skipped():
    modules = library_modules(["pvgraph.components.mechanical", "pvgraph.components.no_such_package"])
    assert [m.__name__ for m in modules] == ["pvgraph.components.mechanical"]
