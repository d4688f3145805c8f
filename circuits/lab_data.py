"""Loaders for the PVG 32 rig measurements (report appendix B.7, used in section 4.7).

The CSV files live in the package ``pvgraph.circuits.data`` and are read with ``importlib.resources``
(provenance, column meanings and accuracies: ``circuits/data/README.md``). Each loader returns a
list of frozen records in SI units (Pa, m^3/s, V) that also keep the values exactly as written in
the file (``*_bar``, ``*_lpm`` fields), so a result can always be traced back to the report table.

Errors: a missing file, a missing or extra column, a non-numeric or out-of-range value or an
unknown category raises :class:`LabDataError`, naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from importlib import resources
from os import PathLike
from pathlib import Path
from typing import Callable

from pvgraph.errors import PvgraphError
from pvgraph.units import bar, lpm

__all__ = [
    "LabDataError",
    "SolenoidStepRecord",
    "VoltageSweepRecord",
    "load_solenoid_steps",
    "load_voltage_sweep",
    "SOLENOID_STEPS_FILE",
    "VOLTAGE_SWEEP_FILE",
    "PRESSURE_ACCURACY",
    "FLOW_ACCURACY",
]

DATA_PACKAGE = "pvgraph.circuits.data"
SOLENOID_STEPS_FILE = "rig_solenoid_steps.csv"
VOLTAGE_SWEEP_FILE = "rig_voltage_sweep.csv"

# Measurement accuracy the report assumes for the rig (appendix B.7, section 4.7.2).
PRESSURE_ACCURACY = bar(1.0)
FLOW_ACCURACY = lpm(1.0)

ORIFICE_SIZES = ("small", "large")
SOLENOID_EVENTS = ("closed_steady", "opening", "closing")

_STEP_COLUMNS = (
    "test", "orifice_L1", "orifice_L3", "solenoid_event", "Q_total_lpm", "Q_branch_lpm",
    "U_input_V", "Pf_bar", "Pm_bar", "Pb_bar",
)
_SWEEP_COLUMNS = ("test", "Pf_bar", "Pm_bar", "Pb_bar", "Q_total_lpm", "U_input_V")


class LabDataError(PvgraphError):
    """A lab data file is missing or malformed (the message names the file, line and column)."""


@dataclass(frozen=True)
class SolenoidStepRecord:
    """One steady state of the solenoid-step tests (report B.7, first table).

    SI fields: ``Q_total``, ``Q_branch`` [m^3/s], ``U_input`` [V], ``Pf``, ``Pm``, ``Pb`` [Pa gauge].
    The ``*_lpm`` / ``*_bar`` fields are the values as transcribed from the report.
    ``Q_total`` is the total flow into the load (Qv), ``Q_branch`` the flow through L2 -> L1.
    """

    test: int
    orifice_L1: str
    orifice_L3: str
    solenoid_event: str
    Q_total: float
    Q_branch: float
    U_input: float
    Pf: float
    Pm: float
    Pb: float
    Q_total_lpm: float
    Q_branch_lpm: float
    Pf_bar: float
    Pm_bar: float
    Pb_bar: float

    @property
    def solenoid_open_after(self) -> bool:
        """True if L2 is open in the tabulated (final) steady state."""
        return self.solenoid_event == "opening"


@dataclass(frozen=True)
class VoltageSweepRecord:
    """One steady state of the voltage sweep with L2 closed (report B.7, second table).

    SI fields: ``Q_total`` [m^3/s], ``U_input`` [V], ``Pf``, ``Pm``, ``Pb`` [Pa gauge];
    ``*_lpm`` / ``*_bar`` fields are the values as transcribed from the report.
    """

    test: int
    Q_total: float
    U_input: float
    Pf: float
    Pm: float
    Pb: float
    Q_total_lpm: float
    Pf_bar: float
    Pm_bar: float
    Pb_bar: float


def _read_text(filename: str, path: str | PathLike | None) -> tuple[str, str]:
    """Return (text, label) of a packaged data file, or of ``path`` if given."""
    if path is not None:
        p = Path(path)
        try:
            return p.read_text(encoding="utf-8"), str(p)
        except FileNotFoundError:
            raise LabDataError(f"lab data file {p} not found") from None
    label = f"{DATA_PACKAGE}/{filename}"
    try:
        resource = resources.files(DATA_PACKAGE).joinpath(filename)
        return resource.read_text(encoding="utf-8"), label
    except (FileNotFoundError, ModuleNotFoundError):
        raise LabDataError(
            f"lab data file {label} not found: it should be installed with the 'circuits' package "
            f"(copy it from the report's appendix B.7 transcription, see circuits/data/README.md)"
        ) from None


def _rows(text: str, label: str, columns: tuple[str, ...]) -> list[tuple[int, dict[str, str]]]:
    reader = csv.DictReader(io.StringIO(text))
    header = tuple(h.strip() for h in (reader.fieldnames or ()))
    if header != columns:
        missing = [c for c in columns if c not in header]
        extra = [c for c in header if c not in columns]
        raise LabDataError(
            f"{label}: unexpected header {list(header)}; expected {list(columns)}"
            + (f"; missing {missing}" if missing else "")
            + (f"; unexpected {extra}" if extra else "")
        )
    rows = []
    for row in reader:
        line = reader.line_num
        if all((v is None or not v.strip()) for v in row.values()):
            continue
        if None in row or any(v is None for v in row.values()):
            raise LabDataError(f"{label}, line {line}: expected {len(columns)} fields")
        rows.append((line, {k.strip(): v.strip() for k, v in row.items()}))
    if not rows:
        raise LabDataError(f"{label}: no data rows")
    return rows


def _number(label: str, line: int, row: dict[str, str], column: str, *, lo: float = -math.inf,
            integer: bool = False) -> float:
    text = row[column]
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        raise LabDataError(f"{label}, line {line}, column {column!r}: {text!r} is not a number") from None
    if not math.isfinite(value) or value < lo:
        raise LabDataError(f"{label}, line {line}, column {column!r}: {text!r} is out of range (>= {lo})")
    return value


def _choice(label: str, line: int, row: dict[str, str], column: str, allowed: tuple[str, ...]) -> str:
    value = row[column]
    if value not in allowed:
        raise LabDataError(
            f"{label}, line {line}, column {column!r}: {value!r} is not one of {list(allowed)}")
    return value


def _check_unique_tests(label: str, records: list) -> None:
    numbers = [r.test for r in records]
    if len(set(numbers)) != len(numbers):
        raise LabDataError(f"{label}: duplicate test numbers in {numbers}")


def load_solenoid_steps(path: str | PathLike | None = None) -> list[SolenoidStepRecord]:
    """Load the 12 solenoid-step steady states (report B.7, first table) in SI units.

    Parameters
    ----------
    path : path-like, optional
        Read this CSV instead of the packaged ``circuits/data/rig_solenoid_steps.csv``
        (same columns).

    Returns
    -------
    list of SolenoidStepRecord, in file order.
    """
    text, label = _read_text(SOLENOID_STEPS_FILE, path)
    records = []
    for line, row in _rows(text, label, _STEP_COLUMNS):
        num: Callable[..., float] = lambda col, **kw: _number(label, line, row, col, **kw)  # noqa: E731
        q_total, q_branch = num("Q_total_lpm", lo=0.0), num("Q_branch_lpm", lo=0.0)
        pf, pm, pb = num("Pf_bar"), num("Pm_bar"), num("Pb_bar")
        records.append(SolenoidStepRecord(
            test=int(num("test", lo=1, integer=True)),
            orifice_L1=_choice(label, line, row, "orifice_L1", ORIFICE_SIZES),
            orifice_L3=_choice(label, line, row, "orifice_L3", ORIFICE_SIZES),
            solenoid_event=_choice(label, line, row, "solenoid_event", SOLENOID_EVENTS),
            Q_total=lpm(q_total), Q_branch=lpm(q_branch), U_input=num("U_input_V", lo=0.0),
            Pf=bar(pf), Pm=bar(pm), Pb=bar(pb),
            Q_total_lpm=q_total, Q_branch_lpm=q_branch, Pf_bar=pf, Pm_bar=pm, Pb_bar=pb,
        ))
    _check_unique_tests(label, records)
    return records


def load_voltage_sweep(path: str | PathLike | None = None) -> list[VoltageSweepRecord]:
    """Load the 7 voltage-sweep steady states with L2 closed (report B.7, second table), SI units.

    Parameters
    ----------
    path : path-like, optional
        Read this CSV instead of the packaged ``circuits/data/rig_voltage_sweep.csv``.

    Returns
    -------
    list of VoltageSweepRecord, in file order.
    """
    text, label = _read_text(VOLTAGE_SWEEP_FILE, path)
    records = []
    for line, row in _rows(text, label, _SWEEP_COLUMNS):
        num: Callable[..., float] = lambda col, **kw: _number(label, line, row, col, **kw)  # noqa: E731
        q_total = num("Q_total_lpm", lo=0.0)
        pf, pm, pb = num("Pf_bar"), num("Pm_bar"), num("Pb_bar")
        records.append(VoltageSweepRecord(
            test=int(num("test", lo=1, integer=True)),
            Q_total=lpm(q_total), U_input=num("U_input_V", lo=0.0),
            Pf=bar(pf), Pm=bar(pm), Pb=bar(pb),
            Q_total_lpm=q_total, Pf_bar=pf, Pm_bar=pm, Pb_bar=pb,
        ))
    _check_unique_tests(label, records)
    return records
