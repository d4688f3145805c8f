"""Parameter studies: run one function over many cases, in parallel, and keep every result.

A sweep applies ``run(**params) -> {output name: float}`` to a list of *cases*, each a dict of
parameter values with the same keys. ``run`` does whatever one case needs (build a circuit from
the parameters, simulate it, reduce the solution to scalars), so a sweep works for any circuit
or model::

    def orifice_flow(A, dp):                      # module level: it is sent to other processes
        system = build_bench(A, dp).compile()
        return {"q": steady_state(system)["dut.a.q"]}

    result = sweep(orifice_flow, grid({"A": [1e-6, 2e-6], "dp": [1e5, 2e5, 4e5]}),
                   progress=True, out="orifice-study")
    result.column("q")                            # numpy array in case order, NaN where failed

Design
------
- **Failures are data.** Every exception raised by ``run`` (and an output that is not a dict
  of scalars) is caught where the case runs and stored in its :class:`CaseResult`: status
  ``"failed"``, the exception type, its message and the traceback text. The other cases go on.
  A worker process that dies outright (killed, out of memory, a crash in compiled code) takes
  the cases it shared a pool with down with it; those are rerun one per fresh process, so only
  the case that kills its process is marked failed.
- **Backends.** ``"process"`` (default): a local :class:`~concurrent.futures.ProcessPoolExecutor`;
  ``run`` and the parameter values must pickle, so ``run`` is a module-level function or a
  :func:`functools.partial` of one. ``"serial"``: the cases one after the other in this
  process, for debugging (breakpoints and ``pdb`` work inside ``run``). ``"dask"``:
  ``dask.distributed`` (an optional dependency, ``pip install "pvgraph[dask]"``) on a given
  ``Client``, on a scheduler address (``"tcp://host:8786"``), or on a local cluster of
  ``workers`` processes started for the sweep and closed after it. Every worker must be able to
  import the modules ``run`` comes from.
- **Order.** Cases finish in any order; the result holds them in case order, and the progress
  callback ``progress(done, total, case_index)`` is called in this process as each finishes.
- **Files.** With ``out=folder`` every finished case is appended to ``folder/cases.jsonl`` (one
  JSON record per line, flushed as the case finishes): the record of what is done, whatever
  happens next. ``folder/sweep.csv`` and ``folder/sweep.json`` are written from the same records
  at the end, atomically (a temporary file renamed over the target), so they always agree and an
  interrupted write never leaves half a file. Files get the permissions of the user's umask.
- **Interruptions.** Ctrl-C stops the sweep cleanly: the workers are stopped, the finished
  cases are written as above and :class:`SweepInterrupted` (a ``KeyboardInterrupt``) carries the
  partial result. ``resume=True`` reads ``cases.jsonl`` and runs only the cases not yet finished
  successfully (failed and timed-out cases run again).
- **Bad cases.** ``timeout=seconds`` stops a case that runs longer (status ``"timeout"``).
  Serial and process backends: ``SIGALRM`` interrupts the case where it runs (not on Windows).
  Dask: the limit is kept on this side, with only as many cases in flight as the cluster has
  worker threads; a late case is recorded and cancelled, and on the local cluster the sweep
  starts, the worker process running it is restarted (that stops it; its cached compiled
  systems are rebuilt). Dask cannot stop a running Python function on a cluster it was given
  (``client=``): there the case runs on in its worker until it returns, and that thread is
  left out of the count of free threads. A ``SystemExit`` inside ``run`` is a
  failed case, not the end of the sweep. An output that is NaN or infinite marks the case
  ``"nonfinite"``. ``check(case)`` runs on every case before any case runs: invalid parameter
  values raise :class:`SweepError` naming the cases, and nothing runs.

Compile once
------------
A ``run`` that builds and compiles its circuit pays the compilation on every case.
:class:`CompiledRun` (and :func:`sweep_system`) compiles the circuit once per worker process and
runs each case with its values as runtime parameters (``simulate(..., params=)``,
``steady_state(..., params=)``)::

    run = CompiledRun(build_bench, outputs=["node.port.p"], steady=True)
    result = sweep(run, grid({"orifice.A": [1e-6, 2e-6], "pump.Q": [1e-4, 2e-4]}))

A case that changes a structural parameter (one the equations turn into a plain number) is
compiled again, once per distinct set of structural values in each process, with a
:class:`~pvgraph.system.RecompileWarning` naming the parameter. With ``build=``, the case values
are arguments of a builder rather than component parameters: each case builds its circuit (cheap),
reads its runtime parameter values into the compiled system of the same structure
(:meth:`~pvgraph.system.System.params_from`) and compiles only a structure not met before.

Cases
-----
:func:`grid` gives the cartesian product of value lists; :func:`random_sample` draws ``n``
cases uniformly or by Latin hypercube from ranges ``(lo, hi)``, or log-uniformly from
``("log", lo, hi)``.
"""

from __future__ import annotations

import csv
import difflib
import functools
import itertools
import json
import math
import numbers
import os
import pickle
import re
import signal
import threading
import time
import traceback as _traceback
import warnings as _warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from .._progress import ProgressBar
from ..errors import ParameterError, PvgraphError

__all__ = ["SweepError", "SweepInterrupted", "CaseResult", "SweepResult", "sweep", "grid",
           "random_sample", "CompiledRun", "sweep_system", "BACKENDS", "LOG_NAME"]

BACKENDS = ("process", "serial", "dask")
SAMPLING_METHODS = ("uniform", "lhs")
MAX_PROCESS_WORKERS = 61   # the largest pool ProcessPoolExecutor accepts on every platform
OK, FAILED, TIMEOUT, NONFINITE = "ok", "failed", "timeout", "nonfinite"
#: CSV columns every sweep writes; no parameter or output may take these names
RESERVED_COLUMNS = ("index", "status", "wall_time", "error_type", "error_message", "warnings")
CSV_NAME, JSON_NAME, LOG_NAME = "sweep.csv", "sweep.json", "cases.jsonl"
LOG_VERSION = 1


class SweepError(PvgraphError, ValueError):
    """A sweep is set up wrongly: no cases, mismatched parameter names, an unknown backend."""


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; ``.result`` holds the finished cases (already written to ``out``)."""

    def __init__(self, result: "SweepResult"):
        super().__init__(f"sweep interrupted after {len(result)} of {result.n_cases} cases")
        self.result = result


class CaseTimeout(BaseException):
    """Raised inside a case that exceeds its time limit (a BaseException: ``except Exception``
    in the case's own code does not swallow it)."""


# --------------------------------------------------------------------------------------------
@dataclass
class CaseResult:
    """The record of one case: its parameters, outputs (SI floats) or error, and wall time."""

    index: int
    params: dict
    outputs: dict = field(default_factory=dict)
    status: str = OK
    wall_time: float = 0.0
    error_type: str | None = None
    error_message: str | None = None
    traceback: str | None = None
    #: the warnings the case raised, ``"module.Category: message"`` each (recorded where the
    #: case ran, in a worker process too, and warned again by :func:`sweep` when it ends)
    warnings: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status == OK

    @property
    def error(self) -> str | None:
        """``"Type: message"`` of a failed case, None for a successful one."""
        return None if self.ok else f"{self.error_type}: {self.error_message}"

    def to_dict(self) -> dict:
        """A JSON-ready dict (non-finite floats become None)."""
        err = None if self.ok else {"type": self.error_type, "message": self.error_message,
                                    "traceback": self.traceback}
        return {"index": self.index, "status": self.status,
                "wall_time": _json_value(self.wall_time),
                "params": {k: _json_value(v) for k, v in self.params.items()},
                "outputs": {k: _json_value(v) for k, v in self.outputs.items()},
                "error": err, "warnings": list(self.warnings)}


def _scalar(name: str, value) -> float:
    """One output value as a float; anything but a real scalar is an error naming the output."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (numbers.Real, np.bool_)):
        return float(value)
    raise SweepError(f"output {name!r} is {type(value).__name__} ({value!r:.60}); each output "
                     f"of run() must be a real scalar")


def _check_outputs(raw, params: Mapping) -> dict:
    if not isinstance(raw, Mapping):
        raise SweepError(f"run() returned {type(raw).__name__}; it must return a dict of "
                         f"output name -> float")
    out = {}
    for name, value in raw.items():
        if not isinstance(name, str):
            raise SweepError(f"output name {name!r} is not a string")
        if name in params or name in RESERVED_COLUMNS:
            raise SweepError(f"output {name!r} has the name of a parameter or of a column every "
                             f"sweep writes ({', '.join(RESERVED_COLUMNS)}); rename it")
        out[name] = _scalar(name, value)
    return out


def _failure(index: int, params: Mapping, exc: BaseException, tb: str | None = None,
             wall: float = 0.0) -> CaseResult:
    return CaseResult(index, dict(params), {}, FAILED, wall, type(exc).__name__, str(exc),
                      tb if tb is not None else "".join(_traceback.format_exception(exc)))


def _alarm(signum, frame):
    raise CaseTimeout()


def _run_case(run: Callable, index: int, params: Mapping,
              timeout: float | None = None) -> CaseResult:
    """Run one case and record its outputs or its error (executed where the case runs)."""
    timed = timeout is not None and hasattr(signal, "setitimer") and \
        threading.current_thread() is threading.main_thread()
    if timed:
        previous = signal.signal(signal.SIGALRM, _alarm)
        signal.setitimer(signal.ITIMER_REAL, timeout)
    t0 = time.perf_counter()
    caught: list = []
    try:
        with _warnings.catch_warnings(record=True) as caught:
            _warnings.simplefilter("always")
            outputs = _check_outputs(run(**params), params)
    except CaseTimeout:
        res = CaseResult(index, dict(params), {}, TIMEOUT, time.perf_counter() - t0,
                         "CaseTimeout", f"stopped after the time limit of {timeout:g} s")
        res.warnings = _warning_texts(caught)
        return res
    except (Exception, SystemExit) as exc:
        res = _failure(index, params, exc, _traceback.format_exc(), time.perf_counter() - t0)
        res.warnings = _warning_texts(caught)
        return res
    finally:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
    wall = time.perf_counter() - t0
    bad = [n for n, v in outputs.items() if not math.isfinite(v)]
    if bad:
        res = CaseResult(index, dict(params), outputs, NONFINITE, wall, "NonFiniteOutput",
                         f"output(s) {', '.join(bad)} not finite: "
                         f"{', '.join(repr(outputs[n]) for n in bad)}")
    else:
        res = CaseResult(index, dict(params), outputs, OK, wall)
    res.warnings = _warning_texts(caught)
    return res


def _warning_texts(caught) -> list[str]:
    """``"module.Category: message"`` of each distinct warning recorded, in order."""
    out: dict[str, None] = {}
    for w in caught:
        cat = w.category
        out[f"{cat.__module__}.{cat.__qualname__}: {w.message}"] = None
    return list(out)


def _warn_again(records) -> None:
    """Warn, in the caller's process, of what the cases warned of where they ran: a
    plausibility warning raised in a worker process would otherwise be lost, and a case at
    1e13 bar read as ok."""
    import importlib
    for r in records:
        for text in r.warnings:
            qualified, _, message = text.partition(": ")
            module, _, name = qualified.rpartition(".")
            try:
                category = getattr(importlib.import_module(module), name)
                if not (isinstance(category, type) and issubclass(category, Warning)):
                    raise TypeError
            except (ImportError, AttributeError, TypeError, ValueError):
                category = UserWarning
            _warnings.warn(category(f"sweep case {r.index} {dict(r.params)}: {message}"),
                           stacklevel=3)


# --------------------------------------------------------------------------------------------
class SweepResult:
    """Every case of a sweep in case order, with column access and CSV / JSON export.

    ``result[i]`` is the :class:`CaseResult` of case ``i``; ``result.ok`` and ``result.failed``
    the successful and failed records; ``result.column(name)`` a parameter or output over all
    cases as a numpy array (NaN for an output of a failed case).
    """

    def __init__(self, records: Sequence[CaseResult], param_names: Sequence[str], *,
                 backend: str = "serial", wall_time: float = 0.0,
                 units: Mapping[str, str] | None = None, n_cases: int | None = None,
                 output_names: Sequence[str] = ()):
        self.records = list(records)
        self.n_cases = len(self.records) if n_cases is None else int(n_cases)
        self.files: tuple[str, str] | None = None
        self.param_names = list(param_names)
        self.backend = backend
        self.wall_time = float(wall_time)
        self.units = dict(units or {})
        # the outputs the run declares (a CompiledRun's), then any other a case returned: a
        # sweep whose cases all failed still has their columns
        names: dict[str, None] = dict.fromkeys(output_names)
        for r in self.records:
            names.update(dict.fromkeys(r.outputs))
        self.output_names = list(names)

    def __len__(self) -> int:
        return len(self.records)

    def __iter__(self) -> Iterator[CaseResult]:
        return iter(self.records)

    def __getitem__(self, index: int) -> CaseResult:
        if isinstance(index, str):
            raise TypeError(f"result[{index!r}]: a sweep result is indexed by case number; "
                            f"use result.column({index!r}) for a parameter or output")
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, (numbers.Integral,
                                                                        slice)):
            raise TypeError(f"result[{index!r}]: give a case number (0 .. {len(self) - 1})")
        if isinstance(index, numbers.Integral) and not -len(self) <= int(index) < len(self):
            raise IndexError(f"case {int(index)} is out of range: the result holds "
                             f"{len(self)} cases (0 .. {len(self) - 1})")
        return self.records[index]

    @property
    def ok(self) -> list[CaseResult]:
        """The successful cases, in case order."""
        return [r for r in self.records if r.ok]

    @property
    def complete(self) -> bool:
        """True when every case has a record (False after an interruption)."""
        return len(self.records) == self.n_cases

    @property
    def failed(self) -> list[CaseResult]:
        """The cases that failed, timed out or gave non-finite outputs, in case order."""
        return [r for r in self.records if not r.ok]

    def column(self, name: str) -> np.ndarray:
        """A parameter, an output or ``"wall_time"`` over all cases, in case order.

        Outputs are floats with NaN where a case failed (or did not return that output);
        parameters keep their values (a float array when all are numbers).
        """
        if name in self.param_names:
            values = [r.params[name] for r in self.records]
            if all(isinstance(v, numbers.Real) for v in values):
                return np.asarray(values, dtype=float)
            return np.asarray(values, dtype=object)
        if name in self.output_names:
            return np.asarray([r.outputs.get(name, math.nan) if r.ok else math.nan
                               for r in self.records], dtype=float)
        if name == "wall_time":
            return np.asarray([r.wall_time for r in self.records], dtype=float)
        pool = self.param_names + self.output_names + ["wall_time"]
        close = difflib.get_close_matches(name, pool, n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise KeyError(f"no parameter or output named {name!r}{hint} The columns are: "
                       f"{', '.join(pool)}")

    def to_dict(self) -> dict:
        """The whole sweep as a JSON-ready dict."""
        return {"backend": self.backend, "wall_time": _json_value(self.wall_time),
                "n_cases": self.n_cases, "n_finished": len(self), "complete": self.complete,
                "n_ok": len(self.ok), "n_failed": len(self.failed),
                "param_names": self.param_names, "output_names": self.output_names,
                "units": self.units, "cases": [r.to_dict() for r in self.records]}

    def to_json(self, path) -> str:
        """Write :meth:`to_dict` to ``path`` atomically (strict JSON: NaN is written as null)."""
        from ..simulate import _atomic_write
        data = self.to_dict()
        _atomic_write(path, lambda f: json.dump(data, f, indent=1, allow_nan=False,
                                                default=str))
        return os.fspath(path)

    def to_csv(self, path) -> str:
        """Write one row per case to ``path`` atomically.

        Columns: ``index, status, wall_time``, the parameters, the outputs (SI, full precision,
        the unit in the column name when known; empty where a case failed), ``error_type,
        error_message, warnings`` (those a case raised, joined by " | "). Tracebacks are in
        the JSON.
        """
        from ..simulate import _atomic_write
        outs = [f"{n} [{self.units[n]}]" if self.units.get(n) else n for n in self.output_names]
        header = (["index", "status", "wall_time"] + self.param_names + outs
                  + ["error_type", "error_message", "warnings"])
        rows = []
        for r in self.records:
            outs = [_csv_value(r.outputs[n]) if n in r.outputs else "" for n in self.output_names]
            rows.append([r.index, r.status, _csv_value(r.wall_time)]
                        + [_csv_value(r.params[n]) for n in self.param_names] + outs
                        + [r.error_type or "", r.error_message or "", " | ".join(r.warnings)])

        def write(f):
            w = csv.writer(f)
            w.writerow(header)
            w.writerows(rows)
        _atomic_write(path, write)
        return os.fspath(path)

    def save(self, folder) -> tuple[str, str]:
        """Write ``folder/sweep.csv`` and ``folder/sweep.json``; returns both paths."""
        folder = os.fspath(folder)
        self.files = (self.to_csv(os.path.join(folder, CSV_NAME)),
                      self.to_json(os.path.join(folder, JSON_NAME)))
        return self.files

    def to_dataframe(self):
        """The CSV table as a pandas DataFrame (pandas is optional and imported here)."""
        try:
            import pandas as pd
        except ImportError:
            raise SweepError("SweepResult.to_dataframe() needs pandas; install it with "
                             "pip install pandas, or use to_csv() / column()") from None
        rows = []
        for r in self.records:
            row = {"index": r.index, "status": r.status, "wall_time": r.wall_time, **r.params}
            row.update({n: r.outputs.get(n, math.nan) for n in self.output_names})
            row.update(error_type=r.error_type, error_message=r.error_message)
            rows.append(row)
        return pd.DataFrame(rows).set_index("index")

    def __repr__(self):
        return (f"<SweepResult: {len(self)} cases, {len(self.ok)} ok, {len(self.failed)} failed, "
                f"backend {self.backend}, {self.wall_time:.1f} s>")


def _json_value(v):
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _csv_value(v):
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float):
        return repr(v)
    return "" if v is None else v


# --------------------------------------------------------------------------------------------
def _check_cases(cases) -> list[dict]:
    if isinstance(cases, Mapping):
        raise SweepError("cases must be a list of dicts (one per case), not one dict; use "
                         "grid({...}) for a cartesian product")
    try:
        cases = [c for c in cases]
    except TypeError:
        raise SweepError(f"cases must be a list of dicts, got {type(cases).__name__}") from None
    if not cases:
        raise SweepError("no cases to run: cases is empty")
    for i, c in enumerate(cases):
        if not isinstance(c, Mapping):
            raise SweepError(f"case {i} is {type(c).__name__}, not a dict of parameter values")
        bad = [k for k in c if not isinstance(k, str) or not k]
        if bad:
            raise SweepError(f"case {i}: parameter names must be non-empty strings (they are "
                             f"passed as keyword arguments); got {bad}")
    names = list(cases[0])
    reserved = [k for k in names if k in RESERVED_COLUMNS]
    if reserved:
        raise SweepError(f"parameter name(s) {reserved} are reserved for the sweep's own "
                         f"columns ({', '.join(RESERVED_COLUMNS)}); rename them")
    for i, c in enumerate(cases[1:], start=1):
        if set(c) != set(names):
            missing = [k for k in names if k not in c]
            extra = [k for k in c if k not in names]
            raise SweepError(f"case {i} has different parameters from case 0: missing "
                             f"{missing}, extra {extra}; every case must set the same names")
    return [dict(c) for c in cases]


def _default_workers(n_cases: int) -> int:
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(n_cases, cpus, MAX_PROCESS_WORKERS))


def _check_picklable(run, cases) -> None:
    try:
        pickle.dumps(run)
    except Exception as exc:
        name = getattr(run, "__qualname__", repr(run))
        raise SweepError(f"run ({name}) cannot be sent to worker processes ({exc}); define it "
                         f"at module level (or use functools.partial of a module-level "
                         f"function), or use backend='serial'") from None
    for i, c in enumerate(cases):
        try:
            pickle.dumps(c)
        except Exception as exc:
            raise SweepError(f"case {i}: the parameter values cannot be sent to worker "
                             f"processes ({exc}); use plain numbers and strings") from None


def _progress_callback(progress, total: int):
    if progress is None or progress is False:
        return None
    if progress is True:
        bar = ProgressBar(total, "sweep")
        return lambda done, n, index: bar.update(done, f"case {index}")
    if callable(progress):
        return progress
    raise SweepError(f"progress must be None, True or a callable progress(done, total, "
                     f"case_index), got {type(progress).__name__}")


# --------------------------------------------------------------------------------------------
def _run_serial(run, todo, cases, report, timeout) -> None:
    for i in todo:
        report(_run_case(run, i, cases[i], timeout))


def _ignore_sigint() -> None:
    """Worker initialiser: Ctrl-C is the parent's to handle (it stops the workers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop_pool(pool) -> None:
    """Cancel what has not started and stop the worker processes now."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    for proc in procs:
        proc.join(timeout=2)


def _run_isolated(run, index, params, timeout=None) -> CaseResult:
    """One case in a fresh single-worker process pool (after a pool broke)."""
    with ProcessPoolExecutor(max_workers=1, initializer=_ignore_sigint) as pool:
        try:
            return pool.submit(_run_case, run, index, params, timeout).result()
        except BrokenProcessPool as exc:
            return _failure(index, params, BrokenProcessPool(
                f"the worker process running case {index} died ({exc}); it was killed, ran "
                f"out of memory or crashed in compiled code"))
        except Exception as exc:
            return _failure(index, params, exc)


def _run_process(run, todo, cases, workers, report, timeout) -> None:
    broken = []
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_ignore_sigint)
    try:
        futures = {pool.submit(_run_case, run, i, cases[i], timeout): i for i in todo}
        for fut in as_completed(futures):
            i = futures[fut]
            try:
                report(fut.result())
            except BrokenProcessPool:
                broken.append(i)
            except Exception as exc:  # the result could not be sent back
                report(_failure(i, cases[i], exc))
    except BaseException:
        _stop_pool(pool)
        raise
    pool.shutdown()
    for i in sorted(broken):
        report(_run_isolated(run, i, cases[i], timeout))


def _start_dask(workers, client):
    """``(distributed, client, owned)``: the Dask client a sweep runs on, started (a local
    cluster) or connected (a scheduler address) here, before the sweep's record is opened;
    ``owned`` are what the sweep closes at its end."""
    try:
        import distributed
    except ImportError:
        raise SweepError('backend "dask" needs dask.distributed; install it with '
                         'pip install "pvgraph[dask]"') from None
    owned = []
    if client is None:
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1,
                                           processes=True, dashboard_address=None)
        owned.append(cluster)
        client = distributed.Client(cluster, set_as_default=False)
        owned.insert(0, client)
    elif isinstance(client, str):
        address = client
        try:
            client = distributed.Client(address, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise SweepError(f"cannot connect to the Dask scheduler at {address!r}: "
                             f"{exc}") from None
        owned.append(client)
    elif not isinstance(client, distributed.Client):
        raise SweepError(f"client must be a distributed.Client or a scheduler address string, "
                         f"got {type(client).__name__}")
    return distributed, client, owned


def _run_dask(run, todo, cases, started, report, timeout=None) -> None:
    distributed, client, owned = started
    futures = []
    try:
        if timeout is not None:
            _run_dask_timed(distributed, client, run, todo, cases, report, timeout,
                            restart=len(owned) == 2, futures=futures)
            return
        futures[:] = [client.submit(_run_case, run, i, cases[i], pure=False) for i in todo]
        index = {f.key: i for i, f in zip(todo, futures)}
        for fut in distributed.as_completed(futures, loop=client.loop):
            i = index[fut.key]
            try:
                report(fut.result())
            except Exception as exc:  # the worker died (KilledWorker), or (de)serialisation
                report(_failure(i, cases[i], exc))
            fut.release()
    except BaseException:
        if not owned:                 # the user's cluster: take back what has not finished
            client.cancel([f for f in futures if not f.done()])
        raise
    finally:
        for obj in owned:
            obj.close()


#: [s] how often a timed Dask sweep looks at its running cases
DASK_POLL = 0.02


#: [s] the longest a timed Dask sweep waits for a worker to warm up
DASK_WARM_MAX = 60.0


def _ready(run) -> bool:
    """A worker's warm-up: receiving ``run`` imports the modules it comes from, and a part of
    it with a ``prepare()`` method (:class:`CompiledRun`) compiles its circuit."""
    parts = [run]
    while parts:
        obj = parts.pop()
        if isinstance(obj, functools.partial):
            parts.extend([obj.func, *obj.args, *obj.keywords.values()])
        elif callable(getattr(obj, "prepare", None)):
            obj.prepare()
    return True


def _warm_workers(client, run, warm: set, limit: float = DASK_WARM_MAX) -> dict:
    """Warm every worker not in ``warm`` (:func:`_ready`), waiting at most ``limit`` seconds,
    so that a fresh worker's imports and compilation are not counted in the time of its first
    case (they are not in the process backend, whose workers start from this process); a
    failing warm-up is left to the cases to report. Returns the workers' thread counts."""
    threads = client.nthreads()
    new = [w for w in threads if w not in warm]
    futs = [client.submit(_ready, run, workers=[w], pure=False) for w in new]
    deadline = time.monotonic() + limit
    while futs and not all(f.done() for f in futs) and time.monotonic() < deadline:
        time.sleep(DASK_POLL)
    for f in futs:
        f.release()
    warm.update(new)
    return threads


def _run_dask_timed(distributed, client, run, todo, cases, report, timeout, *, restart,
                    futures) -> None:
    """Dask with a time limit per case, measured on this side from the case's submission.

    Every worker first receives ``run`` (its imports are not a case's time); then only as
    many cases are in flight as the cluster has free worker threads, so a submitted case
    starts at once and its time is its run time. A case past its limit is recorded as
    ``"timeout"`` at once and its future cancelled. Dask cannot interrupt a Python function
    that is running: on the local cluster started for the sweep (``restart``) the worker
    process running the case is restarted in the background, which stops it, and its threads
    count again once it is back; on a cluster the caller gave, the task runs on in its worker
    thread until it returns, and that thread is no longer counted (one is always kept).
    """
    warm: set = set()
    slots = sum(_warm_workers(client, run, warm).values())
    held = 0                  # threads of restarting workers, or holding a cancelled task
    restarting: list = []     # (background thread, threads it holds)
    pending = list(todo)
    running: dict = {}        # future -> (case index, start time)
    while pending or running:
        for item in [r for r in restarting if not r[0].is_alive()]:
            restarting.remove(item)
            held -= item[1]
        free = slots - held if restart else max(1, slots - held)
        while pending and len(running) < free:
            i = pending.pop(0)
            fut = client.submit(_run_case, run, i, cases[i], pure=False)
            futures.append(fut)
            running[fut] = (i, time.monotonic())
        finished = [f for f in running if f.done()]
        for fut in finished:
            i, _ = running.pop(fut)
            try:
                report(fut.result())
            except Exception as exc:   # the worker died (KilledWorker), or (de)serialisation
                report(_failure(i, cases[i], exc))
            fut.release()
        now = time.monotonic()
        late = [f for f, (_, t0) in running.items() if now - t0 >= timeout and not f.done()]
        if late:
            where = client.processing()
            stuck = sorted({w for w, keys in where.items() for f in late if f.key in keys})
            client.cancel(late)
            note = "" if restart else ("; Dask cannot stop a running task on a cluster the "
                                       "sweep did not start: it runs on in its worker")
            for fut in late:
                i, t0 = running.pop(fut)
                report(CaseResult(i, dict(cases[i]), {}, TIMEOUT, now - t0, "CaseTimeout",
                                  f"stopped after the time limit of {timeout:g} s{note}"))
            if restart and pending:      # (at the end, closing the cluster stops them)
                threads = client.nthreads()
                n = sum(threads.get(w, 1) for w in stuck)
                worker = threading.Thread(target=_restart_workers, daemon=True,
                                          args=(client, stuck, run, warm))
                worker.start()
                restarting.append((worker, n))
                held += n
            elif not restart:
                held += len(late)
        if not finished and not late:
            time.sleep(DASK_POLL)


def _restart_workers(client, workers, run, warm) -> None:
    """Restart the worker processes ``workers`` (stopping what they run) and warm them up;
    runs in a background thread, so a failure here only leaves their threads unused."""
    try:
        client.restart_workers(workers, raise_for_error=False)
        _warm_workers(client, run, warm)
    except Exception:           # the cluster is closing, or a worker did not come back
        pass


def sweep(run: Callable[..., Mapping[str, float]], cases: Iterable[Mapping[str, Any]], *,
          backend: str = "process", workers: int | None = None, client=None,
          progress: bool | Callable[[int, int, int], None] | None = None, out=None,
          units: Mapping[str, str] | None = None, resume: bool = False,
          overwrite: bool = False, timeout: float | None = None,
          check: Callable[[dict], None] | None = None) -> SweepResult:
    """Run ``run(**case)`` for every case and collect the outputs, in case order.

    Parameters
    ----------
    run : callable
        ``run(**params) -> dict[str, float]``: builds and simulates one case and returns its
        scalar outputs. For ``backend="process"`` it must pickle: a module-level function or a
        :func:`functools.partial` of one.
    cases : iterable of dict
        Parameter values per case, all with the same names (see :func:`grid`,
        :func:`random_sample`). Names that are not Python identifiers (dotted paths such as
        ``"rig.pump_flow"``) reach a ``run(**params)`` that collects keyword arguments.
    backend : {"process", "serial", "dask"}
        Local process pool, this process one case after the other, or ``dask.distributed``.
    workers : int, optional
        Processes of the pool or of the local Dask cluster; default the CPUs available to
        this process (at most one per case). Ignored when a Dask ``client`` is given.
    client : distributed.Client or str, optional
        ``backend="dask"`` only: a connected client, or a scheduler address to connect to
        (``"tcp://10.0.0.5:8786"``). Default: a local cluster started for this sweep.
    progress : True or callable, optional
        ``progress(done, total, case_index)`` after each case, or True for a text bar on
        stderr (drawn only when stderr is a terminal).
    out : path, optional
        A folder: ``cases.jsonl`` gets each case as it finishes; ``sweep.csv`` and
        ``sweep.json`` are written (atomically) at the end or on an interruption.
    units : dict, optional
        Unit of each output (``{"q": "m^3/s"}``), kept as metadata in the result and its files.
    resume : bool
        Keep the successful cases recorded in ``out/cases.jsonl`` (they must be the same cases,
        recorded by the same run) and run only the others.
    overwrite : bool
        Replace the record of an earlier sweep in ``out`` (without ``resume`` or
        ``overwrite`` a folder holding one is refused: nothing recorded is lost unasked).
    timeout : float, optional
        Wall-time limit of one case [s]; a case over it is recorded with status ``"timeout"``
        and the sweep goes on (how each backend stops it: see the module docstring).
    check : callable, optional
        ``check(case)`` raises (e.g. :class:`~pvgraph.ParameterError`) for invalid parameter
        values; it runs on every case before any case runs.

    Returns
    -------
    SweepResult
        Every case, failed ones included (status ``"failed"``, ``"timeout"`` or
        ``"nonfinite"``, error type, message and traceback); a failing case never stops the
        others.

    Raises
    ------
    SweepError
        ``run`` is not callable or cannot be pickled, ``cases`` is empty or its cases set
        different parameters, ``check`` refused cases, the backend, the worker count or the
        timeout is invalid, or ``resume`` finds a record of other cases or of another run
        (its function, outputs, t_end or tolerance differ: the record is left as it is).
    SweepInterrupted
        Ctrl-C; the finished cases are in its ``result`` and in ``out``.
    """
    if not callable(run):
        raise SweepError(f"run must be a callable run(**params) -> dict, got "
                         f"{type(run).__name__}")
    if backend not in BACKENDS:
        raise SweepError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    cases = _check_cases(cases)
    if client is not None and backend != "dask":
        raise SweepError(f"client= is only used by backend='dask' (backend is {backend!r})")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise SweepError(f"workers must be a positive integer, got {workers!r}")
    if timeout is not None:
        if not (isinstance(timeout, numbers.Real) and math.isfinite(timeout) and timeout > 0):
            raise SweepError(f"timeout must be a positive number of seconds, got {timeout!r}")
        if backend != "dask" and not hasattr(signal, "setitimer"):
            raise SweepError(f"timeout= needs SIGALRM for backend {backend!r} (not on this "
                             f"system); use backend='dask'")
    for flag, value in (("resume", resume), ("overwrite", overwrite)):
        if not isinstance(value, bool):
            raise SweepError(f"{flag} takes True or False, got {value!r}")
    if resume and out is None:
        raise SweepError("resume=True needs out= (the folder holding cases.jsonl)")
    if overwrite and out is None:
        raise SweepError("overwrite=True replaces the record in out=; give out= (a folder)")
    if out is not None:
        if isinstance(out, bytes) or not isinstance(out, (str, os.PathLike)):
            raise SweepError(f"out takes a folder path (str or pathlib.Path), got "
                             f"{type(out).__name__} {out!r}")
        if not os.fspath(out).strip():
            raise SweepError("out='' names no folder; give a folder path")
        if os.path.exists(out) and not os.path.isdir(out):
            raise SweepError(f"out={os.fspath(out)!r} is a file, not a folder; give a folder "
                             f"for the sweep's record")
    if resume and overwrite:
        raise SweepError("resume=True keeps the record in out=, overwrite=True replaces it: "
                         "give one of them")
    if out is not None and not resume and not overwrite and \
            os.path.exists(os.path.join(os.fspath(out), LOG_NAME)):
        raise SweepError(f"{os.path.join(os.fspath(out), LOG_NAME)} holds the record of an "
                         f"earlier sweep ({_recorded(os.path.join(os.fspath(out), LOG_NAME))}): "
                         f"resume it (resume=True), replace it (overwrite=True) or give "
                         f"another folder")
    if units is not None:
        if not isinstance(units, Mapping):
            raise SweepError(f"units must be a mapping {{output name: unit}}, e.g. "
                             f"{{'q': 'm^3/s'}}, got {units!r}")
        bad = {k: u for k, u in units.items() if not (isinstance(k, str) and isinstance(u, str))}
        if bad:
            raise SweepError(f"units: names and units are strings, got {bad!r}")
    param_names = list(cases[0])
    if isinstance(run, CompiledRun):
        labels = set(run.outputs)
        clash = sorted(labels & (set(param_names) | set(RESERVED_COLUMNS)))
        if clash:
            raise SweepError(f"output {clash[0]!r} has the name of a swept parameter or of a "
                             f"column every sweep writes ({', '.join(RESERVED_COLUMNS)}): the "
                             f"case's value is in its own column already; drop it from the "
                             f"outputs or give it another label (outputs={{'{clash[0]} out': "
                             f"'{run.outputs[clash[0]]}'}})")
        run.validate(cases[0])      # names wrong for every case: told before any case runs
        cases = run.in_si(cases)    # records are SI, as the files say
    records: dict[int, CaseResult] = {}
    log_path = None if out is None else os.path.join(os.fspath(out), LOG_NAME)
    identity = run_identity(run)
    if resume and os.path.exists(log_path):
        records = {i: r for i, r in _read_log(
            log_path, cases, run.in_si if isinstance(run, CompiledRun) else None).items()
            if r.ok}
        before = _recorded_identity(log_path)
        if records and before is not None and before != identity and \
                "CompiledRun of partial" in before:
            # an older pvgraph's record, whose run identity did not spell a compiled run's
            # factory: it cannot be compared, as it was not then (told, not refused)
            from ..errors import PlausibilityWarning
            _warnings.warn(PlausibilityWarning(
                f"resume: {log_path} was recorded by an older pvgraph, whose record does not "
                f"say which circuit and settings made it; its {len(records)} finished "
                f"case{'s' if len(records) != 1 else ''} are kept as this run's. Give "
                f"overwrite=True (--overwrite) to run every case again."), stacklevel=2)
            before = identity
        if records and before is not None and before != identity:
            # the kept cases would be shown as this run's (its t_end, outputs ...): refused
            # like a record of other cases, the record left as it is
            raise SweepError(
                f"resume: {log_path} was recorded by another run "
                f"({_identity_difference(before, identity)}); its {len(records)} finished "
                f"case{'s' if len(records) != 1 else ''} cannot be counted as this run's. "
                f"Use the same arguments as the recorded run, overwrite=True to run every "
                f"case again, or another output folder")
    todo = [i for i in range(len(cases)) if i not in records]
    if check is not None:
        _check_values(check, cases, todo)
    workers = workers if workers is not None else _default_workers(max(len(todo), 1))
    if backend == "process":
        workers = min(workers, max(len(todo), 1), MAX_PROCESS_WORKERS)
        _check_picklable(run, cases)
    tick = _progress_callback(progress, len(cases))
    if out is not None:
        try:
            os.makedirs(os.fspath(out), exist_ok=True)
        except OSError as exc:
            raise SweepError(f"out={os.fspath(out)!r}: the folder cannot be made "
                             f"({exc.strerror or exc})") from None
        if not os.access(os.fspath(out), os.W_OK | os.X_OK):
            raise SweepError(f"out={os.fspath(out)!r}: the folder is not writable")
    # the backend is started before the record is opened: a backend that cannot start
    # (dask missing, a scheduler out of reach) leaves no record that blocks the retry
    started = _start_dask(workers, client) if backend == "dask" and todo else None
    try:
        log = _open_log(log_path, cases, param_names, units, records, identity) \
            if log_path else None
    except BaseException:
        for obj in (started or (None, None, []))[2]:
            obj.close()
        raise
    done = len(records)

    def report(res: CaseResult) -> None:
        nonlocal done
        records[res.index] = res
        if log is not None:
            log.write(json.dumps(_log_record(res), allow_nan=False, default=str) + "\n")
            log.flush()
        done += 1
        if tick is not None:
            tick(done, len(cases), res.index)

    def result(wall):
        declared = getattr(run, "outputs", None) if getattr(run, "reduce", None) is None \
            else None
        res = SweepResult([records[i] for i in sorted(records)], param_names, backend=backend,
                          wall_time=wall, units=units, n_cases=len(cases),
                          output_names=list(declared) if isinstance(declared, Mapping) else ())
        _warn_unknown_units(res)
        _warn_again(res.records)
        if out is not None:
            res.save(out)
        return res

    t0 = time.perf_counter()
    try:
        if not todo:
            pass
        elif backend == "serial":
            _run_serial(run, todo, cases, report, timeout)
        elif backend == "process":
            _run_process(run, todo, cases, workers, report, timeout)
        else:
            _run_dask(run, todo, cases, started, report, timeout)
    except KeyboardInterrupt:
        if log is not None:
            log.close()
        raise SweepInterrupted(result(time.perf_counter() - t0)) from None
    except BaseException:
        if log is not None:
            log.close()
        raise
    if log is not None:
        log.close()
    return result(time.perf_counter() - t0)


def _warn_unknown_units(res: SweepResult) -> None:
    """Warn about ``units`` entries that name neither a parameter nor an output."""
    if not res.ok:
        return
    import warnings
    known = res.param_names + res.output_names
    for name in res.units:
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            warnings.warn(f"sweep: units names {name!r}, which is neither a parameter nor an "
                          f"output{hint} The columns are: {', '.join(known)}", UserWarning,
                          stacklevel=3)


def _check_values(check, cases, todo) -> None:
    bad = []
    for i in todo:
        try:
            check(dict(cases[i]))
        except PvgraphError as exc:
            bad.append(f"case {i} {cases[i]}: {exc}")
        except (ValueError, TypeError) as exc:
            bad.append(f"case {i} {cases[i]}: {type(exc).__name__}: {exc}")
    if bad:
        more = f"\n... and {len(bad) - 5} more" if len(bad) > 5 else ""
        raise SweepError(f"{len(bad)} of {len(todo)} cases have invalid parameter values; "
                         f"nothing was run:\n" + "\n".join(bad[:5]) + more)


def _log_record(r: CaseResult) -> dict:
    d = r.to_dict()
    if d["error"] is None:
        del d["error"]
    if not d["warnings"]:
        del d["warnings"]
    d["outputs"] = {k: (v if v is not None else repr(r.outputs[k])) for k, v in
                    d["outputs"].items()}
    return d


def _from_log(d: dict) -> CaseResult:
    err = d.get("error") or {}
    outs = {k: float(v) for k, v in d.get("outputs", {}).items()}   # "nan", "inf" included
    return CaseResult(int(d["index"]), dict(d["params"]), outs, d["status"],
                      float(d.get("wall_time") or 0.0), err.get("type"), err.get("message"),
                      err.get("traceback"), list(d.get("warnings") or []))


def _recorded(path) -> str:
    """``"12 cases, 5 finished"``: what the sweep record at ``path`` holds, for messages."""
    try:
        with open(path) as f:
            lines = f.read().splitlines()
        n = json.loads(lines[0]).get("n_cases")
        return f"{n} case{'s' if n != 1 else ''}, {len(lines) - 1} finished"
    except (OSError, IndexError, ValueError, AttributeError):
        return "unreadable"


def run_identity(run) -> str:
    """What a sweep's record says made it: ``run.sweep_identity()`` where the run has one
    (:class:`CompiledRun`: its circuit's model text, outputs and settings, hashed), else the
    function's module and name (with a partial's arguments)."""
    own = getattr(run, "sweep_identity", None)
    if callable(own):
        return str(own())
    if isinstance(run, functools.partial):
        args = [_identity_of(a) for a in run.args]
        args += [f"{k}={_identity_of(v)}" for k, v in sorted(run.keywords.items())]
        return f"{run_identity(run.func)} with ({', '.join(args)})"
    name = getattr(run, "__qualname__", type(run).__name__)
    return f"{getattr(run, '__module__', '?')}.{name}"


def _identity_of(value) -> str:
    """An argument of a partial in a run identity: what it says of itself, a function by its
    name, else its repr without a memory address (the same object in another process)."""
    if callable(getattr(value, "sweep_identity", None)) or callable(value):
        return run_identity(value)
    return re.sub(r" at 0x[0-9a-fA-F]+", "", repr(value))


def _identity_difference(before: str, now: str) -> str:
    """``"recorded: t_end 10.0; now: t_end 0.1"``: the items of two run identities that
    differ (items: the parts between ", " outside brackets, so that a list of outputs is one
    item)."""
    def items(text):
        out, depth, start = [], 0, 0
        for k, ch in enumerate(text):
            depth += ch in "([{"
            depth -= ch in ")]}"
            if depth == 0 and text.startswith(", ", k):
                out.append(text[start:k])
                start = k + 2
        return out + [text[start:]]
    a, b = items(before), items(now)
    if len(a) != len(b):
        return f"recorded: {before}; now: {now}"
    differ = [k for k, (x, y) in enumerate(zip(a, b)) if x != y]
    if len(differ) == 1:    # one item: inside its brackets where both open them alike
        x, y = a[differ[0]], b[differ[0]]
        head = x.find("(")
        if head >= 0 and x[:head + 1] == y[:head + 1] and x.endswith(")") and \
                y.endswith(")"):
            return _identity_difference(x[head + 1:-1], y[head + 1:-1])
    return (f"recorded: {', '.join(a[k] for k in differ)}; "
            f"now: {', '.join(b[k] for k in differ)}")


def _recorded_identity(path):
    """The run identity in the header of a record, or None (an older record)."""
    try:
        with open(path) as f:
            return json.loads(f.readline()).get("run")
    except (OSError, ValueError, AttributeError):
        return None


def _open_log(path, cases, param_names, units, kept, identity=None):
    """Start ``cases.jsonl`` afresh (header, then the kept records) and return it for appending."""
    folder = os.path.dirname(path)
    os.makedirs(folder, exist_ok=True)
    tmp = path + ".new"
    with open(tmp, "w") as f:
        f.write(json.dumps({"pvgraph_sweep": LOG_VERSION, "n_cases": len(cases),
                            "param_names": param_names, "units": dict(units or {}),
                            "run": identity,
                            "cases": [{k: _json_value(v) for k, v in c.items()}
                                      for c in cases]}, default=str) + "\n")
        for i in sorted(kept):
            f.write(json.dumps(_log_record(kept[i]), default=str) + "\n")
    os.replace(tmp, path)
    return open(path, "a")


def _read_log(path, cases, in_si=None) -> dict[int, CaseResult]:
    """The records of ``cases.jsonl``, checked to belong to the same ``cases`` (``in_si``:
    how quantities of the cases become SI numbers, for a record written before the records
    were SI)."""
    with open(path) as f:
        lines = f.read().splitlines()
    try:
        head = json.loads(lines[0])
    except (IndexError, ValueError):
        raise SweepError(f"{path} is not a sweep record (no header line); remove it or use "
                         f"another output folder") from None
    same = json.loads(json.dumps([{k: _json_value(v) for k, v in c.items()} for c in cases],
                                 default=str))
    recorded = head.get("cases") or []
    if in_si is not None and head.get("n_cases") == len(cases) and same != recorded:
        try:
            recorded = json.loads(json.dumps(
                [{k: _json_value(v) for k, v in c.items()} for c in in_si(recorded)],
                default=str))
        except Exception:       # noqa: BLE001  (a record that is not cases: told below)
            recorded = head.get("cases") or []
    if head.get("n_cases") != len(cases) or same != recorded:
        first = next((k for k, (a, b) in enumerate(zip(recorded, same)) if a != b), None)
        detail = (f"; case {first} was {recorded[first]}, now {same[first]}"
                  if first is not None else "")
        n_rec = head.get("n_cases")
        raise SweepError(f"resume: {path} records another sweep ({n_rec} "
                         f"case{'' if n_rec == 1 else 's'} of {head.get('param_names')}); these "
                         f"are {len(cases)} case{'' if len(cases) == 1 else 's'} of "
                         f"{list(cases[0])}{detail}. Use the same arguments, or a new output "
                         f"folder")
    out = {}
    for k, line in enumerate(lines[1:], start=2):
        try:
            r = _from_log(json.loads(line))
        except (ValueError, KeyError, TypeError):
            if k == len(lines):      # a last line cut short by a crash: that case reruns
                continue
            raise SweepError(f"{path} line {k} is not a case record; remove the file or use "
                             f"another output folder") from None
        out[r.index] = r
    return out


# --------------------------------------------------------------------------------------------
#: compiled systems of this process, per CompiledRun key: {"base": System or None,
#: "structures": {key: System}, "compilations": int}
_COMPILED: dict[str, dict] = {}
#: CompiledRun keys whose compiled systems are kept in a process (the oldest is dropped)
MAX_CACHED_RUNS = 8


class CompiledRun:
    """``run(**case)`` for :func:`sweep` that compiles its circuit once per process.

    Parameters
    ----------
    circuit : Circuit or callable, optional
        The circuit, or a callable returning it (a module-level function or a
        :func:`functools.partial` of one, for the process backend). Case names are its
        parameter names, ``"component.field"`` (``"orifice.A"``).
    build : callable, optional
        Instead of ``circuit``: ``build(**case) -> Circuit``, for case names that are builder
        arguments. Each case builds its circuit and runs on the compiled system of the same
        structure with the circuit's runtime parameter values.
    outputs : sequence of str or dict
        Variable names whose values are returned (final values of a simulation, or values at
        the steady state); a dict maps output labels to variable names.
    t_end : float, optional
        Simulate from 0 to ``t_end`` [s] at ``rtol``.
    steady : bool
        Solve the steady state at tolerance ``tol`` instead of simulating.
    reduce : callable, optional
        ``reduce(solution_or_operating_point, case) -> dict`` replaces the default outputs.
    warm : bool
        Steady states start from the last steady state this process solved on a system of the
        same size (neighbouring cases of a sweep converge in a few Newton steps); the result
        then agrees with a cold start to within ``tol``. Default: from the system's start
        values, as a rebuilt case does.
    key : str, optional
        Names the compiled systems in each process's cache; two runs with the same key share
        them. Default: unique to this object (and its pickled copies).

    The compiled systems live in a per-process cache, so a process pool compiles once per
    worker; :meth:`compilations` counts the compilations of this process.
    """

    def __init__(self, circuit=None, *, build: Callable | None = None,
                 outputs: Sequence[str] | Mapping[str, str] = (), t_end: float | None = None,
                 steady: bool = False, rtol: float = 1e-6, tol: float = 1e-10,
                 reduce: Callable | None = None, warm: bool = False, key: str | None = None):
        import uuid
        if circuit is None and build is None:
            raise SweepError("CompiledRun needs a circuit (case names are its parameters) or "
                             "build= (case names are the builder's arguments); neither was "
                             "given")
        if circuit is not None and build is not None:
            raise SweepError("CompiledRun takes a circuit (case names are its parameters) or "
                             "build= (case names are the builder's arguments), not both")
        if build is not None and not callable(build):
            raise SweepError(f"build must be callable, got {type(build).__name__}")
        if steady and t_end is not None:
            raise SweepError("CompiledRun takes t_end= (simulate) or steady=True (steady "
                             "states), not both")
        if not steady and t_end is None:
            raise SweepError("CompiledRun needs either t_end= (simulate) or steady=True")
        if t_end is not None and not (isinstance(t_end, numbers.Real) and t_end > 0):
            raise SweepError(f"t_end must be a positive time [s], got {t_end!r}")
        for what, value in (("rtol", rtol), ("tol", tol)):
            if isinstance(value, bool) or not isinstance(value, numbers.Real) or \
                    not (math.isfinite(value) and 0 < value < 1):
                raise SweepError(f"CompiledRun: {what} must be a number between 0 and 1, e.g. "
                                 f"1e-6, got {value!r}")
        if isinstance(outputs, Mapping):
            outputs = dict(outputs)
        else:
            from ..simulate import _name_list
            outputs = {n: n for n in _name_list(outputs, "CompiledRun: outputs")}
        bad = {k: v for k, v in outputs.items() if not (isinstance(k, str) and isinstance(v, str))}
        if bad:
            raise SweepError(f"CompiledRun: outputs map labels to variable names (strings), "
                             f"got {bad!r}")
        if not outputs and reduce is None:
            raise SweepError("CompiledRun needs outputs= (variable names) or reduce=")
        self.circuit, self.build, self.outputs = circuit, build, outputs
        self.t_end, self.steady, self.rtol, self.tol = t_end, bool(steady), rtol, tol
        self.reduce, self.warm = reduce, bool(warm)
        self.key = key or uuid.uuid4().hex

    def sweep_identity(self) -> str:
        """What made a sweep's record (:func:`run_identity`): the circuit (its model-file
        text hashed, or its builder's name), the outputs and the run's settings."""
        import hashlib
        source = self.circuit if self.circuit is not None else self.build
        what = getattr(source, "__qualname__", None)
        if what is None and isinstance(source, functools.partial):
            what = run_identity(source)     # a factory with its arguments (a CLI target)
        if what is None:
            try:
                from ..modelfile import dumps
                text = dumps(source, "toml")
                what = f"{source.name} #{hashlib.sha256(text.encode()).hexdigest()[:12]}"
            except Exception:   # noqa: BLE001  (a part outside the library: its name only)
                what = getattr(source, "name", type(source).__name__)
        how = f"t_end {self.t_end!r}, rtol {self.rtol!r}" if not self.steady else \
            f"steady, tol {self.tol!r}"
        return f"CompiledRun of {what}, outputs {sorted(self.outputs)}, {how}"

    # the per-process cache ------------------------------------------------------------------
    def _cache(self) -> dict:
        entry = _COMPILED.get(self.key)
        if entry is None:
            while len(_COMPILED) >= MAX_CACHED_RUNS:
                del _COMPILED[next(iter(_COMPILED))]
            entry = _COMPILED[self.key] = {"base": None, "structures": {}, "compilations": 0,
                                           "warm": {}}
        return entry

    def prepare(self) -> None:
        """Compile the circuit in this process now, before the first case (a Dask worker
        warming up, so that a per-case time limit counts only the cases' own work)."""
        from .. import solver  # noqa: F401  (what a case imports on its first run)
        from ..simulate import simulate  # noqa: F401
        entry = self._cache()
        if self.circuit is not None and entry["base"] is None:
            entry["base"] = self._circuit().compile()
            entry["compilations"] += 1

    def validate(self, case: Mapping[str, Any]) -> None:
        """Raise :class:`SweepError` for case names the circuit (or the build) does not take
        and outputs it does not know, from ``case`` (one case: the names are the same for
        all). Values are not judged here: a value refused (by a component or the build) fails
        its case only. Compiles in this process (its cache keeps the system for a serial
        sweep)."""
        if self.build is not None:
            import inspect
            try:
                inspect.signature(self.build).bind(**case)
            except TypeError as exc:       # an argument the build does not take
                raise SweepError(f"CompiledRun: the case names {sorted(case)} do not fit "
                                 f"the build: {exc}") from None
            except ValueError:             # no signature to read: the cases will tell
                pass
            try:
                system = self.system(case)
            except Exception:              # noqa: BLE001 (this case's values: it fails alone)
                return
        else:
            self.prepare()
            system = self._cache()["base"]
            valid = self._circuit().parameters()    # every component field, structural too
            unknown = [k for k in case if k not in valid]
            if unknown:
                close = difflib.get_close_matches(unknown[0], list(valid), n=3, cutoff=0.6)
                raise SweepError(
                    f"CompiledRun: {system.name}: no parameter named {unknown[0]!r}"
                    + (f". Close matches: {close}" if close else "")
                    + ". Case names are the circuit's parameters, <component path>.<field>")
        if self.reduce is not None:
            return
        for label, name in self.outputs.items():
            try:
                system.resolve_name(name)
            except (KeyError, PvgraphError) as exc:
                text = exc.args[0] if exc.args else str(exc)
                raise SweepError(f"CompiledRun: output {label!r}: {text}") from None

    def in_si(self, cases: list[dict]) -> list[dict]:
        """``cases`` with each quantity (``"1 mm^2"``) of a circuit parameter declaring a unit
        as its SI number, so that the records hold one kind of value per column; other values
        (numbers, choices, builder arguments) as given, and a quantity that does not convert
        as given (its case then fails with the parameter's own message)."""
        from ..units import declared_unit, is_quantity, to_unit
        if self.circuit is None or not any(isinstance(v, str) and is_quantity(v)
                                           for c in cases for v in c.values()):
            return cases
        valid = self._circuit().parameters()
        out = []
        for case in cases:
            case = dict(case)
            for name, value in case.items():
                if not (isinstance(value, str) and name in valid) or \
                        isinstance(valid[name][0], str):
                    continue
                unit = declared_unit(valid[name][1])
                if unit:
                    try:
                        case[name] = float(to_unit(value, unit, name))
                    except PvgraphError:
                        pass
            out.append(case)
        return out

    def compilations(self) -> int:
        """Compilations this object (or its key) caused in this process."""
        return _COMPILED.get(self.key, {}).get("compilations", 0)

    def _circuit(self):
        from ..circuit import Circuit
        c = self.circuit
        if not isinstance(c, Circuit):
            c = c()
            if not isinstance(c, Circuit):
                raise SweepError(f"CompiledRun: the circuit factory returned "
                                 f"{type(c).__name__}, not a Circuit")
        return c

    def system(self, case: Mapping[str, Any]):
        """The compiled system carrying the values of ``case`` (compiled only if needed)."""
        import warnings

        from ..system import RecompileWarning
        entry = self._cache()
        if self.build is not None:
            circuit = self.build(**case)
            for compiled in entry["structures"].values():
                try:
                    values = compiled.params_from(circuit)
                except ParameterError:
                    continue
                return compiled.with_params(values)
            if entry["structures"]:
                warnings.warn(RecompileWarning(
                    f"{circuit.name}: compiling again, the case {dict(case)} builds another "
                    f"structure"), stacklevel=2)
            compiled = circuit.compile()
            entry["compilations"] += 1
            entry["structures"][len(entry["structures"])] = compiled
            return compiled
        if entry["base"] is None:
            entry["base"] = self._circuit().compile()
            entry["compilations"] += 1
        base = entry["base"]
        runtime = {k: v for k, v in case.items()
                   if k in base.parameters and not base.parameters[k].structural}
        fixed = {k: v for k, v in case.items() if k not in runtime and not (
            k in base.parameters and _same(base.parameters[k].value, v))}
        if not fixed:
            return base.with_params(runtime)
        skey = tuple(sorted((k, repr(v)) for k, v in fixed.items()))
        compiled = entry["structures"].get(skey)
        if compiled is None:
            compiled = base.with_params(fixed)        # compiles, with a RecompileWarning
            entry["compilations"] += 1
            entry["structures"][skey] = compiled
        return compiled.with_params(runtime)

    def __call__(self, **case) -> dict:
        from ..simulate import simulate
        from .steady import steady_state
        system = self.system(case)
        if self.steady:
            starts = self._cache()["warm"]
            res = steady_state(system, tol=self.tol,
                               y0=starts.get(system.n) if self.warm else None)
            if self.warm:
                starts[system.n] = res.y
            value = res.__getitem__
        else:
            res = simulate(system, self.t_end, rtol=self.rtol)
            value = res.final
        if self.reduce is not None:
            return self.reduce(res, dict(case))
        return {label: value(name) for label, name in self.outputs.items()}


def _same(a, b) -> bool:
    """A structural value equal to the compiled one needs no compilation."""
    try:
        return bool(np.all(np.asarray(a) == np.asarray(b))) and np.shape(a) == np.shape(b)
    except (TypeError, ValueError):
        return False


def sweep_system(circuit, cases: Iterable[Mapping[str, Any]], *,
                 outputs: Sequence[str] | Mapping[str, str] = (), t_end: float | None = None,
                 steady: bool = False, rtol: float = 1e-6, tol: float = 1e-10,
                 build: Callable | None = None, reduce: Callable | None = None,
                 warm: bool = False, **options) -> SweepResult:
    """:func:`sweep` of a :class:`CompiledRun`: the circuit compiled once per process.

    ``sweep_system(bench, grid({"orifice.A": [...], "pump.Q": [...]}), outputs=["node.port.p"],
    steady=True)``; ``options`` go to :func:`sweep` (backend, workers, out, progress, ...).
    """
    run = CompiledRun(circuit, build=build, outputs=outputs, t_end=t_end, steady=steady,
                      rtol=rtol, tol=tol, reduce=reduce, warm=warm)
    return sweep(run, cases, **options)


# --------------------------------------------------------------------------------------------
def _plain(v):
    return v.item() if isinstance(v, np.generic) else v


def grid(values: Mapping[str, Iterable]) -> list[dict]:
    """The cartesian product of value lists, the last name varying fastest.

    ``grid({"A": [1e-6, 2e-6], "dp": [1e5, 2e5]})`` gives 4 cases:
    ``{"A": 1e-6, "dp": 1e5}, {"A": 1e-6, "dp": 2e5}, {"A": 2e-6, "dp": 1e5}, ...``.
    """
    if not isinstance(values, Mapping) or not values:
        raise SweepError("grid() takes a non-empty dict of parameter name -> list of values")
    axes = {}
    for name, vals in values.items():
        if isinstance(vals, (str, bytes)) or not isinstance(vals, Iterable):
            raise SweepError(f"grid: the values of {name!r} must be a list (got "
                             f"{type(vals).__name__} {vals!r}); write [{vals!r}] for one value")
        vals = [_case_value("grid", name, _plain(v)) for v in vals]
        if not vals:
            raise SweepError(f"grid: parameter {name!r} has no values")
        axes[name] = vals
    names = list(axes)
    return [dict(zip(names, combo)) for combo in itertools.product(*axes.values())]


def _case_value(where, name, v):
    """``v`` if it is a usable case value: a finite number, a string or another scalar."""
    if isinstance(v, numbers.Real) and not math.isfinite(v):
        raise SweepError(f"{where}: {name!r} has the value {v!r}; case values must be finite")
    if isinstance(v, (list, tuple, dict, set, frozenset, np.ndarray)):
        raise SweepError(f"{where}: {name!r} has the value {v!r}; each case value must be a "
                         f"single number or string, not a {type(v).__name__}")
    return v


def _range_spec(name, spec):
    """``(kind, lo, hi)`` with kind "linear" or "log", or None for a constant."""
    if not isinstance(spec, (tuple, list)):
        return None
    if len(spec) == 3 and spec[0] == "log":
        kind, lo, hi = "log", spec[1], spec[2]
    elif len(spec) == 2:
        kind, lo, hi = "linear", spec[0], spec[1]
    else:
        raise SweepError(f"random_sample: {name!r} must be (lo, hi), ('log', lo, hi) or a "
                         f"constant, got {spec!r}")
    if any(isinstance(v, str) for v in (lo, hi)):
        raise SweepError(f"random_sample: the range of {name!r} takes numbers (SI), got "
                         f"{spec!r}; convert quantities first, e.g. "
                         f"pvgraph.units.to_si('2 mm^2')")
    if not all(isinstance(v, numbers.Real) and math.isfinite(v) for v in (lo, hi)) or \
            not lo < hi:
        raise SweepError(f"random_sample: the range of {name!r} needs finite lo < hi, got "
                         f"{spec!r}")
    if kind == "log" and lo <= 0:
        raise SweepError(f"random_sample: the log range of {name!r} needs lo > 0, got {spec!r}")
    return kind, float(lo), float(hi)


def _latin_hypercube(d: int, n: int, rng: np.random.Generator) -> np.ndarray:
    from scipy.stats import qmc
    try:
        sampler = qmc.LatinHypercube(d, rng=rng)
    except TypeError:  # scipy < 1.15 names the generator "seed"
        sampler = qmc.LatinHypercube(d, seed=rng)
    return sampler.random(n)


def random_sample(ranges: Mapping[str, Any], n: int, *, seed=None,
                  method: str = "lhs") -> list[dict]:
    """``n`` random cases from parameter ranges.

    Parameters
    ----------
    ranges : dict
        Per parameter: ``(lo, hi)`` uniform in [lo, hi]; ``("log", lo, hi)`` log-uniform
        (uniform in log(value), lo > 0); anything else (a number, a string) a constant
        given to every case.
    n : int
        Number of cases.
    seed : int or numpy Generator, optional
        Same seed, same cases.
    method : {"lhs", "uniform"}
        ``"lhs"``: Latin hypercube (:class:`scipy.stats.qmc.LatinHypercube`): split each range
        into ``n`` equal bins (equal in log for log ranges) and every bin holds exactly one
        case. ``"uniform"``: independent uniform draws.
    """
    if not isinstance(ranges, Mapping) or not ranges:
        raise SweepError("random_sample() takes a non-empty dict of parameter name -> range")
    if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 1:
        raise SweepError(f"random_sample: n must be a positive integer, got {n!r}")
    if method not in SAMPLING_METHODS:
        raise SweepError(f"random_sample: unknown method {method!r}; choose one of "
                         f"{', '.join(SAMPLING_METHODS)}")
    specs = {name: _range_spec(name, spec) for name, spec in ranges.items()}
    for name, spec in ranges.items():
        if specs[name] is None:
            _case_value("random_sample", name, _plain(spec))
    ranged = [name for name, s in specs.items() if s is not None]
    if not (seed is None or isinstance(seed, (np.random.Generator, np.random.SeedSequence))
            or (isinstance(seed, numbers.Integral) and not isinstance(seed, bool)
                and seed >= 0)):
        raise SweepError(f"random_sample: seed must be a non-negative integer or a numpy "
                         f"Generator, got {seed!r}")
    rng = np.random.default_rng(seed)
    if not ranged:
        u = np.zeros((int(n), 0))
    elif method == "lhs":
        u = _latin_hypercube(len(ranged), int(n), rng)
    else:
        u = rng.random((int(n), len(ranged)))
    columns = {}
    for k, name in enumerate(ranged):
        kind, lo, hi = specs[name]
        if kind == "log":
            x = np.exp(math.log(lo) + u[:, k] * (math.log(hi) - math.log(lo)))
        else:
            x = lo + u[:, k] * (hi - lo)
        columns[name] = np.clip(x, lo, hi)
    return [{name: (float(columns[name][i]) if specs[name] is not None else _plain(spec))
             for name, spec in ranges.items()} for i in range(int(n))]
