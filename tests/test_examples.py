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


SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith("_"))


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_example_runs(path, tmp_path):
    module = _load(path)
    assert hasattr(module, "main"), f"{path.name} has no main(outdir)"
    result = module.main(tmp_path)
    if path.stem in CHECKS:
        CHECKS[path.stem](result, tmp_path)
    if isinstance(result, dict):
        for key, value in result.items():
            if isinstance(value, float):
                assert math.isfinite(value), key


def test_every_example_has_physics_checks_or_is_new():
    known = {"linearize_pvg32"}        # written by someone else
    missing = {p.stem for p in SCRIPTS} - set(CHECKS) - known
    assert not missing, f"examples without checks in tests/test_examples.py: {missing}"
