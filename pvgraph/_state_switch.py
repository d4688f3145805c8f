"""Changing the states of a constrained mechanism during a run (dynamic state selection).

Index reduction (:mod:`pvgraph.index_reduction`) chooses, among the variables a rigid
constraint ties together, those that stay states, where the constraint's Jacobian is best
conditioned at the start, and watches the determinant of each pivot block. Where it falls
below ``PIVOT_RATIO`` of its start value (a Cartesian pendulum whose state ``y`` no longer
determines ``x`` as it passes through the bottom), :func:`pvgraph.simulate` stops the step
there, compiles the circuit again with the states chosen at the values of that instant, carries
every variable over by name and goes on (as Modelica tools change the states of a mechanism
during a run; Mattsson and Soederlind's dummy derivatives with the pivoting redone). The
segments are returned as one :class:`~pvgraph.simulate.Solution` of the system the run started
with: its unknowns' values and derivatives in that system's layout.

Each switch compiles the circuit again: the pivot watch of the new choice is relative to its
determinant at the switch (a mechanism compiles in milliseconds; a pendulum swinging through
the bottom and past the horizontal switches four times a period).
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np

from .errors import SolverError, StructureError
from .index_reduction import EVENT_OWNER, SWITCH_RATIO, derivative_name

#: switches in one run before it stops (a choice flipping back and forth without progress)
MAX_SWITCHES = 1000

_DER = re.compile(r"^der\((.+?)(?:, (\d+))?\)$")


def watch_names(events) -> set:
    """The names of the pivot watches of index reduction among the solver ``events``: those
    at ``SWITCH_RATIO`` (``switch_k``) and at ``PIVOT_RATIO`` (``pivot_k``)."""
    return {ev.name for ev in events if ev.name.startswith(EVENT_OWNER + ".")}


def for_run(events, switching, dropped=()):
    """The solver ``events`` of a run. Where it switches states: the watches terminal, without
    action (the run stops at their zero and returns what it has), ``dropped`` left out (a
    ``switch_k`` watch whose block kept its states there); where it does not, the
    ``switch_k`` watches left out (a ``pivot_k`` watch ends the run with its error)."""
    if not switching:
        return [ev for ev in events if not ev.name.startswith(EVENT_OWNER + ".switch_")]
    names = watch_names(events)
    return [dataclasses.replace(ev, terminal=True, action=None) if ev.name in names else ev
            for ev in events if ev.name not in dropped]


def fired(res, names):
    """The record of the pivot watch (among ``names``) that ended the run ``res``, or None."""
    if not names or not res.events:
        return None
    t_last = res.events[-1].t
    for rec in reversed(res.events):
        if rec.t != t_last:
            break
        if rec.name in names and f"({rec.name!r})" in (res.message or ""):
            return rec
    return None


def _order(name):
    """``(base, order)`` of a derivative's name (``der(x, 2)`` -> ``("x", 2)``, ``x`` -> 0),
    the inverse of :func:`pvgraph.index_reduction.derivative_name`."""
    m = _DER.match(name)
    return (name, 0) if m is None else (m.group(1), int(m.group(2) or 1))


def _lower(name):
    """The variable whose time derivative ``name`` is (``der(x, 2)`` -> ``der(x)``), or None."""
    base, order = _order(name)
    return derivative_name(base, order - 1) if order else None


def _higher(name):
    """The name of the time derivative of ``name`` (``x`` -> ``der(x)`` -> ``der(x, 2)``)."""
    base, order = _order(name)
    return derivative_name(base, order + 1)


def _column(system, name, Y, YP):
    """Values of ``name`` over the rows of ``Y`` (unknowns of ``system``), or None."""
    try:
        coef, idx, off = system.resolve(name)
    except KeyError:
        lower = _lower(name)
        if lower is None:
            return None
        try:
            coef, idx, off = system.resolve(lower)
        except KeyError:
            return None
        return np.zeros(len(Y)) if idx is None else coef * YP[:, idx]
    return np.full(len(Y), off) if idx is None else coef * Y[:, idx] + off


def _derivative(system, name, Y, YP):
    """Time derivatives of ``name`` over the rows, where ``system`` holds them, or None."""
    try:
        coef, idx, _ = system.resolve(name)
    except KeyError:
        return None
    return np.zeros(len(Y)) if idx is None else coef * YP[:, idx]


def to_layout(target, source, t, Y, YP):
    """``(Y, YP)`` of ``source``'s unknowns (rows at times ``t``) in ``target``'s layout: each
    of its unknowns by name (a dummy derivative ``der(x)`` of one choice is the derivative of
    the state ``x`` of the other); a derivative ``source`` does not hold is taken by
    differences between the rows."""
    Y, YP = np.atleast_2d(Y), np.atleast_2d(YP)
    out_y = np.empty((len(Y), target.n))
    out_yp = np.empty((len(Y), target.n))
    for j, name in enumerate(target.names):
        col = _column(source, name, Y, YP)
        if col is None:
            raise SolverError(f"{target.name}: the variable {name!r} has no counterpart after "
                              f"the states changed")
        out_y[:, j] = col
        d = _derivative(source, name, Y, YP)
        if d is None:
            d = np.gradient(col, t) if len(t) > 1 and np.all(np.diff(t) > 0) else \
                np.zeros(len(Y))
        out_yp[:, j] = d
    return out_y, out_yp


def choice_point(system, y, yp) -> dict:
    """The values of ``system``'s unknowns and of their derivatives, by name."""
    point = {}
    for name, j in system.index.items():
        point.setdefault(name, float(y[j]))
        point.setdefault(_higher(name), float(yp[j]))
    return point


def states_of(system) -> tuple:
    reduction = system.index_reduction
    return tuple(sorted(n for n, _ in reduction.states)) if reduction is not None else ()


#: at the start of a run, the pivots' ratios to their values where the states were chosen
#: outside this range choose them again there (a start elsewhere, other parameter values)
REBASE_RANGE = (0.5, 2.0)


def rebased(system, t, y, yp):
    """``system`` compiled again with the states chosen at ``(t, y, yp)``, where a pivot's
    ratio to its value at the compile's choice is outside ``REBASE_RANGE`` (its watch would
    be relative to another configuration: of the other sign it never fires); else None."""
    names = [f"{path}.{spec.name}" for path, spec in system.event_specs]
    try:
        values = np.asarray(system.event_values(t, np.asarray(y, float), np.asarray(yp, float)),
                            dtype=float)
    except Exception:   # noqa: BLE001  (an event that cannot be evaluated there: as before)
        return None
    lo, hi = REBASE_RANGE
    off = [name for name, g in zip(names, values)
           if name.startswith(EVENT_OWNER + ".switch_") and
           not lo <= g + SWITCH_RATIO <= hi]
    return chosen_at(system, y, yp) if off else None


def switched(system, rec):
    """The system with the states chosen at the record ``rec``, or None where the choice
    made there is the one already made (or none can be made there)."""
    new = chosen_at(system, rec.y, rec.yp)
    return None if new is None or states_of(new) == states_of(system) else new


def chosen_at(system, y, yp):
    """``system``'s circuit compiled again (its parameter values, its backend) with the states
    chosen where its unknowns are ``y`` and ``y'``; None where no choice can be made there."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")     # told when the circuit was first compiled
            new = system._recompiled({}, choice_point=choice_point(system, y, yp))
    except StructureError:
        return None
    return new.use_backend(system.backend) if new.backend != system.backend else new
