"""Parameter sweeps: physics through every backend, failures kept, atomic files, case generators.

The physics bench is a supply, two turbulent orifices in series with a volume between them, and
a tank. With a transition pressure of 1 Pa the orifice law is Q = Cd A sqrt(2 dp / rho) to
within 1e-10 at bar-level drops, so the steady flow and middle pressure are known exactly:

    Q = Cd sqrt(2 p_s / rho) / sqrt(1/A^2 + 1/A_out^2),   p_mid = p_s A^2 / (A^2 + A_out^2)
"""

import csv
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from pvgraph.components.hydraulic import Orifice, PressureSource, Tank, VolumeNode
from pvgraph.analysis import steady_state
from pvgraph.analysis.sweep import (CaseResult, SweepError, SweepResult, grid, random_sample,
                                    sweep)
from pvgraph.circuit import Circuit
from pvgraph.units import bar, cm3, mm2

RHO, CD, DP_T = 870.0, 0.6, 1.0
A_OUT = mm2(4.0)
AREAS = [mm2(1.0), mm2(2.0), mm2(3.0)]
SUPPLIES = [bar(10.0), bar(40.0)]


def series_orifices(A, p_supply):
    """Steady flow and middle pressure of supply -> A -> volume -> A_out -> tank."""
    c = Circuit("series")
    c.add("src", PressureSource(p0=p_supply))
    c.add("r1", Orifice(A=A, Cd=CD, rho=RHO, dp_t=DP_T))
    c.add("mid", VolumeNode(V=cm3(10.0), p0=0.5 * p_supply))
    c.add("r2", Orifice(A=A_OUT, Cd=CD, rho=RHO, dp_t=DP_T))
    c.add("tank", Tank())
    c.connect("src.port", "r1.a")
    c.connect("r1.b", "mid.port", "r2.a")
    c.connect("r2.b", "tank.port")
    op = steady_state(c.compile())
    return {"q": op["r1.a.q"], "q_out": op["r2.a.q"], "p_mid": op["mid.port.p"]}


def expected(A, p_supply):
    q = CD * math.sqrt(2.0 * p_supply / RHO) / math.sqrt(A ** -2 + A_OUT ** -2)
    return q, p_supply * A ** 2 / (A ** 2 + A_OUT ** 2)


def fragile_square(x):
    if x == 3:
        raise ValueError("x = 3 is not allowed")
    if x == 4:
        return [x * x]  # not a dict: the case fails with a clear message
    return {"y": float(x * x), "half": x / 2}


def dies_at_one(x):
    if x == 1:
        os._exit(3)
    return {"y": 10.0 * x}


class Unprintable:
    def __str__(self):
        raise RuntimeError("cannot format this value")


def warns_above_two(x):
    """Squares x and warns (a plausibility warning, as steady_state's) where x > 2."""
    import warnings

    from pvgraph.errors import PlausibilityWarning
    if x > 2:
        warnings.warn(PlausibilityWarning(f"x = {x} is implausibly large"))
    return {"y": float(x * x)}


def orifice_cases():
    return grid({"A": AREAS, "p_supply": SUPPLIES})


# --------------------------------------------------------------------------------------------
def test_grid_sweep_of_series_orifices_matches_the_orifice_law():
    result = sweep(series_orifices, orifice_cases(), backend="serial")
    assert len(result) == 6 and not result.failed
    for r in result:
        q, p_mid = expected(**r.params)
        assert r.outputs["q"] == pytest.approx(q, rel=1e-6)
        assert r.outputs["q_out"] == pytest.approx(q, rel=1e-6)  # conservation in the volume
        assert r.outputs["p_mid"] == pytest.approx(p_mid, rel=1e-6)
        dp1 = r.params["p_supply"] - r.outputs["p_mid"]
        assert r.outputs["q"] == pytest.approx(CD * r.params["A"] * math.sqrt(2 * dp1 / RHO),
                                               rel=1e-6)
    q = result.column("q").reshape(len(AREAS), len(SUPPLIES))
    assert np.all(np.diff(q, axis=0) > 0) and np.all(np.diff(q, axis=1) > 0)
    np.testing.assert_allclose(q[:, 1] / q[:, 0], 2.0, rtol=1e-6)  # Q ~ sqrt(p_s): 40/10 bar


def test_process_pool_and_serial_give_identical_results():
    serial = sweep(series_orifices, orifice_cases(), backend="serial")
    pooled = sweep(series_orifices, orifice_cases(), backend="process", workers=2)
    assert pooled.backend == "process" and [r.index for r in pooled] == list(range(6))
    for name in ("A", "p_supply", "q", "p_mid"):
        np.testing.assert_allclose(pooled.column(name), serial.column(name), rtol=1e-12)


def test_dask_local_cluster_gives_identical_results():
    distributed = pytest.importorskip("distributed")
    serial = sweep(series_orifices, orifice_cases(), backend="serial")
    with distributed.LocalCluster(n_workers=2, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        by_client = sweep(series_orifices, orifice_cases(), backend="dask", client=client)
        by_address = sweep(fragile_square, [{"x": x} for x in range(5)], backend="dask",
                           client=cluster.scheduler_address)
    for name in ("q", "p_mid"):
        np.testing.assert_allclose(by_client.column(name), serial.column(name), rtol=1e-12)
    np.testing.assert_array_equal(by_address.column("y"), [0.0, 1.0, 4.0, np.nan, np.nan])
    assert [r.error_type for r in by_address.failed] == ["ValueError", "SweepError"]


@pytest.mark.parametrize("backend", ["serial", "process"])
def test_failed_cases_are_recorded_and_the_others_kept(backend, tmp_path):
    cases = [{"A": A, "p_supply": bar(20.0)} for A in (mm2(1.0), -mm2(1.0), mm2(2.0))]
    result = sweep(series_orifices, cases, backend=backend, workers=2, out=tmp_path)
    assert [r.status for r in result] == ["ok", "failed", "ok"]
    bad = result[1]
    assert bad.error_type == "ParameterError" and "A" in bad.error_message
    assert "Traceback" in bad.traceback and "Orifice" in bad.traceback
    q = result.column("q")
    assert math.isnan(q[1])
    assert q[0] == pytest.approx(expected(mm2(1.0), bar(20.0))[0], rel=1e-6)
    assert q[2] == pytest.approx(expected(mm2(2.0), bar(20.0))[0], rel=1e-6)

    with open(tmp_path / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [row["status"] for row in rows] == ["ok", "failed", "ok"]
    assert rows[1]["error_type"] == "ParameterError" and rows[1]["q"] == ""
    assert float(rows[2]["q"]) == q[2]  # full precision round trip
    assert float(rows[1]["A"]) == -mm2(1.0)
    data = json.loads((tmp_path / "sweep.json").read_text())
    assert data["n_cases"] == 3 and data["n_failed"] == 1
    assert data["cases"][1]["error"]["type"] == "ParameterError"
    assert data["cases"][1]["outputs"] == {} and data["cases"][2]["outputs"]["q"] == q[2]


def test_errors_and_bad_outputs_of_run_become_failed_cases():
    result = sweep(fragile_square, [{"x": x} for x in range(6)], backend="serial")
    assert [r.index for r in result.failed] == [3, 4]
    assert result[3].error == "ValueError: x = 3 is not allowed"
    assert result[4].error_type == "SweepError" and "must return a dict" in result[4].error_message
    np.testing.assert_array_equal(result.column("y"), [0, 1, 4, np.nan, np.nan, 25])
    np.testing.assert_array_equal(result.column("half"), [0, 0.5, 1, np.nan, np.nan, 2.5])
    assert all(r.wall_time >= 0.0 for r in result)
    with pytest.raises(KeyError, match="did you mean 'half'"):
        result.column("hallf")


def test_a_worker_process_that_dies_fails_only_its_own_case():
    result = sweep(dies_at_one, [{"x": x} for x in range(4)], backend="process", workers=2)
    assert [r.status for r in result] == ["ok", "failed", "ok", "ok"]
    assert result[1].error_type == "BrokenProcessPool" and "case 1" in result[1].error_message
    np.testing.assert_array_equal(result.column("y"), [0.0, np.nan, 20.0, 30.0])


def test_progress_callback_sees_every_case_once():
    seen = []
    sweep(fragile_square, [{"x": x} for x in range(5)], backend="process", workers=2,
          progress=lambda done, total, index: seen.append((done, total, index)))
    assert [d for d, _, _ in seen] == [1, 2, 3, 4, 5]
    assert {t for _, t, _ in seen} == {5} and sorted(i for *_, i in seen) == list(range(5))


def test_writing_is_atomic_when_the_writer_fails_midway(tmp_path):
    good = sweep(fragile_square, [{"x": 1}, {"x": 2}], backend="serial")
    csv_path, json_path = good.save(tmp_path)
    before = {p: Path(p).read_text() for p in (csv_path, json_path)}
    broken = sweep(fragile_square, [{"x": 5}, {"x": Unprintable()}], backend="serial")
    assert broken[1].status == "failed"  # run() could not square it
    with pytest.raises(RuntimeError, match="cannot format"):
        broken.to_csv(csv_path)
    with pytest.raises(RuntimeError, match="cannot format"):
        broken.to_json(json_path)
    assert {p: Path(p).read_text() for p in (csv_path, json_path)} == before
    assert sorted(os.listdir(tmp_path)) == ["sweep.csv", "sweep.json"]  # no temporary left


@pytest.mark.parametrize("kwargs, match", [
    (dict(run=fragile_square, cases=[]), "cases is empty"),
    (dict(run=fragile_square, cases={"x": [1, 2]}), "use grid"),
    (dict(run=fragile_square, cases=[{"x": 1}, {"y": 2}]),
     r"case 1 has different parameters.*missing \['x'\], extra \['y'\]"),
    (dict(run="fragile_square", cases=[{"x": 1}]), "must be a callable"),
    (dict(run=fragile_square, cases=[{"x": 1}], backend="threads"),
     "unknown backend 'threads'; choose one of process, serial, dask"),
    (dict(run=lambda x: {"y": x}, cases=[{"x": 1}]), "define it at module level"),
    (dict(run=fragile_square, cases=[{"x": 1}], client="tcp://localhost:1"),
     "only used by backend='dask'"),
    (dict(run=fragile_square, cases=[{"status": 1}]), "reserved"),
    (dict(run=fragile_square, cases=[{"x": 1}], workers=0), "positive integer"),
])
def test_bad_sweep_setups_raise_clear_errors(kwargs, match):
    with pytest.raises(SweepError, match=match):
        sweep(**kwargs)


def test_dask_backend_without_dask_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(SweepError, match=r'pip install "pvgraph\[dask\]"'):
        sweep(fragile_square, [{"x": 1}], backend="dask")


def test_result_records_and_dict_export():
    result = SweepResult([CaseResult(0, {"a": 1.0}, {"y": math.inf}),
                          CaseResult(1, {"a": 2.0}, {}, "failed", 0.1, "ValueError", "no")],
                         ["a"], units={"y": "m"})
    assert len(result.ok) == 1 and result.failed[0].error == "ValueError: no"
    data = result.to_dict()
    assert data["cases"][0]["outputs"] == {"y": None}  # strict JSON: no Infinity
    assert data["units"] == {"y": "m"} and data["output_names"] == ["y"]
    assert "2 cases, 1 ok, 1 failed" in repr(result)


# --------------------------------------------------------------------------------------------
def test_grid_is_the_cartesian_product_last_name_fastest():
    cases = grid({"a": [1, 2, 3], "b": np.array([10.0, 20.0])})
    assert len(cases) == 6
    assert cases[:3] == [{"a": 1, "b": 10.0}, {"a": 1, "b": 20.0}, {"a": 2, "b": 10.0}]
    assert type(cases[0]["b"]) is float  # numpy scalars become plain numbers
    for bad in ({}, {"a": []}, {"a": 3.0}, {"a": "abc"}):
        with pytest.raises(SweepError):
            grid(bad)


@pytest.mark.parametrize("method", ["uniform", "lhs"])
def test_random_sample_bounds_size_and_seed(method):
    spec = {"A": (1e-6, 4e-6), "K": ("log", 1e-12, 1e-9), "name": "test-9"}
    cases = random_sample(spec, 50, seed=7, method=method)
    assert len(cases) == 50 and list(cases[0]) == ["A", "K", "name"]
    A = np.array([c["A"] for c in cases])
    K = np.array([c["K"] for c in cases])
    assert np.all((A >= 1e-6) & (A <= 4e-6)) and np.all((K >= 1e-12) & (K <= 1e-9))
    assert {c["name"] for c in cases} == {"test-9"}
    assert cases == random_sample(spec, 50, seed=7, method=method)
    assert cases != random_sample(spec, 50, seed=8, method=method)
    # log-uniform: about as many samples per decade in each of the three decades
    assert np.histogram(np.log10(K), bins=[-12, -11, -10, -9])[0].min() >= 8


def test_latin_hypercube_puts_one_sample_in_each_bin():
    n = 20
    cases = random_sample({"x": (2.0, 6.0), "k": ("log", 1e-3, 1e1)}, n, seed=3, method="lhs")
    x_bins = np.floor((np.array([c["x"] for c in cases]) - 2.0) / 4.0 * n).astype(int)
    k_bins = np.floor((np.log10([c["k"] for c in cases]) + 3.0) / 4.0 * n).astype(int)
    assert sorted(x_bins) == list(range(n)) and sorted(k_bins) == list(range(n))


@pytest.mark.parametrize("spec, n, method, match", [
    ({"x": (3.0, 1.0)}, 5, "lhs", "lo < hi"),
    ({"x": ("log", 0.0, 1.0)}, 5, "lhs", "lo > 0"),
    ({"x": (1.0, 2.0, 3.0)}, 5, "lhs", r"\(lo, hi\)"),
    ({"x": (1.0, 2.0)}, 0, "lhs", "positive integer"),
    ({"x": (1.0, 2.0)}, 5, "sobol", "unknown method"),
])
def test_random_sample_rejects_bad_specs(spec, n, method, match):
    with pytest.raises(SweepError, match=match):
        random_sample(spec, n, method=method)


def test_case_values_seeds_units_and_result_indexes_of_the_wrong_kind():
    """NaN and list case values, a string seed, units as a list and a name as a result index
    are refused by name (they were kept silently or gave numpy/list errors); units naming
    no column warn."""
    with pytest.raises(SweepError, match="grid: 'A' has the value nan; case values must be "
                                         "finite"):
        grid({"A": [float("nan"), 1.0]})
    with pytest.raises(SweepError, match=r"grid: 'A' has the value \[1, 2\]; each case value "
                                         "must be a single number or string"):
        grid({"A": [[1, 2]]})
    with pytest.raises(SweepError, match="random_sample: 'A' has the value nan"):
        random_sample({"A": float("nan"), "B": (0.0, 1.0)}, 3)
    with pytest.raises(SweepError, match="seed must be a non-negative integer"):
        random_sample({"A": (0.0, 1.0)}, 3, seed="x")

    def twice(x):
        return {"y": 2.0 * x}
    with pytest.raises(SweepError, match=r"units must be a mapping \{output name: unit\}"):
        sweep(twice, grid({"x": [1.0]}), backend="serial", units=["m"])
    with pytest.warns(UserWarning, match="units names 'yy'.*did you mean 'y'"):
        result = sweep(twice, grid({"x": [1.0, 2.0]}), backend="serial", units={"yy": "m"})
    assert result[1].outputs == {"y": 4.0} and result[-1] is result[1]
    with pytest.raises(TypeError, match=r"use result.column\('x'\)"):
        result["x"]
    with pytest.raises(IndexError, match=r"case 5 is out of range: the result holds 2 cases"):
        result[5]


@pytest.mark.parametrize("backend", ["serial", "process"])
def test_warnings_of_the_cases_are_recorded_and_raised_again(backend, tmp_path):
    """A case's warning, raised in a worker process, reaches the record, the CSV and JSON
    files and the caller (a case at 1e13 bar is not just 'ok')."""
    import json

    from pvgraph.errors import PlausibilityWarning
    with pytest.warns(PlausibilityWarning, match=r"sweep case 3 \{'x': 3\}: x = 3 is "
                                                 r"implausibly large"):
        result = sweep(warns_above_two, [{"x": x} for x in range(4)], backend=backend,
                       workers=2, out=tmp_path)
    assert [r.status for r in result] == ["ok"] * 4
    assert [r.warnings for r in result][:3] == [[], [], []]
    assert result[3].warnings == ["pvgraph.errors.PlausibilityWarning: x = 3 is implausibly "
                                  "large"]
    rows = (tmp_path / "sweep.csv").read_text().splitlines()
    assert rows[0].endswith(",warnings") and rows[4].endswith("x = 3 is implausibly large")
    saved = json.loads((tmp_path / "sweep.json").read_text())
    assert saved["cases"][3]["warnings"] == result[3].warnings


def test_a_sweep_whose_cases_all_fail_keeps_the_declared_output_columns(tmp_path):
    from pvgraph import Circuit
    from pvgraph.analysis import CompiledRun
    from pvgraph.components import FlowSource, Orifice, Tank, VolumeNode

    def build():
        c = Circuit("demo")
        c.add("pump", FlowSource(Q="10 L/min"))
        c.add("node", VolumeNode(V="0.5 L"))
        c.add("orifice", Orifice(A="2 mm^2"))
        c.add("tank", Tank())
        c.connect("pump.port", "node.port", "orifice.a")
        c.connect("orifice.b", "tank.port")
        return c
    run = CompiledRun(build, outputs={"p": "node.port.p"}, steady=True)
    result = sweep(run, [{"orifice.A": -1.0}, {"orifice.A": -2.0}], backend="serial",
                   out=tmp_path)
    assert len(result.failed) == 2 and result.output_names == ["p"]
    header = (tmp_path / "sweep.csv").read_text().splitlines()[0]
    assert header.startswith("index,status,wall_time,orifice.A,p")
