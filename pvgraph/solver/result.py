"""Result containers of the DAE solvers: the solution, event records and dense output."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Optional

import numpy as np

__all__ = ["DAEResult", "EventRecord", "DenseOutput", "interpolate"]


def interpolate(t, tn, kused, psi, phi):
    """Evaluate IDA's interpolating polynomial of the last step and its derivative at t."""
    delt = t - tn
    kord = kused if kused > 0 else 1
    cy = [1.0]
    cyp = [0.0]
    c = 1.0
    d = 0.0
    gam = delt / psi[0]
    for j in range(1, kord + 1):
        d = d * gam + c / psi[j - 1]
        c = c * gam
        cy.append(c)
        cyp.append(d)
        if j < kord:
            gam = (delt + psi[j - 1]) / psi[j]
    block = phi[:kord + 1]
    return np.dot(cy, block), np.dot(cyp, block)


@dataclass
class EventRecord:
    """One located zero crossing: time, event index and name, state just before it."""

    t: float
    index: int
    name: str
    y: np.ndarray
    yp: np.ndarray
    direction: int = 0


class DenseOutput:
    """Piecewise BDF interpolant over the whole integration, ``sol(t)``.

    A scalar ``t`` gives an array of shape (n,); an array of m times gives (m, n), one row
    per time, like ``DAEResult.y``. ``sol.derivative(t)`` gives y' the same way. At an event
    with a state reset the value after the reset is returned. Outside the integrated interval
    the first or last step's polynomial is extrapolated (as scipy's ``OdeSolution`` does):
    values there are not the solution's.
    """

    def __init__(self, n):
        self.n = n
        self._t_end = []        # right end of each segment
        self._t_start = []
        self._pieces = []       # (tn, kused, psi, phi)

    def append(self, t_start, tn, kused, psi, phi):
        """Store the interpolant of one step covering [t_start, tn]."""
        self._t_start.append(t_start)
        self._t_end.append(tn)
        self._pieces.append((tn, kused, tuple(psi[:kused + 1]), phi[:kused + 1].copy()))

    def truncate(self, t):
        """End the last piece at ``t`` (an event inside its step: past it, the pieces after
        the event's action hold the solution)."""
        if self._t_end and self._t_start[-1] <= t < self._t_end[-1]:
            self._t_end[-1] = t

    @property
    def t_min(self):
        return self._t_start[0] if self._t_start else None

    @property
    def t_max(self):
        return self._t_end[-1] if self._t_end else None

    def _evaluate(self, t, which):
        scalar = np.ndim(t) == 0
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        if not self._pieces:
            raise ValueError("dense output is empty: no step was taken")
        ends = np.asarray(self._t_end)
        # first segment ending after t: at an event time this is the one after the reset
        idx = np.searchsorted(ends, ts, side="right")
        idx = np.clip(idx, 0, len(ends) - 1)
        out = np.empty((ts.size, self.n))
        for i, (tq, k) in enumerate(zip(ts, idx)):
            tn, kused, psi, phi = self._pieces[k]
            out[i] = interpolate(tq, tn, kused, psi, phi)[which]
        return out[0] if scalar else out

    def __call__(self, t):
        return self._evaluate(t, 0)

    def derivative(self, t):
        """Interpolated y'(t)."""
        return self._evaluate(t, 1)


@dataclass
class DAEResult:
    """Solution of F(t, y, y') = 0.

    Attributes
    ----------
    t : ndarray (m,)
        Output times.
    y, yp : ndarray (m, n)
        Values and derivatives, one row per time.
    events : list of EventRecord
        Every located event in time order (time, index, name, state before the event).
    t_events : ndarray (k,)
        Times of ``events``.
    stats : dict
        ``nsteps``, ``nre`` (residual calls, including finite-difference Jacobians and
        initialisation), ``nje``, ``nlu``, ``netf``, ``ncfn``, ``nni``, ``nroot``; and
        ``nrescue`` where the built-in (Python) step went on past a corrector that failed
        down to a vanishing step (an algebraic pressure between two closed valves with no
        volume: the algebraic variables solved with a line search a little beyond the last
        step, the run restarted there; see ``solve._rescue``).
    success : bool
        True when the end of the interval or a terminal event was reached.
    message : str
        Why the integration stopped.
    sol : DenseOutput or None
        Continuous solution when ``dense_output=True``.
    """

    t: np.ndarray
    y: np.ndarray
    yp: np.ndarray
    events: list = field(default_factory=list)
    t_events: np.ndarray = field(default_factory=lambda: np.empty(0))
    stats: dict = field(default_factory=dict)
    success: bool = True
    message: str = ""
    sol: Optional[Callable[[Any], np.ndarray]] = None
