"""Sweeps keep their results: a record per finished case, resume, time limits, Ctrl-C,
SystemExit and non-finite outputs inside cases, invalid values refused before anything runs."""

import json
import math
import os
import sys
import time

import pytest

from pvgraph.analysis.sweep import SweepError, SweepInterrupted, grid, sweep
from pvgraph.errors import ParameterError


def square(x):
    """A case with a known answer: y = x^2."""
    return {"y": x * x}


def misbehaving(x):
    """x = 1: SystemExit; x = 2: NaN; x = 3: sleeps past any reasonable limit."""
    if x == 1:
        sys.exit(4)
    if x == 2:
        return {"y": math.nan}
    if x == 3:
        time.sleep(30)
    return {"y": x * x}


def slow_square(x):
    """y = x^2; x = 1 sleeps 3 s (past the test's limit)."""
    if x == 1:
        time.sleep(3.0)
    return {"y": x * x}


def counted(x, folder):
    """y = x^2, leaving a file per call so a test can count the runs; Ctrl-C at x = 3."""
    with open(os.path.join(folder, f"ran-{x}"), "a") as f:
        f.write("x")
    if x == 3 and not os.path.exists(os.path.join(folder, "no-interrupt")):
        raise KeyboardInterrupt
    return {"y": x * x}


def positive(case):
    if case["x"] < 0:
        raise ParameterError(f"x = {case['x']}: must be >= 0")


def _lines(path):
    with open(path) as f:
        return [json.loads(line) for line in f]


def _has_distributed() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


DASK = pytest.param("dask", marks=pytest.mark.skipif(not _has_distributed(),
                                                      reason="dask.distributed not installed"))


@pytest.mark.parametrize("backend", ["serial", "process", DASK])
def test_exit_nan_and_hang_are_recorded_and_the_rest_run(backend, tmp_path):
    """The hanging case sleeps 30 s: the sweep ends long before only if the limit works (on
    Dask, the local cluster's worker running it is restarted)."""
    t0 = time.perf_counter()
    result = sweep(misbehaving, grid({"x": [0, 1, 2, 3, 4]}), backend=backend, workers=2,
                   timeout=1.0, out=tmp_path)
    assert time.perf_counter() - t0 < 20.0
    status = [r.status for r in result]
    assert status == ["ok", "failed", "nonfinite", "timeout", "ok"]
    assert result[1].error_type == "SystemExit"
    assert "output(s) y not finite: nan" in result[2].error_message
    assert 0.9 < result[3].wall_time < 5.0                  # stopped at the limit, not 30 s
    assert result[3].error_type == "CaseTimeout"
    assert result[3].error_message == "stopped after the time limit of 1 s"
    assert [result[0].outputs["y"], result[4].outputs["y"]] == [0.0, 16.0]
    assert [r.index for r in result.failed] == [1, 2, 3]
    records = _lines(tmp_path / "cases.jsonl")[1:]
    assert sorted(r["index"] for r in records) == [0, 1, 2, 3, 4]
    with open(tmp_path / "sweep.json") as f:
        data = json.load(f)
    assert [c["status"] for c in data["cases"]] == status and data["complete"] is True
    with open(tmp_path / "sweep.csv") as f:
        assert [line.split(",")[1] for line in f.read().splitlines()[1:]] == status


def test_ctrl_c_keeps_the_finished_cases_and_resume_runs_only_the_rest(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    cases = grid({"x": [0, 1, 2, 3, 4, 5], "folder": [str(runs)]})
    with pytest.raises(SweepInterrupted) as exc:
        sweep(counted, cases, backend="serial", out=tmp_path / "out")
    partial = exc.value.result
    assert [r.index for r in partial] == [0, 1, 2] and partial.n_cases == 6
    assert not partial.complete
    with open(tmp_path / "out" / "sweep.json") as f:
        data = json.load(f)
    assert data["n_finished"] == 3 and data["complete"] is False
    with open(tmp_path / "out" / "sweep.csv") as f:
        assert len(f.read().splitlines()) == 1 + 3          # the CSV agrees with the JSON
    (runs / "no-interrupt").touch()
    result = sweep(counted, cases, backend="serial", out=tmp_path / "out", resume=True)
    assert result.complete and [r.outputs["y"] for r in result] == [0, 1, 4, 9, 16, 25]
    ran = {p.name: p.read_text() for p in runs.iterdir() if p.name.startswith("ran-")}
    assert ran == {"ran-0": "x", "ran-1": "x", "ran-2": "x", "ran-3": "xx", "ran-4": "x",
                   "ran-5": "x"}                            # the finished cases ran once


def test_resume_refuses_the_record_of_another_sweep(tmp_path):
    sweep(square, grid({"x": [1.0, 2.0]}), backend="serial", out=tmp_path)
    with pytest.raises(SweepError, match=r"records another sweep .*; case 1 was \{'x': 2.0\}, "
                                         r"now \{'x': 3.0\}"):
        sweep(square, grid({"x": [1.0, 3.0]}), backend="serial", out=tmp_path, resume=True)


def test_an_output_folder_that_is_not_one_is_told_before_any_case_runs(tmp_path):
    """out= a file, a number, '' and overwrite=True without out= are refused by name (they
    raised the OS's FileExistsError or TypeError, or were taken silently); a record of another
    sweep is told with its count in words and without the command line's flag."""
    (tmp_path / "f").write_text("x")
    cases = grid({"x": [1.0]})
    for out, told in ((tmp_path / "f", r"out='.*f' is a file, not a folder"),
                      (5, r"out takes a folder path \(str or pathlib.Path\), got int 5"),
                      ("", r"out='' names no folder")):
        with pytest.raises(SweepError, match=told):
            sweep(square, cases, backend="serial", out=out)
    with pytest.raises(SweepError, match=r"overwrite=True replaces the record in out=; give"):
        sweep(square, cases, backend="serial", overwrite=True)
    assert (tmp_path / "f").read_text() == "x"
    sweep(square, grid({"x": [1.0, 2.0]}), backend="serial", out=tmp_path / "o")
    with pytest.raises(SweepError, match=r"^resume: .* \(2 cases of \['x'\]\); these are 1 "
                                         r"case of \['x'\]"):
        sweep(square, cases, backend="serial", out=tmp_path / "o", resume=True)


def test_a_last_line_cut_short_reruns_that_case(tmp_path):
    sweep(square, grid({"x": [1.0, 2.0, 3.0]}), backend="serial", out=tmp_path)
    log = tmp_path / "cases.jsonl"
    text = log.read_text().splitlines()
    log.write_text("\n".join(text[:-1]) + "\n" + text[-1][:20])   # a crash mid-write
    result = sweep(square, grid({"x": [1.0, 2.0, 3.0]}), backend="serial", out=tmp_path,
                   resume=True)
    assert [r.outputs["y"] for r in result] == [1.0, 4.0, 9.0]


def test_invalid_values_are_refused_before_any_case_runs(tmp_path):
    with pytest.raises(SweepError) as exc:
        sweep(square, grid({"x": [1.0, -2.0, -3.0]}), backend="serial", check=positive,
              out=tmp_path)
    msg = str(exc.value)
    assert "2 of 3 cases have invalid parameter values; nothing was run" in msg
    assert "case 1 {'x': -2.0}: x = -2.0: must be >= 0" in msg
    assert not os.listdir(tmp_path)


def test_files_get_the_users_umask(tmp_path):
    old = os.umask(0o022)
    try:
        sweep(square, grid({"x": [1.0]}), backend="serial", out=tmp_path)
    finally:
        os.umask(old)
    for name in ("sweep.csv", "sweep.json", "cases.jsonl"):
        assert os.stat(tmp_path / name).st_mode & 0o777 == 0o644


def test_dask_timeout_on_a_given_cluster_cancels_and_says_the_task_runs_on(tmp_path):
    """On a cluster the sweep did not start, a late case is recorded and cancelled; the
    worker thread it holds is left out, and the next cases still finish on the other one."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        t0 = time.perf_counter()
        result = sweep(slow_square, grid({"x": [0.0, 1.0, 2.0, 3.0]}), backend="dask",
                       client=client, timeout=0.5, out=tmp_path)
        assert time.perf_counter() - t0 < 2.5            # not the 3 s the late case sleeps
    assert [r.status for r in result] == ["ok", "timeout", "ok", "ok"]
    assert [r.outputs["y"] for r in result.ok] == [0.0, 4.0, 9.0]
    assert "runs on in its worker" in result[1].error_message
    late = [r for r in _lines(tmp_path / "cases.jsonl")[1:] if r["index"] == 1]
    assert len(late) == 1 and late[0]["status"] == "timeout"
    assert set(late[0]) == {"index", "status", "wall_time", "params", "outputs", "error"}
    assert late[0]["error"]["type"] == "CaseTimeout"


def test_ctrl_c_in_a_dask_sweep_keeps_the_finished_cases(tmp_path):
    distributed = pytest.importorskip("distributed")
    seen = []

    def progress(done, total, index):
        seen.append(index)
        if done == 2:
            raise KeyboardInterrupt
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster, set_as_default=False) as client:
        with pytest.raises(SweepInterrupted) as exc:
            sweep(square, grid({"x": [0.0, 1.0, 2.0, 3.0]}), backend="dask", client=client,
                  timeout=5.0, progress=progress, out=tmp_path)
    partial = exc.value.result
    assert len(partial) == 2 and partial.n_cases == 4 and not partial.complete
    assert all(r.outputs["y"] == r.params["x"] ** 2 for r in partial)
    assert sorted(seen) == sorted(r.index for r in partial)
    with open(tmp_path / "sweep.json") as f:
        assert json.load(f)["n_finished"] == 2


def test_a_folder_holding_an_earlier_sweep_is_not_overwritten_unasked(tmp_path):
    """A second sweep into the folder of a first one is refused, naming what the record holds
    and the two ways on; overwrite=True replaces it, resume=True keeps it."""
    first = sweep(square, grid({"x": [1.0, 2.0, 3.0]}), backend="serial", out=tmp_path)
    assert len(first) == 3 and len(_lines(tmp_path / "cases.jsonl")) == 4
    with pytest.raises(SweepError, match=r"cases.jsonl holds the record of an earlier sweep "
                                         r"\(3 cases, 3 finished\).*resume.*overwrite"):
        sweep(square, grid({"x": [5.0]}), backend="serial", out=tmp_path)
    assert len(_lines(tmp_path / "cases.jsonl")) == 4         # nothing lost
    again = sweep(square, grid({"x": [1.0, 2.0, 3.0]}), backend="serial", out=tmp_path, resume=True)
    assert [r.outputs["y"] for r in again] == [1.0, 4.0, 9.0]
    other = sweep(square, grid({"x": [5.0]}), backend="serial", out=tmp_path, overwrite=True)
    assert other[0].outputs["y"] == 25.0 and len(_lines(tmp_path / "cases.jsonl")) == 2
    with pytest.raises(SweepError, match="give one of them"):
        sweep(square, grid({"x": [5.0]}), backend="serial", out=tmp_path, overwrite=True, resume=True)


def test_resume_and_overwrite_take_bools_only(tmp_path):
    sweep(square, grid({"x": [1.0, 2.0]}), backend="serial", out=tmp_path)
    for flag, value in (("overwrite", "no"), ("overwrite", 1), ("resume", "yes")):
        with pytest.raises(SweepError, match=f"{flag} takes True or False, got {value!r}"):
            sweep(square, grid({"x": [5.0]}), backend="serial", out=tmp_path, **{flag: value})
    assert len(_lines(tmp_path / "cases.jsonl")) == 3        # nothing replaced


def cube(x):
    return {"y": x ** 3}


def test_resume_with_another_run_is_refused_and_the_record_kept(tmp_path):
    """The record names the run that made it; resuming with another function is refused
    (its finished cases would be counted as the new run's) and the record is left as it
    was; overwrite=True runs them all again with the new one."""
    cases = grid({"x": [1.0, 2.0]})
    sweep(square, cases, backend="serial", out=tmp_path)
    before = (tmp_path / "cases.jsonl").read_text()
    head = json.loads(before.splitlines()[0])
    assert head["run"].endswith("test_sweep_resilience.square")
    with pytest.raises(SweepError, match=r"recorded by another run \(recorded: .*square; now: "
                                         r".*cube\); its 2 finished cases cannot be counted"):
        sweep(cube, cases, backend="serial", out=tmp_path, resume=True)
    assert (tmp_path / "cases.jsonl").read_text() == before
    again = sweep(cube, cases, backend="serial", out=tmp_path, overwrite=True)
    assert [r.outputs["y"] for r in again] == [1.0, 8.0]


class _Plain:
    """An argument with the default repr (its memory address differs per process)."""

    def __call__(self, x):
        return {"y": x}


def test_the_identity_of_a_partial_does_not_hold_memory_addresses():
    """The command line sweeps functools.partial(_noted_case, CompiledRun(...)): the record's
    identity held the CompiledRun's address, and every resume of the very same command
    warned that another run had made the record."""
    import functools

    from pvgraph.analysis.sweep import run_identity
    a = run_identity(functools.partial(square, _Plain()))
    b = run_identity(functools.partial(square, _Plain()))
    assert a == b and "0x" not in a
    assert run_identity(functools.partial(square)) != run_identity(functools.partial(cube))
